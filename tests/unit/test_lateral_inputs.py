"""The roll and the body-y velocity as inputs of the kinematic climb rate (`kinematic.KinematicProcess`,
`estimator_config.LATERAL_ROWS`), and the roll and yaw rates as inputs of its 6-DOF velocity and
attitude terms (`BODY_RATE_ROWS`): a banked, sideslipping, turning aircraft's state, the
longitudinal step kept bit for bit wings level, and the world's rows that measure them."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.kinematic import KinematicProcess
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimator_config import load_estimator
from sim_bridge.sensors import _air_value
from sim_bridge.world import AirData

LAYOUT = FaultLayout(("theta",), ("sensor",), ("theta",), ("gnss_alt", "theta"))
X = np.array([[-500.0], [40.0], [2.0], [0.05], [0.01], [0.0]])      # p_d, u, w, theta, q, f_theta
RATES_EXPERIMENT = Path(__file__).resolve().parents[2] / "docs/robustness/body-rates/real-jsbsim-rates.toml"
U_LEVEL = np.array([0.0, 0.5, 0.5, -9.8, 40.0, 0.0, 0.0, 0.0, 0.0])  # de, dt, ax, az, V, roll, v, p, r


def test_a_banked_sideslipping_aircraft_climbs_by_its_tilted_vertical_velocity():
    proc = KinematicProcess(0.05, LAYOUT, lateral=(5, 6))
    phi, v = math.radians(20.0), -3.0
    u = U_LEVEL.copy()
    u[5:7] = phi, v
    th = 0.05 + 0.5 * 0.05 * 0.01
    down = (v * math.sin(phi) + 2.0 * math.cos(phi)) * math.cos(th) - 40.0 * math.sin(th)
    assert proc.propagate(X, u)[0, 0] == np.float64(-500.0 + 0.05 * down)
    assert abs(proc.propagate(X, u)[0, 0] - KinematicProcess(0.05, LAYOUT).propagate(X, u)[0, 0]) > 0.005


def test_wings_level_or_without_the_rows_the_step_is_the_longitudinal_one_bit_for_bit():
    longitudinal = KinematicProcess(0.05, LAYOUT).propagate(X, U_LEVEL[:5])
    level = KinematicProcess(0.05, LAYOUT, lateral=(5, 6)).propagate(X, U_LEVEL)
    assert np.array_equal(level, longitudinal)
    level = KinematicProcess(0.05, LAYOUT, lateral=(5, 6), rates=(7, 8)).propagate(X, U_LEVEL)
    assert np.array_equal(level, longitudinal)


def test_the_roll_and_yaw_rates_give_the_6dof_velocity_and_attitude_terms():
    proc = KinematicProcess(0.05, LAYOUT, lateral=(5, 6), rates=(7, 8))
    phi, v, p, r = math.radians(20.0), -3.0, 0.2, -0.15
    u = U_LEVEL.copy()
    u[5:] = phi, v, p, r
    out = proc.propagate(X, u)[:, 0]
    lateral_only = KinematicProcess(0.05, LAYOUT, lateral=(5, 6)).propagate(X, u)[:, 0]
    th = 0.05 + 0.5 * 0.05 * 0.01
    g = 9.80665
    assert out[1] == pytest.approx(40.0 + 0.05 * (0.5 - 0.01 * 2.0 + r * v - g * math.sin(th)), abs=1e-12)
    w_dot = -9.8 + 0.01 * 40.0 - p * v + g * math.cos(th) * math.cos(phi)
    assert out[2] == pytest.approx(2.0 + 0.05 * w_dot, abs=1e-12)
    assert out[3] == pytest.approx(0.05 + 0.05 * (0.01 * math.cos(phi) - r * math.sin(phi)), abs=1e-12)
    assert out[0] == lateral_only[0] and out[4] == lateral_only[4]     # the climb rate and q as before
    assert abs(out[3] - lateral_only[3]) > 1e-4


def test_the_rates_need_the_roll_and_v():
    assert KinematicProcess(0.05, LAYOUT, rates=(7, 8)).rates is None


def test_the_robust_estimator_takes_roll_and_v_as_inputs_after_the_pitot():
    est = load_estimator("aerosonde-robust")
    assert est.input_rows == ("ax", "az", "airspeed", "roll", "v")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=20)
    assert filt.parts.predict.process.lateral == (5, 6)
    assert filt.parts.predict.process.rates is None        # measured, not the default ("Body rates")
    assert "roll" not in est.observed and "v" not in est.observed


def test_an_estimator_that_lists_p_and_r_takes_them_after_roll_and_v():
    from sim_bridge.scenario import load_scenario

    est = load_scenario(str(RATES_EXPERIMENT)).estimator
    assert est.input_rows == ("ax", "az", "airspeed", "roll", "v", "p", "r")
    process = build_filter("RJMRPF", est, np.random.default_rng(0), particles=20).parts.predict.process
    assert (process.lateral, process.rates) == ((5, 6), (7, 8))


def test_the_world_measures_roll_v_p_and_r_from_the_truths_air_data():
    air = AirData(40.0, np.array([0.5, -9.8]), np.zeros(2), np.array([0.1, -1.5, 0.2, -0.3]))
    assert [_air_value(air, i) for i in range(7)] == [40.0, 0.5, -9.8, 0.1, -1.5, 0.2, -0.3]
    level = AirData(40.0, np.zeros(2), np.zeros(2))            # the internal aircraft: wings level
    assert list(level.lateral) == [0.0, 0.0, 0.0, 0.0]


def test_a_stock_autopilots_ned_velocity_of_a_banked_sideslipping_aircraft_derives_back_to_u_v_w():
    from fdir_service.runtime.derived import ned_to_body
    from sim_bridge.profiles import ArduPlaneMessages
    from sim_bridge.scenario import load_scenario

    ap = ArduPlaneMessages(load_scenario("real-jsbsim"))
    values = {"u": 39.0, "v": -2.0, "w": 3.0, "theta": 0.05, "roll": 0.3, "baro_alt": 500.0}
    ap._navigate(values)
    assert ned_to_body(np.array(ap.ned), 0.3, 0.05, 0.0) == pytest.approx([39.0, -2.0, 3.0], abs=1e-12)
    ap._navigate({"u": 39.0, "w": 3.0, "theta": 0.05, "baro_alt": 500.0})      # wings level, no v row
    level = (39.0 * math.cos(0.05) + 3.0 * math.sin(0.05), 0.0, -39.0 * math.sin(0.05) + 3.0 * math.cos(0.05))
    assert ap.ned == level                                                     # bit for bit as before


@pytest.mark.parametrize("autopilot", [None, "ardupilot", "px4"])
def test_the_roll_and_yaw_rates_go_on_attitude_and_the_service_reads_them_there(autopilot):
    from fdir_service.autopilot_profile import apply_profile
    from fdir_service.estimator_config import estimator_document
    from fdir_service.service_config import ServiceConfig, default_config_path
    from sim_bridge.profiles import NativeMessages
    from sim_bridge.scenario import load_scenario

    est_doc = copy.deepcopy(estimator_document("aerosonde-robust")[0])     # with the rates' rows
    est_doc["measurements"]["rows"] += ["p", "r"]
    est_doc["measurements"]["sigma"].update(p=0.003, r=0.003)
    cfg = ServiceConfig.from_toml_text(default_config_path().read_text(), estimator_doc=est_doc)
    cfg = cfg if autopilot is None else apply_profile(cfg, autopilot)
    rows = {m.name: (m.message, m.field, m.frozen_s) for m in cfg.measurements}
    assert rows["p"] == ("ATTITUDE", "rollspeed", 0.0) and rows["r"] == ("ATTITUDE", "yawspeed", 0.0)
    values = {"theta": 0.05, "q": 0.01, "roll": 0.1, "p": 0.2, "r": -0.3}
    turning = NativeMessages._attitude(1.0, values, 9.5e4)
    assert (turning.rollspeed, turning.yawspeed) == (0.2, -0.3)
    level = NativeMessages._attitude(1.0, {"theta": 0.05, "q": 0.01}, 9.5e4)   # the internal aircraft
    assert (level.roll, level.rollspeed, level.yawspeed) == (0.0, 0.0, 0.0)
    assert load_scenario(str(RATES_EXPERIMENT)).estimator.input_rows[-2:] == ("p", "r")
