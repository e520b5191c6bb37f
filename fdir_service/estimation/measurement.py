"""Linear measurement model y = H x + v on the extended state, with a per-step availability mask.

Rows follow the scenario's measurement list (SPEC section 3): altitudes measure -p_d, the others
their own state; a sensor fault adds its fault entry to its row. The filters assume the noise
`scenario.sensors.filter_sigma()` (1.5x the true sigma), R = diag(sigma^2). A mask (m,) bool
keeps the rows that arrived; `reduced(mask)` is the model of those rows only (cached per mask).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout

MEASURED_STATE = {"gnss_alt": (0, -1.0), "baro_alt": (0, -1.0), "u": (1, 1.0), "w": (2, 1.0),
                  "theta": (3, 1.0), "q": (4, 1.0)}
"""measurement name -> (airframe-state index, coefficient)."""
DERIVED_STATE = {"airspeed": (1, 1.0)}
"""Derived rows that observe an airframe state: the pitot's airspeed, V = |u - w_x, w - w_z| ~ u - w_x
(within 0.1 % below 3 deg of angle of attack), the head wind w_x along body x carried by the pitot
fault entries' fault-free drift. Not a state measurement for initialising (`measured_state`)."""


@dataclass
class MeasurementModel:
    """names (m,), H (m, n), sigma (m,) SI; R = diag(sigma^2)."""

    names: tuple[str, ...]
    H: np.ndarray
    sigma: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, layout: FaultLayout, sigma: np.ndarray | list[float]) -> MeasurementModel:
        """The model of `layout.measurements` with sensor-fault columns; sigma (m,) SI."""
        m = len(layout.measurements)
        H = np.zeros((m, layout.n))
        for r, name in enumerate(layout.measurements):
            row = MEASURED_STATE.get(name, DERIVED_STATE.get(name))   # the throttle row: no state
            if row is not None:
                H[r, row[0]] = row[1]
        for j, r in enumerate(np.maximum(layout.sensor_row, layout.direct_row)):
            if r >= 0:
                H[r, layout.fault_index[j]] = 1.0
        return cls(tuple(layout.measurements), H, np.asarray(sigma, dtype=float).copy())

    @property
    def m(self) -> int:
        return len(self.names)

    def __post_init__(self) -> None:
        self.R = np.diag(self.sigma**2)
        """(m, m) measurement noise covariance."""
        self.inv_sigma = 1.0 / self.sigma

    def reduced(self, mask: np.ndarray) -> MeasurementModel:
        """The model of the rows where mask is True (the full model when all rows arrived)."""
        mask = np.asarray(mask, dtype=bool)
        if mask.all():
            return self
        key = mask.tobytes()
        sub = self._cache.get(key)
        if sub is None:
            sub = MeasurementModel(tuple(n for n, k in zip(self.names, mask, strict=True) if k),
                                   self.H[mask].copy(), self.sigma[mask].copy())
            self._cache[key] = sub
        return sub

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Predicted measurements (m, N) of a state-major cloud X (n, N); or (m,) of x (n,)."""
        return self.H @ X


def state_gain(H: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(5, k) per row r of rows (k,) (-1: a zero column) the minimum-norm airframe change that moves
    that row's prediction by one unit, h_r^T / |h_r|^2 with h_r the airframe part of H (m, n)."""
    G = np.zeros((N_AIRFRAME, len(rows)))
    for j, r in enumerate(np.asarray(rows, dtype=int).tolist()):
        h = H[r, :N_AIRFRAME] if r >= 0 else np.zeros(N_AIRFRAME)
        if h @ h > 0:
            G[:, j] = h / (h @ h)
    return G


def measured_state(names: tuple[str, ...] | list[str], y: np.ndarray, mask: np.ndarray,
                   ref: np.ndarray) -> np.ndarray:
    """An airframe state (5,) made from one frame: each state the value of a row (names (m,), y (m,)
    SI where mask (m,)) that measures it (altitudes: -p_d), the one nearest ref (5,) where several
    rows measure it; states no valid row measures keep ref."""
    x0 = np.asarray(ref, dtype=float).copy()
    best: dict[int, float] = {}
    for j, name in enumerate(names):
        row = MEASURED_STATE.get(name)
        if row is None or not mask[j] or not np.isfinite(y[j]):
            continue
        col, coef = row
        v = y[j] / coef
        if col not in best or abs(v - ref[col]) < abs(best[col] - ref[col]):
            best[col] = v
    for col, v in best.items():
        x0[col] = v
    return x0
