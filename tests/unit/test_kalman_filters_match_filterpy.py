"""KF and IMM-KF against filterpy's KalmanFilter and IMMEstimator (issue 3 acceptance)."""

from __future__ import annotations

import numpy as np
from filterpy.kalman import IMMEstimator
from filterpy.kalman import KalmanFilter as FpKalman

from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.layout import N_AIRFRAME
from sim_bridge.scenario import load_scenario
from sim_bridge.synthetic import generate

STEPS = 300


def _data(name: str, seed: int = 3):
    sc = load_scenario(name)
    trim_u = generate(sc, np.random.default_rng(seed), 1).u[0]
    # excite the input path too: random elevator/throttle deviations around trim
    u = trim_u + np.random.default_rng(seed + 1).normal(0.0, [0.01, 0.02], (STEPS, 2))
    run = generate(sc, np.random.default_rng(seed), STEPS, u=u)
    return sc, run, u


def _fp_kalman(kf) -> FpKalman:
    """A filterpy KF in deviation coordinates about x* = [trim, 0] equal to our KF's model."""
    n, m = kf.F.shape[0], kf.meas.m
    fp = FpKalman(dim_x=n, dim_z=m, dim_u=2)
    fp.F = kf.F.copy()
    fp.B = kf.process.B.copy()
    fp.Q = kf.Q.copy()
    fp.H = kf.meas.H.copy()
    fp.R = kf.meas.R.copy()
    fp.P = kf.P.copy()
    return fp


def _xstar(kf) -> np.ndarray:
    x = np.zeros(kf.F.shape[0])
    x[:N_AIRFRAME] = kf.process.model.trim.z
    return x


def test_kf_equals_filterpy_on_ch4_and_ch5c():
    for name in ("ch4", "ch5c"):   # sensor faults only; actuator + sensor faults (nonlinear truth)
        sc, run, u = _data(name)
        kf = build_filter("KF", sc.estimator, np.random.default_rng(0))
        fp = _fp_kalman(kf)
        xs = _xstar(kf)
        fp.x = kf.x - xs
        ustar = kf.process.model.trim.u
        worst_x = worst_p = 0.0
        for k in range(STEPS):
            out = kf.step(run.t[k], run.y[k], run.mask[k], u[k])
            fp.predict(u=u[k] - ustar)
            fp.update(run.y[k] - kf.meas.H @ xs)
            worst_x = max(worst_x, np.max(np.abs(out.x_mean - xs - fp.x)))
            worst_p = max(worst_p, np.max(np.abs(out.x_cov - fp.P)))
            np.testing.assert_allclose(kf.last_innovation, fp.y, rtol=0, atol=1e-9)
            np.testing.assert_allclose(kf.last_innovation_cov, fp.S, rtol=0, atol=1e-9)
        assert worst_x < 1e-9 and worst_p < 1e-9, (name, worst_x, worst_p)
        assert abs(kf.log_likelihood - fp.log_likelihood) < 1e-9


def test_imm_equals_filterpy_on_ch4():
    sc, run, u = _data("ch4")
    imm = build_filter("IMM-KF", sc.estimator, np.random.default_rng(0))
    xs = _xstar(imm.filters[0])
    ustar = imm.filters[0].process.model.trim.u
    fps = []
    for f in imm.filters:
        fp = _fp_kalman(f)
        fp.x = f.x - xs
        fps.append(fp)
    fimm = IMMEstimator(fps, np.array([1.0, 0.0]), imm.M.copy())
    worst = 0.0
    mus = []
    for k in range(STEPS):
        out = imm.step(run.t[k], run.y[k], run.mask[k], u[k])
        fimm.predict(u=u[k] - ustar)
        fimm.update(run.y[k] - imm.filters[1].meas.H @ xs)
        worst = max(worst, np.max(np.abs(out.x_mean - xs - fimm.x)), np.max(np.abs(out.x_cov - fimm.P)),
                    np.max(np.abs(imm.mu - fimm.mu)))
        mus.append(imm.mu[1])
    assert worst < 1e-9, worst
    # the comparison is not vacuous: the GNSS fault (10-30 s) switches the IMM to mode 1
    assert max(mus) > 0.9 and min(mus) < 0.1


def test_kf_masked_rows_are_left_out_and_innovation_is_nan_there():
    sc, run, u = _data("ch4")
    kf = build_filter("KF", sc.estimator, np.random.default_rng(0))
    ref = build_filter("KF", sc.estimator, np.random.default_rng(0))
    mask = np.array([False, True, True, True, True, True])
    y = run.y[0].copy()
    y[0] = np.nan
    out = kf.step(run.t[0], y, mask, u[0])
    assert np.isnan(kf.last_innovation[0]) and np.isfinite(kf.last_innovation[1:]).all()
    assert np.isfinite(out.x_mean).all() and np.isfinite(out.x_cov).all()
    # same as a KF whose GNSS row has infinite noise (so it carries no information)
    ref.meas.sigma[0] = 1e12
    ref.meas.R[0, 0] = 1e24
    y2 = run.y[0].copy()
    y2[0] = 0.0
    out2 = ref.step(run.t[0], y2, np.ones(6, bool), u[0])
    np.testing.assert_allclose(out.x_mean, out2.x_mean, atol=1e-8)


def test_kf_runs_on_every_scenario_with_linearised_model():
    for name in ("ch4", "ch5a", "ch5b", "ch5c", "ch6"):
        sc = load_scenario(name)
        run = generate(sc, np.random.default_rng(0), 60)
        kf = build_filter("KF", sc.estimator, np.random.default_rng(0))
        assert kf.process.kind == "linear"
        for k in range(60):
            out = kf.step(run.t[k], run.y[k], run.mask[k], run.u[k])
        assert np.isfinite(out.x_mean).all()
        # fault-free start at trim: the altitude estimate stays within a few metres of the truth
        assert abs(out.x_mean[0] - run.z[59, 0]) < 5.0


def test_kf_masked_step_equals_kf_on_reduced_model():
    from fdir_service.estimation.kalman import KalmanFilter
    from fdir_service.estimation.measurement import MeasurementModel

    sc, run, u = _data("ch5c")
    kf = build_filter("KF", sc.estimator, np.random.default_rng(0))
    keep = np.array([True, False, True, True, False])
    sub = kf.meas.reduced(keep)
    red = KalmanFilter(kf.process, MeasurementModel(sub.names, sub.H.copy(), sub.sigma.copy()),
                       kf.layout, kf.Q, kf.x, kf.P)
    for k in range(50):
        y = run.y[k].copy()
        y[~keep] = np.nan
        a = kf.step(run.t[k], y, keep, u[k])
        b = red.step(run.t[k], run.y[k][keep], np.ones(3, bool), u[k])
        np.testing.assert_allclose(a.x_mean, b.x_mean, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x_cov, b.x_cov, rtol=0, atol=1e-12)
        assert np.isnan(kf.last_innovation[~keep]).all()
        np.testing.assert_allclose(kf.last_innovation[keep], red.last_innovation, atol=1e-12)
