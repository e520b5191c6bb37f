"""Sentinel weighting, per-mode regularisation and the robust Kalman gain (ch4 P(fault) drift,
ch5c singular matrix)."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.correction import kalman_gain
from fdir_service.estimation.factory import build_particle_filter
from fdir_service.estimation.layout import N_AIRFRAME
from fdir_service.estimation.regularize import regularize_per_mode
from sim_bridge.scenario import load_scenario, parse_scenario, scenario_path
from tests.helpers.experiments import with_parts


def _ch4(weighting: str = "prior", jitter: str = "per_mode"):
    sc = load_scenario("ch4")
    return with_parts(sc, sentinel_weighting=weighting, jitter=jitter)


# ------------------------------------------------------------------ robust Kalman gain
def test_kalman_gain_never_raises_on_a_numerically_singular_S():
    """The ch5c N = 60 case: a diverged cloud (variances 1e25-1e47) made S = H P H^T + R singular
    to round-off and np.linalg.inv raised LinAlgError. Now: finite K and S^-1, no exception."""
    d = np.array([1.24e27, 1.93e25, 0.0, 1.74e26, 0.0, 7.92e28, 3.65e47])
    rng = np.random.default_rng(0)
    C = np.corrcoef(rng.standard_normal((7, 3)))          # rank-3 correlation: singular P
    P = np.sqrt(np.outer(d, d)) * np.nan_to_num(C)
    H = np.zeros((5, 7))
    H[0, 0], H[1, 1], H[2, 2], H[3, 3], H[4, 4], H[4, 6] = -1, 1, 1, 1, 1, 1
    R = np.diag([2.25, 2.25, 2.25, 2.25e-4, 9e-6])
    K, S_inv = kalman_gain(P, H, R)
    assert np.isfinite(K).all() and np.isfinite(S_inv).all()
    assert np.allclose(S_inv, S_inv.T)
    # an exactly singular S (R = 0, rank-deficient P) and a non-finite P do not raise either
    K, S_inv = kalman_gain(np.zeros((7, 7)), H, np.diag([1.0, 1, 1, 1, 0]))
    assert np.isfinite(K).all() and np.isfinite(S_inv).all()
    P_bad = np.full((7, 7), np.nan)
    K, S_inv = kalman_gain(P_bad, H, R)
    assert np.all(K == 0) and np.allclose(S_inv, np.linalg.inv(R))


def test_kalman_gain_equals_the_plain_inverse_when_well_conditioned():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((7, 20))
    P = A @ A.T / 20
    H = rng.standard_normal((5, 7))
    R = np.diag(rng.uniform(0.1, 1.0, 5))
    K, S_inv = kalman_gain(P, H, R)
    S = H @ P @ H.T + R
    assert np.allclose(S_inv, np.linalg.inv(S), rtol=1e-10, atol=1e-12)
    assert np.allclose(K, P @ H.T @ np.linalg.inv(S), rtol=1e-10, atol=1e-12)


def test_ch5c_rjmrpf_60_particles_seed_3_run_1_completes_finite():
    """The campaign case that raised LinAlgError: now it runs to the end with finite outputs
    (the filter loses the aircraft at N = 60, but it never raises and never emits NaN/inf)."""
    from sim_bridge import campaign as C
    res = C.run_job(C.Job(load_scenario("ch5c"), "RJMRPF", 1, 3, 60))
    assert isinstance(res, C.RunResult), getattr(res, "error", "")
    assert np.isfinite(res.z_hat).all() and np.isfinite(res.f_hat).all()
    assert np.isfinite(res.prob).all()


def test_diverged_particles_are_dropped_and_the_cloud_reinitialised():
    sc = load_scenario("ch5a")
    f = build_particle_filter("RJMRPF", sc.estimator, np.random.default_rng(0), particles=200)
    y = (f.meas.H @ f.x_mean)
    mask = np.ones(f.meas.m, dtype=bool)
    u = np.zeros(2)
    f.X[:, :] = 1e30                                 # every particle absurd, still finite
    out = f.step(0.05, y, mask, u)
    assert f.reinitialisations == 1
    assert np.isfinite(out.x_mean).all() and np.abs(out.x_mean).max() < 1e6


# ------------------------------------------------------------------ scenario keys
def _doc(name: str) -> dict:
    with open(scenario_path(name), "rb") as fh:
        return tomllib.load(fh)


@pytest.mark.parametrize("sid, key, bad", [
    ("ch4", "sentinel_weighting", "both"),
    ("ch4", "jitter", "local"),
    ("ch5c", "actuator_sentinel", "yes"),
    ("ch6", "adaptive_transition", "bayes"),
])
def test_estimator_choice_keys_reject_unknown_values(sid, key, bad):
    doc = _doc(sid)
    doc["estimator"]["parts"][key] = bad
    with pytest.raises(ConfigError, match=key):
        parse_scenario(doc)


def test_scenario_keys_validated():
    doc = _doc("ch4")
    del doc["estimator"]["faults"][1]["amplitude_max"]
    with pytest.raises(ConfigError, match="amplitude_max"):
        parse_scenario(doc)
    doc = _doc("ch5a")                                # deg in the file, rad once loaded
    doc["estimator"]["faults"][0]["amplitude_max"] = 90.0
    doc["estimator"]["parts"]["jitter"] = "global"
    sc = parse_scenario(doc)
    assert sc.estimator.faults[0].amplitude_max == pytest.approx(np.pi / 2)
    assert sc.estimator.settings.jitter == "global"


# ------------------------------------------------------------------ "prior" sentinel weighting
def test_prior_weighting_gives_a_glr_threshold():
    """A sentinel is worth sqrt(2 pi) s / L (times exp(eps^2/2) for its draw eps) against a mode-0
    particle's exp(-e^2 / 2 s^2): small innovations lose, large ones win."""
    sc = _ch4()
    f = build_particle_filter("JMRPF", sc.estimator, np.random.default_rng(0), particles=2000)
    s = f.meas.sigma[0]                               # gnss row, filter sigma 7.5 m
    L = 2 * sc.estimator.faults[0].amplitude_max
    thr = s * np.sqrt(2 * np.log(L / (np.sqrt(2 * np.pi) * s)))
    mask = np.ones(f.meas.m, dtype=bool)
    u = np.zeros(2)
    for offset, expect_high in ((0.5 * thr, False), (2.0 * thr, True)):
        f = build_particle_filter("JMRPF", sc.estimator, np.random.default_rng(1), particles=2000)
        f.parts.predict.process.propagate = lambda X, u, modes=None: X    # static cloud: isolate the jump
        f.parts.predict.q_std[:] = 0.0
        y = f.meas.H @ f.x_mean
        y[0] += offset
        out = f.step(0.05, y, mask, u)
        p = out.fault_probability[0]
        assert (p > 0.9) if expect_high else (p < 0.2), (offset / thr, p)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ch4_fault_free_closed_loop_p_fault_stays_low(seed):
    """The product's check: ch4 with no fault at all, flown in closed loop on the JMRPF estimate
    for 50 s: P(fault) stays below 0.5 for both faults (thesis weighting: P(baro) -> 0.9-1.0)."""
    from sim_bridge import campaign as C
    sc = load_scenario("ch4")
    sc = dataclasses.replace(sc, faults=tuple(dataclasses.replace(fc, profile=()) for fc in sc.faults))
    res = C.run_job(C.Job(sc, "JMRPF", seed, 11))
    assert isinstance(res, C.RunResult), getattr(res, "error", "")
    assert res.prob.max() < 0.5, res.prob.max(axis=0)


def test_thesis_weighting_still_selectable_and_drifts():
    """sentinel_weighting = "thesis" is Alg. 4.1 as written: in ch4 fault-free, P(baro) climbs."""
    from sim_bridge import campaign as C
    sc = _ch4("thesis", "global")
    sc = dataclasses.replace(sc, faults=tuple(dataclasses.replace(fc, profile=()) for fc in sc.faults))
    res = C.run_job(C.Job(sc, "JMRPF", 0, 11))
    assert res.prob.mean() > 0.2


# ------------------------------------------------------------------ per-mode regularisation
def test_per_mode_jitter_keeps_mode0_faults_at_zero_and_uses_the_group_covariance():
    rng = np.random.default_rng(3)
    n, nf, N = 7, 2, 40000
    X = np.zeros((n, N))
    modes = np.zeros((nf, N), dtype=bool)
    modes[0, N // 2:] = True                          # half the cloud in mode 1 for fault 0
    # mode-0 half: p_d spread 1; mode-1 half: p_d and f_0 spread 20 m along the same direction
    X[:N_AIRFRAME, :] = rng.standard_normal((N_AIRFRAME, N))
    c = 20.0 * rng.standard_normal(N // 2)
    X[0, N // 2:] += c
    X[N_AIRFRAME, N // 2:] = -c
    w = np.full(N, 1.0 / N)
    idx = np.arange(N)
    Xr = X.copy()
    h = 0.5
    regularize_per_mode(Xr, X, w, idx, modes, h, rng)
    d = Xr - X
    assert np.all(d[N_AIRFRAME:, : N // 2] == 0.0)    # mode-0 fault entries untouched
    assert np.all(d[N_AIRFRAME + 1] == 0.0)
    # mode-0 particles: jitter variance h^2 var_group / (n + 4), var_group = 1 (not 1 + 20^2/2)
    v0 = d[0, : N // 2].var()
    assert v0 == pytest.approx(h * h / (n + 4), rel=0.05)
    # mode-1 particles move along their own correlation: p_d + f_0 barely changes
    s = d[0, N // 2:] + d[N_AIRFRAME, N // 2:]
    assert s.var() < 0.05 * d[0, N // 2:].var()


def test_per_mode_jitter_floor_restores_the_spread_of_a_just_detected_fault():
    """Right after a detection the weight sits on one sentinel: its group's weighted covariance is
    0 and the kernel would leave every copy at the onset frame's amplitude. With the floor, the
    fault entry's kernel variance is at least the one-frame amplitude variance."""
    rng = np.random.default_rng(4)
    n, nf, N = 7, 2, 20000
    X = np.zeros((n, N))
    modes = np.zeros((nf, N), dtype=bool)
    modes[0, :10] = True                              # ten sentinels, one holds all the weight
    X[N_AIRFRAME, :10] = 57.0
    w = np.zeros(N)
    w[0] = 1.0
    idx = np.zeros(N, dtype=int)                      # resampled: every particle a copy of it
    Xr = X[:, idx].copy()
    h, floor = 0.3, np.array([7.5**2, 1.5**2])
    regularize_per_mode(Xr, X, w, idx, modes, h, rng, fault_var_floor=floor)
    assert Xr[N_AIRFRAME].std() == pytest.approx(h * 7.5 / np.sqrt(n + 4), rel=0.05)
    assert np.all(Xr[N_AIRFRAME + 1] == 0.0)          # fault 1 stays in mode 0, at 0
    Xr = X[:, idx].copy()
    regularize_per_mode(Xr, X, w, idx, modes, h, rng)  # without the floor: nothing moves
    assert np.allclose(Xr[N_AIRFRAME], 57.0)
