"""EKF-GATE: the detector a user would pick today, a Kalman filter with PX4-EKF2-style innovation
consistency gating (the baseline the thesis's filters are compared against).

Each frame, for every measurement row i that arrived, the normalised innovation test ratio is
    r_i = nu_i^2 / (gate^2 S_ii)
(nu the innovation, S its covariance from the KF's prediction, gate = `estimator.gating.gate_sigma`).
As in EKF2, a row with r_i > 1 is rejected: the frame is re-run without it, so a faulty sensor does
not drag the navigation estimate (the autopilot flies on it). A row is *declared faulty* once its
ratio has stayed above 1 for `estimator.gating.hold_s` seconds, and cleared as soon as it passes.

The KF underneath is the project's KF built from the scenario with every fault channel frozen at 0
(sigma_f = 0, x0_sigma = 0): EKF2 does not estimate these faults, it only rejects them. So the gate
gives **no fault magnitude**: `fault_estimate` is NaN. `fault_probability` is 1.0 on a declared
channel, else 0.0. A sensor fault channel is declared when its measurement row is; an actuator
fault channel (which no single row isolates) when any row not targeted by a sensor fault channel is.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.inputs import NO_SPLIT
from fdir_service.estimator_config import EstimatorConfig

NAME = "EKF-GATE"


def frozen_fault_scenario(scenario: EstimatorConfig) -> EstimatorConfig:
    """The estimator with every fault's process noise and initial spread set to 0."""
    faults = tuple(dataclasses.replace(f, sigma_f=0.0, x0_sigma=0.0) for f in scenario.faults)
    imm = dataclasses.replace(scenario.settings.imm, mode1_sigma_f=(0.0,) * len(faults),
                              mode0_sigma_f=(0.0,) * len(faults))
    est = dataclasses.replace(scenario.settings, imm=imm)
    return dataclasses.replace(scenario, faults=faults, settings=est)


def fault_rows(scenario: EstimatorConfig) -> list[np.ndarray]:
    """For each fault channel, the measurement rows whose declaration declares it (bool (m,))."""
    meas = scenario.observed
    sensor_targets = {f.target for f in scenario.sensor_faults}
    rows = []
    for f in scenario.faults:
        if f.kind == "sensor":
            rows.append(np.array([m == f.target for m in meas]))
        else:
            rows.append(np.array([m not in sensor_targets for m in meas]))
    return rows


def _snapshot(obj: object) -> object:
    """A copy of a filter good enough to re-run one step: shallow, with its arrays copied."""
    snap = copy.copy(obj)
    for k, v in vars(obj).items():
        if isinstance(v, np.ndarray):
            setattr(snap, k, v.copy())
    return snap


class GatedKF:
    """A KF wrapped with innovation gating; honours the `Filter` protocol (name "EKF-GATE").

    kf: any filter with `step` returning StepOutput and, after each step, `last_innovation` (m,)
    and `last_innovation_cov` (m, m) of the rows it was given.
    """

    name = NAME

    def __init__(self, kf: object, scenario: EstimatorConfig) -> None:
        self.kf = kf
        self.fault_ids = tuple(f.id for f in scenario.faults)
        self.gate = scenario.settings.gating.gate_sigma
        self.hold_s = scenario.settings.gating.hold_s
        self._rows = fault_rows(scenario)
        m = len(scenario.observed)
        self.test_ratio = np.zeros(m)              # last frame's ratio per row (NaN: no data)
        self.declared = np.zeros(m, bool)           # row declared faulty
        self.rejected = np.zeros(m, bool)           # row rejected from fusion this frame
        self._fail_since = np.full(m, np.nan)       # time the current run of failures began
        self._rows_matrix = np.array(self._rows, dtype=float).reshape(len(self._rows), m)
        self._nan_f = np.full(len(self.fault_ids), np.nan)
        self._gate2 = float(self.gate) ** 2
        # Fast paths (public so a test can compare them with the generic path). The project's KF
        # (predict / update / output, state in x and P, update rebinding them):
        # predict once, update, and on a rejection restore (x, P) and redo only the update.
        self._split = all(hasattr(kf, a) for a in ("predict", "update", "output"))
        self.restores_state = self._split and all(hasattr(kf, a) for a in ("x", "P", "n_eff"))
        # ... and with a linear measurement model (meas.H, meas.R, as kalman.KalmanFilter): the test
        # ratios come from the prediction alone, so they are computed first and the update runs once.
        meas = getattr(kf, "meas", None)
        self.gates_from_prediction = self.restores_state and hasattr(meas, "H") and hasattr(meas, "R")
        if self.gates_from_prediction:
            self._H = np.asarray(meas.H, float)
            self._r_diag = np.diagonal(np.asarray(meas.R, float)).copy()

    rows = NO_SPLIT
    """The estimator's rows into observed rows and inputs (`inputs.RowSplit`; set by the factory)."""

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        y, mask, u = self.rows.split(y, mask, u)
        mask = np.asarray(mask, bool)
        kf = self.kf
        split, xp = self._split, self.restores_state
        if self.gates_from_prediction:
            # nu = y - H x_pred, S_ii = (H P_pred H^T)_ii + R_ii: gate, then one update
            kf.predict(u)
            H = self._H
            nu = np.asarray(y, float) - H @ kf.x
            s = np.einsum("ij,ij->i", H @ kf.P, H) + self._r_diag
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = nu * nu / (self._gate2 * s)
            ratio[~mask] = np.nan
            fail = mask & (ratio > 1.0)
            kf.update(y, mask & ~fail)
            return self._finish(t, mask, ratio, fail, kf.x, kf.P, kf.n_eff)
        if split:       # the project's KF: predict once, update, redo only the update if gated
            kf.predict(u)
            before = (kf.x.copy(), kf.P.copy()) if xp else _snapshot(kf)
            kf.update(y, mask)
        else:           # any step-only filter: redo the whole step
            before = _snapshot(kf)
            out = kf.step(t, y, mask, u)
        nu = np.asarray(kf.last_innovation, float)
        s = np.diagonal(np.asarray(kf.last_innovation_cov, float))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = nu * nu / (self._gate2 * s)
        ratio[~mask] = np.nan
        fail = mask & (ratio > 1.0)
        if fail.any():
            if xp:
                kf.x, kf.P = before
                kf.update(y, mask & ~fail)
            else:
                self.kf = kf = before
                if split:
                    kf.update(y, mask & ~fail)
                else:
                    out = kf.step(t, y, mask & ~fail, u)
        if xp:          # what kf.output(t) gives, without its (discarded) fault probabilities
            return self._finish(t, mask, ratio, fail, kf.x, kf.P, kf.n_eff)
        if split:
            out = kf.output(t)
        return self._finish(out.t, mask, ratio, fail, out.x_mean, out.x_cov, out.n_eff, copy=False)

    def _finish(self, t: float, mask: np.ndarray, ratio: np.ndarray, fail: np.ndarray, x: np.ndarray,
                P: np.ndarray, n_eff: float, copy: bool = True) -> StepOutput:
        """Hold / declare bookkeeping and the StepOutput of the frame."""
        self.test_ratio = ratio
        self.rejected = fail
        passed = mask & ~fail
        self._fail_since[passed] = np.nan
        start = fail & np.isnan(self._fail_since)
        self._fail_since[start] = t
        self.declared = fail & (t - self._fail_since >= self.hold_s - 1e-9)
        prob = (self._rows_matrix @ self.declared > 0.0).astype(float)
        return StepOutput(t=t, x_mean=x.copy() if copy else x, x_cov=P.copy() if copy else P,
                          fault_ids=self.fault_ids, fault_estimate=self._nan_f.copy(),
                          fault_probability=prob, n_eff=n_eff, resampled=False)

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        return self.kf.top_particles(k)
