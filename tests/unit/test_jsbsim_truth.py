"""The JSBSim truth engine (`[world] engine = "jsbsim"`, sim_bridge/jsbsim_truth.py): it trims where
the internal model does, flies the project's autopilot in calm air and in turbulence, pushes the
same way for the same input, reads its air data, and repeats its bits for a seed."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from fdir_service.airframe import load_airframe, trim
from sim_bridge.jsbsim_truth import JSBSimTruth, jsbsim_root, turbulence_severity
from sim_bridge.scenario import AltitudeStep, load_scenario
from sim_bridge.simulate import run
from sim_bridge.world import Truth, make_truth
from sim_bridge.world_config import KNOT, DispersionConfig, TurbulenceConfig, WindConfig

CALM = dataclasses.replace(load_scenario("jsbsim-calm"), faults=())
"""jsbsim-calm without its pitch-sensor fault: JSBSim, calm air, 40 m/s at 500 m."""


def _sky(sc, **changes):
    return dataclasses.replace(sc, sky=dataclasses.replace(sc.sky, **changes))


def _moderate(sc):
    return _sky(sc, turbulence=TurbulenceConfig(30.0 * KNOT))


def _truth(sc=CALM, seed=0):
    return JSBSimTruth(sc, load_airframe(), np.random.default_rng(seed))


def test_the_experiment_picks_jsbsim_and_it_trims_at_40_mps_500_m_beside_the_internal_model():
    tr = make_truth(CALM, load_airframe(), np.random.default_rng(0))
    assert isinstance(tr, JSBSimTruth) and tr.substeps == 6          # 120 Hz under 20 Hz frames
    air = tr.air_data()
    assert air.airspeed_mps == pytest.approx(40.0, abs=0.5)
    assert -tr.z[0] == pytest.approx(500.0, abs=1.0) and abs(tr.z[4]) < 1e-3
    internal = trim(load_airframe(), 40.0, 500.0)
    assert tr.trim.u[1] == pytest.approx(internal.u[1], abs=0.02)           # 0.533 vs 0.532
    assert math.degrees(tr.trim.u[0]) == pytest.approx(math.degrees(internal.u[0]), abs=0.5)
    assert math.degrees(tr.trim.alpha) == pytest.approx(math.degrees(internal.alpha), abs=0.1)
    for _ in range(40):                                   # 2 s with the trim input: it stays there
        tr.step(tr.trim.u, np.zeros(0))
    assert tr.air_data().airspeed_mps == pytest.approx(40.0, abs=0.5)
    assert -tr.z[0] == pytest.approx(500.0, abs=1.0) and abs(tr.z[4]) < 1e-3


def test_trim_air_data_is_an_accelerometer_in_level_flight():
    tr = _truth()
    air = tr.air_data()
    g, th = 9.806, tr.z[3]                         # WGS84 gravity at 45 deg N, 500 m
    np.testing.assert_allclose(air.specific_force, [g * math.sin(th), -g * math.cos(th)], atol=0.02)
    np.testing.assert_allclose(air.wind_ned, [0.0, 0.0], atol=1e-9)


def test_a_steady_wind_is_carried_by_the_ground_velocity_from_the_start():
    sc = _sky(CALM, wind=WindConfig(north_mps=-10.0))
    tr = _truth(sc)
    air = tr.air_data()
    assert air.airspeed_mps == pytest.approx(40.0, abs=1e-6)
    np.testing.assert_allclose(air.wind_ned, [-10.0, 0.0], atol=1e-9)
    internal = Truth(_sky(sc, engine="internal"), load_airframe(), np.random.default_rng(0))
    np.testing.assert_allclose(tr.z, internal.z, atol=0.02)         # the same start in the air


@pytest.mark.parametrize("du, sign", [((0.02, 0.0), -1), ((-0.02, 0.0), 1), ((0.0, 0.05), 1)])
def test_the_same_input_pushes_the_same_way_in_both_engines(du, sign):
    """+delta_e pitches the nose down, -delta_e up (q over 0.5 s); +delta_t speeds up (u over 1 s)."""
    p = load_airframe()
    row, frames = (4, 10) if du[0] else (1, 20)
    for tr in (_truth(), Truth(_sky(CALM, engine="internal"), p, np.random.default_rng(0))):
        z0 = tr.z.copy()
        for _ in range(frames):
            tr.step(tr.trim.u + np.array(du), np.zeros(0))
        assert np.sign(tr.z[row] - z0[row]) == sign, type(tr).__name__


def test_actuator_faults_add_to_the_command_as_in_the_internal_truth():
    sc = load_scenario("real-jsbsim")
    tr = JSBSimTruth(_sky(sc, turbulence=TurbulenceConfig()), load_airframe(), np.random.default_rng(0))
    faults = np.array([0.1, 0.2, 0.03])                    # theta, q (sensors), delta_e (actuator)
    np.testing.assert_allclose(tr.applied_input(np.array([-0.08, 0.5]), faults), [-0.05, 0.5])
    tr.step(np.array([-0.08, 0.5]), faults)
    np.testing.assert_allclose(tr.u_applied, [-0.05, 0.5])


def test_sixty_seconds_in_calm_air_hold_the_altitude_command_and_follow_a_step_like_the_internal_model():
    flight = run(CALM, 0, seconds=60.0)
    assert np.max(np.abs(-flight.z[:, 0] - 500.0)) < 5.0
    stepped = dataclasses.replace(CALM, command=dataclasses.replace(
        CALM.command, altitude_steps=(AltitudeStep(5.0, 520.0),)))
    h = {eng: -run(_sky(stepped, engine=eng), 0, seconds=60.0).z[:, 0] for eng in ("jsbsim", "internal")}
    late = slice(int(30.0 / CALM.dt_s), None)
    assert np.max(np.abs(h["jsbsim"][late] - 520.0)) < 5.0
    assert np.max(np.abs(h["jsbsim"] - h["internal"])) < 2.0


def test_moderate_turbulence_makes_the_flight_bumpy_but_the_altitude_holds():
    calm, rough = (run(sc, 1, seconds=60.0) for sc in (CALM, _moderate(CALM)))
    assert np.std(rough.z[:, 4]) > 10.0 * np.std(calm.z[:, 4]) + 0.01      # pitch rate, rad/s
    assert np.max(np.abs(-rough.z[:, 0] - 500.0)) < 20.0
    assert turbulence_severity(30.0 * KNOT) == 4 and turbulence_severity(15.0 * KNOT) == 3


def test_the_same_seed_gives_the_same_bits():
    sc = _moderate(CALM)
    a, b, c = (run(sc, s, seconds=10.0) for s in (7, 7, 8))
    assert np.array_equal(a.z, b.z) and np.array_equal(a.u, b.u)
    assert not np.array_equal(a.z, c.z)


def test_dispersion_is_refused():
    sc = _sky(CALM, dispersion=DispersionConfig({"m": 0.1}))
    with pytest.raises(ValueError, match="dispersion"):
        _truth(sc)


def test_the_motor_controller_feed_forward_is_the_propeller_power_table():
    """aerosonde.xml's speed controller uses the C_POWER table of engine/aerosonde_prop.xml."""
    root = jsbsim_root()
    prop = ET.parse(root / "engine" / "aerosonde_prop.xml").getroot()
    aircraft = ET.parse(root / "aircraft" / "aerosonde" / "aerosonde.xml").getroot()

    def rows(table):
        return np.array([float(v) for v in table.find("tableData").text.split()]).reshape(-1, 2)

    power = rows(next(t for t in prop.iter("table") if t.get("name") == "C_POWER"))
    ff = next(f for f in aircraft.iter("fcs_function") if f.get("name") == "motor-power-ff-ftlbps")
    np.testing.assert_array_equal(rows(ff.find(".//table")), power)
