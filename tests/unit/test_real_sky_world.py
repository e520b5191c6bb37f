"""The real-sky world models: Dryden turbulence against its analytic autocorrelation, shear and
1-cosine gusts, aerodynamics on the air-relative velocity, airframe dispersion statistics, GNSS
rate and latency, accelerometer, per-run fault draws; the thesis experiments keep still air."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fdir_service.airframe import load_airframe, trim
from fdir_service.airframe.dynamics import derivatives
from sim_bridge.faults import vary_profiles
from sim_bridge.scenario import FAMILIES, SCENARIO_IDS, load_scenario
from sim_bridge.sensors import SensorSuite
from sim_bridge.turbulence import Dryden, autocorrelation_u, autocorrelation_w, low_altitude
from sim_bridge.wind import gust_ned, wind_ned
from sim_bridge.world import derivatives_in_wind, dispersed_airframe
from sim_bridge.world_config import DispersionConfig, Gust, WindConfig

V, DT = 40.0, 0.05


def _lagged_cov(d: Dryden, row: int, lags: np.ndarray) -> np.ndarray:
    """Covariance of the samples of output `row` at the given lags (steps): C Phi^k P C^T from the
    exact discretisation (P its stationary covariance)."""
    from scipy.linalg import solve_discrete_lyapunov

    from sim_bridge.turbulence import NOISE_INTENSITY, discretise, shaping_filters

    A, B, C = shaping_filters(d.sigma_u, d.sigma_w, d.L_u, d.L_w, V, 2.9)
    Phi, Qd = discretise(A, B, DT, NOISE_INTENSITY)
    P = solve_discrete_lyapunov(Phi, Qd)
    return np.array([C[row] @ np.linalg.matrix_power(Phi, int(k)) @ P @ C[row] for k in lags])


def test_dryden_intensity_and_scale_lengths_follow_mil_f_8785c():
    su, sw, Lu, Lw = low_altitude(30 * 0.514444, 100.0)        # moderate, 328 ft
    h = 100.0 / 0.3048
    assert sw == pytest.approx(0.1 * 30 * 0.514444)
    assert su == pytest.approx(sw / (0.177 + 0.000823 * h) ** 0.4)
    assert Lw == pytest.approx(100.0) and Lu == pytest.approx(h / (0.177 + 0.000823 * h) ** 1.2 * 0.3048)
    assert low_altitude(15.4, 500.0) == low_altitude(15.4, 304.8)   # above 1000 ft: the 1000-ft values


def test_dryden_samples_have_the_analytic_autocorrelation_exactly():
    d = Dryden(15.4, 100.0, V, 2.9, DT, np.random.default_rng(0))
    lags = np.array([0, 1, 10, 40, 100, 200])
    tau = lags * DT
    np.testing.assert_allclose(_lagged_cov(d, 0, lags), autocorrelation_u(tau, d.sigma_u, d.L_u, V),
                               rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(_lagged_cov(d, 1, lags), autocorrelation_w(tau, d.sigma_w, d.L_w, V),
                               rtol=1e-6, atol=1e-9)


def test_dryden_series_matches_its_spectrum_statistically():
    """200 000 samples (10 000 correlation times of w at 100 m): variances within 5 %, the w
    autocorrelation at L / V within 0.1 sigma^2; the pitch gust is small and zero-mean."""
    d = Dryden(15.4, 100.0, V, 2.9, DT, np.random.default_rng(1))
    X = np.array([d.step() for _ in range(200_000)])
    assert X[:, 0].std() == pytest.approx(d.sigma_u, rel=0.05)
    assert X[:, 1].std() == pytest.approx(d.sigma_w, rel=0.05)
    k = int(round(d.L_w / V / DT))
    r = np.mean(X[:-k, 1] * X[k:, 1])
    assert r == pytest.approx(autocorrelation_w(k * DT, d.sigma_w, d.L_w, V), abs=0.1 * d.sigma_w**2)
    assert abs(X[:, 2].mean()) < 0.01 and 0.0 < X[:, 2].std() < d.sigma_w / 2.9


def test_same_stream_same_gusts():
    a = Dryden(15.4, 500.0, V, 2.9, DT, np.random.default_rng(7))
    b = Dryden(15.4, 500.0, V, 2.9, DT, np.random.default_rng(7))
    assert np.array_equal([a.step() for _ in range(50)], [b.step() for _ in range(50)])


def test_power_law_shear_and_one_minus_cosine_gust():
    cfg = WindConfig(north_mps=-10.0, shear_exponent=1 / 7, reference_altitude_m=500.0)
    assert wind_ned(cfg, 0.0, 500.0, V) == pytest.approx((-10.0, 0.0))
    assert wind_ned(cfg, 0.0, 1000.0, V)[0] == pytest.approx(-10.0 * 2 ** (1 / 7))
    g = Gust(start_s=10.0, length_m=80.0, down_mps=3.0)      # 2 s up, 2 s down at 40 m/s
    assert gust_ned(g, 9.99, V) == (0.0, 0.0) and gust_ned(g, 14.01, V) == (0.0, 0.0)
    assert gust_ned(g, 12.0, V)[1] == pytest.approx(3.0)
    assert gust_ned(g, 11.0, V)[1] == pytest.approx(1.5) == pytest.approx(gust_ned(g, 13.0, V)[1])


def test_aerodynamics_see_the_air_kinematics_the_ground():
    """In steady air the aircraft trimmed relative to the air is in equilibrium and drifts with it:
    with (north, down) = (-10, +1) m/s its ground velocity is trim + wind, its accelerations zero
    and it sinks at 1 m/s."""
    p = load_airframe()
    tr = trim(p, 40.0, 500.0)
    z = tr.z.copy()
    th = z[3]
    wb = np.array([-10.0 * math.cos(th) - math.sin(th), -10.0 * math.sin(th) + math.cos(th)])
    z[1:3] += wb                                     # ground velocity = air-relative + wind
    d = derivatives_in_wind(z.tolist(), tr.u.tolist(), p, wb, 0.0)
    assert d[1:] == pytest.approx((0.0, 0.0, 0.0, 0.0), abs=1e-9)
    still = derivatives(tr.z, tr.u, p)
    assert d[0] == pytest.approx(still[0] + 1.0, abs=1e-9)          # p_d' = trim's + the down wind


def test_dispersion_draws_each_field_uniformly_within_its_fraction():
    p = load_airframe()
    cfg = DispersionConfig({"m": 0.1, "C_ma": 0.2})
    rng = np.random.default_rng(3)
    draws = [dispersed_airframe(p, cfg, rng) for _ in range(4000)]
    m = np.array([d.m for d in draws]) / p.m - 1.0
    cma = np.array([d.C_ma for d in draws]) / p.C_ma - 1.0
    for x, f in ((m, 0.1), (cma, 0.2)):
        assert -f <= x.min() < -0.97 * f and 0.97 * f < x.max() <= f
        assert x.mean() == pytest.approx(0.0, abs=0.01)
        assert x.std() == pytest.approx(f / math.sqrt(3), rel=0.05)
    assert all(d.C_La == p.C_La for d in draws[:10])
    same = [dispersed_airframe(p, cfg, np.random.default_rng(5)) for _ in range(2)]
    assert same[0] == same[1]


def _sensors(**realism):
    sc = load_scenario("real-calm")
    sigma = {**sc.sensors.sigma, "gnss_alt": 1e-3}
    sensors = dataclasses.replace(sc.sensors, sigma=sigma, gnss_gauss_markov=False, baro_bias_walk=0.0,
                                  gyro_bias_sigma=0.0, gyro_bias_walk=0.0, **realism)
    return SensorSuite(dataclasses.replace(sc, sensors=sensors), np.random.default_rng(0))


def test_gnss_fixes_arrive_at_their_rate_with_their_latency():
    s = _sensors(gnss_rate_hz=5.0, gnss_latency_s=0.2)
    air = type("Air", (), {"airspeed_mps": 40.0, "specific_force": np.array([0.0, -9.81])})()
    alt, got, mask = [], [], []
    for k in range(40):
        h = 500.0 + 2.0 * k                           # climbing at 40 m/s: 2 m per frame
        z = np.array([-h, 40.0, 0.0, 0.0, 0.0])
        y = s.measure(z, k * DT, np.zeros(3), air)
        alt.append(h), got.append(y[0]), mask.append(s.last_mask[0])
    got, alt = np.array(got), np.array(alt)
    assert np.flatnonzero(mask).tolist() == list(range(0, 40, 4))          # a fix every 0.2 s
    np.testing.assert_allclose(got[8:] - alt[4:-4], 0.0, atol=0.01)         # 4 frames (0.2 s) old


def test_accelerometer_reads_the_specific_force_at_trim():
    p = load_airframe()
    tr = trim(p, 40.0, 500.0)
    sc = load_scenario("real-calm")
    from sim_bridge.world import Truth

    air = Truth(sc, p, np.random.default_rng(0)).air_data()
    expected = [p.g * math.sin(tr.z[3]), -p.g * math.cos(tr.z[3])]
    assert air.specific_force == pytest.approx(expected, abs=1e-6)
    assert air.airspeed_mps == pytest.approx(40.0, abs=1e-6)


def test_fault_profiles_are_drawn_per_run_within_their_ranges():
    sc = load_scenario("real-calm")
    runs = [vary_profiles(sc, np.random.default_rng(s)) for s in range(200)]
    comps = [r.faults[0].profile[0] for r in runs]
    theta = np.array([[c.start_s, c.end_s - c.start_s, c.amplitude] for c in comps])
    assert theta[:, 0].min() >= 15.0 and theta[:, 0].max() <= 30.0 and np.ptp(theta[:, 0]) > 10.0
    assert theta[:, 1].min() >= 8.0 and theta[:, 1].max() <= 15.0
    amp = np.abs(theta[:, 2])
    assert amp.min() >= math.radians(2.0) - 1e-12 and amp.max() <= math.radians(8.0) + 1e-12
    assert 0.35 < np.mean(theta[:, 2] > 0) < 0.65                           # random sign
    assert vary_profiles(sc, np.random.default_rng(3)) == vary_profiles(sc, np.random.default_rng(3))


@pytest.mark.parametrize("sid", SCENARIO_IDS)
def test_thesis_experiments_keep_still_air_and_the_exact_airframe(sid):
    sc = load_scenario(sid)
    assert not sc.sky.moving_air and not sc.sky.dispersion.active and sc.sky.engine == "internal"
    assert vary_profiles(sc, np.random.default_rng(0)) is sc


def test_the_real_family_loads_with_the_default_estimator():
    for sid in FAMILIES["real"]:
        sc = load_scenario(sid)
        assert sc.estimator.doc.get("id") == sid and sc.estimator.faults[0].id == "gnss"
        assert ("faultfree" in sid) == (len(sc.faults) == 0)


def test_an_aircraft_seed_flies_the_same_dispersed_aircraft_in_every_run():
    from sim_bridge.simulate import SimStepper

    one = load_scenario("real-one-aircraft")
    many = load_scenario("real-dispersed")
    a, b = (SimStepper(one, s).truth.params for s in (1, 2))
    c, d = (SimStepper(many, s).truth.params for s in (1, 2))
    assert a == b and c != d
    assert a != SimStepper(one, 1).truth.nominal          # still dispersed from the file's airframe
