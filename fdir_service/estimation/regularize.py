"""Regularisation with the Epanechnikov kernel (thesis [2.5.6.3], Alg. 2.7, eq. 2.60-2.64).

After resampling, x_i <- x_i + h D eps_i with D D^T = P (the weighted covariance of the cloud
before resampling) and eps_i ~ Epanechnikov kernel on the unit ball of R^n, density
prop. to 1 - |x|^2. Bandwidth h = k h_opt, h_opt = A N^(-1/(n+4)),
A = [8 c_n^-1 (n+4) (2 sqrt(pi))^n]^(1/(n+4)), c_n the unit-ball volume.

Sampler (SPEC section 5): eps = r u with u uniform on the unit sphere and r^2 ~ Beta(n/2, 2).
With g ~ N(0, I_n) (so u = g/|g| and |g|^2/2 ~ Gamma(n/2), independent of u) and
G ~ Gamma(2) = -log(U1 U2), r^2 = (|g|^2/2) / (|g|^2/2 + G) is Beta(n/2, 2), hence
eps = g / sqrt(|g|^2 + 2 G): n normals, two uniforms and one log per particle, no Beta draw.
E r^2 = n/(n+4), so Cov(eps) = I/(n+4).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dpotrf


def unit_ball_volume(n: int) -> float:
    """c_n = pi^(n/2) / Gamma(n/2 + 1)."""
    return math.pi ** (n / 2) / math.gamma(n / 2 + 1)


def h_opt(n: int, N: int) -> float:
    """Optimal Epanechnikov bandwidth for a Gaussian target (eq. 2.63-2.64, k = 1)."""
    A = (8.0 / unit_ball_volume(n) * (n + 4) * (2.0 * math.sqrt(math.pi)) ** n) ** (1.0 / (n + 4))
    return A * N ** (-1.0 / (n + 4))


def bandwidth(k: float, n: int, N: int) -> float:
    """h = k h_opt (the thesis uses k = 0.2: n = 7 -> 0.3115, n = 6 -> 0.2817 at N = 1000)."""
    return k * h_opt(n, N)


def epanechnikov(rng: np.random.Generator, n: int, N: int) -> np.ndarray:
    """N draws (n, N) from the Epanechnikov kernel on the unit ball of R^n (mean 0, Cov I/(n+4))."""
    g = rng.standard_normal((n, N))
    uv = rng.random((2, N))
    uv[0] *= uv[1]
    two_gamma2 = np.log(uv[0])
    two_gamma2 *= -2.0                                        # 2 G, G ~ Gamma(2)
    two_gamma2 += np.einsum("ij,ij->j", g, g)                 # |g|^2 + 2 G
    g /= np.sqrt(two_gamma2)
    return g


_IX: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}
"""live directions -> np.ix_ of them (a handful of patterns: JMRPF mode 0 drops the fault rows)."""


def covariance_factor(P: np.ndarray) -> np.ndarray:
    """D (n, n) with D D^T = P, lower-triangular Cholesky over the directions that carry variance.

    Rows/columns with zero variance (e.g. mode-0 fault entries of a JMRPF, pinned at 0) get zero
    columns; if the rest is not numerically positive definite, a symmetric eigen-factor
    V sqrt(max(lambda, 0)) is used instead.
    """
    n = P.shape[0]
    # the live directions as a Python list: n <= ~10, so this beats numpy's per-call overhead
    idx = [i for i, d in enumerate(P.diagonal().tolist()) if d > 1e-300]
    if len(idx) == n:
        L, info = dpotrf(P, lower=1, clean=1)    # LAPACK directly: numpy's wrapper costs more
        if info == 0:
            return L
    D = np.zeros((n, n))
    if not idx:
        return D
    key = tuple(idx)
    ix = _IX.get(key)
    if ix is None:
        ix = _IX[key] = np.ix_(idx, idx)
    Pl = P[ix]
    Dl, info = dpotrf(Pl, lower=1, clean=1)
    if info != 0:
        lam, V = np.linalg.eigh(0.5 * (Pl + Pl.T))
        Dl = V * np.sqrt(np.maximum(lam, 0.0))
    D[ix] = Dl
    return D


def regularize(X: np.ndarray, P: np.ndarray, h: float, rng: np.random.Generator,
               shrink: bool = False) -> np.ndarray:
    """Jitter a resampled cloud X (n, N) in place: X += h D eps (Alg. 2.7); returns X.

    The jitter's covariance is h^2 P / (n + 4) (Cov eps = I / (n + 4)).
    shrink=True (Liu-West): first pull every particle towards the cloud mean by
    a = sqrt(1 - h^2 / (n + 4)) so that the jitter does not inflate the covariance (the spread
    stays P instead of (1 + h^2 / (n + 4)) P); used by the baseline RPF/RRPF, whose unobservable
    directions (ch4: p_d and both altitude faults moved together) would otherwise grow at every
    resample (SPEC section 5).
    """
    n, N = X.shape
    D = covariance_factor(P)
    if shrink:
        a = math.sqrt(max(1.0 - h * h / (n + 4), 0.0))
        mean = X.mean(axis=1, keepdims=True)
        X *= a
        X += (1.0 - a) * mean
    X += (h * D) @ epanechnikov(rng, n, N)
    return X


MIN_EFF_PER_STATE = 2.0
"""A mode pattern whose effective particle count is below this x n borrows the global covariance."""


def mode_codes(modes: np.ndarray) -> np.ndarray:
    """(N,) int64 code of each particle's mode pattern from modes (nf, N) bool: bit j = fault j
    (one float product, exact below 2^53; a loop over the faults beyond 52)."""
    nf = modes.shape[0]
    if nf == 1:
        return modes[0].astype(np.int64)
    if nf <= 52:
        return (np.exp2(np.arange(nf)) @ modes).astype(np.int64)
    code = np.zeros(modes.shape[1], dtype=np.int64)
    for j in range(nf):
        code |= modes[j].astype(np.int64) << j
    return code


def pattern_index(code: np.ndarray, nf: int) -> tuple[np.ndarray, np.ndarray]:
    """(groups (g,) the mode patterns present in code (N,), ascending; inv (N,) each particle's
    index into groups). A bincount for nf <= 16; a sort beyond, where a bincount would span 2^nf
    codes (the catalogue's 19 entries: 2^18 and more each step, 1-2 ms of it)."""
    if nf > 16:
        return np.unique(code, return_inverse=True)
    counts = np.bincount(code)
    groups = np.flatnonzero(counts)
    lut = np.zeros(counts.size, dtype=np.intp)
    lut[groups] = np.arange(groups.size)
    return groups, lut[code]


def _patterns(code: np.ndarray, nf: int) -> tuple[list[int], list[int]]:
    """The mode patterns present in code (N,), ascending, and their particle counts."""
    groups, inv = pattern_index(code, nf)
    return groups.tolist(), np.bincount(inv, minlength=groups.size).tolist()


POO_CONDITION_MAX = 1e10
"""Above this condition number the mode-0 block is taken as singular (pinv instead of solve)."""


def _pinv_from_eigh(lam: np.ndarray, V: np.ndarray) -> np.ndarray:
    """numpy.linalg.pinv(A, hermitian=True) of a symmetric A from its eigh (lam, V), bit for bit:
    the same steps as numpy's (its hermitian svd, then the cut at 1e-15 of the largest)."""
    sgn = np.copysign(1.0, lam)
    s = np.abs(lam)
    order = np.argsort(s)[::-1]
    sgn, s, u = sgn[order], s[order], V[:, order]
    vt = np.transpose(u * sgn[None, :]).conjugate()
    large = s > 1e-15 * np.amax(s)
    s = np.divide(1, s, where=large, out=s)
    s[~large] = 0
    return np.matmul(np.transpose(vt), np.multiply(s[:, None], np.transpose(u)))


def _solve_or_pinv(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^-1 B by solve (bit for bit what logs recorded before the robust monitor replay with), or
    pinv(A) B where A (symmetric) is (near) singular: mode-0 entries that co-vary exactly (a
    drifting pair). One eigen-decomposition gives both the condition number (|lambda| max / min,
    A's singular values) and the pseudo-inverse."""
    lam, V = np.linalg.eigh(A)
    s = np.abs(lam)
    if s.max() < POO_CONDITION_MAX * s.min():
        return np.linalg.solve(A, B)
    return _pinv_from_eigh(lam, V) @ B


_SPLIT: dict[tuple[int, tuple[int, ...]], tuple] = {}
"""(n, off) -> the np.ix_ index pairs of (off, off), (keep, off), (keep, keep): a handful of
mode patterns recur at every resample."""


def _split(n: int, off: list[int]) -> tuple:
    key = (n, tuple(off))
    hit = _SPLIT.get(key)
    if hit is None:
        keep = [i for i in range(n) if i not in off]
        if len(_SPLIT) > 4096:
            _SPLIT.clear()
        hit = _SPLIT[key] = (np.ix_(off, off), np.ix_(keep, off), np.ix_(keep, keep))
    return hit


def conditioned_on_mode0(P: np.ndarray, off: list[int]) -> np.ndarray:
    """P (n, n) conditioned on the entries `off` being 0 (Schur complement), those rows and columns
    zeroed; a new array."""
    P = P.copy()
    if off:
        oo, ko, kk = _split(P.shape[0], off)
        d = P.diagonal()
        if all(d[i] > 1e-300 for i in off):
            Pko = P[ko]
            P[kk] -= Pko @ _solve_or_pinv(P[oo], Pko.T)
        P[off, :] = 0.0
        P[:, off] = 0.0
    return P


class _PatternCovariance:
    """The kernel covariance (n, n) of each mode pattern of a cloud before resampling."""

    def __init__(self, X_prev: np.ndarray, w_prev: np.ndarray, code_prev: np.ndarray, nf: int,
                 fault_var_floor: np.ndarray | None) -> None:
        self.X_prev, self.w_prev, self.code_prev = X_prev, w_prev, code_prev
        self.nf, self.floor = nf, fault_var_floor
        self.na = X_prev.shape[0] - nf
        self.min_eff = MIN_EFF_PER_STATE * X_prev.shape[0]
        self._global = None

    def __call__(self, g: int) -> np.ndarray:
        on = [(g >> j) & 1 for j in range(self.nf)]
        sel = self.code_prev == g
        wg = self.w_prev[sel]
        W = wg.sum()
        if W > 0 and W * W / max(np.dot(wg, wg), 1e-300) >= self.min_eff:
            Xg = self.X_prev[:, sel]
            dX = Xg - (Xg @ wg / W)[:, None]
            P = (dX * (wg / W)) @ dX.T
        else:
            P = conditioned_on_mode0(self._global_cov(), [self.na + j for j in range(self.nf) if not on[j]])
        if self.floor is not None:          # mode-1 entries' kernel variance at least the floor
            js = [j for j in range(self.nf) if on[j]]
            if js:
                d = [self.na + j for j in js]
                P[d, d] = np.maximum(P[d, d], self.floor[js])
        return P

    def _global_cov(self) -> np.ndarray:
        if self._global is None:
            dX = self.X_prev - (self.X_prev @ self.w_prev)[:, None]
            self._global = (dX * self.w_prev) @ dX.T
        return self._global


def regularize_per_mode(X: np.ndarray, X_prev: np.ndarray, w_prev: np.ndarray, idx: np.ndarray,
                        modes_prev: np.ndarray, h: float, rng: np.random.Generator,
                        fault_var_floor: np.ndarray | None = None) -> np.ndarray:
    """Jitter a resampled jump-Markov cloud X (n, N) in place with a kernel per mode pattern.

    X = X_prev[:, idx] (resampled), w_prev (N,) and modes_prev (nf, N) bool from before the
    resampling. The particles of one mode pattern (which faults are in mode 1) are jittered with
    h D_g eps, D_g D_g^T = the weighted covariance of that pattern's particles before resampling
    (a kernel density estimate per mixture component). Its mode-0 fault rows have zero variance,
    so they stay exactly 0, and a mode-0 particle's airframe states are not moved along the
    (airframe, fault) correlation of the mode-1 particles, which the global covariance of the
    mixture carries (ch4: p_d with f_gnss and f_baro along the unobservable direction) and which
    would penalise mode 0 at every resample. A pattern whose effective particle count is below
    2 n uses the global covariance conditioned on its mode-0 fault entries being 0 instead.
    fault_var_floor (nf,): the kernel variance of a mode-1 fault entry is at least this (the
    variance of one frame's amplitude estimate): right after a detection the weight sits on a few
    sentinels (N_eff ~ 1), their weighted covariance is ~0 and the kernel could not restore the
    spread of a fault amplitude known from one frame only (docs/estimation.md).
    """
    n, N = X.shape
    nf = modes_prev.shape[0]
    code_prev = mode_codes(modes_prev)
    code_new = np.take(code_prev, idx)
    eps = epanechnikov(rng, n, N)
    groups, counts = _patterns(code_new, nf)
    covariance = _PatternCovariance(X_prev, w_prev, code_prev, nf, fault_var_floor)
    if len(groups) == 1:          # one pattern: every column (same product, no gather)
        X += (h * covariance_factor(covariance(groups[0]))) @ eps
        return X
    jitter = None            # (n, N): each column's h D_g eps, for several patterns
    single = []              # (column, h D_g eps of it) of one-particle patterns
    for g, count in zip(groups, counts, strict=True):
        hD = h * covariance_factor(covariance(g))
        if count == 1:            # a matrix-vector product: kept apart (BLAS gemv, not gemm)
            col = np.flatnonzero(code_new == g)
            single.append((col, hD @ eps[:, col]))
        elif jitter is None:      # a product's column depends only on that column of eps, so
            jitter = hD @ eps     # the full product holds every pattern's columns bit for bit
        else:
            np.copyto(jitter, hD @ eps, where=code_new == g)
    _add_jitter(X, jitter, single)
    return X


def _add_jitter(X: np.ndarray, jitter: np.ndarray | None, single: list) -> None:
    """X += the per-pattern jitter (n, N) with the one-particle patterns' columns in place."""
    if jitter is not None:
        for col, J in single:
            jitter[:, col] = J
        X += jitter
    else:
        for col, J in single:
            X[:, col] += J


class NoJitter:
    """No regularisation (the bootstrap filter)."""

    needs_covariance = False

    def jitter(self, X: np.ndarray, X_prev: np.ndarray, w_prev: np.ndarray, idx: np.ndarray,
               modes_prev: np.ndarray, P: np.ndarray | None, rng: np.random.Generator) -> None:
        """Nothing moves."""


class GlobalJitter(NoJitter):
    """One Epanechnikov kernel of bandwidth h on the cloud's covariance P (Alg. 2.7); shrink:
    Liu-West shrinkage first (RPF, RRPF)."""

    needs_covariance = True

    def __init__(self, h: float, shrink: bool) -> None:
        self.h, self.shrink = float(h), bool(shrink)

    def jitter(self, X, X_prev, w_prev, idx, modes_prev, P, rng) -> None:
        regularize(X, P, self.h, rng, self.shrink)


class PerModeJitter(NoJitter):
    """One kernel per mode pattern (`regularize_per_mode`, parts.jitter = "per_mode"); floor (nf,):
    the least kernel variance of a mode-1 fault entry (SI^2)."""

    def __init__(self, h: float, fault_var_floor: np.ndarray) -> None:
        self.h = float(h)
        self.fault_var_floor = np.asarray(fault_var_floor, dtype=float)

    def jitter(self, X, X_prev, w_prev, idx, modes_prev, P, rng) -> None:
        regularize_per_mode(X, X_prev, w_prev, idx, modes_prev, self.h, rng, self.fault_var_floor)
