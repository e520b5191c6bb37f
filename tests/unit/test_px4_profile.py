"""The PX4 profile (config/autopilots/px4.toml): it maps every row of the robust estimator from
PX4's Onboard streams with the right units, the body velocity from LOCAL_POSITION_NED (m/s), the
elevator and throttle from PWM with PX4's control allocation parameters (CA_SV_CSi_TYPE,
PWM_MAIN_FUNCn / MINn / MAXn / CENTn, the PWM_MAIN_REV bitmask), integer PARAM_VALUEs in PX4's
bytewise encoding, `auto` on HEARTBEAT 12, and a bad key named with its file."""

from __future__ import annotations

import math
import struct

import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.autopilot_profile import profile_path, select_autopilot
from fdir_service.estimator_config import ACTUATORS, load_estimator
from fdir_service.mavlink import dialect
from fdir_service.runtime.derived import SourceCache, derive_value, param_number
from fdir_service.service_config import load_service_config
from tests.helpers.profiles import assert_bad_key_named

PX4 = profile_path("px4").read_text()
D10 = math.radians(10.0)


def _config():
    return select_autopilot(load_service_config(estimator="aerosonde-robust"), "px4")


def test_px4_profile_maps_every_row_of_the_robust_estimator():
    est = load_estimator("aerosonde-robust")
    c = _config()
    assert c.autopilot == "px4"
    assert [m.name for m in c.measurements] == list(est.measurements)
    assert [m.name for m in c.inputs] == list(ACTUATORS)
    by = {m.name: m for m in c.measurements + c.inputs}
    assert by["u"].sources == ("LOCAL_POSITION_NED", "ATTITUDE") and by["w"].derive == "body_velocity_w"
    assert (by["delta_e"].derive, by["delta_t"].derive) == ("px4_servo_angle", "px4_servo_range")
    assert dict(by["delta_e"].options)["surface_type"] == 3 and dict(by["delta_t"].options)["function"] == 101
    assert dict(c.parameters)["PWM_MAIN_FUNC3"] == 203


def test_px4_profile_units():
    by = {m.name: m for m in _config().measurements}
    assert by["gnss_alt"].convert(512_345) == pytest.approx(512.345)           # mm -> m
    hpa = pressure_from_altitude(500.0) / 100.0
    assert by["baro_alt"].convert(hpa) == pytest.approx(500.0, abs=1e-6)       # hPa -> Pa -> m
    assert by["az"].convert(-9.80665) == pytest.approx(-9.80665)               # m/s^2 as sent
    assert by["u"].convert(40.0) == pytest.approx(40.0)                        # m/s as derived
    assert by["airspeed"].convert(23.5) == pytest.approx(23.5)


def test_auto_picks_px4_on_heartbeat_12():
    auto = select_autopilot(load_service_config(), "auto")
    profiles = dict(auto.auto_profiles)
    assert profiles[dialect.MAV_AUTOPILOT_PX4].autopilot == "px4"
    assert profiles[dialect.MAV_AUTOPILOT_ARDUPILOTMEGA].autopilot == "ardupilot"


def test_body_velocity_from_local_position_ned_in_m_per_s():
    cache, opt = SourceCache(), {"max_attitude_age_s": 0.2}
    cache.observe(dialect.MAVLink_attitude_message(900, 0.0, D10, 0.0, 0.0, 0.0, 0.0), 900_000)
    sample = dialect.MAVLink_local_position_ned_message(1000, 0.0, 0.0, -500.0, 40.0, 0.0, 0.0)
    assert derive_value("body_velocity_w", sample, 1_000_000, cache, opt) == pytest.approx(40 * math.sin(D10))
    assert derive_value("body_velocity_u", sample, 1_000_000, cache, opt) == pytest.approx(40 * math.cos(D10))


def _bytewise(value: int) -> float:
    return struct.unpack("<f", struct.pack("<i", value))[0]


def test_param_values_in_px4_bytewise_and_ardupilot_cast_encodings():
    assert param_number(_bytewise(203), 6) == 203.0
    assert param_number(_bytewise(-1), 6) == -1.0                  # NaN as a float
    assert param_number(_bytewise(1100), 6) == 1100.0
    assert param_number(203.0, 6) == 203.0                         # ArduPilot: the integer cast to float
    assert param_number(0.0, 6) == 0.0
    assert param_number(2.5e-43, 9) == 2.5e-43                     # a REAL32 stays as sent
    assert param_number(struct.unpack("<f", struct.pack("<I", 0xFF))[0], 2) == -1.0   # INT8 -1


def _servo(**raw):
    ch = [raw.get(f"servo{n}_raw", 0) for n in range(1, 17)]
    return dialect.MAVLink_servo_output_raw_message(0, 0, *ch)


def _param(name, value):
    return dialect.MAVLink_param_value_message(name.encode(), _bytewise(value),
                                               dialect.MAV_PARAM_TYPE_INT32, 900, 0)


def test_px4_elevator_from_control_surface_type_centre_and_reversal():
    params = {"CA_SV_CS0_TYPE": 1, "CA_SV_CS2_TYPE": 3, "PWM_MAIN_FUNC1": 201, "PWM_MAIN_FUNC3": 203,
              "PWM_MAIN_MIN3": 1000, "PWM_MAIN_MAX3": 2000}
    cache = SourceCache(params)
    opt = {"surface_type": 3.0, "max_deflection_deg": 25.0, "sign": -1.0}
    half = math.radians(12.5)
    msg = _servo(servo1_raw=1900, servo3_raw=1750, servo6_raw=1650)
    assert derive_value("px4_servo_angle", msg, 0, cache, opt) == pytest.approx(-half)   # centre 1500
    cache.observe(_param("PWM_MAIN_REV", 0b100), None)                                    # bit 2: MAIN 3
    assert derive_value("px4_servo_angle", msg, 0, cache, opt) == pytest.approx(half)
    cache.observe(_param("PWM_MAIN_REV", 0b1), None)
    cache.observe(_param("PWM_MAIN_CENT3", 1250), None)                                    # off-centre trim
    assert derive_value("px4_servo_angle", msg, 0, cache, opt) == pytest.approx(-math.radians(25.0 * 2 / 3))
    cache.observe(_param("PWM_MAIN_CENT3", -1), None)                                      # -1: the midpoint
    assert derive_value("px4_servo_angle", msg, 0, cache, opt) == pytest.approx(-half)
    for name, value in (("CA_SV_CS2_TYPE", 4), ("CA_SV_CS5_TYPE", 3), ("PWM_MAIN_FUNC6", 206),
                        ("PWM_MAIN_MIN6", 1100), ("PWM_MAIN_MAX6", 1900)):
        cache.observe(_param(name, value), None)
    assert derive_value("px4_servo_angle", msg, 0, cache, opt) == pytest.approx(-math.radians(9.375))
    cache.observe(_param("CA_SV_CS5_TYPE", 0), None)
    assert math.isnan(derive_value("px4_servo_angle", msg, 0, cache, opt))    # no elevator surface


def test_px4_throttle_from_the_motor_channel():
    cache = SourceCache({"PWM_MAIN_FUNC5": 101, "PWM_MAIN_MIN5": 1000, "PWM_MAIN_MAX5": 2000})
    opt = {"function": 101.0}
    assert derive_value("px4_servo_range", _servo(servo5_raw=1600), 0, cache, opt) == pytest.approx(0.6)
    cache.observe(_param("PWM_MAIN_REV", 0b10000), None)
    assert derive_value("px4_servo_range", _servo(servo5_raw=1600), 0, cache, opt) == pytest.approx(0.4)
    assert math.isnan(derive_value("px4_servo_range", _servo(servo5_raw=0), 0, cache, opt))   # not output


@pytest.mark.parametrize(("old", "new", "key"), [
    ('sources = ["LOCAL_POSITION_NED", "ATTITUDE"]', 'sources = ["GLOBAL_POSITION_INT", "ATTITUDE"]',
     "measurements.u.sources: expected ['LOCAL_POSITION_NED', 'ATTITUDE']"),
    ('message = "LOCAL_POSITION_NED"    #', 'message = "ATTITUDE"    #',
     "measurements.u.message: derivation 'body_velocity_u' samples GLOBAL_POSITION_INT or "
     "LOCAL_POSITION_NED"),
    ('surface_type = 3 ', 'surface_type = 30 ',
     "inputs.delta_e.surface_type: expected a PX4 control surface"),
    ('surface_type = 3 ', 'function = 203 ', "inputs.delta_e.surface_type: missing"),
    ('function = 101 ', 'function = 0 ', "inputs.delta_t.function: expected a PX4 output function"),
    ('field = "abs_pressure"', 'field = "abs_press"', "measurements.baro_alt.field"),
    ('PWM_MAIN_REV = 0 ', 'PWM_MAIN_REV = "none" ', "parameters.PWM_MAIN_REV: expected a finite number"),
    ('heartbeat_autopilot = 12', 'heartbeat_autopilot = -12', "autopilot.heartbeat_autopilot"),
])
def test_a_bad_px4_profile_key_is_named_with_its_file(tmp_path, old, new, key):
    assert_bad_key_named(tmp_path, PX4, old, new, key)
