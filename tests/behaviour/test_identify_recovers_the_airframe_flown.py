"""`fdir identify` on a simulated flight in moderate turbulence gives back the airframe that flew:
the frames as the service assembles them (the input of frame k is u_{k-1}), an elevator doublet
on top of the autopilot (`sim-bridge fly --doublet`), the pitch balance within 10 %."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fdir_service.airframe.params import load_airframe
from fdir_service.identification import FlightFrames, _combined, _intervals, _moment_rows, _usable, identify
from sim_bridge.autopilot import ElevatorDoublet, ExcitedAutopilot
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import default_autopilot, run


@pytest.fixture(scope="module")
def flight() -> FlightFrames:
    sc = load_scenario("real-turbulence-faultfree")
    sc = dataclasses.replace(sc, duration_s=150.0)
    ap = ExcitedAutopilot(default_autopilot(sc, load_airframe(sc.truth.airframe)),
                          ElevatorDoublet(math.radians(3.0)))
    tr = run(sc, seed=3, autopilot=ap)
    u = np.vstack([tr.u[:1], tr.u[:-1]])             # frame k's input: u_{k-1}, as the service's
    return FlightFrames(tuple(sc.sensors.measurements), tr.t, tr.y, tr.mask, u)


def test_the_pitch_balance_of_the_aircraft_flown_comes_back(flight):
    base = load_airframe("aerosonde")                   # real-turbulence flies the file's airframe
    ident = identify(flight, base)
    fit, truth = _combined(ident.params), _combined(base)
    assert fit[1] == pytest.approx(truth[1], rel=0.1)    # C_ma / C_La
    assert fit[3] == pytest.approx(truth[3], rel=0.1)    # the elevator's C_mde'
    assert -7.2 < ident.params.C_mq < -1.8               # pitch damping, within a factor 2
    assert not any(c.kept for c in ident.coefficients)


def test_plain_least_squares_on_the_same_rows_shrinks_the_elevator(flight):
    """What the instruments buy: the accelerometer's noise and the gusts make least squares
    underestimate the elevator's effectiveness."""
    base = load_airframe("aerosonde")
    s = _usable(flight)
    A, b, _ = _moment_rows(s, _intervals(s), base)
    plain = np.linalg.lstsq(A, b, rcond=None)[0]
    assert plain[3] > 0.92 * _combined(base)[3]          # |C_mde'| more than 8 % short
