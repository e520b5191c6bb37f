"""The slots of a particle filter's recipe, as protocols: what a new part must answer.

Shapes: X (n, N) the cloud, state-major; modes (nf, N) bool; w (N,) normalised weights; a
`Frame` (t, mask (m,), u (2,), the measurement model of the rows that arrived, their values).
Each part draws only from the `rng` it is handed (the filter's own stream), in a fixed order.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.frame import Frame


class Predictor(Protocol):
    """predict: the process model plus its noise (`predict.GaussianPredict`, `ModeGatedPredict`)."""

    process: object
    """propagate(X, u): the frame's step; close_frame(prior, X, rng, frame): in place once the correction
    has moved X (`process.WholeFrameStep`: nothing; `kinematic.KinematicProcess`: theta's trapezoid,
    or its spread)."""

    def predict(self, X: np.ndarray, modes: np.ndarray, u: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        """The predicted cloud (a new (n, N) array)."""
        ...

    def annotate(self, out: StepOutput) -> None:
        """Add to the step's output (the typed faults' values, `fault_types.TypedPredict`)."""
        ...


class JumpPart(Protocol):
    """jump: the modes' Markov chain (`jump.NoJump`, `jump.MarkovJump`)."""

    sentinels: np.ndarray

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> np.ndarray | None:
        """Jump X and modes in place; an (N,) log-weight term or None."""
        ...

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """Put pinned fault entries back (in place)."""
        ...

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray: ...

    def reinitialise(self, modes: np.ndarray) -> None:
        """A fresh cloud with modes (nf, N): reset what the part holds per particle."""
        ...

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """P(fault) (nf,)."""
        ...

    def annotate(self, out: StepOutput) -> None:
        """Add what this part knows to the step's output (Pfa, Pmd, transition matrices)."""
        ...


class SentinelWeighting(Protocol):
    """sentinel weighting (`sentinels.ThesisSentinels`, `PriorSentinels`)."""

    def weigh(self, X: np.ndarray, frame: Frame, sentinels: np.ndarray,
              rng: np.random.Generator) -> np.ndarray | None:
        """An (N,) log-weight term for the particles that just jumped (X may move), or None."""
        ...


class Correction(Protocol):
    """correction (`correction.Likelihood`, `KalmanCorrection`)."""

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        """The (N,) log-likelihood of each particle (X may move)."""
        ...


class ResampleTrigger(Protocol):
    """resample: when (`resample.BelowEffectiveSize`, `EveryStep`)."""

    def due(self, n_eff: float, N: int) -> bool: ...


class Regulariser(Protocol):
    """regularise (`regularize.NoJitter`, `GlobalJitter`, `PerModeJitter`)."""

    needs_covariance: bool

    def jitter(self, X: np.ndarray, X_prev: np.ndarray, w_prev: np.ndarray, idx: np.ndarray,
               modes_prev: np.ndarray, P: np.ndarray | None, rng: np.random.Generator) -> None:
        """Jitter the resampled cloud X in place (X_prev, w_prev, modes_prev: before resampling;
        idx (N,) the ancestors; P the cloud's covariance when needs_covariance)."""
        ...


Resampler = Callable[[np.ndarray, np.random.Generator], np.ndarray]
"""resampler(w (N,), rng) -> ancestor indices (N,) (`resample.multinomial`, `systematic`)."""
