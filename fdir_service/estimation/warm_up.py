"""Compile the filter's kernels before the first frame arrives (`kernels`, numba).

numba compiles a kernel at its first call (about 10-30 s for all of them on a fresh install, then
~0.5 s to load them from its cache). The daemon steps a throwaway copy of its filter, 32 particles
on frames from the estimator's own model with a fault in them, before it listens, so that its
first frames are not late. The service's filter and its random streams are not touched.
"""

from __future__ import annotations

import time

import numpy as np

from fdir_service.estimator_config import EstimatorConfig


def warm_up(name: str, estimator: EstimatorConfig, steps: int = 60) -> float:
    """Step filter `name` of `estimator` (32 particles, its own rng) over `steps` model frames with a
    5-sigma sensor fault from the 20th; returns the seconds it took."""
    from fdir_service.estimation.factory import build_filter
    from fdir_service.estimation.model_frames import model_frames

    t0 = time.perf_counter()
    frames = model_frames(estimator, steps, np.random.default_rng(0), onset_s=20 * estimator.dt_s)
    f = build_filter(name, estimator, np.random.default_rng(1), particles=32)
    for k in range(steps):
        f.step(frames.t[k], frames.y[k], frames.mask[k], frames.u[k])
    return time.perf_counter() - t0
