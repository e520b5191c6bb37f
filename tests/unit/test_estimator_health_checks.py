"""Estimator health: each problem with real numbers, the holdoff, the HEARTBEAT state and the
state a re-initialisation starts from."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import dialect
from fdir_service.runtime.events import Cause, HealthProblem
from fdir_service.runtime.frames import AssembledFrame
from fdir_service.runtime.health import NON_FINITE, EstimatorHealth, filter_raised, is_finite
from tests.helpers.experiments import ch4_service

CFG = ch4_service()
X_TRIM = np.array([-500.0, 25.0, 1.0, 0.04, 0.0])


def step_output(x5=X_TRIM, n_eff: float = 500.0, p=(0.0, 0.0)) -> StepOutput:
    x = np.concatenate([np.asarray(x5, dtype=float), [0.0, 0.0]])
    return StepOutput(0.0, x, np.eye(7), ("gnss", "baro"), np.zeros(2), np.asarray(p, dtype=float), n_eff,
                      False)


class Particles:
    """A particle filter as health sees it: N particles and its own re-initialisation counter."""

    N = 100
    reinitialisations = 0


def frame(k: int, *, stale=(), restart=False, synthetic=False) -> AssembledFrame:
    return AssembledFrame(k, 50_000 * k, np.zeros(6), np.ones(6, dtype=bool), np.zeros(2), synthetic, stale,
                          restart)


def test_non_finite_and_state_jump():
    h = EstimatorHealth(CFG.health, CFG.estimator)
    assert h.problem(step_output(), Particles()) is None
    bad = step_output()
    bad.fault_probability[1] = math.nan
    assert not is_finite(bad) and h.problem(bad, Particles()) is NON_FINITE
    prev = X_TRIM.copy()
    assert h.problem(step_output(X_TRIM + [49.0, 0, 0, 0, 0]), Particles(), prev) is None   # < 50 m
    jump = h.problem(step_output(X_TRIM + [-20_000.0, 0, 0, 0, 0]), Particles(), prev)
    assert jump == HealthProblem(Cause.STATE_JUMP, "p_d jump -2e+04/frame") and jump.acute
    theta = h.problem(step_output(X_TRIM + [0, 0, 0, 1.5, 0]), Particles(), prev)
    assert theta.text == "theta jump +1.5/frame"
    # no jump check across a restart or a synthetic frame
    h.published(step_output())
    far = step_output(X_TRIM + [-20_000.0, 0, 0, 0, 0])
    assert h.check(far, Particles(), frame(5, restart=True)) is None
    assert h.check(far, Particles(), frame(5, synthetic=True)) is None
    assert h.check(far, Particles(), frame(5)).cause is Cause.STATE_JUMP


def test_filter_reset_and_degeneracy():
    h = EstimatorHealth(CFG.health, CFG.estimator)
    f = Particles()
    f.reinitialisations = 1
    assert h.problem(step_output(), f) == HealthProblem(Cause.FILTER_RESET, "filter lost every particle")
    assert h.problem(step_output(), f) is None                     # counted once
    got = [h.problem(step_output(n_eff=1.2), f) for _ in range(10)]
    assert got[:9] == [None] * 9
    assert got[9] == HealthProblem(Cause.DEGENERATE, "N_eff < 1.5 for 10 frames") and not got[9].acute
    h.problem(step_output(n_eff=2.0), f)
    assert h.low_neff == 0
    kalman = EstimatorHealth(CFG.health, CFG.estimator)
    assert all(kalman.problem(step_output(n_eff=1.0), object()) is None for _ in range(20))   # no N_eff check
    assert filter_raised(np.linalg.LinAlgError("x")) == HealthProblem(Cause.FILTER_RAISED,
                                                                      "filter raised LinAlgError")


def test_holdoff_decides_and_heartbeat_state():
    h = EstimatorHealth(CFG.health, CFG.estimator)
    degenerate = HealthProblem(Cause.DEGENERATE, "N_eff < 1.5 for 10 frames")
    assert h.must_reinitialise(degenerate, 0) and not h.in_holdoff(0)
    h.reinitialised(Particles(), 5_000_000)
    assert h.in_holdoff(5_999_999) and not h.in_holdoff(6_000_000)    # reinit_holdoff_s = 1.0
    assert not h.must_reinitialise(degenerate, 5_500_000)
    assert h.must_reinitialise(NON_FINITE, 5_500_000)               # acute: at once
    assert h.heartbeat_state(frame(119), False) == dialect.MAV_STATE_CRITICAL     # t = 5.95 s
    assert h.heartbeat_state(frame(120), False) == dialect.MAV_STATE_ACTIVE       # t = 6.00 s
    assert h.heartbeat_state(frame(120, stale=("baro_alt",)), False) == dialect.MAV_STATE_CRITICAL
    assert h.heartbeat_state(frame(120), True) == dialect.MAV_STATE_CRITICAL


def test_state_from_measurements_prefers_the_row_nearest_the_last_good_state():
    h = EstimatorHealth(CFG.health, CFG.estimator)
    h.healthy(step_output(X_TRIM))
    assert h.last_good_state.tolist() == X_TRIM.tolist()
    # rows: gnss_alt, baro_alt, u, w, theta, q; GNSS 10 km off (a glitch), q not measured
    y = np.array([10_500.0, 503.0, 24.0, 1.2, 0.05, np.nan])
    mask = np.array([True, True, True, True, True, False])
    x0, keep = h.state_from_measurements(y, mask)
    assert x0 == pytest.approx([-503.0, 24.0, 1.2, 0.05, 0.0])     # baro wins; q from the last good state
    # gate: |y - x0| <= 20 sigma (gnss sigma 7.5 m: 150 m)
    assert keep.tolist() == [False, True, True, True, True, False]
    y[0] = 620.0                                                   # 117 m from the baro: within 150 m
    assert h.state_from_measurements(y, mask)[1].tolist() == [True, True, True, True, True, False]
    h.published(step_output([np.nan, 0, 0, 0, 0]))
    assert h.prev_state is None
