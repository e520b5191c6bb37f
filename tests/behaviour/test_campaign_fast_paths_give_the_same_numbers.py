"""Campaign fast paths of the particle filters give the same numbers (issue 4 speed point)."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter
from sim_bridge.scenario import load_scenario
from sim_bridge.synthetic import generate


@pytest.mark.parametrize("name", ["RPF", "JMRPF", "RJMRPF"])
def test_covariance_output_off_changes_nothing_else(name):
    """output_covariance = False (what a campaign sets) skips only the covariance: the estimates,
    fault probabilities, N_eff and the cloud are bit for bit those of the default filter."""
    sc = load_scenario("ch5a")
    run = generate(sc, np.random.default_rng(3), 260)      # across the step fault at 10 s
    on = build_filter(name, sc.estimator, np.random.default_rng(8), particles=300)
    off = build_filter(name, sc.estimator, np.random.default_rng(8), particles=300)
    off.output_covariance = False
    resampled = 0
    for k in range(len(run.t)):
        a = on.step(run.t[k], run.y[k], run.mask[k], run.u[k])
        b = off.step(run.t[k], run.y[k], run.mask[k], run.u[k])
        assert b.x_cov is None and a.x_cov.shape == (on.layout.n,) * 2
        np.testing.assert_array_equal(a.x_mean, b.x_mean)
        np.testing.assert_array_equal(a.fault_probability, b.fault_probability)
        assert a.n_eff == b.n_eff and a.resampled == b.resampled
        resampled += a.resampled
    np.testing.assert_array_equal(on.X, off.X)
    np.testing.assert_array_equal(on.w, off.w)
    assert resampled > 0          # the resampling (and the RPF's covariance jitter) was exercised
