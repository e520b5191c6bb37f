"""Compiled loops for the jump-Markov parts' elementwise work (numba), bit for bit numpy's.

A step of the robust monitor at N = 1000 is ~300 numpy calls on (entries x particles) arrays, and
at that size a call costs its overhead more than its arithmetic (docs/robustness.md, "Cost"). Each
kernel here does in one pass what a part did in several numpy calls. They only gather, compare,
multiply and add element by element in the order numpy did (no sum is reassociated, no fast-math,
no fused multiply-add), so a step's bits are those of the numpy code it replaces; every sum over
particles and every matrix product stays with numpy.

Compiled on first use and cached beside this module, or in NUMBA_CACHE_DIR, or in the user's
cache folder; where numba has nowhere to write (a read-only install and no home), compiled at every
start instead of failing.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit


def _compiled(fn: Callable) -> Callable:
    """numba's njit with its on-disk cache, or without it where numba finds no folder to write."""
    try:
        return njit(cache=True, nogil=True)(fn)
    except RuntimeError:              # "cannot cache function ...: no locator available"
        return njit(nogil=True)(fn)


@_compiled
def sentinel_pairs(sentinels: np.ndarray, js: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.nonzero(sentinels[js]): (rows (s,) into js, cols (s,) particles), fault-major, for the
    sentinels (nf, N) bool of the faults js (k,)."""
    n = 0
    for k in range(js.size):
        row = sentinels[js[k]]
        for i in range(row.size):
            if row[i]:
                n += 1
    rows = np.empty(n, dtype=np.intp)
    cols = np.empty(n, dtype=np.intp)
    n = 0
    for k in range(js.size):
        row = sentinels[js[k]]
        for i in range(row.size):
            if row[i]:
                rows[n] = k
                cols[n] = i
                n += 1
    return rows, cols


@_compiled
def spread_sentinels(X: np.ndarray, first_fault: int, js: np.ndarray, consts: np.ndarray,
                     carry_col: np.ndarray, carry_B: np.ndarray, rows: np.ndarray,
                     cols: np.ndarray, eps: np.ndarray, clip: float) -> np.ndarray:
    """Move each sentinel (rows, cols: `sentinel_pairs`) of X (n, N) in place by consts[k, 0] eps
    (eps (s,) clipped at +-clip sigmas when clip > 0), its airframe states by carry_B[:, c] times
    that where carry_col[k] = c >= 0; returns the (N,) log p / q bonus: per particle, the sum over
    its sentinels of consts[k, 1] + eps^2 / 2 (`sentinels.PriorSentinels.weigh`)."""
    bonus = np.zeros(X.shape[1])
    n_air = carry_B.shape[0]
    for i in range(rows.size):
        k, col = rows[i], cols[i]
        e = eps[i]
        if clip > 0.0:
            if e < -clip:
                e = -clip
            if e > clip:
                e = clip
        step = consts[k, 0] * e
        X[first_fault + js[k], col] += step
        c = carry_col[k]
        if c >= 0:
            for a in range(n_air):
                X[a, col] += carry_B[a, c] * step
        bonus[col] += consts[k, 1] + 0.5 * e * e
    return bonus


@_compiled
def faint_exit_pi10(F: np.ndarray, center: np.ndarray, threshold: np.ndarray, pi10: np.ndarray,
                    rate: float) -> np.ndarray:
    """(nf, N) exit probabilities: max(pi10[j], rate) where |F[j, i] - center[j]| < threshold[j],
    else pi10[j] (`jump.FaintExit.pi10`); F (nf, N), center, threshold, pi10 (nf,)."""
    out = np.empty(F.shape)
    for j in range(F.shape[0]):
        faint = rate if rate > pi10[j] else pi10[j]
        for i in range(F.shape[1]):
            out[j, i] = faint if abs(F[j, i] - center[j]) < threshold[j] else pi10[j]
    return out


@_compiled
def exit_folds(F: np.ndarray, modes: np.ndarray, v: np.ndarray, pi10: np.ndarray,
               rows: np.ndarray, armed: np.ndarray, reset_to: np.ndarray) -> tuple[np.ndarray, bool]:
    """((k, N) the fault values F[rows] - reset_to[rows] of the mode-1 particles that fold (v <
    pi10 / 2) where their fault is armed, 0 elsewhere; whether any folds) (`jump.ExitFold.capture`).
    F, modes, v (nf, N); pi10 (nf, N) or (nf, 1); rows (k,) the folding faults; armed, reset_to (nf,)."""
    out = np.zeros((rows.size, F.shape[1]))
    anyone = False
    per_particle = pi10.shape[1] > 1
    for r in range(rows.size):
        j = rows[r]
        if not armed[j]:
            continue
        for i in range(F.shape[1]):
            if modes[j, i] and v[j, i] < 0.5 * pi10[j, i if per_particle else 0]:
                out[r, i] = F[j, i] - reset_to[j]
                anyone = True
    return out, anyone


@_compiled
def jump_entries(F: np.ndarray, modes: np.ndarray, amplitude: np.ndarray, may: np.ndarray,
                 pi01: np.ndarray, pi10: np.ndarray, v: np.ndarray, forced_zero: bool,
                 reset_to: np.ndarray) -> np.ndarray:
    """Alg. 4.1 in place on F, modes (nf, N) (`jump.jump`, whose argument shapes these are; may and
    pi10 (nf, N) or (nf, 1)); an exit's entry becomes reset_to[j] unless forced_zero (then every
    mode-0 entry is 0). Returns the (nf, N) bool sentinels."""
    up = np.zeros(modes.shape, dtype=np.bool_)
    may_each, pi10_each = may.shape[1] > 1, pi10.shape[1] > 1
    for j in range(F.shape[0]):
        for i in range(F.shape[1]):
            was = modes[j, i]
            if not was and may[j, i if may_each else 0] and v[j, i] < pi01[j]:
                up[j, i] = True
                F[j, i] = amplitude[j, i]
                modes[j, i] = True
            elif was and v[j, i] < pi10[j, i if pi10_each else 0]:
                modes[j, i] = False
                if not forced_zero:
                    F[j, i] = reset_to[j]
            if forced_zero:
                F[j, i] = F[j, i] * (1.0 if modes[j, i] else 0.0)
    return up


@_compiled
def mode_patterns(modes: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(groups (g,) the mode patterns present, ascending, as codes with bit j = fault j; inv (N,)
    each particle's index into groups; share (g, N): w where the particle has that pattern, else 0)
    for modes (nf, N) bool (nf <= 63) and weights w (N,) (`correction.within_mode_cov`)."""
    nf, n = modes.shape
    code = np.zeros(n, dtype=np.int64)
    for j in range(nf):
        for i in range(n):
            if modes[j, i]:
                code[i] |= np.int64(1) << j
    groups, inv = _distinct(code)
    share = np.zeros((groups.size, n))
    for i in range(n):
        share[inv[i], i] = w[i]
    return groups, inv, share


@_compiled
def _distinct(code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(np.unique(code), each element's index into it) for int64 codes (N,) of few distinct values
    (a linear scan; np.unique's sort past 32 of them)."""
    seen = np.empty(32, dtype=np.int64)
    slot = np.empty(code.size, dtype=np.intp)
    g = 0
    for i in range(code.size):
        c = code[i]
        k = 0
        while k < g and seen[k] != c:
            k += 1
        if k == g:
            if g == seen.size:
                groups = np.unique(code)
                return groups, np.searchsorted(groups, code)
            seen[g] = c
            g += 1
        slot[i] = k
    order = np.argsort(seen[:g])
    rank = np.empty(g, dtype=np.intp)
    for r in range(g):
        rank[order[r]] = r
    for i in range(code.size):
        slot[i] = rank[slot[i]]
    return seen[:g][order], slot


@_compiled
def pattern_deviations(X: np.ndarray, means: np.ndarray, inv: np.ndarray,
                       w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dX, dX w) (n, N): each particle of X (n, N) about its pattern's mean, means (g, n) and inv
    (N,) from `mode_patterns`, and the same times the weights w (N,)."""
    dX = np.empty(X.shape)
    dXw = np.empty(X.shape)
    for a in range(X.shape[0]):
        for i in range(X.shape[1]):
            d = X[a, i] - means[inv[i], a]
            dX[a, i] = d
            dXw[a, i] = d * w[i]
    return dX, dXw


@_compiled
def add_drift_noise(X: np.ndarray, noise: np.ndarray, modes: np.ndarray, q_std: np.ndarray,
                    drift_std: np.ndarray, tail_draw: np.ndarray, tail_share: float,
                    tail_scale: float, stalled: np.ndarray, bound: np.ndarray) -> None:
    """X (n, N) += the process noise of `predict.DriftPredict`, in place: standard normals noise
    (n, N) times q_std (n, 1) (a fault entry j in mode 0: drift_std[j, 0] instead); the pitch
    rate's (row 4) times tail_scale where tail_draw (N,) < tail_share (empty: no tail) and times
    1 + (tail_scale - 1) stalled (N,) (empty: no stall); fault entries then kept within +-bound
    (nf, 1)."""
    n_air, n = X.shape[0] - modes.shape[0], X.shape[1]
    for a in range(n_air):
        if a == 4 and (tail_draw.size > 0 or stalled.size > 0):
            _add_pitch_rate_noise(X[4], noise[4], q_std[4, 0], tail_draw, tail_share, tail_scale, stalled)
            continue
        q = q_std[a, 0]
        for i in range(n):
            X[a, i] += noise[a, i] * q
    for j in range(modes.shape[0]):
        a, b, q, d = n_air + j, bound[j, 0], q_std[n_air + j, 0], drift_std[j, 0]
        for i in range(n):
            x = X[a, i] + noise[a, i] * (q if modes[j, i] else d)
            if x > b:
                x = b
            if x < -b:
                x = -b
            X[a, i] = x


@_compiled
def _add_pitch_rate_noise(x: np.ndarray, noise: np.ndarray, q: float, tail_draw: np.ndarray,
                          tail_share: float, tail_scale: float, stalled: np.ndarray) -> None:
    """x (N,) += noise q times the heavy tail (tail_scale where tail_draw < tail_share; empty: none)
    and times the stall blend 1 + (tail_scale - 1) stalled (empty: none), in place."""
    tail, stall = tail_draw.size > 0, stalled.size > 0
    for i in range(x.size):
        e = noise[i] * q
        if tail:
            e = e * (tail_scale if tail_draw[i] < tail_share else 1.0)
        if stall:
            e = e * (1.0 + (tail_scale - 1.0) * stalled[i])
        x[i] += e


@_compiled
def mode0_weights(modes: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(nf, N): the weights w (N,) where modes (nf, N) is False, 0 where True."""
    out = np.zeros(modes.shape)
    for j in range(modes.shape[0]):
        for i in range(modes.shape[1]):
            if not modes[j, i]:
                out[j, i] = w[i]
    return out


@_compiled
def share_means(s: np.ndarray, total: np.ndarray, w_total: float) -> tuple[np.ndarray, np.ndarray]:
    """((nf,) s / total where total > 1e-12, else 0; (nf,) total / w_total)."""
    mean = np.zeros(s.size)
    share = np.empty(s.size)
    for j in range(s.size):
        if total[j] > 1e-12:
            mean[j] = s[j] / total[j]
        share[j] = total[j] / w_total
    return mean, share


@_compiled
def add_held(X: np.ndarray, dX: np.ndarray, modes: np.ndarray) -> None:
    """X (n, N) += dX in place, a fault entry's row only where its mode (nf, N) is 1 (the last nf
    rows: dX times the mode, as `correction.KalmanCorrection` with hold_mode0_faults)."""
    n_air = X.shape[0] - modes.shape[0]
    for a in range(X.shape[0]):
        for i in range(X.shape[1]):
            d = dX[a, i]
            if a >= n_air:
                d = d * (1.0 if modes[a - n_air, i] else 0.0)
            X[a, i] = X[a, i] + d


@_compiled
def all_finite(A: np.ndarray) -> bool:
    """np.isfinite(A).all() for a 2-D float array."""
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            if not np.isfinite(A[i, j]):
                return False
    return True


@_compiled
def symmetrised(A: np.ndarray) -> np.ndarray:
    """(A + A^T) / 2 of a square A, as numpy's `A += A.T; A *= 0.5`."""
    out = np.empty(A.shape)
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            out[i, j] = (A[i, j] + A[j, i]) * 0.5
    return out


@_compiled
def arm_folds(p: np.ndarray, arming: np.ndarray, arming_end: np.ndarray, own: np.ndarray,
              own_end: np.ndarray, since_arming: np.ndarray, blamed_for: np.ndarray,
              window: np.ndarray, young: np.ndarray, gated: np.ndarray, armed: np.ndarray,
              far: int) -> None:
    """`jump.FoldArming.observe`'s counters and `armed`, in place, from P(mode 1) p (nf,): gated
    fault i's fold_after entries are arming[arming_end[i - 1]:arming_end[i]], its own item's
    own[...] likewise (fewer than 8 each: numpy sums those in order from 0)."""
    start_a, start_o = 0, 0
    for i in range(gated.size):
        s = 0.0
        for k in range(start_a, arming_end[i]):
            s += p[arming[k]]
        since_arming[i] = 0 if s >= 0.5 else since_arming[i] + 1
        s = 0.0
        for k in range(start_o, own_end[i]):
            s += p[own[k]]
        if s >= 0.5:
            blamed_for[i] = 0 if blamed_for[i] >= far else blamed_for[i] + 1
        else:
            blamed_for[i] = far
        armed[gated[i]] = since_arming[i] <= window[i] or blamed_for[i] <= young[i]
        start_a, start_o = arming_end[i], own_end[i]


@_compiled
def _block_sum(a: np.ndarray) -> float:
    """numpy's add.reduce of a float64 a (n,), n <= 128, bit for bit: in order from 0 below 8
    terms, else 8 running sums (numpy's pairwise summation, whose halving starts past 128)."""
    n = a.size
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    r = a[:8].copy()
    i = 8
    while i < n - n % 8:
        for k in range(8):
            r[k] += a[i + k]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[i]
        i += 1
    return 0.0 + res


@_compiled
def window_centred(buffer: np.ndarray, start: int, n: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(t - mean t, theta - mean theta, mean q) over n <= 128 rows (t, theta, q) of a
    `rate_window.RateWindow` ring (frames, 3), oldest first from row `start`; the means are
    numpy's x.sum() / n bit for bit."""
    size = buffer.shape[0]
    rows = np.empty((3, n))
    for i in range(n):
        r = (start + i) % size
        for c in range(3):
            rows[c, i] = buffer[r, c]
    t_mean = _block_sum(rows[0]) / n
    th_mean = _block_sum(rows[1]) / n
    return rows[0] - t_mean, rows[1] - th_mean, _block_sum(rows[2]) / n


@_compiled
def any_related(M: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """(nf, N) bool: (M @ modes) > 0 for a nonnegative (nf, nf) M and modes (nf, N) bool, i.e.
    entry b of particle i has some a with M[b, a] > 0 in mode 1 (the same bools whatever the
    order of the sum: every term is >= 0)."""
    nf, n = modes.shape
    out = np.zeros((M.shape[0], n), dtype=np.bool_)
    for b in range(M.shape[0]):
        for a in range(nf):
            if M[b, a] > 0.0:
                for i in range(n):
                    if modes[a, i]:
                        out[b, i] = True
    return out


@_compiled
def hand_over(F: np.ndarray, modes: np.ndarray, v: np.ndarray, pairs: np.ndarray,
              rates: np.ndarray, back: np.ndarray) -> None:
    """`fault_types.TypeSwitch.apply` in place, pair by pair in order: where entry a is in mode 1,
    b is not and v[p, i] < rates[p], b takes a's offset (F[b] += F[a] - back[a]), a leaves
    mode 1 at back[a], b enters it. F, modes (nf, N); v (p, N); pairs (p, 2); back (nf,)."""
    for p in range(pairs.shape[0]):
        a, b = pairs[p, 0], pairs[p, 1]
        for i in range(F.shape[1]):
            if modes[a, i] and not modes[b, i] and v[p, i] < rates[p]:
                F[b, i] += F[a, i] - back[a]
                F[a, i] = back[a]
                modes[a, i] = False
                modes[b, i] = True


@_compiled
def inverse_checks(S: np.ndarray, R: np.ndarray) -> tuple[bool, float, float]:
    """(S (m, m) all finite, min diag R (0 for an empty R), trace S as numpy's S.trace()) for
    `correction._spd_inverse`: one call for three (m <= 128)."""
    if not all_finite(S):
        return False, 0.0, 0.0
    floor = 0.0
    for i in range(R.shape[0]):
        d = R[i, i]
        if i == 0 or d < floor or np.isnan(d):
            floor = d
            if np.isnan(d):
                break
    return True, floor, _block_sum(np.diag(S).copy())
