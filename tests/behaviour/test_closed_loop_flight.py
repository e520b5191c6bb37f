"""Closed-loop runs: fault-free hold on truth navigation, determinism, nav wiring, streaming."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import SimStepper, default_autopilot, run


def _fault_free(sid, model):
    sc = load_scenario(sid)
    return dataclasses.replace(sc, faults=(), truth=dataclasses.replace(sc.truth, model=model))


@pytest.mark.parametrize("sid,model", [("ch4", "linear"), ("ch5a", "nonlinear")])
def test_fault_free_hold_20_seeds(sid, model):
    sc = _fault_free(sid, model)
    for seed in range(20):
        tr = run(sc, seed)
        assert tr.t.size == 1000 and tr.t[-1] == pytest.approx(49.95)
        after = tr.t >= 1.0
        h = -tr.z[after, 0]
        va = np.hypot(tr.z[after, 1], tr.z[after, 2])
        assert np.max(np.abs(h - 500.0)) < 0.5, (seed, h.min(), h.max())
        assert np.max(np.abs(va - 40.0)) < 0.2, (seed, va.min(), va.max())
        # The sensor noise is really there (and differs per seed).
        assert np.std(tr.y[:, -1]) > 0.001


def test_same_seed_same_trajectory_bit_for_bit():
    sc = load_scenario("ch5c")           # nonlinear truth, actuator + sensor faults
    a, b = run(sc, 42, seconds=20.0), run(sc, 42, seconds=20.0)
    for name in ("t", "z", "y", "mask", "u", "faults", "nav", "gamma_cmd", "static_pressure_pa"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    c = run(sc, 43, seconds=20.0)
    assert not np.array_equal(a.y, c.y)


H_CH4 = np.array([[-1.0, 0, 0, 0, 0], [-1.0, 0, 0, 0, 0], [0, 1.0, 0, 0, 0], [0, 0, 1.0, 0, 0],
                  [0, 0, 0, 1.0, 0], [0, 0, 0, 0, 1.0]])
S_CH4 = np.array([[1.0, 0], [0, 1.0], [0, 0], [0, 0], [0, 0], [0, 0]])


def test_sensor_noise_does_not_depend_on_navigation():
    sc = load_scenario("ch4")
    ref = run(sc, 5, seconds=10.0)

    def nav(t, y, mask, u_prev):     # the truth of the reference run, reading 3 m high
        return ref.z[int(round(t / sc.dt_s))] + np.array([-3.0, 0.0, 0.0, 0.0, 0.0])

    other = run(sc, 5, seconds=10.0, nav=nav)
    noise_ref = ref.y - ref.z @ H_CH4.T - ref.faults @ S_CH4.T
    noise_other = other.y - other.z @ H_CH4.T - other.faults @ S_CH4.T
    assert np.max(np.abs(ref.z[:, 0] - other.z[:, 0])) > 0.5   # the loop flew differently...
    assert noise_other == pytest.approx(noise_ref, abs=1e-6)    # ...with the same sensor noise


class _Out:
    """Stands in for a filter's StepOutput: the autopilot reads `.state`."""

    def __init__(self, state):
        self.state = state


def test_autopilot_flies_on_the_navigation_estimate():
    # A navigation altitude that reads 10 m high makes the aircraft settle 10 m low (thesis Fig. 4.14).
    sc = _fault_free("ch5a", "nonlinear")
    st = SimStepper(sc, 3)
    ap = default_autopilot(sc, st.airframe)
    for _ in range(int(40.0 / sc.dt_s)):
        fr = st.frame()
        st.advance(ap.update(fr.t, fr.z_true + np.array([-10.0, 0, 0, 0, 0])))
    assert -st.truth.z[0] == pytest.approx(490.0, abs=0.5)


def test_run_records_nav_outputs_and_passes_previous_input():
    sc = load_scenario("ch5c")
    seen = []
    z_hold = np.array([-500.0, 39.95, 1.91, 0.0478, 0.0])

    def nav(t, y, mask, u_prev):
        seen.append((t, y.copy(), mask.copy(), u_prev.copy()))
        return _Out(z_hold)

    tr = run(sc, 3, seconds=1.0, nav=nav)
    assert len(tr.outputs) == 20 and all(isinstance(o, _Out) for o in tr.outputs)
    assert np.array_equal(tr.nav, np.tile(z_hold, (20, 1)))
    assert [s[0] for s in seen] == pytest.approx(tr.t)
    assert np.array_equal(np.array([s[1] for s in seen]), tr.y)
    assert np.array_equal(seen[0][3], SimStepper(sc, 3).truth.trim.u)
    assert np.array_equal(np.array([s[3] for s in seen[1:]]), tr.u[:-1])


def test_stepper_frame_is_stable_until_advance():
    sc = load_scenario("ch5c")
    st = SimStepper(sc, 1)
    f1, f2 = st.frame(), st.frame()
    assert f1 is f2 and f1.t == 0.0 and f1.mask.all() and f1.y.shape == (5,)
    assert f1.u_applied == pytest.approx(st.truth.trim.u)
    assert 95000.0 < f1.static_pressure_pa < 96000.0
    u = st.truth.trim.u + np.array([0.01, 0.0])
    st.advance(u)
    f3 = st.frame()
    assert f3.t == pytest.approx(0.05) and np.array_equal(f3.u_applied, u)
    assert not np.array_equal(f3.z_true, f1.z_true)
    # Stepping by hand with the default autopilot reproduces run() exactly.
    tr = run(sc, 9, seconds=15.0)
    st = SimStepper(sc, 9)
    ap = default_autopilot(sc, st.airframe)
    for k in range(tr.t.size):
        fr = st.frame()
        assert np.array_equal(fr.y, tr.y[k])
        st.advance(ap.update(fr.t, fr.z_true))
    assert np.array_equal(st.truth.z, run(sc, 9, seconds=15.05).z[-1])


def test_onboard_navigation_ignores_the_monitor():
    # navigation = "onboard": the autopilot flies on its own navigation, whatever the monitor says
    sc = dataclasses.replace(load_scenario("ch5c"), navigation="onboard")   # elevator and gyro faults

    def lost(t, y, mask, u_prev):      # a monitor that has lost the state altogether
        return _Out(np.array([0.0, 5.0, -3.0, 1.0, 0.5]))

    alone, watched = run(sc, 4, seconds=25.0), run(sc, 4, seconds=25.0, nav=lost)
    for name in ("z", "y", "u", "faults"):
        assert np.array_equal(getattr(alone, name), getattr(watched, name)), name
    assert np.array_equal(watched.nav[-1], [0.0, 5.0, -3.0, 1.0, 0.5])   # what the monitor said
    monitored = run(dataclasses.replace(sc, navigation="monitor"), 4, seconds=25.0, nav=lost)
    assert np.max(np.abs(monitored.z[:, 0] - watched.z[:, 0])) > 10.0   # on its estimate: upset


def _baro_reading_high(metres: float):
    """A barometer bias of `metres` for the whole flight (a world fault channel)."""
    from sim_bridge.scenario import FaultChannel, ProfileComponent

    return FaultChannel(id="baro", target="baro_alt", kind="sensor", unit="m",
                        profile=(ProfileComponent("step", 0.0, 1e9, metres),))


def test_onboard_navigation_follows_its_faulty_barometer():
    # A barometer reading 10 m high: an autopilot on its own navigation holds 500 m on it, 490 m true
    baro = _baro_reading_high(10.0)
    sc = dataclasses.replace(_fault_free("ch5a", "nonlinear"), faults=(baro,), navigation="onboard")
    tr = run(sc, 3, seconds=40.0)
    assert -tr.z[-1, 0] == pytest.approx(490.0, abs=0.5)


def test_truth_navigation_holds_its_altitude_under_a_faulty_barometer():
    # navigation = "truth": the faulty sensor does not reach the autopilot; the monitor only watches
    baro = _baro_reading_high(10.0)
    sc = dataclasses.replace(_fault_free("ch5a", "nonlinear"), faults=(baro,), navigation="truth")

    def lost(t, y, mask, u_prev):
        return _Out(np.array([0.0, 5.0, -3.0, 1.0, 0.5]))

    tr = run(sc, 3, seconds=40.0, nav=lost)
    assert -tr.z[-1, 0] == pytest.approx(500.0, abs=0.5)
    assert np.array_equal(tr.z, run(sc, 3, seconds=40.0).z)
