"""The filter family as one table: a filter's name -> the parts it is made of (SPEC sections 5-7).

A recipe names a part per slot; the parts' numbers (noise, bandwidth, resampler, transition
probabilities, sentinel weighting ...) come from the estimator file's `[parts]` table, and
`factory.build_filter` turns recipe + estimator into part objects. A new filter is one new row;
a new kind of part is one new value of a slot plus its class (docs/architecture.md).

Slots of a particle filter (`particle.ParticleFilter.step` runs them in this order):
    predict      process model + noise ("gaussian"; mode-0 fault entries get none when the
                 jump pins them, parts.mode0 = "forced_zero")
    jump         "none" (no modes: P(fault) from |f| > 3 sigma) | "fixed" (thesis Alg. 4.1) |
                 "adaptive" (ch. 6 saddlepoint-driven matrix; parts.adaptive_transition, or
                 "thesis" forced by the recipe)
    sentinels    weighting of the particles that just jumped (parts.sentinel_weighting)
    correction   "none" (likelihood only) | "kalman" (every particle corrected, Alg. 5.1-5.2)
    resample     "parts" (N_eff < Gamma N with parts.resampler) | "every_step" (systematic)
    regularise   "none" | "shrink" (one Epanechnikov kernel with Liu-West shrinkage) |
                 "parts" (parts.jitter: one kernel, or one per mode pattern)
Kalman-type filters ("kalman", "imm", "gated") have no slots: they are built whole.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Recipe:
    """The parts of one filter; see the module docstring for the slots and their values."""

    family: str                        # "particle" | "kalman" | "imm" | "gated"
    summary: str
    jump: str = "none"                 # "none" | "fixed" | "adaptive"
    correction: str = "none"           # "none" | "kalman"
    resample: str = "parts"            # "parts" | "every_step"
    regularise: str = "parts"          # "none" | "shrink" | "parts"
    adaptive_transition: str = "parts"  # "parts" | "thesis" (eq. 6.1 as written)

    @property
    def has_modes(self) -> bool:
        """True for the jump-Markov filters (a mode per fault and particle)."""
        return self.jump != "none"


RECIPES: dict[str, Recipe] = {
    "KF": Recipe("kalman", "Kalman filter on the linearised model, faults as random-walk states"),
    "IMM-KF": Recipe("imm", "interacting multiple model: a fault-free and a faulty Kalman filter"),
    "EKF-GATE": Recipe("gated", "Kalman filter with PX4-EKF2-style innovation gating (no magnitude)"),
    "bootstrap": Recipe("particle", "plain bootstrap particle filter (the cost reference)",
                        resample="every_step", regularise="none"),
    "RPF": Recipe("particle", "regularised particle filter", regularise="shrink"),
    "RRPF": Recipe("particle", "RPF with the Kalman correction of every particle",
                   correction="kalman", regularise="shrink"),
    "JMRPF": Recipe("particle", "jump-Markov RPF, fixed transition matrix (thesis ch. 4)", jump="fixed"),
    "RJMRPF": Recipe("particle", "JMRPF with the Kalman correction (thesis ch. 5)", jump="fixed",
                     correction="kalman"),
    "AJMRPF": Recipe("particle", "JMRPF with the adaptive transition matrix (thesis ch. 6)",
                     jump="adaptive"),
    "ARJMRPF": Recipe("particle", "AJMRPF with the Kalman correction", jump="adaptive",
                      correction="kalman"),
    "AJMRPF-thesis": Recipe("particle", "AJMRPF with eq. 6.1 as written", jump="adaptive",
                            adaptive_transition="thesis"),
    "ARJMRPF-thesis": Recipe("particle", "ARJMRPF with eq. 6.1 as written", jump="adaptive",
                             correction="kalman", adaptive_transition="thesis"),
}

FILTER_NAMES: tuple[str, ...] = tuple(RECIPES)
"""Every filter a config may name, in the table's order."""
PARTICLE_FILTERS: tuple[str, ...] = tuple(k for k, r in RECIPES.items() if r.family == "particle")


def recipe(name: str) -> Recipe:
    """The recipe called `name`; ValueError naming the choices otherwise."""
    try:
        return RECIPES[name]
    except KeyError:
        raise ValueError(f"unknown filter {name!r}; expected one of {', '.join(FILTER_NAMES)}") from None
