"""`fdir identify`'s fits on frames with known answers: the pitch balance the monitor uses, the lift
curve when the flight tells it, the file's values where it does not, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.airframe.params import AirframeParams, load_airframe
from fdir_service.cli import main
from fdir_service.identification import (
    FlightFrames,
    _combined,
    _fit_moment,
    _moment_rows,
    _usable,
    airspeed_spread,
    held_airspeed_tau,
    identify,
)

ROWS = ("gnss_alt", "baro_alt", "u", "w", "theta", "q", "ax", "az", "airspeed")


def _frames(truth: AirframeParams, K: int = 4000, excite: float = 1.0, seed: int = 0,
            az_noise: float = 0.0) -> FlightFrames:
    """Frames of a flight that obeys `truth`'s pitch balance exactly: angle of attack, pitch rate and
    airspeed vary (by `excite`), the elevator is what balances them, the accelerometer reads the
    lift (plus white noise of std az_noise, m/s^2), w = V sin(alpha)."""
    rng = np.random.default_rng(seed)
    dt, p = 0.05, truth
    t = dt * np.arange(K)
    V = 40.0 + excite * 2.0 * np.sin(0.05 * t)
    alpha = 0.05 + excite * (0.02 * np.sin(0.7 * t + 1.0) + 0.003 * np.sin(2.3 * t))
    q = excite * 0.05 * np.sin(0.9 * t + 0.3)
    qdot = excite * 0.05 * 0.9 * np.cos(0.9 * t + 0.3)
    qbar_S = 0.5 * p.rho * V**2 * p.S
    K_q = qbar_S * p.c / p.Jy
    qc = q * p.c / (2.0 * V)
    de = (qdot / K_q - p.C_m0 - p.C_ma * alpha - p.C_mq * qc) / p.C_mde
    CL = p.C_L0 + p.C_La * alpha + p.C_Lq * qc + p.C_Lde * de
    y = np.zeros((K, len(ROWS)))
    y[:, ROWS.index("w")] = V * np.sin(alpha)
    y[:, ROWS.index("q")] = q + 1e-5 * rng.standard_normal(K)
    y[:, ROWS.index("az")] = -CL * qbar_S / p.m + az_noise * rng.standard_normal(K)
    y[:, ROWS.index("airspeed")] = V
    u = np.column_stack([de, np.full(K, 0.5)])
    return FlightFrames(ROWS, t, y, np.ones_like(y, dtype=bool), u)


def test_an_excited_flight_gives_back_the_pitch_balance_and_the_lift_curve():
    base = load_airframe("aerosonde")
    truth = AirframeParams(C_m0=-0.035, C_ma=-0.45, C_mde=-0.42, C_La=3.9, C_L0=0.25)
    ident = identify(_frames(truth), base)
    assert ident.lift_r2 > 0.99
    assert ident.params.C_La == pytest.approx(3.9, rel=0.02)
    assert ident.params.C_L0 == pytest.approx(0.25, abs=0.005)
    np.testing.assert_allclose(_combined(ident.params)[[0, 1, 3]], _combined(truth)[[0, 1, 3]],
                               rtol=0.05, atol=2e-3)
    assert ident.moment_residual_std < 0.2 * ident.moment_residual_std_before


def test_a_steady_flight_moves_the_trim_and_keeps_the_files_slopes():
    base = load_airframe("aerosonde")
    truth = AirframeParams(C_m0=-0.035)                 # the pitch balance off by 0.012 in C_m
    ident = identify(_frames(truth, excite=0.0), base)
    assert "kept" in ident.report()                     # no angle-of-attack variation: no lift curve
    assert ident.params.C_La == base.C_La and ident.params.C_mq == pytest.approx(base.C_mq, rel=0.05)
    assert ident.params.C_ma == pytest.approx(base.C_ma, rel=0.05)
    frames = _frames(truth, excite=0.0)
    CL, de = float(-frames.column("az")[0] * 25.0 / (0.5 * 1.168 * 1600 * 0.55)), float(frames.u[0, 0])
    c_fit, c_true = _combined(ident.params), _combined(truth)
    # the balance at the trim it flew is the truth's: zero pitch acceleration there
    assert c_fit[0] + c_fit[1] * CL + c_fit[3] * de == pytest.approx(0.0, abs=2e-4)
    assert c_true[0] + c_true[1] * CL + c_true[3] * de == pytest.approx(0.0, abs=1e-9)


def test_too_few_frames_or_missing_rows_are_refused():
    frames = _frames(AirframeParams(), K=100)
    with pytest.raises(ValueError, match="usable frames"):
        identify(frames, AirframeParams())
    short = FlightFrames(ROWS[:6], frames.t, frames.y[:, :6], frames.mask[:, :6], frames.u)
    with pytest.raises(ValueError, match="lack rows"):
        identify(short, AirframeParams())


def test_identify_names_the_missing_rows_of_a_log_without_them(tmp_path, capsys):
    from pathlib import Path

    legacy = Path(__file__).resolve().parents[1] / "data" / "legacy-scenario-ch4.mcap"
    assert main(["identify", str(legacy), "--out", str(tmp_path / "a.toml")]) == 1
    err = capsys.readouterr().err
    assert "fdir identify:" in err and not (tmp_path / "a.toml").exists()


def test_the_accelerometers_noise_does_not_shrink_the_slopes():
    """Noise in C_L (0.5 m/s^2 on a_z: ~0.02 in C_L) shrinks least-squares slopes towards zero; the
    instruments (the intervals two and three frames back) do not share it."""
    base = load_airframe("aerosonde")
    truth = AirframeParams(C_m0=-0.035, C_ma=-0.45, C_mde=-0.42)
    ident = identify(_frames(truth, K=6000, az_noise=0.5), base)
    fit, want = _combined(ident.params), _combined(truth)
    assert fit[1] == pytest.approx(want[1], rel=0.1)          # C_ma / C_La
    assert fit[3] == pytest.approx(want[3], rel=0.1)          # the elevator's C_mde'
    A, b, _ = _moment_rows(_usable(_frames(truth, K=6000, az_noise=0.5)), np.arange(2, 6000), base)
    plain = np.linalg.lstsq(A, b, rcond=None)[0]               # what plain least squares gives
    assert abs(plain[1]) < 0.8 * abs(want[1])


def test_a_slope_fitted_with_the_wrong_sign_is_kept_at_the_files():
    """A positive pitch damping is no physics the monitor can use (JSBSim's rotational gusts fitted
    C_mq = +12): the file's C_mq is kept and the other slopes refitted without it."""
    rng = np.random.default_rng(1)
    A = np.column_stack([np.ones(3000), rng.normal(0.4, 0.05, 3000), rng.normal(0, 0.01, 3000),
                         rng.normal(0, 0.02, 3000)])
    prior = np.array([0.0, -0.1, -3.6, -0.5])
    b = A @ np.array([0.01, -0.12, 8.0, -0.45]) + 1e-4 * rng.standard_normal(3000)
    a, std, kept = _fit_moment(A, A, b, prior, noise_std=1e-4)
    assert kept == [2] and a[2] == pytest.approx(-3.6) and std[2] < 1e-6
    assert a[1] == pytest.approx(-0.12, rel=0.25) and a[3] == pytest.approx(-0.45, rel=0.25)
    free, _, none = _fit_moment(A, A, b - A[:, 2] * 11.6, prior, noise_std=1e-4)   # C_mq = -3.6: fitted
    assert none == [] and free[2] == pytest.approx(-3.6, rel=0.02)


def test_moment_rows_are_frame_intervals_with_the_held_elevator():
    """Row k: q' over (k-1, k], C_L, q, V at the midpoint, the elevator of frame k's input."""
    p = load_airframe("aerosonde")
    f = _frames(AirframeParams(), K=300)
    s = _usable(f)
    A, b, K = _moment_rows(s, np.array([10]), p)
    q = f.column("q")
    assert b[0] * K[0] == pytest.approx((q[10] - q[9]) / 0.05)
    assert A[0, 3] == f.u[10, 0]
    assert A[0, 2] == pytest.approx(0.5 * (q[9] + q[10]) * p.c / (2 * 40.0), rel=0.06)


def test_the_airspeed_holds_spread_is_told_from_the_pitots_noise():
    t = np.arange(0.0, 600.0, 0.05)                  # 10 min at 20 Hz
    rng = np.random.default_rng(7)
    held = 40.0 + 0.6 * np.sin(2 * np.pi * t / 20.0)  # what the hold lets through: 0.42 m/s RMS
    V = held + 0.5 * rng.standard_normal(t.size)     # the pitot's noise
    V[::50] = np.nan                                 # readings that did not arrive
    spread, noise = airspeed_spread(t, V)
    assert noise == pytest.approx(0.5, abs=0.02)
    assert spread == pytest.approx(0.6 / np.sqrt(2), abs=0.03)
    spread, noise = airspeed_spread(t, 40.0 + 0.5 * rng.standard_normal(t.size))
    assert spread < 0.05 and noise == pytest.approx(0.5, abs=0.02)   # a perfect hold: noise only
    assert np.isnan(airspeed_spread(t[:1000], V[:1000])[0])         # 50 s: too short to tell


def test_the_held_airspeeds_time_constant_is_told_from_the_pitots_noise():
    dt, tau = 0.05, 0.8
    t = np.arange(0.0, 600.0, dt)
    rng = np.random.default_rng(3)
    a = np.exp(-dt / tau)
    e = 0.7 * np.sqrt(1.0 - a * a) * rng.standard_normal(t.size)
    held = np.zeros(t.size)
    for k in range(1, t.size):                       # what a hold lets through: a 0.8 s Gauss-Markov
        held[k] = a * held[k - 1] + e[k]
    V = 40.0 + held + 0.5 * rng.standard_normal(t.size)
    assert held_airspeed_tau(t, V) == pytest.approx(tau, rel=0.15)
    assert np.isnan(held_airspeed_tau(t, 40.0 + 0.5 * rng.standard_normal(t.size)))  # noise only
    assert np.isnan(held_airspeed_tau(t[:1000], V[:1000]))                           # too short
