"""Jump parts: per-fault two-mode Markov chain of the jump-Markov filters (thesis Alg. 4.1, eq. 4.11-4.12).

Each particle carries a mode per fault (False = m(0) fault-free, True = m(1) faulty). With one
uniform v per particle and fault: mode 0 -> 1 if v < pi01, and the fault entry is set to the
predicted amplitude A (the particle becomes a "sentinel"); mode 1 -> 0 if v < pi10, and the fault
entry is set to 0. In "forced_zero" handling (JMRPF, thesis ch. 4) every mode-0 entry is 0; in
"reset_on_exit" (thesis 5.5.2) mode-0 entries evolve freely and are only zeroed on 1 -> 0.

Parts (one slot of a recipe, see recipes.py): `NoJump` (filters without modes) and `MarkovJump`
(a transition strategy: `FixedTransition` or `adaptive.AdaptiveTransition`, an amplitude
predictor, and an `ActuatorCarry` that moves an actuator sentinel's airframe state with its fault).
Each part also answers how modes are resampled, pinned and turned into fault probabilities.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.layout import N_AIRFRAME

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame

MODE0_HANDLING = ("forced_zero", "reset_on_exit")


def transition_matrices(pi01: np.ndarray, pi10: np.ndarray) -> np.ndarray:
    """(nf, 2, 2) matrices [[pi00, pi01], [pi10, pi11]] from per-fault pi01, pi10 (nf,)."""
    pi01 = np.asarray(pi01, dtype=float)
    pi10 = np.asarray(pi10, dtype=float)
    T = np.empty(pi01.shape + (2, 2))
    T[..., 0, 0] = 1.0 - pi01
    T[..., 0, 1] = pi01
    T[..., 1, 0] = pi10
    T[..., 1, 1] = 1.0 - pi10
    return T


class FixedTransition:
    """The thesis's fixed transition matrix: pi01, pi10 per fault (scalars: the same for all), every step."""

    adaptive = False
    proposal = False
    """Never a proposal: the jump's matrix is the model's (see `adaptive.AdaptiveTransition`)."""

    def __init__(self, pi01: np.ndarray | float, pi10: np.ndarray | float, nf: int) -> None:
        self.pi01 = np.broadcast_to(np.asarray(pi01, dtype=float), (nf,)).copy()
        self.pi10 = np.broadcast_to(np.asarray(pi10, dtype=float), (nf,)).copy()

    def matrices(self) -> np.ndarray:
        """(nf, 2, 2) transition matrices in force."""
        return transition_matrices(self.pi01, self.pi10)

    def observe(self, A: np.ndarray, F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> None:
        """Fixed: nothing to learn from the cloud."""

    def log_weight_correction(self, before: np.ndarray | None, after: np.ndarray,
                              available: np.ndarray) -> None:
        """Fixed: the jump draws from the model's own matrix, no importance correction."""
        return None

    def annotate(self, out: StepOutput) -> None:
        """Fixed: nothing to add to the step's output."""


def jump(F: np.ndarray, modes: np.ndarray, amplitude: np.ndarray, available: np.ndarray,
         pi01: np.ndarray, pi10: np.ndarray, v: np.ndarray, forced_zero: bool = True) -> np.ndarray:
    """Apply Alg. 4.1 in place to fault entries F (nf, N) and modes (nf, N) bool.

    amplitude (nf, N): predicted fault amplitude per particle (A_f, eq. 4.14/4.16); available (nf,)
    bool: False where no amplitude could be predicted this frame (its measurement rows did not
    arrive), then no particle enters mode 1 for that fault; pi01, pi10 (nf,); v (nf, N) ~ U(0, 1).
    Returns the sentinels (nf, N) bool: the particles that jumped 0 -> 1 this step.
    """
    up = v < pi01[:, None]
    up &= ~modes
    up &= available[:, None]
    down = v < pi10[:, None]
    down &= modes
    np.copyto(F, amplitude, where=up)
    modes |= up
    modes &= ~down
    if forced_zero:
        F *= modes
    else:
        F[down] = 0.0
    return up


class NoCarry:
    """Actuator sentinels keep their airframe state (parts.actuator_sentinel = "thesis")."""

    def capture(self, F: np.ndarray) -> None:
        return None

    def apply(self, X: np.ndarray, F: np.ndarray, before: None) -> None:
        """Nothing moves."""


class ActuatorCarry:
    """An actuator fault entry that jumps by dF moves its particle's airframe state by B_a dF: the
    amplitude is the fault that acted over the last frame (eq. 4.13), so the sentinel is weighted
    on this frame's data as it stands (parts.actuator_sentinel = "consistent").

    columns (k,): fault indices of the actuator faults; B (5, k): their one-frame airframe response.
    """

    def __init__(self, columns: np.ndarray, B: np.ndarray) -> None:
        self.columns = np.asarray(columns, dtype=int)
        self.B = np.asarray(B, dtype=float)
        self.index = {int(j): k for k, j in enumerate(self.columns)}
        """fault index -> column of B."""

    def capture(self, F: np.ndarray) -> np.ndarray:
        """The actuator fault entries (k, N) before the jump."""
        return F[self.columns].copy()

    def apply(self, X: np.ndarray, F: np.ndarray, before: np.ndarray) -> None:
        """X[:5] += B (F_act - before), in place."""
        dF = F[self.columns] - before
        X[:N_AIRFRAME] += self.B @ dF


class NoJump:
    """Filters without modes (RPF, RRPF, bootstrap): P(fault j) = weight of |f_j| > threshold_j.

    fault_threshold (nf,) SI (3 sigma of the fault's residual).
    """

    def __init__(self, fault_threshold: np.ndarray) -> None:
        self.fault_threshold = np.asarray(fault_threshold, dtype=float)
        self.sentinels = np.zeros((self.fault_threshold.size, 0), dtype=bool)

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> None:
        """No modes: nothing jumps; no log-weight term."""
        return None

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """No modes: fault entries are free."""

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        return modes

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        return (np.abs(X[N_AIRFRAME:]) > self.fault_threshold[:, None]) @ w

    def annotate(self, out: StepOutput) -> None:
        """Nothing to add."""


class MarkovJump:
    """The jump step of the jump-Markov filters (Alg. 4.1) with a transition strategy.

    transition: `FixedTransition` | `adaptive.AdaptiveTransition`; amplitude: the A_f predictor;
    forced_zero: mode-0 fault entries pinned at 0 (parts.mode0); carry: `NoCarry` | `ActuatorCarry`.
    After `jump`, `sentinels` (nf, N) are the particles that jumped 0 -> 1 and `last_amplitude`
    (nf, N) their predicted amplitudes (indices before this step's resampling).
    """

    def __init__(self, transition, amplitude: AmplitudePredictor, forced_zero: bool, carry) -> None:
        self.transition = transition
        self.amplitude = amplitude
        self.forced_zero = bool(forced_zero)
        self.carry = carry
        nf = amplitude.layout.nf
        self.sentinels = np.zeros((nf, 0), dtype=bool)
        self.last_amplitude = np.zeros((nf, 0))

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> np.ndarray | None:
        """Jump the modes and fault entries of X in place; returns the (N,) log-weight term of a
        proposal transition (None for the model's own matrix)."""
        innov = frame.yv[:, None] - frame.mm.H @ X
        self.amplitude.observe(frame)
        A, avail = self.amplitude.predict(X, innov, frame.mask)
        F = X[N_AIRFRAME:]
        self.transition.observe(A, F, modes, w)
        v = rng.random(modes.shape)
        self.last_amplitude = A
        before = modes.copy() if self.transition.proposal else None
        carried = self.carry.capture(F)
        self.sentinels = jump(F, modes, A, avail, self.transition.pi01, self.transition.pi10, v,
                              self.forced_zero)
        self.carry.apply(X, F, carried)
        return self.transition.log_weight_correction(before, modes, avail)

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """Mode-0 fault entries back to 0 (forced_zero), in place."""
        if self.forced_zero:
            X[N_AIRFRAME:] *= modes

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        return np.take(modes, idx, axis=1)

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """P(mode 1) per fault (nf,) (Alg. 4.3)."""
        return modes @ w

    def annotate(self, out: StepOutput) -> None:
        self.transition.annotate(out)
