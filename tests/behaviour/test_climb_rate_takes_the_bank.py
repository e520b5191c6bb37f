"""The kinematic model's climb rate on JSBSim's 6-DOF aircraft, which banks and sideslips in
turbulence (docs/robustness.md, "Banks and sideslip"): fed the world's measured roll and body-y
velocity, the robust estimator's process model predicts the true altitude change; without them its
longitudinal climb rate loses about 0.05 m/s, which the barometer used to be blamed for."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter, trim_state
from fdir_service.estimation.inputs import RowSplit
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run


@pytest.fixture(scope="module")
def banking_flight():
    """(scenario, trajectory): 60 s of JSBSim's Aerosonde in moderate turbulence, flown on its truth."""
    sc = load_scenario("real-jsbsim-faultfree")
    return sc, run(sc, 2, seconds=60.0)


def climb_rate_errors(sc, tr, lateral: bool) -> np.ndarray:
    """(K - 1,) m/s: the climb rate the process model predicts over one frame from the true state
    with the frame's measured inputs, less the true one; lateral False: roll and v dropped."""
    est = sc.estimator
    process = build_filter("RJMRPF", est, np.random.default_rng(0), particles=10).parts.predict.process
    if not lateral:
        process.lateral = None
    rows = sc.estimator_rows()
    split = RowSplit.of(est, True, trim_state(est))
    err = []
    for k in range(len(tr.t) - 1):
        y, mask = tr.y[k + 1, rows], tr.mask[k + 1, rows] & (rows >= 0)
        _, _, u = split.split(y, mask, tr.u[k + 1])
        x = np.concatenate([tr.z[k], np.zeros(len(est.faults))])
        err.append((tr.z[k + 1, 0] - process.propagate(x, u)[0]) / sc.dt_s)   # p_d is down
    return np.asarray(err)


def test_with_the_roll_and_v_the_predicted_climb_rate_is_unbiased(banking_flight):
    sc, tr = banking_flight
    assert {"roll", "v"} <= set(sc.estimator.input_rows)
    with_bank = climb_rate_errors(sc, tr, lateral=True)
    level = climb_rate_errors(sc, tr, lateral=False)
    assert abs(with_bank.mean()) < 0.01          # seeds 1-3: -0.001, +0.002, -0.003 m/s
    assert level.mean() > 0.04                   # seeds 1-3: +0.053, +0.057, +0.066 m/s
    assert with_bank.std() < level.std()         # the measured roll and v are noisy: 0.10 against 0.15
