"""Kalman filter (thesis Alg. 2.1) on the extended state, linear process model.

Every scenario can run it: the KF always uses the linearised model (the scenario's
`estimator.linear_matrices`, printed or derived, about trim), even when the scenario's process
model is nonlinear; the innovation-gating detector (EKF-GATE) is built on it. Fault entries are
random walks with their `sigma_f` (0 freezes them). The covariance update is Joseph's form, as in
filterpy. After each step `last_innovation` (m,) holds y - H x_pred on the rows used (NaN on
masked rows) and `last_innovation_cov` (m, m) the predicted S = H P H^T + R of every row.
State lives in arrays only (x, P, ...), so `copy.copy` plus copied arrays is a snapshot.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.inputs import NO_SPLIT
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.process import LinearProcess

LOG_2PI = math.log(2.0 * math.pi)


def exceed_probability_gaussian(mean: np.ndarray, var: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """P(|f| > tau) for f ~ N(mean, var), elementwise: a mode-free filter's fault probability."""
    sd = np.sqrt(np.maximum(var, 1e-300))
    return ndtr((mean - tau) / sd) + ndtr((-tau - mean) / sd)


class KalmanFilter:
    """Linear KF: x_{k+1} = F x_k + c(u_k) + w, w ~ N(0, Q); y = H x + v, v ~ N(0, R)."""

    def __init__(self, process: LinearProcess, meas: MeasurementModel, layout: FaultLayout,
                 Q: np.ndarray, x0: np.ndarray, P0: np.ndarray, name: str = "KF",
                 fault_threshold: np.ndarray | None = None, n_eff: float = 1000.0) -> None:
        self.name = name
        self.n_eff = float(n_eff)   # reported as StepOutput.n_eff: "N for KF-type filters" (base.py)
        self.fault_ids = layout.fault_ids
        self.process = process
        self.meas = meas
        self.layout = layout
        self.F = process.F.copy()
        self.Q = np.asarray(Q, dtype=float)
        self.x = np.asarray(x0, dtype=float).copy()
        self.P = np.asarray(P0, dtype=float).copy()
        m = meas.m
        self.last_innovation = np.full(m, np.nan)
        self.last_innovation_cov = np.full((m, m), np.nan)
        self._nu = self._S = self._S_inv = None
        self.fault_threshold = (np.full(layout.nf, np.inf) if fault_threshold is None
                                else np.asarray(fault_threshold, dtype=float))
        self._I = np.eye(layout.n)
        self._rows: dict[bytes, tuple] = {}
        """mask -> (H[mask], R[mask][:, mask], the rows (m_r,), np.ix_ of them): the partial updates'
        constant parts (meas is the filter's fixed model)."""

    # -- the two halves of a step (the IMM and the gating detector call them separately)
    def predict(self, u: np.ndarray) -> None:
        """x <- F x + c(u), P <- F P F^T + Q."""
        self.x = self.F @ self.x + self.process.offset(u)
        self.P = self.F @ self.P @ self.F.T + self.Q

    def update(self, y: np.ndarray, mask: np.ndarray) -> None:
        """Measurement update with the rows where mask is True (Joseph form)."""
        mask = np.asarray(mask, dtype=bool)
        H, R = self.meas.H, self.meas.R
        PHt_all = self.P @ H.T
        S_all = H @ PHt_all + R
        self.last_innovation_cov = S_all
        nu_all = np.full(self.meas.m, np.nan)
        self.last_innovation = nu_all
        if mask.all():
            Hr, Rr, S, PHt = H, R, S_all, PHt_all
        elif not mask.any():
            self._nu = self._S = None
            return
        else:
            key = mask.tobytes()
            rows = self._rows.get(key)
            if rows is None:
                idx = np.flatnonzero(mask)
                ix = np.ix_(idx, idx)
                rows = self._rows[key] = (H[idx], R[ix], idx, ix)
            Hr, Rr, idx, ix = rows
            S, PHt = S_all[ix], PHt_all[:, idx]
        nu = np.asarray(y, dtype=float)[mask] - Hr @ self.x
        nu_all[mask] = nu
        S_inv = np.linalg.inv(S)
        K = PHt @ S_inv
        self.x = self.x + K @ nu
        IKH = self._I - K @ Hr
        self.P = IKH @ self.P @ IKH.T + K @ Rr @ K.T
        self._nu, self._S, self._S_inv = nu, S, S_inv

    @property
    def log_likelihood(self) -> float:
        """log N(nu; 0, S) of the last update (0 if no row arrived)."""
        if self._nu is None:
            return 0.0
        _, logdet = np.linalg.slogdet(self._S)
        nu = self._nu
        return float(-0.5 * (nu @ self._S_inv @ nu + logdet + nu.size * LOG_2PI))

    def output(self, t: float) -> StepOutput:
        f = self.x[N_AIRFRAME:]
        var = np.diag(self.P)[N_AIRFRAME:]
        prob = exceed_probability_gaussian(f, var, self.fault_threshold)
        return StepOutput(t=t, x_mean=self.x.copy(), x_cov=self.P.copy(), fault_ids=self.fault_ids,
                          fault_estimate=f.copy(), fault_probability=prob, n_eff=self.n_eff,
                          resampled=False)

    rows = NO_SPLIT
    """The estimator's rows into observed rows and inputs (`inputs.RowSplit`; set by the factory)."""

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        y, mask, u = self.rows.split(y, mask, u)
        self.predict(u)
        self.update(y, mask)
        return self.output(t)

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """A KF has one 'particle': its mean, weight 1."""
        return self.x[None, :].copy(), np.ones(1)
