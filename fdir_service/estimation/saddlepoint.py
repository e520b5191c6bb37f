"""False-alarm and missed-detection probabilities by saddlepoint approximation (SPEC section 6).

The AJMRPF (thesis ch. 6) tests, for each sensor fault, H0: y_k ~ N(mu0_k, s0_k^2) against
H1: y_k ~ N(mu1_k, s1_k^2) over the last n residual samples. The statistic is the mean log-likelihood
ratio Xbar = (1/n) sum_k X_k, X_k = a_k y_k^2 + b_k y_k + c_k (thesis eq. 6.43-6.46), and

    Pfa(alpha) = P(Xbar > alpha | H0),    Pmd(alpha) = P(Xbar < alpha | H1),

each by the Lugannani-Rice formula for independent, non-identically distributed samples (thesis
Prop. 2-3, eq. 6.47-6.58), with Daniels' (1987) second-order term by default (``order=2``): the
first-order formula alone is up to 5 % off in the tails when the variances differ and n = 3.
`roc_optimal` is the thesis's threshold search (Alg. 6.4-6.5). Formulas, domain and limit handling,
measured accuracy and speed: docs/saddlepoint.md.

Inputs are SI residual means and standard deviations (any common unit: the statistic is
dimensionless). Arrays of shape (n,), or (..., n) for the batched `roc_optimal`.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.special import ndtr

__all__ = ["pfa_pmd", "roc_optimal", "bench_roc_optimal"]

_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)
# Inputs are normalised per sample (y' = (y - mu0) / s0); the separation d = (mu1 - mu0) / s0 and
# the standard-deviation ratio r = s1 / s0 are clipped so that every intermediate stays finite
# (fourth cumulants involve r^8 d^2). Beyond these bounds the probabilities are far below 1e-300
# for the mean shift, and the variance ratio is physically meaningless.
_D_MAX = 1e20
_R_MIN, _R_MAX = 1e-20, 1e20
_SERIES_X = 0.01  # |x| = |2 q T| below which F(x), S(x) use their power series
_U0 = 0.5  # |u| scale below which the second-order term is interpolated across T = 0
_MAXIT = 100
_RTOL = 1e-10  # Newton stops once a step is below this relative size (error then ~ RTOL^2)
_W_CLIP = 1e6  # phi(w) and Phi(w) are exactly 0 / 1 in double precision long before this

# Power series (coefficients in ascending powers of x), used for |x| < _SERIES_X:
#   F(x) = (x / (1 - x) + log(1 - x)) / x^2 = sum_{j>=2} (j - 1) / j x^(j - 2)
#   S(x) = (2 / (1 - x)^2 - 4 F(x)) / x    = sum_{m>=1} 2 m (m + 1) / (m + 2) x^(m - 1)
# 6 terms: truncation 0.01^6 = 1e-12 relative; the direct forms lose at most ~1e-11 at |x| = 0.01.
# Both are evaluated in one Horner pass (row 0: F, row 1: S).
_FS_COEF = np.array(
    [[(j - 1) / j for j in range(2, 8)], [2 * m * (m + 1) / (m + 2) for m in range(1, 7)]]
)[:, ::-1].T.copy()  # (6, 2), highest power first


def _avg(x: np.ndarray) -> np.ndarray:
    """Mean over the trailing sample axis (np.add.reduce: a few us cheaper than ndarray.mean)."""
    return np.add.reduce(x, -1) / x.shape[-1]


def _fs_series(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Power series of F(x) and S(x) (see `_fs`), one Horner pass on a trailing (F, S) axis."""
    xx = x[..., None]
    out = _FS_COEF[0] * xx + _FS_COEF[1]
    for c in _FS_COEF[2:]:
        out = out * xx + c
    return out[..., 0], out[..., 1]


def _check(mu0, s0, mu1, s1) -> np.ndarray:
    """Validated (4, ..., n) float array [mu0, s0, mu1, s1] (one array op on the fast path)."""
    try:
        arr = np.array((mu0, s0, mu1, s1), dtype=float)
    except ValueError:  # different shapes: broadcast them
        arr = np.array(np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (mu0, s0, mu1, s1))))
    if arr.ndim < 2 or arr.shape[-1] < 1:
        raise ValueError("mu0, s0, mu1, s1 must have a trailing sample axis of length n >= 1")
    if not (np.isfinite(arr).all() and (arr[1::2] > 0).all()):
        raise ValueError("mu0, mu1 must be finite and s0, s1 finite and > 0")
    return arr


def hypotheses(mu0, s0, mu1, s1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample CGF parameters (g, h^2, q) of X_k, each (2, ..., n): index 0 under H0, 1 under H1.

    With y' = (y - mu0)/s0 ~ N(0, 1) under H0 and N(d, r^2) under H1 (d = (mu1 - mu0)/s0,
    r = s1/s0), X_k = A y'^2 + B y' + C exactly as eq. 6.44-6.46 with A = (1 - 1/r^2)/2,
    B = d/r^2, C = -log r - d^2/(2 r^2). For y' ~ N(m, s^2), X_k = g + h z + q z^2 with z ~ N(0, 1),
    g = A m^2 + B m + C, h = s (2 A m + B), q = A s^2, so
        H0: g = C,                h = B = d/r^2,  q = A = (r^2 - 1)/(2 r^2)
        H1: g = d^2/2 - log r,    h = r d,        q = (r^2 - 1)/2.
    g is also X_k evaluated at the hypothesis mean (the ends of Alg. 6.4's threshold grid).
    """
    with np.errstate(over="ignore", under="ignore"):
        d = np.clip((mu1 - mu0) / s0, -_D_MAX, _D_MAX)
        r = np.clip(s1 / s0, _R_MIN, _R_MAX)
    rr = r * r
    dd = d * d
    rm = (r - 1.0) * (r + 1.0)  # exact 0 when s1 == s0, accurate near r = 1
    log_r = np.log(r)
    g = np.array((-log_r - 0.5 * dd / rr, 0.5 * dd - log_r))
    h2 = np.array((dd / (rr * rr), rr * dd))
    q = np.array((rm / (2.0 * rr), 0.5 * rm))
    return g, h2, q


def kbar12(T: np.ndarray, g, h2, q) -> tuple[np.ndarray, np.ndarray]:
    """Kbar'(T) and Kbar''(T) (mean over the trailing sample axis) of eq. 6.49 / 6.55.

    K_k(t) = t g + t^2 h^2 / (2 D) - log(D)/2, D = 1 - 2 q t (SPEC section 6), so
    K_k'(t) = g + h^2 t (1 - q t) / D^2 + q / D and K_k''(t) = h^2 / D^3 + 2 q^2 / D^2 (> 0).
    """
    t = T[..., None]
    qt = q * t
    iD = 1.0 / (1.0 - 2.0 * qt)
    k1 = _avg(g + h2 * (t * iD) * ((1.0 - qt) * iD) + q * iD)
    k2 = _avg(iD * iD * (h2 * iD + 2.0 * q * q))
    return k1, k2


def domain(q) -> tuple[np.ndarray, np.ndarray]:
    """Open interval (t_lo, t_hi) where 1 - 2 q_k t > 0 for every k (eq. 6.50, 6.56)."""
    with np.errstate(divide="ignore"):
        inv = 0.5 / q
    t_hi = np.where(q > 0, inv, np.inf).min(-1)
    t_lo = np.where(q < 0, inv, -np.inf).max(-1)
    return t_lo, t_hi


def support(g, h2, q) -> tuple[np.ndarray, np.ndarray]:
    """Essential infimum and supremum of Xbar (finite only when every a_k has one sign)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        extra = h2 / (4.0 * np.abs(q))
    lin = h2 > 0  # a_k = 0 but b_k != 0: X_k is Gaussian, unbounded both ways
    sup = _avg(np.where(q > 0, np.inf, np.where(q < 0, g + extra, np.where(lin, np.inf, g))))
    inf = _avg(np.where(q < 0, -np.inf, np.where(q > 0, g - extra, np.where(lin, -np.inf, g))))
    return inf, sup


def solve_saddlepoint(alpha: np.ndarray, g, h2, q) -> np.ndarray:
    """T solving Kbar'(T) = alpha inside the CGF's domain, vectorised over alpha.

    When q_k = a_k s_k^2 is the same for every sample (equal variances, q = 0; or the AJMRPF's
    variance change with a common ratio), the equation is a quadratic in T and is solved in closed
    form (`closed_form`). Otherwise: bracketed Newton-Raphson from T = 0 (`newton`).
    `alpha` must lie strictly inside the support of Xbar (callers answer the rest exactly).
    """
    qc = q[..., :1]
    if (q == qc).all():
        T = closed_form(alpha, g, h2, qc[..., 0])
    else:
        T = newton(alpha, g, h2, q)
    # A root closer to the domain edge than double precision resolves (only for absurd inputs,
    # e.g. s1/s0 ~ 1e20) is held at the last representable point strictly inside.
    if (q * T[..., None] < 0.5).all():
        return T
    t_lo, t_hi = domain(q)
    return np.clip(T, np.nextafter(t_lo, np.inf), np.nextafter(t_hi, -np.inf))


def closed_form(alpha: np.ndarray, g, h2, q) -> np.ndarray:
    """Saddlepoint for a common q: multiplying Kbar'(T) = alpha by D^2 (D = 1 - 2 q T) gives
    A2 T^2 + A1 T + A0 = 0, A2 = -q (4 q e + hb), A1 = hb + 4 q e - 2 q^2, A0 = q - e, with
    e = alpha - mean(g), hb = mean(h^2). Exactly one root has D > 0 (the other is the image of
    the negative root in v = 1/D); for q -> 0 it tends to the Gaussian T = e / hb without loss.
    One Newton step polishes the rounding of the quadratic formula."""
    e = alpha - _avg(g)
    hb = _avg(h2)
    a2 = -q * (4.0 * q * e + hb)
    a1 = hb + 4.0 * q * e - 2.0 * q * q
    a0 = q - e
    root = np.sqrt(np.maximum(a1 * a1 - 4.0 * a2 * a0, 0.0))
    s = a1 + np.where(a1 >= 0, root, -root)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_a = -2.0 * a0 / s
        t_b = -s / (2.0 * a2)
    d_a = np.where(np.isfinite(t_a), 1.0 - 2.0 * q * t_a, -np.inf)
    d_b = np.where(np.isfinite(t_b), 1.0 - 2.0 * q * t_b, -np.inf)
    T = np.where(d_a >= d_b, t_a, t_b)
    T = np.where(np.isfinite(T), T, 0.0)
    k1, k2 = kbar12(T, g, h2, q[..., None])
    Tn = T - (k1 - alpha) / k2
    ok = (1.0 - 2.0 * q * Tn > 0) & np.isfinite(Tn)
    return np.where(ok, Tn, T)


def newton(alpha: np.ndarray, g, h2, q) -> np.ndarray:
    """Bracketed Newton-Raphson from T = 0 (safeguarded as Numerical Recipes' rtsafe).

    Kbar' is increasing on the domain (Kbar'' > 0), so each evaluation tightens a bracket [lo, hi]
    that starts as the domain itself; a Newton step that would leave the bracket (plain Newton can
    jump past 1/(2 q_k), where the CGF does not exist) or that is not halving the previous step
    is replaced by bisection (by geometric expansion on an unbounded side); a step right after a
    bisection is always a Newton try, so the bisection cannot lock.
    """
    lo, hi = domain(q)
    lo = np.broadcast_to(lo, alpha.shape).copy()
    hi = np.broadcast_to(hi, alpha.shape).copy()
    T = np.zeros_like(alpha)
    newton_old = np.full_like(alpha, np.inf)  # last Newton step taken (inf after a bisection)
    for _ in range(_MAXIT):
        k1, k2 = kbar12(T, g, h2, q)
        f = k1 - alpha
        lo = np.where(f < 0, T, lo)
        hi = np.where(f > 0, T, hi)
        step = f / k2
        Tn = T - step
        small = np.abs(step) <= _RTOL * np.abs(T)  # converged (the step is rounding noise)
        bad = ~((Tn > lo) & (Tn < hi)) | (np.abs(step) > 0.5 * np.abs(newton_old))
        bad &= (f != 0) & ~small
        newton_old = np.where(bad, np.inf, step)
        if bad.any():
            lo_f, hi_f = np.isfinite(lo), np.isfinite(hi)
            with np.errstate(invalid="ignore", over="ignore"):
                mid = np.where(
                    lo_f & hi_f,
                    0.5 * lo + 0.5 * hi,
                    np.where(hi_f, hi - (1.0 + np.abs(hi)), lo + (1.0 + np.abs(lo))),
                )
            Tn = np.where(bad, mid, Tn)
        Tn = np.where((f == 0) | small, T, Tn)
        done = np.abs(Tn - T) <= _RTOL * np.abs(Tn)
        T = Tn
        if done.all():
            break
    return T


def _lr_terms(T: np.ndarray, g, h2, q, n: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """(w, c) at the saddlepoint T so that P(Xbar > alpha) = 1 - Phi(w) + phi(w) c (eq. 6.37).

    w = sign(T) sqrt(2 n (T alpha - Kbar(T))) = T sqrt(n G), u = T sqrt(n Kbar''),
    c = 1/u - 1/w [+ Daniels' second-order term], all written without cancellation at T -> 0:
    T Kbar' - Kbar = T^2 G / 2 with G = mean(h^2/D^2 + 4 q^2 F(x)), x = 2 q T, and
    Kbar'' - G = T mean(2 q (h^2/D^3 + q^2 S(x))), so 1/u - 1/w has no 1/T and no 1/q.
    The second-order term's own pieces (each ~ 1/u^3) cancel near T = 0: there, |T| < tau with
    tau = U0 / sqrt(n Kbar''(0)) (|u| ~ U0), it is interpolated linearly in T between +-tau (it is
    O(n^-1/2) and smooth; |2 q_k tau| <= U0 sqrt(2) keeps +-tau inside the CGF's domain). The two
    end points ride along as two extra columns of the same vectorised pass.
    T (..., A); g, h2, q (..., 1, n).
    """
    qq = q * q
    n_a = T.shape[-1]
    near = None
    if order >= 2:
        tau = _U0 / np.sqrt(n * _avg(h2 + 2.0 * qq))  # (..., 1)
        near = np.abs(T) < tau
        if near.any():
            T = np.concatenate((T, -tau, tau), axis=-1)
        else:
            near = None
    x = (2.0 * q) * T[..., None]
    iD = 1.0 / (1.0 - x)
    iD2 = iD * iD
    F, S = _fs(x, iD, iD2)
    h2iD2 = h2 * iD2
    k2 = _avg(iD2 * (2.0 * qq) + h2iD2 * iD)
    G = _avg(h2iD2 + (4.0 * qq) * F)
    E = _avg((2.0 * q) * (h2iD2 * iD + qq * S))
    sk, sg = np.sqrt(k2), np.sqrt(G)
    rn = np.sqrt(n)
    w = T * (rn * sg)
    c = -E / (rn * sk * sg * (sk + sg))
    if order >= 2:
        dan = _daniels(T, q, h2, n, k2, w, iD, iD2)
        if near is not None:
            lo_end, hi_end = dan[..., n_a : n_a + 1], dan[..., n_a + 1 :]
            T, w, c, dan = T[..., :n_a], w[..., :n_a], c[..., :n_a], dan[..., :n_a]
            interp = lo_end + (T + tau) / (2.0 * tau) * (hi_end - lo_end)
            dan = np.where(near, interp, dan)
        c = c + dan
    return w, c


def _fs(x, iD, iD2) -> tuple[np.ndarray, np.ndarray]:
    """F(x) = (x/(1-x) + log(1-x))/x^2 and S(x) = (2/(1-x)^2 - 4 F(x))/x, series near x = 0."""
    small = np.abs(x) < _SERIES_X
    if small.any():
        xs = np.where(small, x, 0.0)
        xd = np.where(small, 0.5, x)
        iDd = np.where(small, 2.0, iD)
        F_dir = (xd * iDd + np.log1p(-xd)) / (xd * xd)
        S_dir = (2.0 * iDd * iDd - 4.0 * F_dir) / xd
        F_ser, S_ser = _fs_series(xs)
        return np.where(small, F_ser, F_dir), np.where(small, S_ser, S_dir)
    F = (x * iD + np.log1p(-x)) / (x * x)
    return F, (2.0 * iD2 - 4.0 * F) / x


def _daniels(T, q, h2, n, k2, w, iD, iD2) -> np.ndarray:
    """Daniels' (1987) second-order term (1/u)(l4/8 - 5 l3^2/24) - l3/(2 u^2) - 1/u^3 + 1/w^3.

    l3 = K3/(sqrt(n) K2^1.5), l4 = K4/(n K2^2) from the mean's cumulant derivatives at T; per
    sample (D = 1 - 2 q t): K3 = 6 q h^2/D^4 + 8 q^3/D^3, K4 = 48 q^2 h^2/D^5 + 48 q^4/D^4.
    """
    qq = q * q
    iD3 = iD2 * iD
    k3 = _avg(iD3 * ((6.0 * q) * h2 * iD + 8.0 * qq * q))
    k4 = _avg((48.0 * qq) * iD3 * iD * (h2 * iD + qq))
    l3 = k3 / (np.sqrt(n) * k2 * np.sqrt(k2))
    l4 = k4 / (n * k2 * k2)
    iu = 1.0 / (T * np.sqrt(n * k2))
    return iu * (l4 / 8.0 - (5.0 / 24.0) * l3 * l3 - 0.5 * l3 * iu - iu * iu) + 1.0 / (w * w * w)


# Tail sign per hypothesis: H0 gives the upper tail (Pfa), H1 the lower tail (Pmd).
_SIDE = np.array([-1.0, 1.0])


def pfa_pmd_core(alpha: np.ndarray, hyp, n: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """General (unequal-variance capable) path. alpha (..., A); hyp = (g, h2, q), (2, ..., 1, n)."""
    g, h2, q = hyp
    g0, h20, q0 = g[0], h2[0], q[0]
    with np.errstate(all="ignore"):
        inf, sup = support(g0, h20, q0)  # the support of Xbar is the same under H0 and H1
        degenerate = _avg(h20 + q0 * q0) == 0  # every X_k is constant: Xbar = mean(g)
        below = alpha <= inf
        above = alpha >= sup
        inside = ~(below | above | degenerate)
        # Points outside the open support are answered exactly; solve with a harmless stand-in.
        a_solve = np.where(inside, alpha, _avg(g0 + q0))
        T0 = solve_saddlepoint(a_solve, g0, h20, q0)
        # The H1 CGF is the H0 CGF shifted by one: K1(t) = K0(t + 1), because X is the exact
        # log-likelihood ratio; so the H1 saddlepoint is T0 - 1 (no second solve). Both tails are
        # evaluated in one stacked pass, each directly (eq. 6.52, 6.58): the lower tail is
        # Phi(w) - phi(w) c, never 1 minus an upper tail.
        w, c = _lr_terms(np.array((T0, T0 - 1.0)), g, h2, q, n, order)
        w = np.clip(w, -_W_CLIP, _W_CLIP)
        side = _SIDE.reshape((2,) + (1,) * (w.ndim - 1))
        p = np.clip(ndtr(side * w) - side * (_INV_SQRT_2PI * np.exp(-0.5 * w * w) * c), 0.0, 1.0)
        pfa, pmd = p[0], p[1]
        # Last-resort guard (never seen on inputs of physical size, see the property test): a
        # non-finite value falls back to which side of the hypothesis mean Kbar'(0) alpha is.
        bad = np.isnan(p)
        if bad.any():
            pfa = np.where(bad[0], (alpha < _avg(g0 + q0)) * 1.0, pfa)
            pmd = np.where(bad[1], (alpha > _avg(g[1] + q[1])) * 1.0, pmd)
    if inside.all():
        return pfa, pmd
    point = _avg(g0)
    deg_up = np.where(alpha < point, 1.0, np.where(alpha > point, 0.0, 0.5))
    pfa = np.where(inside, pfa, np.where(degenerate, deg_up, np.where(below, 1.0, 0.0)))
    pmd = np.where(inside, pmd, np.where(degenerate, 1.0 - deg_up, np.where(below, 0.0, 1.0)))
    return pfa, pmd


def _gaussian_pfa_pmd(alpha: np.ndarray, hyp, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact answer when every a_k = 0 (s1_k == s0_k): Xbar is Gaussian under both hypotheses,
    mean mean_k(g), variance mean_k(h^2)/n (Lugannani-Rice reproduces this exactly)."""
    g, h2, _ = hyp
    m0, m1 = _avg(g[0]), _avg(g[1])
    sd = np.sqrt(_avg(h2[0]) / n)
    pfa, pmd = ndtr((m0 - alpha) / (sd + (sd == 0))), ndtr((alpha - m1) / (sd + (sd == 0)))
    if (sd == 0).any():  # identical hypotheses: Xbar is the point 0 = m0 = m1; at alpha = 0 the
        # answer is the d' -> 0 limit of Phi(-d'/2), 1/2
        step = np.where(alpha < m0, 1.0, np.where(alpha > m0, 0.0, 0.5))
        pfa = np.where(sd == 0, step, pfa)
        pmd = np.where(sd == 0, 1.0 - step, pmd)
    return pfa, pmd


def _dispatch(alpha, hyp, n, order):
    if not (hyp[2] != 0).any():
        return _gaussian_pfa_pmd(alpha, hyp, n)
    return pfa_pmd_core(alpha, hyp, n, order)


def pfa_pmd(
    alpha: float | np.ndarray,
    mu0: np.ndarray,
    s0: np.ndarray,
    mu1: np.ndarray,
    s1: np.ndarray,
    order: int = 2,
) -> tuple[np.ndarray, np.ndarray]:
    """Pfa = P(Xbar > alpha | H0) and Pmd = P(Xbar < alpha | H1) (thesis eq. 6.51-6.58).

    mu0, s0, mu1, s1: (n,) hypothesis means and standard deviations of the last n samples (s > 0);
    alpha: LLR threshold, scalar or any-shape array. Returns two float64 arrays of alpha's shape.
    order: 1 = the thesis's Lugannani-Rice; 2 (default) adds Daniels' second-order term. Equal
    variances (every a_k = 0) are answered by the exact Gaussian formula, which both orders equal.
    """
    mu0, s0, mu1, s1 = _check(mu0, s0, mu1, s1)
    if mu0.ndim != 1:
        raise ValueError("pfa_pmd takes (n,) arrays; use roc_optimal for batches")
    a = np.asarray(alpha, dtype=float)
    if not np.isfinite(a).all():
        raise ValueError("alpha must be finite")
    hyp = hypotheses(mu0[None, :], s0[None, :], mu1[None, :], s1[None, :])  # (2, 1, n)
    pfa, pmd = _dispatch(a.reshape(-1), hyp, mu0.shape[-1], order)
    return pfa.reshape(a.shape), pmd.reshape(a.shape)


def roc_optimal(
    mu0: np.ndarray,
    s0: np.ndarray,
    mu1: np.ndarray,
    s1: np.ndarray,
    n_alpha: int = 50,
    order: int = 2,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The thesis's threshold search (Alg. 6.4-6.5): best (Pfa, Pmd, alpha) on a threshold grid.

    n_alpha thresholds evenly spaced (endpoints included) from E[Xbar | H0] to E[Xbar | H1] (with
    equal variances: Xbar at the H0 and H1 means, eq. 6.63-6.66); returns the one minimising
    sqrt(Pfa^2 + Pmd^2) (eq. 2.15).
    mu0, s0, mu1, s1: (n,) or batched (..., n) (e.g. one row per fault); returns float64 scalars
    (0-d arrays) or arrays of shape (...).
    """
    mu0, s0, mu1, s1 = _check(mu0, s0, mu1, s1)
    if n_alpha < 1:
        raise ValueError("n_alpha must be >= 1")
    n = mu0.shape[-1]
    frac = _frac(n_alpha)
    if (s0 == s1).all():
        # Equal variances (the thesis's case): Xbar ~ N(-/+ D2/(2n), D2/n^2) under H0/H1, with
        # D2 = d'^2 = sum_k ((mu1_k - mu0_k)/s0_k)^2; the grid runs from -D2/(2n) to +D2/(2n).
        with np.errstate(over="ignore"):
            d = np.clip((mu1 - mu0) / s0, -_D_MAX, _D_MAX)
        d2 = (d * d).sum(-1)[..., None]
        m = d2 / (2 * n)
        sd = np.sqrt(d2) / n + (d2 == 0)  # d2 == 0: identical hypotheses, every z = 0 -> 1/2
        alphas = m * (2.0 * frac - 1.0)
        pfa = ndtr((-m - alphas) / sd)
        pmd = ndtr((alphas - m) / sd)
    else:
        hyp = hypotheses(mu0[..., None, :], s0[..., None, :], mu1[..., None, :], s1[..., None, :])
        # The grid runs from E[Xbar | H0] to E[Xbar | H1], E[X_k] = g + q (see hypotheses): with
        # equal variances (q = 0) Xbar at the hypothesis means, as eq. 6.63-6.66; a pure variance
        # test (mu1 = mu0, a noisy sensor) would otherwise have one threshold, the support's end.
        a_min, a_max = _avg(hyp[0] + hyp[2])  # (..., 1) each
        alphas = a_min + (a_max - a_min) * frac  # (..., n_alpha)
        pfa, pmd = pfa_pmd_core(alphas, hyp, n, order)
    best = np.argmin(np.hypot(pfa, pmd), axis=-1)[..., None]  # hypot: no underflow of tiny tails
    if best.ndim == 1:
        i = best[0]
        return pfa[i], pmd[i], alphas[i]
    take = lambda arr: np.take_along_axis(arr, best, axis=-1)[..., 0]  # noqa: E731
    return take(pfa), take(pmd), take(alphas)


_FRAC_CACHE: dict[int, np.ndarray] = {}


def _frac(n_alpha: int) -> np.ndarray:
    """linspace(0, 1, n_alpha), cached (the filter calls roc_optimal at every step)."""
    f = _FRAC_CACHE.get(n_alpha)
    if f is None:
        f = _FRAC_CACHE[n_alpha] = np.linspace(0.0, 1.0, n_alpha)
    return f


def bench_roc_optimal(n: int = 3, n_alpha: int = 50, variances: str = "equal", repeats: int = 2000) -> float:
    """Median microseconds per `roc_optimal` call on a typical AJMRPF input (n samples, one fault).

    variances: "equal" (the thesis's case, s1 = s0), "ratio" (variance change with one ratio for
    the window: closed-form saddlepoint) or "mixed" (a different ratio per sample: Newton).
    """
    rng = np.random.default_rng(0)
    mu0 = np.zeros(n)
    s0 = np.full(n, 2.0)
    mu1 = rng.normal(3.0, 1.0, n)
    s1 = {"equal": s0, "ratio": 1.5 * s0, "mixed": s0 * rng.uniform(0.7, 1.6, n)}[variances]
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        roc_optimal(mu0, s0, mu1, s1, n_alpha)
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


def _bench_numpy_op(repeats: int = 20000) -> float:
    """Median microseconds of one small numpy multiply ((2, 50, 3) arrays): the machine's unit cost."""
    a = np.ones((2, 50, 3))
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        a * a
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


if __name__ == "__main__":
    print(f"reference: one small numpy op {_bench_numpy_op():.2f} us")
    for kind, reps in (("equal", 2000), ("ratio", 500), ("mixed", 500)):
        us = bench_roc_optimal(variances=kind, repeats=reps)
        print(f"roc_optimal n=3 n_alpha=50, {kind} variances: {us:.1f} us/call")
