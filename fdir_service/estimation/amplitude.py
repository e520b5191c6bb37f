"""Predicted fault amplitude A_f of the jump step (thesis eq. 4.13-4.16, SPEC section 5).

Per particle i, A is the fault value that explains this frame's measurement y_k, given the
particle's prediction x_i (taken before the jump, i.e. with its current fault entries f_i):

- sensor fault on row r (eq. 4.16): A = f_i + (y_r - (H x_i)_r) = y_r - h_r(z_i) without the fault;
- actuator fault (eq. 4.13-4.14): the thesis writes A = B^+ (z_k - F z_{k-1} - B u_{k-1}) but
  leaves z_k open (its predicted z_k|k-1 carries no information about the fault). We use the
  measurement-informed, noise-weighted version of the same formula: the fault a that, entering
  like the input over the last frame, best explains the innovation r_i = y - H x_i in the metric
  of its covariance S_a = H_z Q_z H_z^T + R (process noise of the airframe states + measurement
  noise). With M = H_z B_a (the one-frame measurement response to a unit fault):
      A = f_i + (M^T S_a^-1 M)^-1 M^T S_a^-1 r_i,
  i.e. eq. 4.13 applied to the generalised-least-squares estimate of z_k from y_k along the
  range of B_a. Its standard deviation sqrt((M^T S_a^-1 M)^-1) is the fault's residual sigma
  for the adaptive transition matrix.
A fault whose rows did not arrive this frame has no amplitude (`available` False).
"""

from __future__ import annotations

import numpy as np

from fdir_service.estimation.fault_types import NOISY_SIGMA
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel

NO_ONSET_STEP = ("blocked",)
"""Types whose fault has no onset step: a blocked pitot reads the air at the moment it blocks and
leaves it only as the altitude changes (g dh / V), so its new entry starts at the particle's own
value, A = f, and no frame's innovation is taken as its offset (the innovation of a healthy
particle whose wind lags a gust is not a blockage)."""


class AmplitudePredictor:
    """A = f + G r for every fault, with a gain G (nf, m_rows) per measurement mask (cached).

    layout, meas (full model), B_actuator (5, nf) one-frame airframe response to each fault entry
    (zero columns for sensor faults), q_airframe (5,) process-noise std of the airframe states.
    """

    def __init__(self, layout: FaultLayout, meas: MeasurementModel, B_actuator: np.ndarray,
                 q_airframe: np.ndarray) -> None:
        self.layout = layout
        self.meas = meas
        self.B_actuator = np.asarray(B_actuator, dtype=float)
        self.Qz = np.diag(np.asarray(q_airframe, dtype=float) ** 2)
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._noisy_rows = [(j, r) for j, r in enumerate(layout.noisy_row.tolist()) if r >= 0]
        """(fault, measurement row) of each noisy-sensor fault."""
        full = np.ones(meas.m, dtype=bool)
        _, _, self.sigma = self.gain(full)

    def gain(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(G (nf, m_rows), available (nf,) bool, sigma (nf,)) for the rows where mask is True."""
        mask = np.asarray(mask, dtype=bool)
        key = mask.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        lay = self.layout
        rows = np.flatnonzero(mask)
        G = np.zeros((lay.nf, rows.size))
        avail = np.zeros(lay.nf, dtype=bool)
        sigma = np.full(lay.nf, np.inf)
        for j, r in enumerate(lay.sensor_row):
            if r >= 0 and mask[r]:
                G[j, np.searchsorted(rows, r)] = 0.0 if lay.type_of(j) in NO_ONSET_STEP else 1.0
                avail[j] = True
                sigma[j] = self.meas.sigma[r]
        for j, r in enumerate(lay.direct_row):        # an input its own derived row observes
            if r >= 0 and mask[r]:
                G[j, np.searchsorted(rows, r)] = 1.0
                avail[j] = True
                sigma[j] = self.meas.sigma[r]
        for j, r in enumerate(lay.noisy_row):          # |e| sqrt(pi / 2) / sigma_r - 1 (`predict`)
            if r >= 0 and mask[r]:
                avail[j] = True
                sigma[j] = NOISY_SIGMA
        if rows.size:
            self._actuator_gain(rows, G, avail, sigma)
        out = (G, avail, sigma)
        self._cache[key] = out
        return out

    def _actuator_gain(self, rows: np.ndarray, G: np.ndarray, avail: np.ndarray, sigma: np.ndarray) -> None:
        """Fill the actuator faults' rows of G, avail and sigma (in place) for the frame's rows: one
        generalised least-squares fit per input, shared by every fault entry on that input (its
        types differ in how the entry evolves, not in what one frame says of it)."""
        lay = self.layout
        moves = np.abs(self.B_actuator).sum(axis=0) > 0
        act = np.flatnonzero((lay.actuator_input >= 0) & (lay.direct_row < 0) & moves)
        if not act.size:
            return
        inputs, first = np.unique(lay.actuator_input[act], return_index=True)
        cols = act[first]                                  # one fault entry per input
        Hz = self.meas.H[rows, :N_AIRFRAME]
        M = Hz @ self.B_actuator[:, cols]                  # (m_rows, n_inputs)
        Sa = Hz @ self.Qz @ Hz.T + np.diag(self.meas.sigma[rows] ** 2)
        SiM = np.linalg.solve(Sa, M)
        info = M.T @ SiM                                   # (n_inputs, n_inputs) Fisher information
        if np.linalg.matrix_rank(info) < cols.size:
            return
        cov = np.linalg.inv(info)
        per_input = cov @ SiM.T
        for j in act.tolist():
            i = int(np.searchsorted(inputs, lay.actuator_input[j]))
            G[j] = per_input[i]
            avail[j] = True
            sigma[j] = np.sqrt(cov[i, i])

    def observe(self, frame) -> None:
        """Learn from the frame before `predict` (nothing here; `rate_window.RateWindowAmplitude`
        keeps a window of it)."""

    def predict(self, X: np.ndarray, innovation: np.ndarray, mask: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """A (nf, N) for the cloud X (n, N) and innovations (m_rows, N); and available (nf,)."""
        G, avail, _ = self.gain(mask)
        A = G @ innovation
        A += X[N_AIRFRAME:]
        self._noisy_amplitude(A, innovation, mask)
        return A, avail

    def _noisy_amplitude(self, A: np.ndarray, innovation: np.ndarray, mask: np.ndarray) -> None:
        """A noisy fault's amplitude (in place): k - 1 from one innovation, |e| sqrt(pi / 2) / sigma_r
        - 1 (unbiased for Gaussian noise of k sigma_r); what the adaptive transition's variance test
        takes as its H1 (a new noisy fault's entry is drawn from its prior, `NoisySentinels`)."""
        rows = self._noisy_rows
        if not rows:
            return
        reduced = np.cumsum(mask) - 1
        for j, r in rows:
            if mask[r]:
                A[j] = np.abs(innovation[reduced[r]]) * (np.sqrt(np.pi / 2.0) / self.meas.sigma[r]) - 1.0
