"""Autopilot: LQR with integral action and the saturated altitude guidance loop (SPEC 4)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.airframe import load_airframe, printed_model
from sim_bridge.autopilot import GAMMA_LIMIT_RAD, Autopilot, design_gains
from sim_bridge.scenario import AltitudeStep, CommandConfig, load_scenario
from sim_bridge.simulate import default_autopilot, run

T_STEP = 1.0


def _step_run(dh, model="nonlinear", seconds=30.0):
    sc = load_scenario("ch5a")
    sc = dataclasses.replace(
        sc, faults=(), truth=dataclasses.replace(sc.truth, model=model),
        command=dataclasses.replace(sc.command, altitude_steps=(AltitudeStep(T_STEP, 500.0 + dh),)))
    return run(sc, 0, seconds=seconds)


def _settling_time(tr, target, band):
    err = np.abs(-tr.z[:, 0] - target)
    outside = np.flatnonzero(err > band)
    return tr.t[outside[-1] + 1] - T_STEP if outside.size else 0.0


@pytest.mark.parametrize("model", ["nonlinear", "linear"])
@pytest.mark.parametrize("dh", [50.0, -50.0])
def test_50m_step_settles_without_actuator_saturation(model, dh):
    tr = _step_run(dh, model)
    ts = _settling_time(tr, 500.0 + dh, 1.0)
    assert 2.0 < ts < 20.0, ts
    assert np.all(np.abs(tr.u[:, 0]) < np.radians(30.0))
    assert np.all((tr.u[:, 1] > 0.0) & (tr.u[:, 1] < 1.0))
    # A 50 m step is large enough to reach the +-28 deg flight-path limit (thesis Fig. 3.12) ...
    assert np.max(np.abs(tr.gamma_cmd)) == pytest.approx(GAMMA_LIMIT_RAD)
    assert np.all(np.abs(tr.gamma_cmd) <= GAMMA_LIMIT_RAD + 1e-12)
    # ... and anti-windup keeps the overshoot small; airspeed stays near 40 m/s.
    assert np.max((-tr.z[:, 0] - 500.0) * np.sign(dh)) < abs(dh) + 1.0
    assert np.max(np.abs(np.hypot(tr.z[:, 1], tr.z[:, 2]) - 40.0)) < 2.0


def test_1m_step_does_not_saturate_the_flight_path_command():
    tr = _step_run(1.0)
    assert np.max(np.abs(tr.gamma_cmd)) < np.radians(5.0)
    h = -tr.z[:, 0]
    assert h[tr.t <= T_STEP] == pytest.approx(500.0, abs=1e-6)
    assert _settling_time(tr, 501.0, 0.1) < 15.0
    assert np.max(h) < 501.4                           # overshoot below 40 %
    assert h[-1] == pytest.approx(501.0, abs=0.01)


def test_closed_loops_are_stable_and_well_damped():
    g = design_gains(default_autopilot(load_scenario("ch5a"), load_airframe()).model)
    for key in ("inner_closed", "outer_closed"):
        z = np.linalg.eigvals(g[key])
        assert np.max(np.abs(z)) < 1.0, key
        s = np.log(z.astype(complex)) / 0.05
        zeta = -s.real / np.abs(s)
        assert np.min(zeta) > 0.6, (key, np.round(s, 2))


def test_output_limits_and_reset():
    sc = load_scenario("ch5a")
    ap = default_autopilot(sc, load_airframe())
    z = ap.z_trim.copy()
    assert ap.update(0.0, z) == pytest.approx(ap.u_trim, abs=1e-12)
    assert ap.gamma_command == 0.0
    # A wildly wrong navigation state: outputs stay inside the actuator limits.
    for _ in range(50):
        u = ap.update(0.0, z + np.array([300.0, -15.0, 8.0, 0.6, 1.0]))
        assert abs(u[0]) <= np.radians(30.0) + 1e-15 and 0.0 <= u[1] <= 1.0
        assert abs(ap.gamma_command) <= GAMMA_LIMIT_RAD + 1e-15
    assert abs(ap.gamma_command) == pytest.approx(GAMMA_LIMIT_RAD)
    ap.reset()
    assert ap.update(0.0, z) == pytest.approx(ap.u_trim, abs=1e-12)


def test_altitude_command_schedule_and_printed_model():
    cmd = CommandConfig(500.0, 40.0, (AltitudeStep(20.0, 450.0), AltitudeStep(5.0, 520.0)))
    ap = Autopilot(printed_model(load_airframe()), cmd, 0.05)
    assert [ap.altitude_command(t) for t in (0.0, 4.99, 5.0, 19.0, 20.0, 60.0)] == [
        500.0, 500.0, 520.0, 520.0, 450.0, 450.0]
    with pytest.raises(ValueError):
        Autopilot(printed_model(load_airframe()), cmd, 0.02)


def test_elevator_doublet_adds_plus_then_minus_every_period_within_travel():
    import math

    from sim_bridge.autopilot import ELEVATOR_LIMIT_RAD, ElevatorDoublet

    d = ElevatorDoublet(math.radians(3.0))              # +3 deg 5.0-5.5 s, -3 deg 5.5-6.0 s, every 10 s
    got = [math.degrees(d.offset(t)) for t in (0.0, 4.95, 5.0, 5.45, 5.5, 5.95, 6.0, 15.2, 15.7, 16.1)]
    assert got == pytest.approx([0, 0, 3, 3, -3, -3, 0, 3, -3, 0])
    u = d.add(5.2, np.array([ELEVATOR_LIMIT_RAD - 0.01, 0.5]))
    assert u[0] == ELEVATOR_LIMIT_RAD and u[1] == 0.5     # clipped to the travel, throttle untouched
    assert ElevatorDoublet(0.0).add(5.2, np.array([0.1, 0.5]))[0] == 0.1
    with pytest.raises(ValueError, match="--doublet"):
        ElevatorDoublet(math.radians(45.0))


def test_a_saturated_throttle_holds_only_the_integrator_that_would_deepen_it():
    """Overspeed below the commanded altitude: the throttle sits at 0. The airspeed integrator,
    whose step would push the throttle further below 0, is held; the flight-path integrator, whose
    climb step raises the throttle, still integrates (holding both locked real-jsbsim run 78 in a
    dive to the ground)."""
    sc = load_scenario("real-calm")
    ap = default_autopilot(sc, load_airframe("aerosonde"))
    ap.reset()
    z = ap.model.trim.z.copy()
    z[0] = -450.0                   # 50 m below the 500 m command
    z[1] += 10.0                    # 10 m/s too fast
    u = ap.update(0.0, z)
    assert u[1] == 0.0 and ap.saturated
    assert ap.x_v == 0.0            # held
    assert ap.x_gamma > 0.0         # integrates the climb command
    ap.reset()
    z[1] = ap.model.trim.z[1] + 1.0  # 1 m/s fast on altitude: nothing saturates, both integrate
    z[0] = -500.0
    ap.update(0.0, z)
    assert not ap.saturated and ap.x_v != 0.0
