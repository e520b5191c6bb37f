"""Interacting multiple model bank of two Kalman filters, one per mode (thesis Alg. 2.9-2.12, [2.5.7]).

Mode 0 (fault-free): fault entries have process noise `imm.mode0_sigma_f` (thesis: 0), H has
no fault columns and F holds them at 0 (the fault-free model has no fault: "no fault estimation
on the process model of this mode", thesis 4.5), so mixing cannot leave stale fault values there;
mode 1 (faulty): `imm.mode1_sigma_f` and the full H. Mode transition matrix
[[1 - pi01, pi01], [pi10, 1 - pi10]]. One frame = mixing + both predictions, then both updates,
mode probabilities mu_j prop. to cbar_j L_j, and the combined estimate (the order of filterpy's
`IMMEstimator.predict` then `.update`). P(fault j) = mu_1 for every fault.
"""

from __future__ import annotations

import sys

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.inputs import NO_SPLIT
from fdir_service.estimation.kalman import KalmanFilter
from fdir_service.estimation.layout import N_AIRFRAME


class IMMKalman:
    """IMM-KF over two `KalmanFilter`s sharing state size; mu0 (2,) initial mode probabilities."""

    def __init__(self, filters: list[KalmanFilter], M: np.ndarray, mu0: np.ndarray,
                 name: str = "IMM-KF") -> None:
        self.name = name
        self.filters = filters
        self.fault_ids = filters[0].fault_ids
        self.M = np.asarray(M, dtype=float)
        self.mu = np.asarray(mu0, dtype=float).copy()
        self._mixing()
        self._combine()

    def _mixing(self) -> None:
        self.cbar = self.mu @ self.M
        self.omega = self.M * self.mu[:, None] / self.cbar[None, :]

    def _combine(self) -> None:
        xs = np.array([f.x for f in self.filters])
        self.x = self.mu @ xs
        self.P = np.zeros((xs.shape[1], xs.shape[1]))
        for f, mu in zip(self.filters, self.mu, strict=True):
            d = f.x - self.x
            self.P += mu * (np.outer(d, d) + f.P)

    rows = NO_SPLIT
    """The estimator's rows into observed rows and inputs (`inputs.RowSplit`; set by the factory)."""

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        y, mask, u = self.rows.split(y, mask, u)
        # mixing (Alg. 2.11) and mode-matched prediction
        xs = [f.x for f in self.filters]
        Ps = [f.P for f in self.filters]
        for j, f in enumerate(self.filters):
            x = sum(self.omega[i, j] * xs[i] for i in range(len(xs)))
            P = np.zeros_like(Ps[0])
            for i in range(len(xs)):
                d = xs[i] - x
                P += self.omega[i, j] * (np.outer(d, d) + Ps[i])
            f.x, f.P = x, P
            f.predict(u)
        # mode-matched update and mode probabilities (Alg. 2.9)
        lik = np.empty(len(self.filters))
        for j, f in enumerate(self.filters):
            f.update(y, mask)
            lik[j] = max(np.exp(f.log_likelihood), sys.float_info.min)
        mu = self.cbar * lik
        total = mu.sum()
        self.mu = mu / total if np.isfinite(total) and total > 0 else self.cbar.copy()
        self._mixing()
        self._combine()  # Alg. 2.10
        pf = np.full(len(self.fault_ids), float(self.mu[1]))
        return StepOutput(t=t, x_mean=self.x.copy(), x_cov=self.P.copy(), fault_ids=self.fault_ids,
                          fault_estimate=self.x[N_AIRFRAME:].copy(), fault_probability=pf,
                          n_eff=self.filters[0].n_eff, resampled=False)

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """The mode-matched means, most probable first, and their mode probabilities."""
        order = np.argsort(-self.mu)[:k]
        return np.array([self.filters[i].x for i in order]), self.mu[order].copy()
