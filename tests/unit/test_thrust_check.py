"""The thrust check (fdir_service/estimation/thrust.py): the throttle the accelerometer implies,
checked against the airframe's own force balance, and the derived row it gives the filters."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.airframe.dynamics import derivatives_scalar
from fdir_service.estimation.factory import build_filter, trim_input, trim_state
from fdir_service.estimation.inputs import EngineLag, G, RowSplit
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.thrust import ThrustCheck
from fdir_service.estimator_config import load_estimator
from fdir_service.propulsion_identification import lagged


@pytest.fixture(scope="module")
def catalogue():
    return load_estimator("aerosonde-catalogue")


def specific_force(z: np.ndarray, de: float, dt: float, params) -> tuple[float, float]:
    """[a_x, a_z] (m/s^2) the accelerometer reads in the airframe's own equations at state z (5,)."""
    _, u, w, th, q = z
    _, du, dw, _, _ = derivatives_scalar(u, w, th, q, de, dt, params)
    return du + q * w + G * np.sin(th), dw - q * u - G * np.cos(th)


@pytest.mark.parametrize("throttle", [0.3, 0.532, 0.8])
def test_the_implied_throttle_is_the_one_flown_in_still_air(catalogue, params, throttle):
    z, (de, _) = trim_state(catalogue), trim_input(catalogue)
    ax, az = specific_force(z, de, throttle, params)
    V = float(np.hypot(z[1], z[2]))
    assert ThrustCheck(params).implied_throttle(ax, az, V, de) == pytest.approx(throttle, abs=0.01)


def test_an_engine_that_quits_implies_no_throttle(catalogue, params):
    z, (de, _) = trim_state(catalogue), trim_input(catalogue)
    ax, az = specific_force(z, de, 0.0, params)
    check = ThrustCheck(params)
    assert check.implied_throttle(ax, az, float(np.hypot(z[1], z[2])), de) < 0.05
    assert check.implied_throttle(ax - 100.0, az, 40.0, de) == 0.0            # never negative


def test_the_derived_row_follows_the_observed_rows_and_a_throttle_fault_adds_to_it(catalogue):
    assert catalogue.derived_rows == ("throttle", "airspeed") and catalogue.observed[-2] == "throttle"
    T = catalogue.observed.index("throttle")
    split = RowSplit.of(catalogue, True, trim_state(catalogue))
    rows = catalogue.measurements
    y = np.zeros(len(rows))
    y[[rows.index(r) for r in ("ax", "az", "airspeed")]] = [0.5, -9.7, 40.0]
    mask = np.ones(len(rows), bool)
    y_obs, mask_obs, u = split.split(y, mask, np.array([-0.08, 0.5]))
    assert y_obs.size == len(catalogue.observed) and mask_obs[T]
    assert y_obs[T] == pytest.approx(split.thrust.implied_throttle(0.5, -9.7, 40.0, -0.08) - 0.5)
    assert y_obs[-1] == 40.0                                                    # the pitot's own row
    mask[rows.index("ax")] = False                                              # no fresh IMU: no row
    assert not split.split(y, mask, np.array([-0.08, 0.5]))[1][T]
    layout = FaultLayout.from_estimator(catalogue)
    meas = MeasurementModel.build(layout, catalogue.observed_sigma())
    dt = [f.id for f in catalogue.faults].index("dt_eff")
    assert meas.H[T, N_AIRFRAME + dt] == 1.0 and not meas.H[T, :N_AIRFRAME].any()


def test_the_throttle_delivered_follows_the_command_through_the_engines_lag():
    lag = EngineLag(0.25, 0.05)
    assert lag.step(0.5) == 0.5                                   # starts where the command is
    out = [lag.step(0.8) for _ in range(5)]                       # a step of 0.3: 1 - 1/e in 0.25 s
    assert out[-1] == pytest.approx(0.8 - 0.3 * np.exp(-1.0))
    assert np.all(np.diff(out) > 0) and lag.step(float("nan")) == out[-1]
    command = 0.5 + 0.2 * np.sin(np.arange(200) * 0.3)    # `fdir identify`'s offline lag is the same
    stream = EngineLag(0.25, 0.05)
    np.testing.assert_allclose(lagged(command, 0.25, 0.05), [stream.step(c) for c in command], rtol=1e-12)


def test_with_an_engine_lag_the_row_and_the_throttle_faults_take_the_delivered_throttle(catalogue):
    settings = dataclasses.replace(catalogue.settings, engine_tau_s=0.25)
    lagged = dataclasses.replace(catalogue, settings=settings)
    T = catalogue.observed.index("throttle")
    rows = catalogue.measurements
    y = np.zeros(len(rows))
    y[[rows.index(r) for r in ("ax", "az", "airspeed")]] = [0.5, -9.7, 40.0]
    mask = np.ones(len(rows), bool)
    for est, delivered in ((catalogue, 0.8), (lagged, 0.8 - 0.3 * np.exp(-0.05 / 0.25))):
        split = RowSplit.of(est, True, trim_state(est))
        split.split(y, mask, np.array([-0.08, 0.5]))
        y_obs, _, u = split.split(y, mask, np.array([-0.08, 0.8]))          # the autopilot opens up
        assert u[1] == pytest.approx(delivered)
        assert y_obs[T] == pytest.approx(split.thrust.implied_throttle(0.5, -9.7, 40.0, -0.08) - delivered)
    assert catalogue.settings.engine_tau_s == 0.0


def test_a_throttle_entry_jumps_to_the_throttle_the_row_shows(catalogue):
    filt = build_filter("RJMRPF", catalogue, np.random.default_rng(0), particles=300)
    amp = filt.parts.jump.amplitude
    G_, avail, sigma = amp.gain(np.ones(len(catalogue.observed), bool))
    T = catalogue.observed.index("throttle")
    for name in ("dt", "dt_eff"):
        j = [f.id for f in catalogue.faults].index(name)
        assert avail[j] and G_[j, T] == 1.0 and sigma[j] == catalogue.settings.thrust_sigma
    de = [f.id for f in catalogue.faults].index("de")
    assert avail[de] and np.isfinite(sigma[de])                 # the elevator keeps its own fit


@pytest.mark.parametrize("theta_deg,q_deg", [(30.0, 0.0), (5.0, -40.0), (5.0, 20.0)])
def test_the_derived_rows_are_read_near_level_flight_only(catalogue, theta_deg, q_deg):
    """A jammed elevator that frees tumbles the aircraft: beyond 25 deg of pitch or 15 deg/s of pitch
    rate (as read) neither the throttle row (a polar below the stall) nor the pitot's row is read."""
    T, A = catalogue.observed.index("throttle"), catalogue.observed.index("airspeed")
    split = RowSplit.of(catalogue, True, trim_state(catalogue))
    rows = catalogue.measurements
    y = np.zeros(len(rows))
    y[[rows.index(r) for r in ("ax", "az", "airspeed", "theta", "q")]] = [0.5, -9.7, 40.0, 0.05, 0.02]
    mask = np.ones(len(rows), bool)
    level = split.split(y, mask, np.array([-0.08, 0.5]))[1]
    y[[rows.index("theta"), rows.index("q")]] = np.radians([theta_deg, q_deg])
    upset = split.split(y, mask, np.array([-0.08, 0.5]))[1]
    assert level[T] and level[A] and not upset[T] and not upset[A]
    assert np.array_equal(np.delete(level, [T, A]), np.delete(upset, [T, A]))   # the sensors still are
