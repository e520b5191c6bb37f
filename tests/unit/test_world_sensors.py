"""Barometric formula and the simulated sensor suite (SPEC section 3)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fdir_service.atmosphere import altitude_from_pressure, pressure_from_altitude
from sim_bridge.scenario import load_scenario
from sim_bridge.sensors import SensorSuite

Z_TRIM = np.array([-500.0, 39.954, 1.912, 0.0478, 0.0])


def test_barometric_formula_values():
    assert pressure_from_altitude(0.0) == pytest.approx(101325.0)
    # ISA: 500 m -> 95461 Pa, 1000 m -> 89875 Pa, 11000 m -> 22632 Pa (standard tables).
    assert pressure_from_altitude(500.0) == pytest.approx(95461.0, abs=2.0)
    assert pressure_from_altitude(1000.0) == pytest.approx(89875.0, abs=2.0)
    assert pressure_from_altitude(11000.0) == pytest.approx(22632.0, abs=5.0)
    assert isinstance(pressure_from_altitude(500.0), float)


def test_barometric_round_trip_vectorised():
    h = np.linspace(-200.0, 5000.0, 101).reshape(1, 101)
    p = pressure_from_altitude(h)
    assert p.shape == (1, 101) and np.all(np.diff(p[0]) < 0)
    assert np.max(np.abs(altitude_from_pressure(p) - h)) < 1e-8
    # Near 500 m, 1 m of altitude is rho g ~ 1.1673 * 9.80665 ~ 11.45 Pa.
    assert pressure_from_altitude(500.0) - pressure_from_altitude(501.0) == pytest.approx(11.45, abs=0.02)


def _noise(sc, n=4000, seed=1, faults=None):
    s = SensorSuite(sc, np.random.default_rng(seed))
    f = np.zeros(len(sc.faults)) if faults is None else faults
    return np.array([s.measure(Z_TRIM, 0.05 * k, f) for k in range(n)]), s


def test_noise_levels_and_rows():
    sc = load_scenario("ch4")
    y, _ = _noise(sc)
    clean = np.array([500.0, 500.0, 39.954, 1.912, 0.0478, 0.0])
    sigma = np.array([5.0, 1.0, 1.0, 1.0, 0.01, 0.002])
    err = y - clean
    assert np.all(np.abs(err.mean(0)) < 4 * sigma / np.sqrt(len(y)))
    assert err.std(0) / sigma == pytest.approx(np.ones(6), abs=0.05)
    # Rows are independent.
    corr = np.corrcoef(err.T)
    assert np.max(np.abs(corr - np.eye(6))) < 0.06


def test_sensor_faults_land_on_their_rows():
    sc = load_scenario("ch4")
    f = np.array([50.0, 30.0])
    a = SensorSuite(sc, np.random.default_rng(7)).measure(Z_TRIM, 25.0, np.zeros(2))
    b = SensorSuite(sc, np.random.default_rng(7)).measure(Z_TRIM, 25.0, f)
    assert b - a == pytest.approx([50.0, 30.0, 0, 0, 0, 0], abs=1e-8)
    sc5 = load_scenario("ch5c")     # elevator (actuator) fault must not touch any row; q fault on q
    a = SensorSuite(sc5, np.random.default_rng(7)).measure(Z_TRIM, 25.0, np.zeros(2))
    b = SensorSuite(sc5, np.random.default_rng(7)).measure(Z_TRIM, 25.0, np.array([0.17, 0.2]))
    assert b - a == pytest.approx([0, 0, 0, 0, 0.2], abs=1e-12)


def test_barometer_goes_through_static_pressure():
    sc = load_scenario("ch5a")
    s = SensorSuite(sc, np.random.default_rng(3))
    y = s.measure(Z_TRIM, 0.0, np.zeros(1))
    p = s.last_static_pressure_pa
    assert p == pytest.approx(pressure_from_altitude(y[0]), rel=1e-12)
    assert 95461.0 - 60.0 < p < 95461.0 + 60.0          # 500 m +- ~5 sigma of 1 m
    assert altitude_from_pressure(p) == y[0]
    # Without a barometer, the frame still carries the static pressure of the true altitude.
    no_baro = dataclasses.replace(sc, sensors=dataclasses.replace(
        sc.sensors, measurements=("u", "w", "theta", "q"), sigma={k: 1.0 for k in "u w theta q".split()}))
    s2 = SensorSuite(no_baro, np.random.default_rng(3))
    s2.measure(Z_TRIM, 0.0, np.zeros(1))
    assert s2.last_static_pressure_pa == pytest.approx(pressure_from_altitude(500.0))


def test_noise_depends_only_on_the_generator():
    sc = load_scenario("ch5a")
    y1, _ = _noise(sc, n=50, seed=11)
    y2, _ = _noise(sc, n=50, seed=11)
    y3, _ = _noise(sc, n=50, seed=12)
    assert np.array_equal(y1, y2) and not np.array_equal(y1, y3)


def test_gnss_gauss_markov_option():
    sc = load_scenario("ch4")
    gm = dataclasses.replace(sc, sensors=dataclasses.replace(sc.sensors, gnss_gauss_markov=True))
    # Off: the GNSS row is white. On: it carries a slowly varying error updated once per second.
    s = SensorSuite(gm, np.random.default_rng(5))
    errs = []
    for k in range(20 * 600):                      # 10 minutes at 20 Hz
        s.measure(Z_TRIM, 0.05 * k, np.zeros(2))
        errs.append(s.gnss_error_m)
    errs = np.array(errs)
    steps = np.diff(errs)
    jumps = steps[steps != 0.0]
    assert jumps.size == 599                       # one Gauss-Markov sample per second
    # Increments: b_{n+1} - b_n = (e^{-1/1100} - 1) b_n + eta, eta ~ N(0, 0.40^2).
    assert np.std(jumps) == pytest.approx(0.40, rel=0.1)
    # Random-walk-like growth: after 600 s the spread is ~0.4 sqrt(600) ~ 10 m scale (not white 0.4).
    assert np.max(np.abs(errs)) > 2.0
    decay = math.exp(-1.0 / 1100.0)
    assert decay == pytest.approx(0.99909, abs=1e-5)
    off = SensorSuite(sc, np.random.default_rng(5))
    off.measure(Z_TRIM, 100.0, np.zeros(2))
    assert off.gnss_error_m == 0.0
