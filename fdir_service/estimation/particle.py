"""The particle filters, composed from the parts (SPEC section 5; thesis Alg. 2.8, 4.3, 5.4, ch. 6).

One class, `ParticleFilter`, configured with:
- a process model (`process.LinearProcess` | `process.NonlinearProcess`) plus Gaussian process
  noise q_std (n,) per step;
- a measurement model (`measurement.MeasurementModel`) and the per-step mask;
- a jump strategy (None = no modes: RPF/RRPF/bootstrap; `jump.FixedTransition`: JMRPF/RJMRPF;
  `adaptive.AdaptiveTransition`: AJMRPF/ARJMRPF) with the amplitude predictor
  (`amplitude.AmplitudePredictor`) and the mode-0 handling ("forced_zero" | "reset_on_exit");
- correction=True adds the Kalman correction of every particle (`correction`, the R variants);
- a resampler (`resample`) triggered by N_eff < Gamma N (or every step: the bootstrap filter);
- a regulariser (`regularize`, Epanechnikov, h = k h_opt; None: no jitter); jitter_per_mode=True
  uses one kernel per mode pattern with a floor on the mode-1 fault variance
  (`regularize.regularize_per_mode`, scenario `estimator.jitter = "per_mode"`);
- an adaptive jump strategy built with proposal=True (scenario `estimator.adaptive_transition =
  "proposal"`) adds its `log_weight_correction` (model / proposal transition probability) to the
  log-likelihood of every particle;
- actuator_jump_state=True (scenario `estimator.actuator_sentinel = "consistent"`): an actuator
  fault entry that jumps by dF also moves the particle's airframe state by B_a dF (the amplitude
  is the fault that acted over the last frame, eq. 4.13);
- sentinel_prior_width (nf,) = 2 amplitude_max per sensor fault (and per actuator fault with
  actuator_jump_state; NaN: the thesis's weighting): the "prior" sentinel weighting
  (scenario `estimator.sentinel_weighting = "prior"`): sentinels drawn from N(A, s^2) and
  weighted by p(f | jump) / q(f), see `_spread_sentinels` and docs/estimation.md.

One step: propagate + noise (mode-0 fault entries get none when forced to zero) -> [adaptive:
Pfa/Pmd -> transition matrix] -> jump (sentinels at the predicted amplitude) -> [Kalman correction]
-> weight update -> estimate -> resample + regularise if N_eff < Gamma N.
The cloud is stored state-major, X (n, N), so every row operation runs on contiguous memory.
"""

from __future__ import annotations

import numpy as np

from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.correction import gaussian_loglik, kalman_gain, weighted_cov, weighted_mean_cov
from fdir_service.estimation.jump import MODE0_HANDLING, jump
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.regularize import regularize, regularize_per_mode
from fdir_service.estimation.resample import resampler as get_resampler

STATE_BOUND = 1e6
"""A particle with any |state| >= this (SI: m, m/s, rad, rad/s) has diverged: it gets weight 0."""


class ParticleFilter:
    """A (regularised, jump-Markov, robustified) particle filter; see the module docstring.

    x0_mean (n,), x0_std (n,): initial cloud N(x0_mean, diag(x0_std^2)), all modes 0;
    threshold: Gamma; always_resample: resample every step (bootstrap filter); h: bandwidth or
    None; shrink: Liu-West shrinkage with the jitter; fault_threshold (nf,): for filters without
    modes, P(fault j) = weight of particles with |f_j| > fault_threshold_j.
    """

    def __init__(self, name: str, layout: FaultLayout, process, meas: MeasurementModel,
                 rng: np.random.Generator, N: int, x0_mean: np.ndarray, x0_std: np.ndarray,
                 q_std: np.ndarray, transition=None, amplitude: AmplitudePredictor | None = None,
                 correction: bool = False, resampler: str = "multinomial", threshold: float = 0.5,
                 always_resample: bool = False, h: float | None = None, shrink: bool = False,
                 mode0: str = "forced_zero", fault_threshold: np.ndarray | None = None,
                 rejump: bool = False, sentinel_prior_width: np.ndarray | None = None,
                 jitter_per_mode: bool = False, actuator_jump_state: bool = False) -> None:
        if mode0 not in MODE0_HANDLING:
            raise ValueError(f"mode0 must be one of {MODE0_HANDLING}, got {mode0!r}")
        if transition is not None and amplitude is None:
            raise ValueError("a jump strategy needs an amplitude predictor")
        self.name = name
        self.layout = layout
        self.fault_ids = layout.fault_ids
        self.process = process
        self.meas = meas
        # All draws come from a fast SFC64 stream seeded by one draw from `rng` (deterministic:
        # the same rng state gives the same bits); its normals are ~25 % cheaper than PCG64's.
        self.rng = np.random.Generator(np.random.SFC64(int(rng.integers(2**63))))
        rng = self.rng
        self.N = int(N)
        self.n = layout.n
        self.nf = layout.nf
        self.transition = transition
        self.amplitude = amplitude
        self.correction = bool(correction)
        self.resample = get_resampler(resampler)
        self.threshold = float(threshold)
        self.always_resample = bool(always_resample)
        self.h = h
        self.shrink = bool(shrink)
        self.forced_zero = transition is not None and mode0 == "forced_zero"
        self.q_std = np.asarray(q_std, dtype=float).reshape(-1, 1)
        self.x0_std = np.asarray(x0_std, dtype=float).copy()
        self.fault_threshold = (np.full(self.nf, np.inf) if fault_threshold is None
                                else np.asarray(fault_threshold, dtype=float))
        self.rejump = bool(rejump)
        self._act = None
        if actuator_jump_state and transition is not None:
            act = np.flatnonzero(layout.actuator_input >= 0)
            if act.size:
                self._act = act
                self._B_act = np.asarray(process.B_actuator, dtype=float)[:, act]
        self.jitter_per_mode = bool(jitter_per_mode) and transition is not None and self.nf > 0
        self._fault_var_floor = None
        if self.jitter_per_mode:
            sig = np.asarray(amplitude.sigma, dtype=float)
            self._fault_var_floor = np.where(np.isfinite(sig), sig, 0.0) ** 2
        # "prior" sentinel weighting: log(sqrt(2 pi) / L_j) per sensor fault j (NaN: thesis weighting)
        self._prior_logc = None
        if sentinel_prior_width is not None and transition is not None:
            L = np.asarray(sentinel_prior_width, dtype=float)
            c = np.where(np.isfinite(L) & (L > 0), 0.5 * np.log(2.0 * np.pi) - np.log(
                np.where(L > 0, L, 1.0)), np.nan)
            # actuator faults take the "prior" weighting only when their sentinels carry the last
            # frame's effect (actuator_jump_state): else a sentinel cannot fit the frame it is
            # weighted on, and p / q would only penalise it
            act_ok = np.zeros(self.nf, dtype=bool)
            if self._act is not None:
                act_ok[self._act] = True
            c[(layout.sensor_row < 0) & ~act_ok] = np.nan
            if np.isfinite(c).any():
                self._prior_logc = c
        self._act_index = {} if self._act is None else {int(j): k for k, j in enumerate(self._act)}
        self.spread_sentinels = True
        """"prior" weighting: draw sentinels from q = N(A, s^2) (True) or place them at A with the
        marginal weight sqrt(2 pi) s / L (False: q's mode, a Laplace approximation)."""
        self._row_index: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        """mask bytes -> `_sentinel_rows` (faults (k,), their (s_j, log c_j + log s_j) (k, 2))."""
        self.reinitialisations = 0
        self.x0_mean = np.asarray(x0_mean, dtype=float).copy()
        self.X = np.asarray(x0_mean, dtype=float)[:, None] + rng.standard_normal((self.n, self.N)) \
            * self.x0_std[:, None]
        self.modes = np.zeros((self.nf, self.N), dtype=bool)
        self.w = np.full(self.N, 1.0 / self.N)
        self.x_mean, self.x_cov = weighted_mean_cov(self.X, self.w)
        self.output_covariance = True
        """False: StepOutput.x_cov is None and `step` computes the weighted covariance `x_cov` only
        when the (global) jitter needs it, else None; a campaign, which keeps none, turns it off."""
        self.fault_probability = np.zeros(self.nf)
        self.sentinels = np.zeros((self.nf, self.N), dtype=bool)
        """(nf, N) particles that jumped 0 -> 1 at the last step (indices before its resampling)."""
        self.last_amplitude = np.zeros((self.nf, self.N))
        """(nf, N) predicted amplitudes A_f of the last step, same indexing as `sentinels`."""

    # ------------------------------------------------------------------ parts of a step
    def _predict(self, u: np.ndarray) -> np.ndarray:
        X = self.process.propagate(self.X, u)
        if not self.forced_zero:
            noise = self.rng.standard_normal((self.n, self.N))
            noise *= self.q_std
            X += noise
            return X
        # mode-0 fault entries are pinned at 0: draw noise only for the airframe rows and the
        # mode-1 fault entries
        noise = self.rng.standard_normal((N_AIRFRAME, self.N))
        noise *= self.q_std[:N_AIRFRAME]
        X[:N_AIRFRAME] += noise
        for j in range(self.nf):
            on = np.flatnonzero(self.modes[j])     # (a row view indexed by position: cheapest)
            if on.size:
                X[N_AIRFRAME + j][on] += self.q_std[N_AIRFRAME + j, 0] * self.rng.standard_normal(on.size)
        return X

    def _adapt(self, A: np.ndarray, F: np.ndarray) -> None:
        """Adaptive strategy: this step's H1 means (SPEC section 6) -> new transition matrices.

        A (nf, N) predicted amplitudes, F (nf, N) predicted fault entries (before the jump).
        """
        w, m1 = self.w, self.modes
        w1 = m1 @ w                          # (nf,) weight in mode 1
        w0 = 1.0 - w1
        s0 = (A * ~m1) @ w                   # weighted sum of A over mode-0 particles
        s1 = (F * m1) @ w        # weighted sum of f over mode-1 particles
        mu10 = np.where(w0 > 1e-12, s0 / np.maximum(w0, 1e-300), A @ w)
        mu11 = np.where(w1 > 1e-12, s1 / np.maximum(w1, 1e-300), mu10)
        self.transition.update(mu10, mu11)

    def _sentinel_rows(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(faults with prior weighting that could jump this frame, their (s_j, log c_j + log s_j)
        as a (k, 2) array): sensor faults whose row arrived, actuator faults with an amplitude."""
        key = mask.tobytes()
        hit = self._row_index.get(key)
        if hit is None:
            js, consts = [], []
            _, avail, amp_sigma = self.amplitude.gain(mask)
            for j, r in enumerate(self.layout.sensor_row.tolist()):
                if not np.isfinite(self._prior_logc[j]):
                    continue
                if r >= 0 and mask[r]:
                    sj = self.meas.sigma[r]                  # sensor fault: its row's filter sigma
                elif r < 0 and avail[j] and np.isfinite(amp_sigma[j]):
                    sj = amp_sigma[j]                        # actuator fault: its amplitude's sigma
                else:
                    continue
                js.append(j)
                consts.append((sj, self._prior_logc[j] + np.log(sj)))
            hit = (np.array(js, dtype=int), np.array(consts, dtype=float).reshape(-1, 2))
            self._row_index[key] = hit
        return hit

    def _spread_sentinels(self, X: np.ndarray, mask: np.ndarray) -> np.ndarray | None:
        """"prior" weighting: draw this step's sentinels from q and weight by p / q.

        The jump proposes a sentinel's amplitude from the data: q(f) = N(A, s^2), A = y_r - h_r(z_i)
        (eq. 4.16) and s = the row's filter sigma. The amplitude prior of a fault that has just
        appeared is uniform, p(f | jump) = 1 / L on [-amplitude_max, amplitude_max], so the
        sentinel's importance weight must carry p(f) / q(f) = sqrt(2 pi) s exp(eps^2 / 2) / L
        (f = A + s eps) on top of its likelihood, which the filter computes as for any particle.
        An actuator fault (with actuator_jump_state) uses its amplitude's sigma for s, and its
        sentinel's airframe state moves by B_a s eps with the fault.
        Against a mode-0 particle, a sentinel is then worth ~ 1/L against N(e; 0, s^2): it wins
        only when e^2 / s^2 > 2 log(L / (sqrt(2 pi) s)) (a GLR threshold), instead of always
        (the thesis's point mass at A fits row r exactly). Returns the (N,) log factor, or None.
        """
        js, consts = self._sentinel_rows(mask)
        if js.size == 0:
            return None
        bonus = np.zeros(self.N)
        for j, (sj, logc) in zip(js.tolist(), consts.tolist(), strict=True):
            cols = np.flatnonzero(self.sentinels[j])
            if cols.size == 0:
                continue
            if self.spread_sentinels:
                eps = self.rng.standard_normal(cols.size)
                X[N_AIRFRAME + j][cols] += sj * eps
                k = self._act_index.get(j)
                if k is not None:          # an actuator sentinel's state carries its fault's frame
                    X[:N_AIRFRAME, cols] += self._B_act[:, k:k + 1] * (sj * eps)
                bonus[cols] += logc + 0.5 * eps * eps
            else:
                bonus[cols] += logc
        return bonus

    def _loglik(self, X: np.ndarray, yv: np.ndarray, mm: MeasurementModel) -> np.ndarray:
        if mm.m == 0:
            return np.zeros(self.N)
        e = yv[:, None] - mm.H @ X
        e *= mm.inv_sigma[:, None]
        return -0.5 * np.einsum("ij,ij->j", e, e)

    def _reinitialise(self, center: np.ndarray) -> None:
        """Fresh cloud around `center` (n,) with the initial spread; modes from P(fault) > 0.5."""
        self.reinitialisations += 1
        std = self.x0_std.copy()
        if self.amplitude is not None:
            amp_sigma = np.where(np.isfinite(self.amplitude.sigma), self.amplitude.sigma, 0.0)
            std[N_AIRFRAME:] = np.maximum(std[N_AIRFRAME:], amp_sigma)
        self.X = center[:, None] + self.rng.standard_normal((self.n, self.N)) * std[:, None]
        self.modes = np.broadcast_to((self.fault_probability > 0.5)[:, None],
                                     (self.nf, self.N)).copy()
        if self.forced_zero:
            self.X[N_AIRFRAME:] *= self.modes
        self.w = np.full(self.N, 1.0 / self.N)

    def _weights(self, ll: np.ndarray) -> np.ndarray | None:
        """w * exp(ll), normalised (computed in place in ll); None if every weight vanished."""
        top = ll.max()
        if not np.isfinite(top):               # NaN or +-inf somewhere: drop those particles
            ll = np.where(np.isfinite(ll), ll, -np.inf)
            top = ll.max()
            if not np.isfinite(top):
                return None
        ll -= top
        w = np.exp(ll, out=ll)
        w *= self.w
        s = w.sum()
        if not (s > 0.0 and np.isfinite(s)):
            return None
        w /= s
        return w

    # ------------------------------------------------------------------ the step
    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        mask = np.asarray(mask, dtype=bool)
        mm = self.meas.reduced(mask)
        yv = np.asarray(y, dtype=float)[mask]
        u = np.asarray(u, dtype=float)
        X = self._predict(u)
        move_lw = None
        if self.transition is not None:
            innov = yv[:, None] - mm.H @ X
            A, avail = self.amplitude.predict(X, innov, mask)
            if self.transition.adaptive:
                self._adapt(A, X[N_AIRFRAME:])
            v = self.rng.random((self.nf, self.N))
            F = X[N_AIRFRAME:]
            self.last_amplitude = A
            before = self.modes.copy() if self.transition.proposal else None
            F_act = F[self._act].copy() if self._act is not None else None
            self.sentinels = jump(F, self.modes, A, avail, self.transition.pi01,
                                  self.transition.pi10, v, self.forced_zero, self.rejump)
            if F_act is not None:
                # the amplitude A of an actuator fault is the fault that acted over the last frame
                # (eq. 4.13): a particle whose fault entry jumped gets that frame's effect on its
                # airframe state too, so it is weighted on this frame's data as it stands
                dF = F[self._act] - F_act
                X[:N_AIRFRAME] += self._B_act @ dF
            if before is not None:
                move_lw = self.transition.log_weight_correction(before, self.modes, avail)
        bonus = None
        if self._prior_logc is not None and mm.m > 0:
            bonus = self._spread_sentinels(X, mask)
        if self.correction and mm.m > 0:
            mean, P = weighted_mean_cov(X, self.w)
            K, S_inv = kalman_gain(P, mm.H, mm.R)
            innov = yv[:, None] - mm.H @ X
            ll = gaussian_loglik(innov, S_inv)
            X += K @ innov
            if self.forced_zero:
                X[N_AIRFRAME:] *= self.modes
        else:
            ll = self._loglik(X, yv, mm)
        if bonus is not None:
            ll += bonus
        if move_lw is not None:
            ll += move_lw
        xm = X @ self.w
        if not np.abs(xm).max() < STATE_BOUND:     # also True for NaN and inf (max propagates NaN)
            # a particle left the finite numbers (or the physically possible: |x| >= 1e6 SI) drop it
            with np.errstate(invalid="ignore", over="ignore"):
                finite = np.isfinite(X).all(axis=0) & (np.abs(X).max(axis=0) < STATE_BOUND)
            ll = np.where(finite, ll, -np.inf)
            X[:, ~finite] = 0.0
            self.w = np.where(finite, self.w, 0.0)
        self.X = X
        w = self._weights(ll)
        if w is None:
            wsum = self.w.sum()
            prior_mean = X @ (self.w / wsum) if wsum > 0 else self.process.propagate(self.x_mean, u)
            if not (np.isfinite(prior_mean).all() and np.abs(prior_mean).max() < STATE_BOUND):
                prior_mean = self.x_mean.copy()
            if not (np.isfinite(prior_mean).all() and np.abs(prior_mean).max() < STATE_BOUND):
                prior_mean = self.x0_mean.copy()
            self._reinitialise(prior_mean)
            w = self._weights(self._loglik(self.X, yv, mm))
            if w is None:
                w = np.full(self.N, 1.0 / self.N)
        self.w = w
        # estimate (Alg. 2.4 / 5.3)
        self.x_mean = self.X @ w
        if self.transition is not None:
            self.fault_probability = self.modes @ w
        else:
            self.fault_probability = (np.abs(self.X[N_AIRFRAME:]) > self.fault_threshold[:, None]) @ w
        n_eff = float(1.0 / np.dot(w, w))
        resampled = self.always_resample or n_eff < self.threshold * self.N
        global_jitter = resampled and self.h is not None and not self.jitter_per_mode
        self.x_cov = (weighted_cov(self.X, w, self.x_mean)
                      if self.output_covariance or global_jitter else None)
        if resampled:
            idx = self.resample(w, self.rng)
            X_prev, modes_prev = self.X, self.modes
            self.X = np.take(self.X, idx, axis=1)
            if self.nf and self.transition is not None:
                self.modes = np.take(self.modes, idx, axis=1)
            if self.h is not None and self.jitter_per_mode:
                regularize_per_mode(self.X, X_prev, w, idx, modes_prev, self.h, self.rng,
                                    fault_var_floor=self._fault_var_floor)
            w.fill(1.0 / self.N)     # w is this step's own array: reuse it for the uniform weights
            self.w = w
            if self.h is not None and self.jitter_per_mode:
                pass
            elif self.h is not None:
                regularize(self.X, self.x_cov, self.h, self.rng, self.shrink)
                if self.forced_zero:
                    self.X[N_AIRFRAME:] *= self.modes
        out = StepOutput(t=t, x_mean=self.x_mean.copy(),
                         x_cov=self.x_cov.copy() if self.output_covariance else None,
                         fault_ids=self.fault_ids, fault_estimate=self.x_mean[N_AIRFRAME:].copy(),
                         fault_probability=np.asarray(self.fault_probability, dtype=float).copy(),
                         n_eff=n_eff, resampled=bool(resampled))
        if self.transition is not None and self.transition.adaptive:
            out.pfa = self.transition.pfa.copy()
            out.pmd = self.transition.pmd.copy()
            out.transition = self.transition.matrices()
        return out

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """The k most weighted particles (k, n) and their weights (k,), heaviest first."""
        k = min(int(k), self.N)
        idx = np.argpartition(-self.w, k - 1)[:k]
        idx = idx[np.argsort(-self.w[idx], kind="stable")]
        return self.X[:, idx].T.copy(), self.w[idx].copy()
