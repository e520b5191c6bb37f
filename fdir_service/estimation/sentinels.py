"""Sentinel weighting parts: how a particle that has just jumped 0 -> 1 is weighted (docs/estimation.md).

`ThesisSentinels` (parts.sentinel_weighting = "thesis", Alg. 4.1 as written): a sentinel sits at
its predicted amplitude A and is weighted by its likelihood like any particle.
`PriorSentinels` ("prior"): the jump proposes a sentinel's amplitude from the data,
q(f) = N(A, s^2) with A = y_r - h_r(z_i) (eq. 4.16) and s the row's filter sigma, while the
amplitude prior of a fault that has just appeared is uniform, p(f | jump) = 1 / L on
[-amplitude_max, amplitude_max]. So the sentinel is drawn from q and its importance weight carries
p(f) / q(f) = sqrt(2 pi) s exp(eps^2 / 2) / L (f = A + s eps) on top of its likelihood. Against a
mode-0 particle a sentinel is then worth ~ 1/L against N(e; 0, s^2): it wins only when
e^2 / s^2 > 2 log(L / (sqrt(2 pi) s)) (a GLR threshold) instead of always (the thesis's point
mass at A fits row r exactly). An actuator fault (with `jump.ActuatorCarry`) uses its amplitude's
sigma for s, and its sentinel's airframe state moves by B_a s eps with the fault.

`clip` (parts.sentinel_clip, in sigmas; 0 = off): eps is clipped to [-clip, clip]. The weight
p / q grows as exp(eps^2 / 2) while a sentinel whose frame is explained anyway (a gyro sentinel's
carry keeps its gyro prediction) loses nothing by the draw's distance: with the uniform prior's
tails far heavier than the normal proposal's, a 5-sigma draw (about twice in ten fault-free hours
of the robust monitor's sentinels) took 98 % of the weight in one frame and a gyro fault was
declared for 2-3 s (docs/robustness.md, "Attitude sentinels as many as the gyro's"). Clipped, the
proposal is the normal truncated at clip sigma with its tails' mass at the bounds, and p / q is
bounded by exp(clip^2 / 2) sqrt(2 pi) s / L.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.kernels import sentinel_pairs, spread_sentinels
from fdir_service.estimation.layout import N_AIRFRAME

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame


class ThesisSentinels:
    """Sentinels are weighted like any particle: no extra log-weight term."""

    def weigh(self, X: np.ndarray, frame: Frame, sentinels: np.ndarray, rng: np.random.Generator) -> None:
        return None


def prior_log_constants(amplitude_max: np.ndarray, sensor_row: np.ndarray,
                        carried: np.ndarray) -> np.ndarray:
    """log(sqrt(2 pi) / L_j) per fault (nf,) with L_j = 2 amplitude_max_j (SI); NaN where the fault
    keeps the thesis weighting: no amplitude_max, or an actuator fault whose sentinels do not carry
    the last frame's effect (`carried` False: it could not fit the frame it is weighted on)."""
    L = 2.0 * np.asarray(amplitude_max, dtype=float)
    ok = np.isfinite(L) & (L > 0)
    c = np.where(ok, 0.5 * np.log(2.0 * np.pi) - np.log(np.where(ok, L, 1.0)), np.nan)
    c[(np.asarray(sensor_row) < 0) & ~np.asarray(carried, dtype=bool)] = np.nan
    return c


class PriorSentinels:
    """The "prior" weighting (module docstring).

    log_c (nf,): `prior_log_constants` (NaN: that fault is weighted as in the thesis);
    row_sigma (m,): the filter's measurement sigma; amplitude: the A_f predictor (its sigma for
    actuator faults); carry: the jump's `ActuatorCarry` (or `NoCarry`).
    """

    def __init__(self, log_c: np.ndarray, sensor_row: np.ndarray, row_sigma: np.ndarray,
                 amplitude: AmplitudePredictor, carry, clip: float = 0.0) -> None:
        self.log_c = np.asarray(log_c, dtype=float)
        self.sensor_row = np.asarray(sensor_row, dtype=int)
        self.row_sigma = np.asarray(row_sigma, dtype=float)
        self.amplitude = amplitude
        self.carry_index: dict[int, int] = getattr(carry, "index", {})
        self.carry_B = getattr(carry, "B", None)
        self._carry_B = np.zeros((N_AIRFRAME, 0)) if self.carry_B is None else np.asarray(self.carry_B, float)
        self._carry_of = np.full(self.log_c.size, -1, dtype=np.intp)
        """(nf,) each fault's column of carry_B, -1 where its sentinel carries no state."""
        for j, c in self.carry_index.items():
            self._carry_of[j] = c
        self._rows: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self.clip = float(clip)
        """eps bound in sigmas (parts.sentinel_clip); 0: no bound."""

    def rows(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(faults k with the prior weighting that could jump this frame (k,), their
        (s_j, log c_j + log s_j) (k, 2)): sensor faults whose row arrived, actuator faults with an
        amplitude. Cached per mask."""
        key = mask.tobytes()
        hit = self._rows.get(key)
        if hit is None:
            hit = self._rows[key] = self._rows_for(mask)
        return hit

    def _rows_for(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        js, consts = [], []
        _, avail, amp_sigma = self.amplitude.gain(mask)
        for j, r in enumerate(self.sensor_row.tolist()):
            if not np.isfinite(self.log_c[j]):
                continue
            if r >= 0 and mask[r]:
                sj = self.row_sigma[r]                   # sensor fault: its row's filter sigma
            elif r < 0 and avail[j] and np.isfinite(amp_sigma[j]):
                sj = amp_sigma[j]                        # actuator fault: its amplitude's sigma
            else:
                continue
            js.append(j)
            consts.append((sj, self.log_c[j] + np.log(sj)))
        return np.array(js, dtype=int), np.array(consts, dtype=float).reshape(-1, 2)

    def weigh(self, X: np.ndarray, frame: Frame, sentinels: np.ndarray,
              rng: np.random.Generator) -> np.ndarray | None:
        """Spread this step's sentinels (nf, N) bool in X (n, N) in place; their (N,) log p / q, or
        None when no row of the frame allows it."""
        if frame.mm.m == 0:
            return None
        js, consts = self.rows(frame.mask)
        if js.size == 0:
            return None
        rows, cols = sentinel_pairs(sentinels, js)   # fault-major: the draws in turn per fault
        if cols.size == 0:
            return np.zeros(X.shape[1])
        eps = rng.standard_normal(cols.size)
        return spread_sentinels(X, N_AIRFRAME, js, consts, self._carry_of[js], self._carry_B,
                                rows, cols, eps, self.clip)
