"""`fdir identify`'s propulsion (fdir_service/propulsion_identification.py): the throttle's thrust
and the engine's lag recovered from a flight whose propeller is not the file's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.airframe.params import load_airframe
from fdir_service.estimation.thrust import ThrustCheck
from fdir_service.propulsion_identification import fit_propulsion, lagged

DT = 0.05


def flight(params, truth, tau_s: float, seconds: float = 300.0, noise: float = 0.2, seed: int = 5):
    """Level frames of an aircraft whose propeller is `truth`'s and lags the command by tau_s: the
    throttle command wanders as an autopilot's in turbulence, a_x is what that thrust gives against
    the file's polar (plus the accelerometer's noise, m/s^2)."""
    rng = np.random.default_rng(seed)
    K = int(seconds / DT)
    command = np.clip(0.55 + 0.15 * np.sin(np.arange(K) * DT * 1.3) + 0.05 * rng.standard_normal(K), 0, 1)
    V = 40.0 + 1.5 * np.sin(np.arange(K) * DT * 0.2)
    az, de = np.full(K, -9.75), np.full(K, -0.02)
    check, true = ThrustCheck(params), ThrustCheck(truth)
    d = lagged(command, tau_s, DT)
    fx = np.array([check.aero_axial(a, v, e) for a, v, e in zip(az, V, de, strict=True)])
    ax = fx + true.k_thrust * (true.k_motor2 * d * d - V * V) + noise * rng.standard_normal(K)
    zeros = np.zeros(K)
    return {"ax": ax, "az": az, "airspeed": V, "de": de, "dt": command, "theta": zeros + 0.02,
            "q": zeros, "u": V, "w": zeros + 0.8}


def test_a_propeller_that_is_not_the_files_and_lags_is_fitted():
    params = load_airframe("aerosonde")
    truth = dataclasses.replace(params, k_motor=95.0, C_prop=0.25)
    fit = fit_propulsion(flight(params, truth, 0.25), params, DT)
    assert fit.k_motor == pytest.approx(95.0, rel=0.03)
    assert fit.C_prop == pytest.approx(0.25, rel=0.05)
    assert fit.engine_tau_s == pytest.approx(0.25, abs=0.05)
    assert fit.residual < 0.5 * fit.residual_before            # the fit explains what the file did not
    again = fit.apply(params)
    assert (again.k_motor, again.C_prop, again.C_Dp) == (fit.k_motor, fit.C_prop, params.C_Dp)


def test_the_files_own_propeller_flown_at_once_is_the_file():
    params = load_airframe("aerosonde")
    fit = fit_propulsion(flight(params, params, 0.0), params, DT)
    assert fit.k_motor == pytest.approx(params.k_motor, rel=0.02)
    assert fit.C_prop == pytest.approx(params.C_prop, rel=0.05)
    assert fit.engine_tau_s == 0.0 and fit.residual == pytest.approx(fit.residual_before, rel=0.05)


def test_too_few_level_frames_fit_nothing():
    params = load_airframe("aerosonde")
    s = flight(params, params, 0.0, seconds=20.0)
    s["theta"] = np.full(s["ax"].size, 0.6)                    # 34 deg: no frame near level flight
    assert fit_propulsion(s, params, DT) is None
