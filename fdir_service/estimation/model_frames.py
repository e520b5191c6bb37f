"""Frames drawn from an estimator's own model: the world as its filter believes it to be.

For `fdir bench` and self-checks that need frames but no simulator: the estimator's linear model
about its own airframe's trim (SPEC section 2), driven by the trim input, with the process noise
and measurement noise the estimator assumes, and optionally a step on one monitored sensor fault.
It knows no world: everything comes from the estimator file (judging a filter against a world it
was not built from is the lab's job, `sim_bridge`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fdir_service.estimation.factory import estimator_linear_model
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimator_config import EstimatorConfig


@dataclass
class ModelFrames:
    """t (K,) s; y (K, m) SI in the estimator's row order; mask (K, m) all True; u (K, 2) trim input."""

    t: np.ndarray
    y: np.ndarray
    mask: np.ndarray
    u: np.ndarray


def model_frames(estimator: EstimatorConfig, steps: int, rng: np.random.Generator,
                 onset_s: float | None = None, size_sigma: float = 5.0) -> ModelFrames:
    """`steps` frames at the estimator's dt from its own model (module docstring).

    onset_s: from this time the first monitored sensor fault steps to size_sigma times its row's
    assumed sigma (None: fault-free).
    """
    lm = estimator_linear_model(estimator)
    layout = FaultLayout.from_estimator(estimator)
    meas = MeasurementModel.build(layout, estimator.observed_sigma())
    q = np.asarray(estimator.state_process_std())
    K, dt = int(steps), estimator.dt_s
    t = dt * np.arange(1, K + 1)
    z = np.empty((K, N_AIRFRAME))
    zk = lm.trim.z.copy()
    noise = rng.standard_normal((K, N_AIRFRAME)) * q
    for k in range(K):                       # a loop over frames (the truth's own time), not particles
        zk = lm.step(zk, lm.trim.u) + noise[k]
        z[k] = zk
    y = z @ meas.H[:, :N_AIRFRAME].T + rng.standard_normal((K, meas.m)) * meas.sigma
    rows = [r for r in layout.sensor_row if r >= 0]
    if onset_s is not None and rows:
        y[t >= onset_s - 1e-9, rows[0]] += size_sigma * meas.sigma[rows[0]]
    u = np.broadcast_to(np.asarray(lm.trim.u, dtype=float), (K, 2)).copy()
    return ModelFrames(t, y, np.ones_like(y, dtype=bool), u)
