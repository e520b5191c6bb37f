"""Predict parts: the process model plus Gaussian process noise (SPEC section 5, thesis Alg. 2.8 step 1).

Each takes the cloud X (n, N), the modes (nf, N) bool, the input u (2,) and the filter's
generator, and returns the predicted cloud (a new array; X is not modified). The process model's
`propagate(X, u, modes)` gets the modes too (the kinematic moment's wind, parts.moment_wind).
"""

from __future__ import annotations

import numpy as np

from fdir_service.estimation.kernels import add_drift_noise
from fdir_service.estimation.layout import N_AIRFRAME

_NONE = np.zeros(0)
"""An empty (0,) array: no tail draw, no stall share (`kernels.add_drift_noise`)."""


class GaussianPredict:
    """x+ = f(x, u) + q eps on every entry; q_std (n,) per-step std (SI)."""

    def __init__(self, process, q_std: np.ndarray) -> None:
        self.process = process
        self.q_std = np.asarray(q_std, dtype=float).reshape(-1, 1)

    def predict(self, X: np.ndarray, modes: np.ndarray, u: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        X = self.process.propagate(X, u, modes)
        noise = rng.standard_normal(X.shape)
        noise *= self.q_std
        X += noise
        return X

    def annotate(self, out) -> None:
        """Nothing to add to the step's output (`fault_types.TypedPredict` adds the typed values)."""


class ModeGatedPredict(GaussianPredict):
    """As `GaussianPredict`, but a fault entry gets noise only in mode 1 (mode-0 entries are pinned
    at 0 by the jump, parts.mode0 = "forced_zero")."""

    def predict(self, X: np.ndarray, modes: np.ndarray, u: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        X = self.process.propagate(X, u, modes)
        N = X.shape[1]
        noise = rng.standard_normal((N_AIRFRAME, N))
        noise *= self.q_std[:N_AIRFRAME]
        X[:N_AIRFRAME] += noise
        rows, cols = np.nonzero(modes)                # fault-major, as the faults are drawn in turn
        if rows.size:
            X[N_AIRFRAME + rows, cols] += self.q_std[N_AIRFRAME + rows, 0] * rng.standard_normal(rows.size)
        return X


class DriftPredict(GaussianPredict):
    """As `GaussianPredict`, but a fault entry's noise depends on its mode (parts.mode0 = "drift"):
    q_std in mode 1 (a fault evolving), drift_std (nf,) per-step std in mode 0 (the sensor's slow
    fault-free error: a bias walk that no jump explains). Fault entries stay within +-bound (nf,)
    (`FaultSpec.bound`: faults.value_max, else the amplitude prior's support amplitude_max; inf:
    unbounded), so an unobservable fault cannot wander off and drag the airframe state with it."""

    def __init__(self, process, q_std: np.ndarray, drift_std: np.ndarray, bound: np.ndarray,
                 q_tail: tuple[float, float] = (0.0, 1.0)) -> None:
        super().__init__(process, q_std)
        self.drift_std = np.asarray(drift_std, dtype=float).reshape(-1, 1)
        self.bound = np.asarray(bound, dtype=float).reshape(-1, 1)
        self.q_tail = (float(q_tail[0]), float(q_tail[1]))
        """(probability, scale): that share of the particles gets scale x the pitch-rate noise each
        step (parts.q_tail): a heavy tail for the pitch accelerations no moment model foresees.
        Past the airframe's stall (the process's `stall_share`, parts.moment_alpha = "stall_blend")
        every particle gets it, blended by its stall share: the moment's model, fit about trim,
        is no better there."""

    def predict(self, X: np.ndarray, modes: np.ndarray, u: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        X = self.process.propagate(X, u, modes)
        noise = rng.standard_normal(X.shape)
        share, scale = self.q_tail
        tail = rng.random(X.shape[1]) if share > 0.0 else _NONE
        stalled = getattr(self.process, "stall_share", None)
        add_drift_noise(X, noise, modes, self.q_std, self.drift_std, tail, share, scale,
                        _NONE if stalled is None else stalled, self.bound)
        return X
