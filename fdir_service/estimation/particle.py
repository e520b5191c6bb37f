"""The particle filter: a fixed sequence of parts chosen at build time (SPEC section 5; thesis Alg.
2.8, 4.3, 5.4, ch. 6).

One step (`ParticleFilter.step`), the same for every filter of the family:

    predict -> jump -> sentinel weighting -> correction (log-likelihood) -> weights
    -> estimate -> resample (if due) -> regularise

Which part fills each slot is a filter's recipe (recipes.py; built by factory.py):
- predict: `predict.GaussianPredict` | `predict.ModeGatedPredict`;
- jump: `jump.NoJump` | `jump.MarkovJump` (a `FixedTransition` or an `AdaptiveTransition`);
- sentinel weighting: `sentinels.ThesisSentinels` | `sentinels.PriorSentinels`;
- correction: `correction.Likelihood` | `correction.KalmanCorrection`;
- resample: a trigger (`resample.BelowEffectiveSize` | `resample.EveryStep`) and a resampler;
- regularise: `regularize.NoJitter` | `GlobalJitter` | `PerModeJitter`.
The weights, the guard against diverged particles and the re-initialisation when every weight
vanishes are the step's own. The cloud is stored state-major, X (n, N), so every row operation
runs on contiguous memory; modes (nf, N) bool; weights w (N,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.correction import row_loglik, weighted_cov, weighted_mean_cov
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.inputs import NO_SPLIT
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.pitot import NO_WIND
from fdir_service.estimation.slots import (
    Correction,
    JumpPart,
    Predictor,
    Regulariser,
    Resampler,
    ResampleTrigger,
    SentinelWeighting,
)

STATE_BOUND = 1e6
"""A particle with any |state| >= this (SI: m, m/s, rad, rad/s) has diverged: it gets weight 0."""


@dataclass
class Parts:
    """The part filling each slot of a particle filter (module docstring; the slots' protocols:
    `slots.py`)."""

    predict: Predictor
    jump: JumpPart
    sentinel_weighting: SentinelWeighting
    correction: Correction
    resample_due: ResampleTrigger
    resampler: Resampler
    regulariser: Regulariser


class ParticleFilter:
    """A particle filter of the family, made of `parts`; see the module docstring.

    layout: the fault layout; meas: the full measurement model; N particles; x0_mean (n,),
    x0_std (n,): initial cloud N(x0_mean, diag(x0_std^2)), all modes 0; reinit_std (n,): the spread
    of a fresh cloud when every weight vanished. All draws come from a fast SFC64 stream seeded by
    one draw from `rng` (the same rng state gives the same bits).
    """

    def __init__(self, name: str, layout: FaultLayout, meas: MeasurementModel, parts: Parts,
                 rng: np.random.Generator, N: int, x0_mean: np.ndarray, x0_std: np.ndarray,
                 reinit_std: np.ndarray) -> None:
        self.name = name
        self.layout = layout
        self.fault_ids = layout.fault_ids
        self.meas = meas
        self.parts = parts
        self.rng = np.random.Generator(np.random.SFC64(int(rng.integers(2**63))))
        self.N = int(N)
        self.n, self.nf = layout.n, layout.nf
        self.x0_mean = np.asarray(x0_mean, dtype=float).copy()
        self.reinit_std = np.asarray(reinit_std, dtype=float).copy()
        self.reinitialisations = 0
        self.X = self.x0_mean[:, None] + self.rng.standard_normal((self.n, self.N)) \
            * np.asarray(x0_std, dtype=float)[:, None]
        self.modes = np.zeros((self.nf, self.N), dtype=bool)
        self.w = np.full(self.N, 1.0 / self.N)
        self.x_mean, self.x_cov = weighted_mean_cov(self.X, self.w)
        self.fault_probability = np.zeros(self.nf)
        self.output_covariance = True
        """False: StepOutput.x_cov is None and `step` computes the weighted covariance `x_cov` only
        when the regulariser needs it; a campaign, which keeps none, turns it off."""

    @property
    def adaptive(self) -> bool:
        """True when the jump's transition matrix adapts (AJMRPF, ARJMRPF): outputs carry Pfa/Pmd."""
        return bool(getattr(getattr(self.parts.jump, "transition", None), "adaptive", False))

    # ------------------------------------------------------------------ the step
    rows = NO_SPLIT
    """The estimator's rows into observed rows and inputs (`inputs.RowSplit`; set by the factory)."""
    wind = NO_WIND
    """The wind of an estimator that watches the pitot (`pitot.PitotRow`, set by the factory)."""

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        p, rng = self.parts, self.rng
        y, mask, u = self.rows.split(y, mask, u)
        frame = Frame.of(t, y, mask, u, self.meas)
        X = p.predict.predict(self.X, self.modes, frame.u, rng)   # a new array: self.X stays the prior
        self.wind.evolve(X, self.modes, y, mask, rng, self.X[1])  # its ground speed, m/s (N,)
        move_lw = p.jump.jump(X, self.modes, self.w, frame, rng)
        bonus = p.sentinel_weighting.weigh(X, frame, p.jump.sentinels, rng)
        ll = p.correction.update(X, self.w, self.modes, frame)
        p.predict.process.close_frame(self.X, X, rng, frame)
        if bonus is not None:
            ll += bonus
        if move_lw is not None:
            ll += move_lw
        ll = self._drop_diverged(X, ll)
        self.X = X
        w = self._posterior_weights(ll, frame)
        self.x_mean = self.X @ w
        self.fault_probability = p.jump.fault_probability(self.X, self.modes, w)
        n_eff = float(1.0 / np.dot(w, w))
        resampled = p.resample_due.due(n_eff, self.N)
        self.x_cov = (weighted_cov(self.X, w, self.x_mean)
                      if self.output_covariance or (resampled and p.regulariser.needs_covariance) else None)
        if resampled:
            w = self._resample(w)
        self.w = w
        out = self._output(t, n_eff, resampled)
        self.wind.follow(out.fault_estimate)
        return out

    # ------------------------------------------------------------------ its pieces
    def _drop_diverged(self, X: np.ndarray, ll: np.ndarray) -> np.ndarray:
        """Particles that left the finite numbers (or |x| >= STATE_BOUND) get weight 0 and state 0."""
        xm = X @ self.w
        if np.abs(xm).max() < STATE_BOUND:        # False for NaN and inf too (max propagates NaN)
            return ll
        with np.errstate(invalid="ignore", over="ignore"):
            finite = np.isfinite(X).all(axis=0) & (np.abs(X).max(axis=0) < STATE_BOUND)
        X[:, ~finite] = 0.0
        self.w = np.where(finite, self.w, 0.0)
        return np.where(finite, ll, -np.inf)

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

    def _posterior_weights(self, ll: np.ndarray, frame: Frame) -> np.ndarray:
        """This step's normalised weights (N,); if every weight vanished, a fresh cloud about the
        best remaining guess of the state, weighted on the frame (uniform if that fails too)."""
        w = self._weights(ll)
        if w is not None:
            return w
        self._reinitialise(self._fallback_centre(frame.u))
        w = self._weights(row_loglik(self.X, frame))
        return w if w is not None else np.full(self.N, 1.0 / self.N)

    def _fallback_centre(self, u: np.ndarray) -> np.ndarray:
        """The prior mean of the cloud, else the last estimate propagated, else x0 (all bounded)."""
        wsum = self.w.sum()
        process = self.parts.predict.process
        centre = self.X @ (self.w / wsum) if wsum > 0 else process.propagate(self.x_mean, u)
        for fallback in (self.x_mean, self.x0_mean):
            if np.isfinite(centre).all() and np.abs(centre).max() < STATE_BOUND:
                break
            centre = fallback.copy()
        return centre

    def _reinitialise(self, centre: np.ndarray) -> None:
        """Fresh cloud around `centre` (n,) with reinit_std; modes from P(fault) > 0.5."""
        self.reinitialisations += 1
        self.X = centre[:, None] + self.rng.standard_normal((self.n, self.N)) * self.reinit_std[:, None]
        self.modes = np.broadcast_to((self.fault_probability > 0.5)[:, None], (self.nf, self.N)).copy()
        self.parts.jump.reinitialise(self.modes)
        self.parts.jump.pin(self.X, self.modes)
        self.w = np.full(self.N, 1.0 / self.N)

    def _resample(self, w: np.ndarray) -> np.ndarray:
        """Resample by w (N,), regularise, re-pin; returns the uniform weights (in w's array)."""
        p = self.parts
        idx = p.resampler(w, self.rng)
        X_prev, modes_prev = self.X, self.modes
        self.X = np.take(X_prev, idx, axis=1)
        self.modes = p.jump.resample_modes(modes_prev, idx)
        p.regulariser.jitter(self.X, X_prev, w, idx, modes_prev, self.x_cov, self.rng)
        p.jump.pin(self.X, self.modes)
        w.fill(1.0 / self.N)
        return w

    def _output(self, t: float, n_eff: float, resampled: bool) -> StepOutput:
        out = StepOutput(t=t, x_mean=self.x_mean.copy(),
                         x_cov=self.x_cov.copy() if self.output_covariance else None,
                         fault_ids=self.fault_ids, fault_estimate=self.x_mean[N_AIRFRAME:].copy(),
                         fault_probability=np.asarray(self.fault_probability, dtype=float).copy(),
                         n_eff=n_eff, resampled=bool(resampled))
        self.parts.jump.annotate(out)
        self.parts.predict.annotate(out)
        return out

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """The k most weighted particles (k, n) and their weights (k,), heaviest first."""
        k = min(int(k), self.N)
        idx = np.argpartition(-self.w, k - 1)[:k]
        idx = idx[np.argsort(-self.w[idx], kind="stable")]
        return self.X[:, idx].T.copy(), self.w[idx].copy()
