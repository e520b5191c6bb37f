"""Resampling (thesis Alg. 2.5) and its trigger N_eff < Gamma N (eq. 2.53).

Both resamplers return ancestor indices (N,) drawn from normalised weights w (N,) with one
generator call: multinomial (the thesis's) from N sorted uniforms, systematic from one offset.
The triggers `BelowEffectiveSize` and `EveryStep` say when a filter resamples.
"""

from __future__ import annotations

import numpy as np

RESAMPLERS = ("multinomial", "systematic")


def effective_sample_size(w: np.ndarray) -> float:
    """N_eff = 1 / sum w^2 for normalised weights w (N,)."""
    return float(1.0 / np.dot(w, w))


def _search(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    c = w.cumsum()      # (the method: np.cumsum's wrapper costs more than the sum at N = 1000)
    c[-1] = 1.0  # guard the last bin against round-off in the weight sum
    return np.minimum(np.searchsorted(c, u, side="right"), w.size - 1)


def multinomial(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """N i.i.d. draws from Categorical(w): ancestor indices (N,), sorted.

    The N sorted uniforms are drawn directly as normalised partial sums of N + 1 exponentials
    (the order statistics of uniforms), which is cheaper than sorting.
    """
    e = rng.standard_exponential(w.size + 1).cumsum()
    u = e[:-1] / e[-1]
    return _search(w, u)


def systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling: one uniform offset, N evenly spaced points; indices (N,)."""
    n = w.size
    u = (rng.random() + np.arange(n)) / n
    return _search(w, u)


class BelowEffectiveSize:
    """Resample when N_eff < Gamma N (eq. 2.53); threshold = Gamma."""

    def __init__(self, threshold: float) -> None:
        self.threshold = float(threshold)

    def due(self, n_eff: float, N: int) -> bool:
        return n_eff < self.threshold * N


class EveryStep:
    """Resample at every step (the bootstrap filter)."""

    def due(self, n_eff: float, N: int) -> bool:
        return True


def resampler(name: str):
    """The resampling function called `name` ("multinomial" | "systematic")."""
    if name == "multinomial":
        return multinomial
    if name == "systematic":
        return systematic
    raise ValueError(f"resampler must be one of {RESAMPLERS}, got {name!r}")
