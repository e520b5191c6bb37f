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
from fdir_service.estimation.inputs import trim_inputs
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
    y_obs = z @ meas.H[:, :N_AIRFRAME].T + rng.standard_normal((K, meas.m)) * meas.sigma
    rows = [r for r in layout.sensor_row if r >= 0]
    if onset_s is not None and rows:
        y_obs[t >= onset_s - 1e-9, rows[0]] += size_sigma * meas.sigma[rows[0]]
    y = _with_input_rows(estimator, y_obs, z, rng)
    u = np.broadcast_to(np.asarray(lm.trim.u, dtype=float), (K, 2)).copy()
    return ModelFrames(t, y, np.ones_like(y, dtype=bool), u)


def _with_input_rows(estimator: EstimatorConfig, y_obs: np.ndarray, z: np.ndarray,
                     rng: np.random.Generator) -> np.ndarray:
    """(K, m) frames over all the estimator's rows: the observed ones, and its input rows as steady
    flight at each state z (K, 5) reads them (the linear model's world has no accelerations),
    with their assumed noise."""
    rows, sigma = estimator.measurements, dict(zip(estimator.measurements, estimator.sigma, strict=True))
    if rows == estimator.observed:
        return y_obs
    y = np.empty((y_obs.shape[0], len(rows)))
    obs = [j for j, r in enumerate(rows) if r in estimator.observed]
    y[:, obs] = y_obs[:, [estimator.observed.index(rows[j]) for j in obs]]   # derived rows: made later
    for j, r in enumerate(rows):
        if r not in estimator.observed:
            steady = np.array([trim_inputs(zk)[r] for zk in z])
            y[:, j] = steady + sigma[r] * rng.standard_normal(len(z))
    return y
