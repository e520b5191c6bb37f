"""Kalman correction of every particle: the "R" (robustified) variants (thesis Alg. 5.1-5.2, eq. 5.3-5.9).

From the weighted predicted cloud: x_bar = sum w x_i, y_bar = sum w h(x_i), P_xy, S = P_yy + R,
K = P_xy S^-1. Weights are multiplied by N(y - h(x_i); 0, S) and every particle moves
x_i <- x_i + K (y - h(x_i)). With the linear measurement model h(x) = H x, P_xy = P H^T and
P_yy = H P H^T with P the weighted (n, n) covariance of the cloud, computed once.

Parts of the "correction" slot of a recipe (recipes.py): `Likelihood` (weights only, Alg. 2.8)
and `KalmanCorrection` (every particle corrected, Alg. 5.1-5.2). Both take the predicted cloud
X (n, N), the prior weights w (N,), the modes (nf, N) and the frame, and return the (N,)
log-likelihood of each particle.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg.lapack import dpotrf, dtrtri

from fdir_service.estimation.kernels import (
    add_held,
    all_finite,
    inverse_checks,
    mode_patterns,
    pattern_deviations,
    symmetrised,
)

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame

try:                                   # numpy.linalg.inv's own gufunc, without its wrapper (8 -> 3 us)
    from numpy.linalg import _umath_linalg as _linalg
except ImportError:                    # pragma: no cover - another numpy's layout
    _linalg = None


def _inv(S: np.ndarray) -> np.ndarray:
    """Inverse of a well-conditioned float64 (m, m) matrix: numpy.linalg.inv's bits (its LAPACK
    gufunc, called directly; a singular S gives non-finite entries instead of LinAlgError)."""
    if _linalg is None:
        return np.linalg.inv(S)
    return _linalg.inv(S, signature="d->d")


def weighted_mean_cov(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean (n,) and covariance (n, n) of a state-major cloud X (n, N), weights w (N,)."""
    mean = X @ w
    return mean, weighted_cov(X, w, mean)


def weighted_cov(X: np.ndarray, w: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Weighted covariance (n, n) of a cloud X (n, N) with weights w (N,) about its mean (n,) = X @ w."""
    dX = X - mean[:, None]
    return (dX * w) @ dX.T


HYPOTHESIS_SHARE = 0.05
"""A mode pattern holding at least this share of the weight is a hypothesis of its own for
`within_mode_cov`; the rest (the step's sentinels, a few stragglers) are spread about the cloud."""


def within_mode_cov(X: np.ndarray, w: np.ndarray, modes: np.ndarray,
                    share_min: float = HYPOTHESIS_SHARE) -> np.ndarray:
    """Weighted covariance (n, n) of X (n, N), each particle about its mode pattern's mean when
    that pattern holds >= share_min of the weights w (N,) (modes (nf, N) bool), else about the
    cloud's mean: the spread within each hypothesis, without the distance between them, while a
    young hypothesis (this step's sentinels) is still spread about the cloud, so that the data
    refine its amplitude as with the cloud's covariance."""
    if modes.shape[0] > 63:
        raise ValueError(f"{modes.shape[0]} fault entries: mode patterns are int64 codes, at most 63")
    _, inv, share = mode_patterns(modes, w)
    total = share.sum(axis=1)
    means = (share @ X.T) / np.maximum(total, 1e-300)[:, None]
    means[total < share_min] = X @ w
    dX, dXw = pattern_deviations(X, means, inv, w)
    return dXw @ dX.T


def kalman_gain(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gain K (n, m) and inverse innovation covariance S^-1 (m, m) from the cloud covariance P (n, n).

    Alg. 5.1 with h(x) = H x: P_xy = P H^T, S = H P H^T + R, K = P_xy S^-1. S is m x m (m <= 6):
    its explicit inverse is cheaper than a factorisation call and is reused by the weights.
    """
    PHt = P @ H.T
    S = H @ PHt + R
    S_inv = _spd_inverse(S, R)
    if S_inv is None:       # the cloud's covariance is not finite: no correction this step
        return np.zeros_like(PHt), _spd_inverse(R, R, fallback=False)
    K = PHt @ S_inv
    if not all_finite(K):
        return np.zeros_like(PHt), S_inv
    return K, S_inv


def _numpy_checks(S: np.ndarray, R: np.ndarray) -> tuple[bool, float, float]:
    """`kernels.inverse_checks` for S past 128 rows."""
    floor = float(np.min(np.diag(R))) if R.size else 0.0
    return bool(np.isfinite(S).all()), floor, float(S.trace())


def _spd_inverse(S: np.ndarray, R: np.ndarray, fallback: bool = True) -> np.ndarray | None:
    """Inverse of a symmetric positive-definite S (m, m) that never raises.

    Symmetrised S -> Cholesky (LAPACK dpotrf/dpotri); if that fails (S numerically singular: a
    cloud whose spread exploded to 1e40 and more makes S = H P H^T + R lose R to round-off),
    eigen-decomposition with the eigenvalues clipped to at least the smallest diagonal entry of R
    (S >= R holds exactly). None if S is not finite (or for fallback=False, R^-1 from the
    diagonal). The result is finite and symmetric.
    """
    if not fallback:
        d = np.diag(R)
        return np.diag(1.0 / np.where(d > 0, d, 1.0))
    finite, floor, tr = inverse_checks(S, R) if S.shape[0] <= 128 else _numpy_checks(S, R)
    if not finite:
        return None
    if floor > 0 and tr < 1e10 * floor:
        # S >= R, so cond(S) <= trace(S) / min R < 1e10: the plain inverse is accurate (and the
        # cheapest call); symmetrised against round-off
        inv = _inv(S) if S.dtype == np.float64 else np.linalg.inv(S)
        if all_finite(inv):       # else (S singular after all) the factorisations below
            return symmetrised(inv)
    S = 0.5 * (S + S.T)
    L, info = dpotrf(S, lower=1, clean=1)
    if info == 0:
        Li, info = dtrtri(L, lower=1)
        if info == 0:
            inv = Li.T @ Li
            if np.isfinite(inv).all():
                return inv
    floor = floor if floor > 0 else 1e-12
    try:
        lam, V = np.linalg.eigh(S)
    except np.linalg.LinAlgError:
        return None
    lam = np.maximum(lam, floor)
    inv = (V / lam) @ V.T
    return inv if np.isfinite(inv).all() else None


def gaussian_loglik(innovation: np.ndarray, S_inv: np.ndarray) -> np.ndarray:
    """log N(e_i; 0, S) up to a constant, for innovations (m, N) and S^-1: -0.5 e_i^T S^-1 e_i (N,)."""
    return -0.5 * np.einsum("ij,ij->j", innovation, S_inv @ innovation)


def row_loglik(X: np.ndarray, frame: Frame) -> np.ndarray:
    """log N(y; H x_i, R) up to a constant for each particle of X (n, N) on the frame's rows (N,)."""
    mm = frame.mm
    if mm.m == 0:
        return np.zeros(X.shape[1])
    e = frame.yv[:, None] - mm.H @ X
    e *= mm.inv_sigma[:, None]
    return -0.5 * np.einsum("ij,ij->j", e, e)


class Likelihood:
    """No correction: the particles stay where the prediction put them."""

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        return row_loglik(X, frame)


GAIN_COVARIANCES = ("cloud", "within_mode")
"""parts.gain_covariance: the covariance P the Kalman gain and the predictive S are built from:
the whole cloud's, or `within_mode_cov` (each particle about its own mode pattern's mean)."""

ALTITUDE_GAINS = ("all_rows", "altimeters", "no_pitch_rate")
"""parts.altitude_gain: which rows' innovations may move the altitude (p_d, state 0) in the Kalman
correction: every row; only the rows that measure it; every row but the gyro's (state 4)."""


AIRFRAME_STATES = 5
"""[p_d, u, w, theta, q] lead the extended state (`layout.N_AIRFRAME`; not imported: the config
module imports this one)."""
ALTIMETER_GAINS = ("all_states", "altitude")
"""parts.altimeter_gain: which states the altimeters' innovations (rows measuring the altitude)
may move in the Kalman correction: every state; only the altitude (and the fault entries)."""


FAULTY_ROW_GAINS = ("all_states", "fault_entry")
"""parts.faulty_row_gain: what a row moves in a particle that holds one of its sensor faults in
mode 1: every state (the cloud's gain), or only the fault entries (`FaultyRowCut`)."""


class FaultyRowCut:
    """A row a particle believes faulty tells that particle nothing of its airframe state
    (parts.faulty_row_gain = "fault_entry"): for each particle, the airframe part of the Kalman move
    loses the rows where it holds an additive sensor fault in mode 1; its fault entries keep it. The
    gain is the cloud's, built from every row: a barometer ramp declared in mode 1 still pulled
    each faulty particle's altitude along through it, and when the ramp ended that altitude was 2-3 m
    off the true reading, which was then declared. Measured, not a default: over real-drift 21 ->
    21 false alarms, real-stuck 4 -> 7, real-pitot 3 -> 6 (docs/faults.md, "A faulty row moves its
    fault only").

    sensor_row (nf,): each fault's row in the full measurement model (-1: not an additive sensor
    fault, `layout.FaultLayout.sensor_row`)."""

    def __init__(self, sensor_row: np.ndarray) -> None:
        self.sensor_row = np.asarray(sensor_row, dtype=int)
        self._maps: dict[bytes, np.ndarray | None] = {}

    def row_map(self, frame: Frame) -> np.ndarray | None:
        """(m_rows, nf) 1 where fault j adds to the frame's row (cached per mask); None: none does."""
        key = frame.mask.tobytes()
        if key not in self._maps:
            here = (self.sensor_row >= 0) & frame.mask[np.maximum(self.sensor_row, 0)]
            E = np.zeros((frame.mm.m, self.sensor_row.size))
            E[frame.row_of[self.sensor_row[here]], np.flatnonzero(here)] = 1.0
            self._maps[key] = E if here.any() else None
        return self._maps[key]

    def apply(self, dX: np.ndarray, K: np.ndarray, innov: np.ndarray, modes: np.ndarray,
              frame: Frame) -> None:
        """dX (n, N) = K innov, in place: its airframe rows without each particle's faulty rows."""
        E = self.row_map(frame)
        if E is None:
            return
        faulty = (E @ modes) > 0.0                       # (m_rows, N): rows each particle holds faulty
        if faulty.any():
            dX[:AIRFRAME_STATES] -= K[:AIRFRAME_STATES] @ np.where(faulty, innov, 0.0)


def altimeter_gain_cut(H: np.ndarray, altimeter_gain: str) -> np.ndarray | None:
    """(m,) bool: the rows of H (m, n) whose gain on u, w, theta and q is zeroed; None: none."""
    if altimeter_gain == "altitude":
        return H[:, 0] != 0.0
    return None


def altitude_gain_cut(H: np.ndarray, altitude_gain: str) -> np.ndarray | None:
    """(m,) bool: the rows of H (m, n) whose gain on the altitude is zeroed; None: none."""
    if altitude_gain == "altimeters":
        return H[:, 0] == 0.0
    if altitude_gain == "no_pitch_rate":
        return H[:, 4] != 0.0
    return None


class KalmanCorrection:
    """Weights N(y - H x_i; 0, S) and x_i += K (y - H x_i) in place (eq. 5.3-5.9); `pin(X, modes)`
    puts pinned fault entries back afterwards (the jump's `pin`). hold_mode0_faults (parts.mode0 =
    "drift"): a mode-0 fault entry is not corrected (its drift is slow: the weights select it), so
    the cloud's gain cannot carry a mode-1 particle's fault into the fault-free mode.
    altitude_gain (`ALTITUDE_GAINS`, `altitude_gain_cut`): which rows may move the altitude. In an
    upset the pitch rate's and the velocities' innovations are the kinematic model's lag, and the
    cloud's covariance of the altitude with those states turned them into metres of altitude that
    the altimeters' drift entries then absorbed (docs/robustness.md, run 56 of
    real-turbulence-faultfree, seed 1); the default keeps every row.
    covariance (`GAIN_COVARIANCES`): "within_mode" builds the gain from the spread within each mode
    pattern. The cloud's covariance also holds the distance between hypotheses: beside a crowd that
    blames the barometer for an altitude 5 m off, the barometer's gain on the fault-free particles'
    altitude was ~0 (the altitude and its fault entry anti-correlated across the cloud) and the
    GNSS's ten times the one within either hypothesis, so each GNSS frame's noise moved them off
    the barometer (docs/robustness.md, "A gain from within each hypothesis")."""

    def __init__(self, pin, hold_mode0_faults: bool = False, altitude_gain: str = "all_rows",
                 covariance: str = "cloud", altimeter_gain: str = "all_states",
                 faulty_rows: FaultyRowCut | None = None) -> None:
        self.pin = pin
        self.hold_mode0_faults = bool(hold_mode0_faults)
        if altitude_gain not in ALTITUDE_GAINS:
            raise ValueError(f"altitude_gain {altitude_gain!r}: expected one of {ALTITUDE_GAINS}")
        if covariance not in GAIN_COVARIANCES:
            raise ValueError(f"covariance {covariance!r}: expected one of {GAIN_COVARIANCES}")
        if altimeter_gain not in ALTIMETER_GAINS:
            raise ValueError(f"altimeter_gain {altimeter_gain!r}: expected one of {ALTIMETER_GAINS}")
        self.altitude_gain = altitude_gain
        self.altimeter_gain = altimeter_gain
        self.within_mode = covariance == "within_mode"
        self.faulty_rows = faulty_rows
        """None, or the `FaultyRowCut` of parts.faulty_row_gain = "fault_entry"."""

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        mm = frame.mm
        if mm.m == 0:
            return np.zeros(X.shape[1])
        P = within_mode_cov(X, w, modes) if self.within_mode else weighted_mean_cov(X, w)[1]
        K, S_inv = kalman_gain(P, mm.H, mm.R)
        cut = altitude_gain_cut(mm.H, self.altitude_gain)
        if cut is not None:
            K[0, cut] = 0.0
        reach = altimeter_gain_cut(mm.H, self.altimeter_gain)
        if reach is not None:
            K[1:AIRFRAME_STATES, reach] = 0.0
        innov = frame.yv[:, None] - mm.H @ X
        ll = gaussian_loglik(innov, S_inv)
        dX = K @ innov
        if self.faulty_rows is not None:
            self.faulty_rows.apply(dX, K, innov, modes, frame)
        if self.hold_mode0_faults:
            add_held(X, dX, modes)
        else:
            X += dX
        self.pin(X, modes)
        return ll
