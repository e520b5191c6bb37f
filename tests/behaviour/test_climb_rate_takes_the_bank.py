"""The kinematic model on JSBSim's 6-DOF aircraft, which banks, sideslips and turns in turbulence
(docs/robustness.md, "Banks and sideslip", "Body rates"): fed the world's measured roll and body-y
velocity, the robust estimator's process model predicts the true altitude change (without them
its longitudinal climb rate loses about 0.05 m/s, which the barometer used to be blamed for); fed
the roll and yaw rates too, its forward velocity and its attitude follow the truth closer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter, trim_state
from fdir_service.estimation.inputs import RowSplit
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run

RATES = Path(__file__).resolve().parents[2] / "docs/robustness/body-rates/real-jsbsim-faultfree-rates.toml"
"""real-jsbsim-faultfree with the roll and yaw rates measured and listed by the monitor."""


@pytest.fixture(scope="module")
def banking_flight():
    """(scenario, trajectory): 60 s of JSBSim's Aerosonde in moderate turbulence, flown on its truth,
    its monitor listing roll, v, p and r."""
    sc = load_scenario(str(RATES))
    return sc, run(sc, 2, seconds=60.0)


def one_frame_errors(sc, tr, lateral: bool, rates: bool = True) -> np.ndarray:
    """(K - 1, 5): the state [p_d, u, w, theta, q] the process model predicts over one frame from the
    true state with the frame's measured inputs, less the true one (SI); lateral False: roll, v, p
    and r dropped; rates False: p and r dropped."""
    est = sc.estimator
    process = build_filter("RJMRPF", est, np.random.default_rng(0), particles=10).parts.predict.process
    if not lateral:
        process.lateral = None
    if not (lateral and rates):
        process.rates = None
    rows = sc.estimator_rows()
    split = RowSplit.of(est, True, trim_state(est))
    err = []
    for k in range(len(tr.t) - 1):
        y, mask = tr.y[k + 1, rows], tr.mask[k + 1, rows] & (rows >= 0)
        _, _, u = split.split(y, mask, tr.u[k + 1])
        x = np.concatenate([tr.z[k], np.zeros(len(est.faults))])
        err.append(process.propagate(x, u)[:5] - tr.z[k + 1])
    return np.asarray(err)


def test_with_the_roll_and_v_the_predicted_climb_rate_is_unbiased(banking_flight):
    sc, tr = banking_flight
    assert {"roll", "v"} <= set(sc.estimator.input_rows)
    with_bank = -one_frame_errors(sc, tr, lateral=True)[:, 0] / sc.dt_s     # p_d is down
    level = -one_frame_errors(sc, tr, lateral=False)[:, 0] / sc.dt_s
    assert abs(with_bank.mean()) < 0.01          # seeds 1-3: -0.001, +0.002, -0.003 m/s
    assert level.mean() > 0.04                   # seeds 1-3: +0.053, +0.057, +0.066 m/s
    assert with_bank.std() < level.std()         # the measured roll and v are noisy: 0.10 against 0.15


def test_with_the_roll_and_yaw_rates_the_forward_velocity_and_the_attitude_follow_the_truth(banking_flight):
    sc, tr = banking_flight
    assert {"p", "r"} <= set(sc.estimator.input_rows)
    with_rates = one_frame_errors(sc, tr, lateral=True)
    without = one_frame_errors(sc, tr, lateral=True, rates=False)
    # seeds 1-3: u 0.016-0.017 against 0.018-0.021 m/s a frame (ratio 0.79-0.88); the attitude's
    # 10 s drift 0.15-0.17 against 0.20-0.25 deg (0.68-0.78): the measured roll, p and r are noisy
    assert with_rates[:, 1].std() < 0.92 * without[:, 1].std()
    ten_s = np.ones(int(round(10.0 / sc.dt_s)))
    drift, drift_without = (np.convolve(e[:, 3], ten_s, "valid") for e in (with_rates, without))
    assert drift.std() < 0.85 * drift_without.std()
