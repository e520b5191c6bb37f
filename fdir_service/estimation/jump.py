"""Jump step of the jump-Markov filters: per-fault two-mode Markov chain (thesis Alg. 4.1, eq. 4.11-4.12).

Each particle carries a mode per fault (False = m(0) fault-free, True = m(1) faulty). With one
uniform v per particle and fault: mode 0 -> 1 if v < pi01, and the fault entry is set to the
predicted amplitude A (the particle becomes a "sentinel"); mode 1 -> 0 if v < pi10, and the fault
entry is set to 0. In "forced_zero" handling (JMRPF, thesis ch. 4) every mode-0 entry is 0; in
"reset_on_exit" (thesis 5.5.2) mode-0 entries evolve freely and are only zeroed on 1 -> 0.
"""

from __future__ import annotations

import numpy as np

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
    """The thesis's fixed transition matrix, the same pi01, pi10 for every fault and step."""

    adaptive = False
    proposal = False
    """Never a proposal: the jump's matrix is the model's (see `adaptive.AdaptiveTransition`)."""

    def __init__(self, pi01: float, pi10: float, nf: int) -> None:
        self.pi01 = np.full(nf, float(pi01))
        self.pi10 = np.full(nf, float(pi10))

    def matrices(self) -> np.ndarray:
        """(nf, 2, 2) transition matrices in force."""
        return transition_matrices(self.pi01, self.pi10)


def jump(F: np.ndarray, modes: np.ndarray, amplitude: np.ndarray, available: np.ndarray,
         pi01: np.ndarray, pi10: np.ndarray, v: np.ndarray, forced_zero: bool = True,
         rejump: bool = False) -> np.ndarray:
    """Apply Alg. 4.1 in place to fault entries F (nf, N) and modes (nf, N) bool.

    amplitude (nf, N): predicted fault amplitude per particle (A_f, eq. 4.14/4.16); available (nf,)
    bool: False where no amplitude could be predicted this frame (its measurement rows did not
    arrive), then no particle enters mode 1 for that fault; pi01, pi10 (nf,); v (nf, N) ~ U(0, 1).
    Returns the sentinels (nf, N) bool: the particles that jumped 0 -> 1 this step.
    rejump (not in the thesis; off by default): a mode-1 particle with v in [pi10, pi10 + pi01)
    is also moved to the predicted amplitude (stays in mode 1), so that sentinels keep being
    placed when no mode-0 particle is left (see docs/estimation.md, ch4 lock-in).
    """
    up = v < pi01[:, None]
    up &= ~modes
    up &= available[:, None]
    down = v < pi10[:, None]
    down &= modes
    if rejump:
        re = (v >= pi10[:, None]) & (v < (pi10 + pi01)[:, None]) & modes & available[:, None]
        np.copyto(F, amplitude, where=re)
        up |= re
    np.copyto(F, amplitude, where=up)
    modes |= up
    modes &= ~down
    if forced_zero:
        F *= modes
    else:
        F[down] = 0.0
    return up
