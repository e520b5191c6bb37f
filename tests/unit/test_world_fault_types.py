"""Typed world faults (sim_bridge.fault_types): stuck, noisy, blocked sensors; jammed and
effectiveness actuators; their additive-equivalent truth and activity; the loader's checks."""

from __future__ import annotations

import copy
import math
import re
import tomllib

import numpy as np
import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.errors import ConfigError
from sim_bridge.fault_types import air_density, blocked_pitot_airspeed
from sim_bridge.faults import channel_value
from sim_bridge.metrics import detection_metrics
from sim_bridge.scenario import load_scenario, parse_scenario, scenario_path
from sim_bridge.sensors import SensorSuite
from sim_bridge.simulate import SimStepper, default_autopilot, run
from sim_bridge.world import AirData
from sim_bridge.yardstick import run_yardstick

ROWS = ["gnss_alt", "baro_alt", "u", "w", "theta", "q", "airspeed"]
THETA, AIRSPEED = ROWS.index("theta"), ROWS.index("airspeed")
DT = 0.05


def _doc(faults: list[dict], steps: tuple[tuple[float, float], ...] = ()) -> dict:
    """ch4 with a nonlinear world, a pitot row, an altitude step command and the given faults."""
    with open(scenario_path("ch4"), "rb") as fh:
        doc = tomllib.load(fh)
    w = doc["world"]
    w["model"] = "nonlinear"
    w["sensors"]["measurements"] = list(ROWS)
    w["sensors"]["sigma"]["airspeed"] = 0.5
    w["command"]["altitude_steps"] = [{"t_s": t, "altitude_m": h} for t, h in steps]
    w["faults"] = copy.deepcopy(faults)
    doc["experiment"]["duration_s"] = 12.0
    return doc


def _scenario(faults: list[dict], steps=()):
    return parse_scenario(_doc(faults, steps))


def _fault(fid, target, ftype, amplitude, start=2.0, end=8.0, unit="1", **extra):
    return {"id": fid, "target": target, "type": ftype, "unit": unit, **extra,
            "profile": [{"shape": "step", "start_s": start, "end_s": end, "amplitude": amplitude}]}


def _frames(t, start=2.0, end=8.0):
    return (t >= start - 1e-9) & (t < end - 1e-9)


CLIMB = ((1.0, 540.0),)


# ----------------------------------------------------------------------------- sensors

def test_stuck_row_without_noise_holds_the_last_fault_free_reading():
    sc = _scenario([_fault("th", "theta", "stuck", 0.0, unit="rad", noise="none")], CLIMB)
    tr = run(sc, 3)
    on = _frames(tr.t)
    k0 = int(np.flatnonzero(on)[0])
    y = tr.y[on, THETA]
    assert np.all(y == y[0])                                   # constant while stuck
    assert y[0] == pytest.approx(tr.z[k0 - 1, 3], abs=1e-12)   # the noise-free theta before onset
    assert np.ptp(tr.z[on, 3]) > 0.02                          # while the true pitch moves (climb)
    # truth: held reading - true reading; 0 outside; activity from the profile
    np.testing.assert_allclose(tr.faults[on, 0], y[0] - tr.z[on, 3], atol=1e-12)
    assert np.all(tr.faults[~on, 0] == 0.0)
    np.testing.assert_array_equal(tr.active[:, 0], on)
    # after the fault the row is the noisy true pitch again
    after = tr.t >= 8.0
    assert np.std(tr.y[after, THETA] - tr.z[after, 3]) == pytest.approx(0.01, rel=0.25)


def test_stuck_row_with_noise_follows_the_held_value_plus_amplitude():
    sc = _scenario([_fault("th", "theta", "stuck", 2.0, unit="deg")], CLIMB)
    tr = run(sc, 4)
    on = _frames(tr.t)
    k0 = int(np.flatnonzero(on)[0])
    held = tr.z[k0 - 1, 3] + math.radians(2.0)
    err = tr.y[on, THETA] - held
    assert abs(err.mean()) < 4 * 0.01 / math.sqrt(on.sum())
    assert err.std() == pytest.approx(0.01, rel=0.2)           # the row's own noise kept
    np.testing.assert_allclose(tr.faults[on, 0], held - tr.z[on, 3], atol=1e-12)


def test_noisy_row_multiplies_its_noise_by_k_and_leaves_the_other_rows_alone():
    k = 4.0
    plain = _scenario([])
    noisy = _scenario([_fault("th", "theta", "noisy", k, start=0.0, end=6.0)])
    s0 = SensorSuite(plain, np.random.default_rng(5))
    s1 = SensorSuite(noisy, np.random.default_rng(5))
    z = np.array([-500.0, 39.954, 1.912, 0.0478, 0.0])
    air = AirData(40.0, np.array([0.5, -9.8]), np.zeros(2))
    y0, y1 = [], []
    for n in range(4000):
        t = n * DT if n < 2000 else 7.0              # first half active, second half not
        ch = noisy.faults[0]
        y0.append(s0.measure(z, t, np.zeros(0), air))
        y1.append(s1.measure(z, t, np.array([channel_value(ch, t)]), air, np.array([t < 6.0 - 1e-9])))
        if n < 2000:
            assert s1.last_fault_truth[0] == pytest.approx(k - 1.0) or t >= 6.0 - 1e-9
    y0, y1 = np.array(y0), np.array(y1)
    others = [r for r in range(len(ROWS)) if r != THETA]
    np.testing.assert_array_equal(y0[:, others], y1[:, others])        # same draws elsewhere
    act = np.arange(4000) * DT < 6.0 - 1e-9
    act[2000:] = False
    ratio = np.std(y1[act, THETA] - z[3]) / np.std(y0[act, THETA] - z[3])
    assert ratio == pytest.approx(k, rel=1e-9)                          # the same draw scaled
    assert np.std(y1[act, THETA] - z[3]) == pytest.approx(k * 0.01, rel=0.1)
    np.testing.assert_array_equal(y0[~act, THETA], y1[~act, THETA])


def test_noisy_with_k_one_is_an_active_fault_of_value_zero():
    sc = _scenario([_fault("th", "theta", "noisy", 1.0)])
    tr = run(sc, 1, seconds=10.0)
    on = _frames(tr.t)
    np.testing.assert_array_equal(tr.active[:, 0], on)
    assert np.all(tr.faults[:, 0] == 0.0)
    m = detection_metrics(tr.t, np.where(on, 0.9, 0.1)[None], tr.faults[None, :, 0],
                          active=tr.active[None, :, 0])
    assert m["detected_fraction"] == 1.0 and m["missed_fraction"] == 0.0
    ys = run_yardstick(tr.t, np.where(on, 0.9, 0.1)[:, None], ["th"], tr.faults, ["th"],
                       _hysteresis(), world_active=tr.active)
    assert len(ys["episodes"]) == 1


def _hysteresis():
    from sim_bridge.yardstick import Hysteresis
    return Hysteresis.of_service()


def test_blocked_pitot_formula_reads_fast_in_a_climb_by_about_g_dh_over_v():
    v0, h0 = 40.0, 500.0
    assert blocked_pitot_airspeed(v0, h0, h0) == v0
    for dh in (2.0, 5.0, 10.0):
        v = blocked_pitot_airspeed(v0, h0, h0 + dh)
        assert v - v0 == pytest.approx(9.81 * dh / v0, rel=0.05)
        assert v - v0 > 0.0
    assert blocked_pitot_airspeed(v0, h0, h0 - 10.0) < v0                # descent reads slow
    # density: p M / (R T) at 500 m, ~1.1673 kg/m^3 (ISA)
    assert air_density(500.0) == pytest.approx(1.1673, abs=1e-3)
    exact = math.sqrt(v0**2 + 2 * (pressure_from_altitude(500.0) - pressure_from_altitude(530.0))
                      / air_density(500.0))
    assert blocked_pitot_airspeed(v0, h0, 530.0) == pytest.approx(exact, rel=1e-12)


def test_blocked_pitot_in_closed_loop_climb():
    sc = _scenario([_fault("pit", "airspeed", "blocked", 0.0, start=2.0, end=11.0, unit="m/s")], CLIMB)
    tr = run(sc, 2)
    on = _frames(tr.t, 2.0, 11.0)
    k0 = int(np.flatnonzero(on)[0])
    va = np.hypot(tr.z[:, 1], tr.z[:, 2])                      # still air: airspeed = |(u, w)|
    h = -tr.z[:, 0]
    ind = np.array([blocked_pitot_airspeed(va[k0], h[k0], hk) for hk in h])
    np.testing.assert_allclose(tr.faults[on, 0], ind[on] - va[on], atol=1e-9)
    dh = h[on][-1] - h[k0]
    assert dh > 15.0                                           # it climbed
    # V_ind^2 - V_0^2 = 2 g dh (rho(h) ~ rho_0): about g dh / V_0 for small dh
    assert ind[on][-1] ** 2 - va[k0] ** 2 == pytest.approx(2 * 9.81 * dh, rel=0.02)
    k5 = k0 + int(np.argmax(h[on] - h[k0] > 5.0))
    assert tr.faults[k5, 0] + va[k5] - va[k0] == pytest.approx(9.81 * (h[k5] - h[k0]) / va[k0], rel=0.05)
    err = tr.y[on, AIRSPEED] - ind[on]
    assert abs(err.mean()) < 0.1 and err.std() == pytest.approx(0.5, rel=0.2)


# ----------------------------------------------------------------------------- actuators

def _fly(sc, seed=0, seconds=10.0):
    """(t, commanded u, applied u, fault truth, active) of a closed loop on the truth."""
    st = SimStepper(sc, seed)
    ap = default_autopilot(sc, st.airframe)
    ap.reset()
    rows = []
    for _ in range(int(round(seconds / sc.dt_s))):
        fr = st.frame()
        u = ap.update(fr.t, fr.autopilot_view(fr.z_true))
        f = st.fault_truth(u)
        st.advance(u)
        rows.append((fr.t, np.array(u), st.truth.u_applied.copy(), f.copy(), fr.active.copy(), fr.faults))
    t, uc, ua, f, act, ff = (np.array(x) for x in zip(*rows, strict=True))
    np.testing.assert_array_equal(f, ff)       # advance filled the frame's truth in
    return t, uc, ua, f, act


def test_jammed_elevator_stays_at_its_onset_position_while_the_command_moves():
    sc = _scenario([_fault("de", "delta_e", "jammed", 1.0, unit="deg", start=3.0, end=9.0)], ((3.5, 540.0),))
    t, uc, ua, f, act = _fly(sc)
    on = _frames(t, 3.0, 9.0)
    k0 = int(np.flatnonzero(on)[0])
    assert np.all(ua[on, 0] == ua[k0 - 1, 0] + math.radians(1.0))
    assert np.ptp(uc[on, 0]) > 0.01                            # the command moved (rad)
    np.testing.assert_allclose(f[on, 0], ua[on, 0] - uc[on, 0], atol=1e-15)
    assert np.all(f[~on, 0] == 0.0) and np.array_equal(act[:, 0], on)
    np.testing.assert_array_equal(ua[~on, 0], uc[~on, 0])
    np.testing.assert_array_equal(ua[:, 1], uc[:, 1])         # the throttle untouched


def test_effectiveness_scales_the_command():
    sc = _scenario([_fault("dt", "delta_t", "effectiveness", 0.6)])
    t, uc, ua, f, act = _fly(sc)
    on = _frames(t)
    np.testing.assert_allclose(ua[on, 1], 0.6 * uc[on, 1], rtol=1e-15)
    np.testing.assert_array_equal(ua[~on, 1], uc[~on, 1])
    np.testing.assert_allclose(f[on, 0], ua[on, 1] - uc[on, 1], rtol=1e-12)   # (g - 1) u_cmd
    assert np.all(f[~on, 0] == 0.0)


def test_effectiveness_zero_applies_zero_throttle_and_is_an_active_fault():
    sc = _scenario([_fault("eng", "delta_t", "effectiveness", 0.0)])
    t, uc, ua, f, act = _fly(sc)
    on = _frames(t)
    assert np.all(ua[on, 1] == 0.0) and np.all(uc[on, 1] > 0.0)
    np.testing.assert_array_equal(act[:, 0], on)
    np.testing.assert_array_equal(f[on, 0], -uc[on, 1])          # (g - 1) u_cmd with g = 0
    tr = run(sc, 0, seconds=10.0)
    np.testing.assert_array_equal(tr.active[:, 0], on)
    np.testing.assert_array_equal(tr.faults[on, 0], -tr.u[on, 1])
    va = np.hypot(tr.z[:, 1], tr.z[:, 2])
    assert va[on][-1] < va[0] - 1.0 or -tr.z[on, 0][-1] < 499.0   # it sinks or slows without thrust


def test_an_engine_that_quits_gives_no_thrust_rather_than_the_windmill_drag():
    sc = _scenario([_fault("eng", "delta_t", "engine", 0.0)])
    st = SimStepper(sc, 0)
    ap = default_autopilot(sc, st.airframe)
    ap.reset()
    p = st.truth.params
    for _ in range(int(round(5.0 / sc.dt_s))):          # 3 s into the fault (onset 2 s)
        fr = st.frame()
        u = ap.update(fr.t, fr.autopilot_view(fr.z_true))
        f = st.fault_truth(u)
        va = st.truth.airspeed()
        st.advance(u)
    applied = st.truth.u_applied[1]
    assert u[1] > 0.4 and applied < u[1] - 0.1                  # the command stays up
    thrust = p.rho * p.S_prop * p.C_prop * ((p.k_motor * applied) ** 2 - va ** 2) / (2.0 * p.m)
    assert abs(thrust) < 1e-9                                    # SPEC section 2's k_T (k_m^2 d^2 - V^2)
    assert applied == pytest.approx(va / p.k_motor) and f[0] == pytest.approx(applied - u[1])


def test_an_engine_at_half_thrust_keeps_half_of_the_propeller_force():
    sc = _scenario([_fault("eng", "delta_t", "engine", 0.5)])
    truth = SimStepper(sc, 0).truth
    zero = truth.airspeed() / truth.params.k_motor
    d = truth.engine_out(0.9, 0.5)
    assert d * d - zero * zero == pytest.approx(0.5 * (0.9 * 0.9 - zero * zero))
    assert truth.engine_out(0.9, 1.0) == pytest.approx(0.9) and truth.engine_out(0.9, -1.0) == zero


# ----------------------------------------------------------------------------- bias, unchanged

def test_bias_truth_and_activity_are_the_profile_values():
    sc = load_scenario("ch4")
    tr = run(sc, 1, seconds=45.0)
    vals = np.array([[channel_value(ch, t) for ch in sc.faults] for t in tr.t])
    np.testing.assert_array_equal(tr.faults, vals)
    np.testing.assert_array_equal(tr.active, vals != 0.0)
    assert all(ch.fault_type == "bias" for ch in sc.faults)


# ----------------------------------------------------------------------------- validation

@pytest.mark.parametrize("fault,key,expect", [
    (_fault("th", "theta", "jammed", 0.0, unit="rad"), r"world\.faults\[0\]\.type", "one of bias"),
    (_fault("th", "theta", "blocked", 0.0, unit="rad"), r"world\.faults\[0\]\.type", "airspeed"),
    (_fault("de", "delta_e", "stuck", 0.0, unit="rad"), r"world\.faults\[0\]\.type", "jammed"),
    (_fault("th", "theta", "bias", 0.0, unit="rad", noise="none"), r"world\.faults\[0\]\.noise",
     "only a stuck"),
    (_fault("th", "theta", "stuck", 0.0, unit="rad", noise="some"), r"world\.faults\[0\]\.noise",
     "one of kept, none"),
    (_fault("th", "theta", "noisy", 3.0, unit="rad"), r"world\.faults\[0\]\.unit", '"1"'),
    (_fault("th", "theta", "noisy", 0.5), r"world\.faults\[0\]\.profile\[0\]\.amplitude", "k >= 1"),
    (_fault("dt", "delta_t", "effectiveness", 1.5), r"world\.faults\[0\]\.profile\[0\]\.amplitude",
     r"\[0, 1\]"),
    (_fault("dt", "delta_t", "effectiveness", -0.1), r"world\.faults\[0\]\.profile\[0\]\.amplitude",
     r"\[0, 1\]"),
    (_fault("de", "delta_e", "engine", 0.0), r"world\.faults\[0\]\.type", "throttle"),
    (_fault("dt", "delta_t", "engine", 2.0), r"world\.faults\[0\]\.profile\[0\]\.amplitude",
     r"share of the thrust g in \[0, 1\]"),
])
def test_bad_fault_types_name_the_key_and_expected_value(fault, key, expect):
    with pytest.raises(ConfigError, match=key) as exc:
        parse_scenario(_doc([fault]))
    assert re.search(expect, str(exc.value)), str(exc.value)


def test_bad_fault_type_in_a_file_names_the_file(tmp_path):
    text = scenario_path("ch4").read_text()
    text = text.replace('target = "gnss_alt"\nunit = "m"',
                        'target = "gnss_alt"\ntype = "jammed"\nunit = "m"', 1)
    p = tmp_path / "typed.toml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert "typed.toml" in msg and "world.faults[0].type" in msg and "bias, stuck, noisy, blocked" in msg


def test_random_sign_is_refused_for_a_factor():
    f = _fault("th", "theta", "noisy", 2.0)
    f["profile"][0]["random_sign"] = True
    with pytest.raises(ConfigError, match=r"world\.faults\[0\]\.profile\[0\]\.random_sign"):
        parse_scenario(_doc([f]))


def test_types_load():
    sc = _scenario([_fault("th", "theta", "stuck", 1.0, unit="deg", noise="none"),
                    _fault("p", "airspeed", "blocked", 0.0, unit="m/s"),
                    _fault("eng", "delta_t", "effectiveness", 0.0)])
    assert [(f.fault_type, f.noise) for f in sc.faults] == [("stuck", "none"), ("blocked", "kept"),
                                                           ("effectiveness", "kept")]
    assert sc.faults[0].profile[0].amplitude == pytest.approx(math.radians(1.0))
