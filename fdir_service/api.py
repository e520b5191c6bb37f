"""The public API of what flies, for scripts and notebooks (docs/api.md). These names stay.

    from fdir_service.api import build_estimator
    f = build_estimator("aerosonde", filter="RJMRPF", seed=1)     # or a path to your own file
    out = f.step(t, y, mask, u)         # y (m,) SI in the estimator's row order, mask (m,) bool,
    out.fault_probability, out.fault_estimate                     # u (2,) [delta_e rad, delta_t]
"""

from __future__ import annotations

import os

import numpy as np

from fdir_service.estimation.base import Filter, StepOutput
from fdir_service.estimation.recipes import FILTER_NAMES
from fdir_service.estimator_config import EstimatorConfig, load_estimator

__all__ = ["FILTER_NAMES", "EstimatorConfig", "Filter", "StepOutput", "build_estimator", "load_estimator",
           "trim_state", "trim_input"]


def build_estimator(estimator: str | os.PathLike[str] | EstimatorConfig = "aerosonde", *,
                    filter: str | None = None, particles: int | None = None,
                    seed: int | None = None) -> Filter:
    """A ready filter from an estimator file (name in config/estimators/, a path, or a loaded
    `EstimatorConfig`); filter, particles and seed override the file's. Deterministic: the same
    seed and the same frames give the same bits."""
    from fdir_service.estimation.factory import build_filter

    cfg = estimator if isinstance(estimator, EstimatorConfig) else load_estimator(estimator)
    cfg = cfg.with_filter(filter, particles, seed)
    return build_filter(cfg.filter, cfg, np.random.default_rng(cfg.seed), particles=cfg.particles)


def trim_state(estimator: EstimatorConfig) -> np.ndarray:
    """The estimator's own trim state (5,) [p_d m, u m/s, w m/s, theta rad, q rad/s] at its
    operating point."""
    from fdir_service.estimation.factory import trim_state as _trim_state

    return _trim_state(estimator)


def trim_input(estimator: EstimatorConfig) -> np.ndarray:
    """The trim input (2,) [delta_e rad, delta_t 0..1] at the estimator's operating point."""
    from fdir_service.estimation.factory import trim_input as _trim_input

    return _trim_input(estimator)
