"""The roll and the body-y velocity as inputs of the kinematic climb rate (`kinematic.KinematicProcess`,
`estimator_config.LATERAL_ROWS`): a banked, sideslipping aircraft's altitude, the longitudinal
step kept bit for bit wings level, and the world's rows that measure them."""

from __future__ import annotations

import math

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
U_LEVEL = np.array([0.0, 0.5, 0.5, -9.8, 40.0, 0.0, 0.0])           # de, dt, ax, az, V, roll, v


def test_a_banked_sideslipping_aircraft_climbs_by_its_tilted_vertical_velocity():
    proc = KinematicProcess(0.05, LAYOUT, lateral=(5, 6))
    phi, v = math.radians(20.0), -3.0
    u = U_LEVEL.copy()
    u[5:] = phi, v
    th = 0.05 + 0.5 * 0.05 * 0.01
    down = (v * math.sin(phi) + 2.0 * math.cos(phi)) * math.cos(th) - 40.0 * math.sin(th)
    assert proc.propagate(X, u)[0, 0] == np.float64(-500.0 + 0.05 * down)
    assert abs(proc.propagate(X, u)[0, 0] - KinematicProcess(0.05, LAYOUT).propagate(X, u)[0, 0]) > 0.005


def test_wings_level_or_without_the_rows_the_step_is_the_longitudinal_one_bit_for_bit():
    longitudinal = KinematicProcess(0.05, LAYOUT).propagate(X, U_LEVEL[:5])
    level = KinematicProcess(0.05, LAYOUT, lateral=(5, 6)).propagate(X, U_LEVEL)
    assert np.array_equal(level, longitudinal)


def test_the_robust_estimator_takes_roll_and_v_as_inputs_after_the_pitot():
    est = load_estimator("aerosonde-robust")
    assert est.input_rows == ("ax", "az", "airspeed", "roll", "v")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=20)
    assert filt.parts.predict.process.lateral == (5, 6)
    assert "roll" not in est.observed and "v" not in est.observed


def test_the_world_measures_roll_and_v_from_the_truths_air_data():
    air = AirData(40.0, np.array([0.5, -9.8]), np.zeros(2), np.array([0.1, -1.5]))
    assert [_air_value(air, i) for i in range(5)] == [40.0, 0.5, -9.8, 0.1, -1.5]
    level = AirData(40.0, np.zeros(2), np.zeros(2))            # the internal aircraft: wings level
    assert list(level.lateral) == [0.0, 0.0]


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
