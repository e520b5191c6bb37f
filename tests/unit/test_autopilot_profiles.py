"""Autopilot profiles (config/autopilots/*.toml, `fdir run --autopilot`): the body-velocity and
servo derivations against hand values, the ArduPilot profile covers every estimator row, and a bad
profile key is named with its file."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fdir_service.autopilot_profile import profile_path, select_autopilot
from fdir_service.cli import main
from fdir_service.estimator_config import ACTUATORS, load_estimator
from fdir_service.mavlink import dialect
from fdir_service.runtime.derived import (
    SourceCache,
    derive_value,
    ned_to_body,
    pwm_to_angle_fraction,
    pwm_to_range_fraction,
)
from fdir_service.service_config import load_service_config
from tests.helpers.profiles import assert_bad_key_named

D10 = math.radians(10.0)
ARDUPILOT = profile_path("ardupilot").read_text()


# ----------------------------------------------------------------------------- body velocity

@pytest.mark.parametrize(("att", "v_ned", "v_body"), [
    ((0.0, 0.0, 0.0), (40.0, 0.0, 1.5), (40.0, 0.0, 1.5)),                       # level, heading north
    ((0.0, D10, 0.0), (40.0, 0.0, 0.0), (40 * math.cos(D10), 0.0, 40 * math.sin(D10))),  # nose 10 deg up
    # climbing along the nose
    ((0.0, D10, 0.0), (40 * math.cos(D10), 0.0, -40 * math.sin(D10)), (40.0, 0.0, 0.0)),
    ((0.0, 0.0, math.pi / 2), (0.0, 40.0, 0.0), (40.0, 0.0, 0.0)),               # heading east, flying east
    ((0.0, 0.0, math.pi / 2), (40.0, 0.0, 0.0), (0.0, -40.0, 0.0)),              # heading east, moving north
    ((math.pi / 2, 0.0, 0.0), (0.0, 0.0, 5.0), (0.0, 5.0, 0.0)),                 # rolled right: down = right
])
def test_body_velocity_against_hand_rotation(att, v_ned, v_body):
    assert ned_to_body(np.array(v_ned), *att) == pytest.approx(v_body, abs=1e-12)


def test_body_velocity_is_vectorised_and_keeps_the_speed():
    rng = np.random.default_rng(0)
    v = rng.normal(0.0, 20.0, (50, 3))
    roll, pitch, yaw = rng.uniform(-1.0, 1.0, (3, 50))
    out = ned_to_body(v, roll, pitch, yaw)
    assert out.shape == (50, 3)
    assert np.linalg.norm(out, axis=1) == pytest.approx(np.linalg.norm(v, axis=1))
    assert out[7] == pytest.approx(ned_to_body(v[7], roll[7], pitch[7], yaw[7]))


def _attitude(t_ms, roll=0.0, pitch=0.0, yaw=0.0):
    return dialect.MAVLink_attitude_message(t_ms, roll, pitch, yaw, 0.0, 0.0, 0.0)


def _gpi(t_ms, vx, vy, vz):
    return dialect.MAVLink_global_position_int_message(t_ms, 0, 0, 500_000, 100_000, vx, vy, vz, 0)


def test_body_velocity_uses_the_attitude_at_or_before_the_sample_and_never_nan():
    cache, opt = SourceCache(), {"max_attitude_age_s": 0.2}
    sample = _gpi(1000, 4000, 0, 0)   # 40 m/s north, cm/s
    assert math.isnan(derive_value("body_velocity_w", sample, 1_000_000, cache, opt))   # no attitude yet
    cache.observe(_attitude(900, pitch=D10), 900_000)
    cache.observe(_attitude(1020, pitch=0.5), 1_020_000)   # after the sample: not used
    w = derive_value("body_velocity_w", sample, 1_000_000, cache, opt)
    assert w == pytest.approx(4000 * math.sin(D10))
    assert math.isnan(derive_value("body_velocity_u", _gpi(1200, 4000, 0, 0), 1_200_000,
                                   SourceCache(), opt))
    old = SourceCache()
    old.observe(_attitude(700), 700_000)                     # 0.3 s before the sample: too old
    assert math.isnan(derive_value("body_velocity_u", sample, 1_000_000, old, opt))
    bad = SourceCache()
    bad.observe(_attitude(1000, pitch=math.nan), 1_000_000)
    assert math.isnan(derive_value("body_velocity_u", sample, 1_000_000, bad, opt))


# ----------------------------------------------------------------------------- servo PWM

def test_pwm_to_elevator_fraction_with_trim_reversal_and_limits():
    f = pwm_to_angle_fraction
    assert f(np.array([1500, 1900, 1100, 1700, 1300]), 1100, 1500, 1900) == pytest.approx([0, 1, -1, .5, -.5])
    # an off-centre trim: each side scaled by its own travel
    assert f(np.array([1400, 1700, 1200, 2000, 1000]), 1000, 1400, 2000) == pytest.approx([0, .5, -.5, 1, -1])
    assert f(1700, 1000, 1400, 2000, reversed_=True) == pytest.approx(-0.5)
    assert f(np.array([2200, 900]), 1100, 1500, 1900) == pytest.approx([1, -1])      # clipped
    assert np.isnan(f(1500, 1100, 1900, 1900))                                     # trim at max: no travel
    thr = pwm_to_range_fraction(np.array([1100, 1580, 1900, 2100]), 1100, 1900)
    assert thr == pytest.approx([0, .6, 1, 1])
    assert pwm_to_range_fraction(1580, 1100, 1900, reversed_=True) == pytest.approx(0.4)


def _servo(t_us, **raw):
    ch = [raw.get(f"servo{n}_raw", 0) for n in range(1, 17)]
    return dialect.MAVLink_servo_output_raw_message(t_us, 0, *ch)


def _param(name, value):
    return dialect.MAVLink_param_value_message(name.encode(), float(value), 9, 100, 0)


def test_elevator_radians_from_parameters_and_param_value():
    params = {"SERVO2_FUNCTION": 19, "SERVO2_MIN": 1100, "SERVO2_TRIM": 1500, "SERVO2_MAX": 1900}
    cache = SourceCache(params)
    opt = {"function": 19.0, "max_deflection_deg": 25.0, "sign": -1.0}
    msg = _servo(0, servo2_raw=1700, servo5_raw=1300)
    half = math.radians(12.5)
    assert derive_value("servo_angle", msg, 0, cache, opt) == pytest.approx(-half)   # nose-up = TE up
    cache.observe(_param("SERVO2_REVERSED", 1), None)
    assert derive_value("servo_angle", msg, 0, cache, opt) == pytest.approx(half)
    for name, value in (("SERVO2_FUNCTION", 0), ("SERVO5_FUNCTION", 19), ("SERVO5_MIN", 1100),
                        ("SERVO5_TRIM", 1500), ("SERVO5_MAX", 1900)):
        cache.observe(_param(name, value), None)
    assert derive_value("servo_angle", msg, 0, cache, opt) == pytest.approx(half)      # channel 5 now
    cache.observe(_param("SERVO5_FUNCTION", 0), None)
    assert math.isnan(derive_value("servo_angle", msg, 0, cache, opt))                  # no elevator channel
    thr = SourceCache({"SERVO3_FUNCTION": 70, "SERVO3_MIN": 1100, "SERVO3_MAX": 1900})
    assert derive_value("servo_range", _servo(0, servo3_raw=1580), 0, thr, {"function": 70.0}) == \
        pytest.approx(0.6)


# ----------------------------------------------------------------------------- the profile

def test_ardupilot_profile_maps_every_row_of_the_robust_estimator():
    est = load_estimator("aerosonde-robust")
    c = select_autopilot(load_service_config(estimator="aerosonde-robust"), "ardupilot")
    assert c.autopilot == "ardupilot"
    assert [m.name for m in c.measurements] == list(est.measurements)
    assert [m.name for m in c.inputs] == list(ACTUATORS)
    by = {m.name: m for m in c.measurements + c.inputs}
    assert (by["u"].derive, by["w"].derive) == ("body_velocity_u", "body_velocity_w")
    assert by["u"].sources == ("GLOBAL_POSITION_INT", "ATTITUDE")
    assert dict(by["delta_e"].options)["function"] == 19 and dict(by["delta_t"].options)["function"] == 70
    assert by["az"].convert(-1000) == pytest.approx(-9.80665)
    assert dict(c.parameters)["SERVO2_FUNCTION"] == 19
    auto = select_autopilot(load_service_config(), "auto")
    assert auto.autopilot == "auto" and dict(auto.auto_profiles)[3].autopilot == "ardupilot"
    assert auto.measurements == load_service_config().measurements   # until the HEARTBEAT


@pytest.mark.parametrize(("old", "new", "key"), [
    ('sources = ["GLOBAL_POSITION_INT", "ATTITUDE"]', 'sources = ["GLOBAL_POSITION_INT"]',
     "measurements.u.sources: expected ['GLOBAL_POSITION_INT', 'ATTITUDE']"),
    ('derive = "body_velocity_u"', 'derive = "body_speed"', "measurements.u.derive: expected one of"),
    ('function = 19 ', 'function = 0 ', "inputs.delta_e.function: expected a servo function"),
    ('max_deflection_deg = 25.0', 'max_deflection_deg = -5.0', "inputs.delta_e.max_deflection_deg"),
    ('max_deflection_deg = 25.0', 'max_deflection = 25.0', "inputs.delta_e.max_deflection_deg: missing"),
    ('stamp = "latest"', 'stamp = "now"', "measurements.airspeed.stamp: expected one of"),
    ('stamp = "latest"', '', "measurements.airspeed.message: VFR_HUD carries no"),
    ('SERVO2_TRIM = 1500', 'SERVO2_TRIM = "mid"', "parameters.SERVO2_TRIM: expected a finite number"),
    ('heartbeat_autopilot = 3', 'heartbeat_autopilot = 300', "autopilot.heartbeat_autopilot"),
    ('[measurements.q]', '[measurements.qq]', "measurements.q: missing"),
])
def test_a_bad_profile_key_is_named_with_its_file(tmp_path, old, new, key):
    assert_bad_key_named(tmp_path, ARDUPILOT, old, new, key)


def test_fdir_run_exits_2_on_a_bad_or_missing_profile(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(ARDUPILOT.replace("function = 70", "function = 70.5"))
    assert main(["run", "--autopilot", str(bad), "--no-record", "--duration", "0"]) == 2
    assert "inputs.delta_t.function" in capsys.readouterr().err
    assert main(["run", "--autopilot", "px5", "--no-record", "--duration", "0"]) == 2
    assert "px5" in capsys.readouterr().err


@pytest.mark.parametrize("choice", ["ardupilot", "px4", "auto"])
def test_the_recorded_setup_rebuilds_the_profile(choice):
    from fdir_service.pipeline import Pipeline
    from fdir_service.replay import build_pipeline
    from tests.helpers.service import fake_factory

    meta: dict = {}

    class Meta:
        def on_metadata(self, name, data):
            meta[name] = data

        def __getattr__(self, name):
            return lambda *a, **k: None

    config = select_autopilot(load_service_config(), choice)
    Pipeline(config, observers=[Meta()], filter_factory=fake_factory([]))
    cfg = meta["config"]
    setup = {"service_toml": cfg["service_toml"], "estimator_doc": None, "legacy_scenario": None,
             "autopilot": cfg["autopilot"], "autopilot_profiles": json.loads(cfg["autopilot_profiles_json"])}
    again = build_pipeline(setup, filter_name=None, particles=None, seed=None, observers=(),
                           filter_factory=fake_factory([])).config
    def mapping(c):
        return c.autopilot, c.measurements, c.inputs, c.parameters

    assert mapping(again) == mapping(config)
    assert [(k, mapping(c)) for k, c in again.auto_profiles] == \
        [(k, mapping(c)) for k, c in config.auto_profiles]
