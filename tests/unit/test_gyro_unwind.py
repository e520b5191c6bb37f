"""The attitude a gyro-fault hypothesis integrated, taken back when it ends (`gyro_unwind.GyroUnwind`,
parts.gyro_exit_unwind)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.gyro_unwind import THETA, GyroUnwind, NoUnwind
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator

DT = 0.05


def _frame(y_q: float, arrived: bool = True) -> SimpleNamespace:
    """A frame of two rows, the gyro's second (index 1)."""
    mask = np.array([True, arrived])
    yv = np.array([0.0, y_q])[mask]
    return SimpleNamespace(mask=mask, yv=yv, row_of=np.cumsum(mask) - 1)


def _cloud(q: np.ndarray) -> np.ndarray:
    """A cloud (6, N) of pitch rates q (N,), attitude 0, one fault entry."""
    X = np.zeros((6, q.size))
    X[4] = q
    return X


def test_a_gyro_hypothesis_integrates_what_its_rate_left_of_the_gyro_and_mode0_nothing():
    unwind = GyroUnwind(np.array([0]), q_row=1, dt=DT, share=1.0, N=3)
    modes = np.array([[True, True, False]])
    X = _cloud(np.array([0.01, 0.03, 0.0]))
    for _ in range(20):                                   # 1 s of a gyro reading 0.03 rad/s
        held = unwind.before(X, modes, _frame(0.03))
        unwind.after(X, modes, held, np.random.default_rng(0))
    np.testing.assert_allclose(unwind.S, [0.02, 0.0, 0.0], atol=1e-15)   # 1 s x 0.02 rad/s
    unwind.before(X, modes, _frame(0.5, arrived=False))   # no gyro reading: nothing to add
    np.testing.assert_allclose(unwind.S, [0.02, 0.0, 0.0], atol=1e-15)


def test_the_particles_that_leave_the_gyro_fault_take_back_their_attitude():
    unwind = GyroUnwind(np.array([0]), q_row=1, dt=DT, share=1.0, N=3)
    unwind.S[:] = [0.02, -0.01, 0.5]
    X = _cloud(np.zeros(3))
    X[THETA] = 0.1
    held = np.array([True, True, False])
    modes = np.array([[False, True, False]])             # particle 0 leaves, 1 stays, 2 was never in
    unwind.after(X, modes, held, np.random.default_rng(0))
    np.testing.assert_allclose(X[THETA], [0.12, 0.1, 0.1])
    np.testing.assert_allclose(unwind.S, [0.0, -0.01, 0.0])  # 0 in mode 0, kept in mode 1


def test_only_the_share_unwinds_and_the_rest_keep_their_attitude():
    N = 4000
    unwind = GyroUnwind(np.array([0]), q_row=1, dt=DT, share=0.5, N=N)
    unwind.S[:] = 0.02
    X = _cloud(np.zeros(N))
    unwind.after(X, np.zeros((1, N), dtype=bool), np.ones(N, dtype=bool), np.random.default_rng(1))
    moved = X[THETA] != 0.0
    assert set(np.unique(X[THETA])) == {0.0, 0.02}
    assert 0.46 < moved.mean() < 0.54


def test_the_integral_follows_its_particle_on_resampling_and_a_fresh_cloud_holds_none():
    unwind = GyroUnwind(np.array([0]), q_row=1, dt=DT, share=1.0, N=3)
    unwind.S[:] = [1.0, 2.0, 3.0]
    unwind.resample(np.array([2, 2, 0]))
    np.testing.assert_array_equal(unwind.S, [3.0, 3.0, 1.0])
    unwind.reinitialise()
    np.testing.assert_array_equal(unwind.S, 0.0)


def _catalogue_doc() -> dict:
    doc, _ = estimator_document("aerosonde-catalogue")
    return doc


def test_gyro_exit_unwind_is_read_and_builds_the_part_on_the_gyros_item():
    doc = _catalogue_doc()
    doc["parts"]["gyro_exit_unwind"] = 0.5
    est = parse_estimator(doc, "unwind.toml")
    f = build_filter("RJMRPF", est, np.random.default_rng(0), particles=50)
    unwind = f.parts.jump.unwind
    assert isinstance(unwind, GyroUnwind) and unwind.share == 0.5 and unwind.S.shape == (50,)
    ids = [x.id for x in est.faults]
    assert sorted(ids[j] for j in unwind.entries) == ["q", "q_st"]
    assert est.observed[unwind.q_row] == "q"
    assert isinstance(build_filter("RJMRPF", load_estimator("aerosonde-robust"), np.random.default_rng(0),
                                   particles=50).parts.jump.unwind, NoUnwind)


def test_gyro_exit_unwind_outside_0_1_fails_naming_the_key():
    doc = _catalogue_doc()
    doc["parts"]["gyro_exit_unwind"] = 1.5
    with pytest.raises(ConfigError, match="gyro_exit_unwind"):
        parse_estimator(doc, "unwind.toml")
