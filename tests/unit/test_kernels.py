"""The compiled kernels (`fdir_service.estimation.kernels`) give the bits of the numpy code they
replaced, on random clouds: a changed kernel would change every campaign's flights."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation import kernels as K
from fdir_service.estimation.regularize import mode_codes, pattern_index

NF, N = 5, 400


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


def _cloud(rng: np.random.Generator, share: float = 0.2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X (5 + NF, N) of spread-out magnitudes, modes (NF, N) bool, weights w (N,) summing to 1)."""
    X = rng.standard_normal((5 + NF, N)) * 10.0 ** rng.uniform(-3, 3, (5 + NF, 1))
    modes = rng.random((NF, N)) < share
    w = rng.random(N) ** 4
    return X, modes, w / w.sum()


def test_sentinel_pairs_are_numpys_nonzero_fault_major(rng):
    sentinels = rng.random((NF, N)) < 0.03
    js = np.array([0, 2, 3, 4])
    rows, cols = K.sentinel_pairs(sentinels, js)
    ref_rows, ref_cols = np.nonzero(sentinels[js])
    assert np.array_equal(rows, ref_rows) and np.array_equal(cols, ref_cols)
    assert rows.size > 10


def test_spread_sentinels_moves_and_weighs_as_numpy(rng):
    X, _, _ = _cloud(rng)
    js = np.array([1, 3, 4])
    consts = rng.random((3, 2)) + 0.1
    carry_col = np.array([-1, 0, 1])
    carry_B = rng.standard_normal((5, 2))
    rows, cols = np.nonzero(rng.random((3, N)) < 0.05)
    eps = rng.standard_normal(cols.size) * 2.0
    clip = 1.5
    ref = X.copy()
    e = np.minimum(np.maximum(eps, -clip), clip)
    step = consts[rows, 0] * e
    ref[5 + js[rows], cols] += step
    for k, c in enumerate(carry_col.tolist()):
        if c >= 0:
            mine = rows == k
            ref[:5, cols[mine]] += carry_B[:, c:c + 1] * step[mine]
    ref_bonus = np.bincount(cols, consts[rows, 1] + 0.5 * e * e, minlength=N)
    bonus = K.spread_sentinels(X, 5, js, consts, carry_col, carry_B, rows, cols, eps, clip)
    assert np.array_equal(X, ref) and np.array_equal(bonus, ref_bonus)


def test_faint_exits_are_numpys_where(rng):
    F = rng.standard_normal((NF, N)) * 0.1
    center, threshold = rng.standard_normal(NF) * 0.05, np.full(NF, 0.08)
    pi10 = np.array([0.01, 0.2, 0.05, 0.0, 0.3])
    ref = np.where(np.abs(F - center[:, None]) < threshold[:, None],
                   np.maximum(pi10, 0.1)[:, None], pi10[:, None])
    assert np.array_equal(K.faint_exit_pi10(F, center, threshold, pi10, 0.1), ref)


@pytest.mark.parametrize("per_particle", [False, True])
def test_exit_folds_are_the_exiting_mode_one_values(rng, per_particle):
    X, modes, _ = _cloud(rng, 0.5)
    F = X[5:]
    v = rng.random((NF, N))
    pi10 = rng.random((NF, N)) * 0.3 if per_particle else rng.random((NF, 1)) * 0.3
    rows, armed = np.array([0, 1, 3]), np.array([True, True, True, False, True])
    reset = rng.standard_normal(NF)
    fold = (v[rows] < 0.5 * np.broadcast_to(pi10, F.shape)[rows]) & modes[rows] & armed[rows, None]
    ref = np.where(fold, F[rows] - reset[rows, None], 0.0)
    values, anyone = K.exit_folds(F, modes, v, pi10, rows, armed, reset)
    assert anyone and np.array_equal(values, ref)
    assert not np.any(values[2]) and np.any(values[0])        # row 3 is not armed


def _numpy_jump(F, modes, A, may, pi01, pi10, v, forced_zero, reset_to):
    """Alg. 4.1 as numpy did it before the kernel (`jump.jump` up to stop 53)."""
    up = (v < pi01[:, None]) & ~modes & may
    down = (v < pi10) & modes
    np.copyto(F, A, where=up)
    modes |= up
    modes &= ~down
    if forced_zero:
        F *= modes
    else:
        np.copyto(F, np.broadcast_to(reset_to[:, None], F.shape), where=down)
    return up


@pytest.mark.parametrize("forced_zero", [True, False])
def test_jump_entries_is_algorithm_4_1_bit_for_bit(rng, forced_zero):
    X, modes, _ = _cloud(rng, 0.3)
    F, A = X[5:].copy(), rng.standard_normal((NF, N))
    may = rng.random((NF, 1)) < 0.8
    pi01, pi10 = np.full(NF, 0.1), rng.random((NF, N)) * 0.2
    v, reset = rng.random((NF, N)), rng.standard_normal(NF)
    F2, modes2 = F.copy(), modes.copy()
    ref = _numpy_jump(F, modes, A, may, pi01, pi10, v, forced_zero, reset)
    up = K.jump_entries(F2, modes2, A, may, pi01, pi10, v, forced_zero, reset)
    assert np.array_equal(up, ref) and np.array_equal(modes2, modes) and np.array_equal(F2, F)
    assert up.sum() > 20


def test_mode_patterns_are_the_sorted_codes_and_their_weights(rng):
    _, modes, w = _cloud(rng, 0.1)
    groups, inv, share = K.mode_patterns(modes, w)
    ref_groups, ref_inv = pattern_index(mode_codes(modes), NF)
    assert np.array_equal(groups, ref_groups) and np.array_equal(inv, ref_inv)
    assert np.array_equal(share, (mode_codes(modes) == groups[:, None]) * w)


def test_many_mode_patterns_take_the_sort(rng):
    modes = rng.random((12, N)) < 0.5                     # ~ 400 patterns, past the scan's 32
    groups, inv, _ = K.mode_patterns(modes, np.full(N, 1.0 / N))
    ref_groups, ref_inv = np.unique(mode_codes(modes), return_inverse=True)
    assert groups.size > 32 and np.array_equal(groups, ref_groups) and np.array_equal(inv, ref_inv)


def test_pattern_deviations_gather_each_particles_mean(rng):
    X, modes, w = _cloud(rng)
    _, inv, _ = K.mode_patterns(modes, w)
    means = rng.standard_normal((inv.max() + 1, X.shape[0]))
    dX, dXw = K.pattern_deviations(X, means, inv, w)
    ref = X - np.take(means.T, inv, axis=1)
    assert np.array_equal(dX, ref) and np.array_equal(dXw, ref * w)


@pytest.mark.parametrize("tail", [True, False])
def test_drift_noise_is_the_predicts_numpy(rng, tail):
    X, modes, _ = _cloud(rng)
    noise = rng.standard_normal(X.shape)
    q, d = rng.random((5 + NF, 1)), rng.random((NF, 1)) * 0.01
    bound = np.array([[np.inf], [0.5], [1.0], [2.0], [np.inf]])
    draw = rng.random(N) if tail else np.zeros(0)
    stalled = rng.random(N) * (rng.random(N) < 0.3)
    ref = noise.copy()
    ref[:5] *= q[:5]
    ref[5:] *= np.where(modes, q[5:], d)
    if tail:
        ref[4] *= np.where(draw < 0.05, 5.0, 1.0)
    ref[4] *= 1.0 + (5.0 - 1.0) * stalled
    ref += X
    np.minimum(ref[5:], bound, out=ref[5:])
    np.maximum(ref[5:], -bound, out=ref[5:])
    K.add_drift_noise(X, noise, modes, q, d, draw, 0.05, 5.0, stalled, bound)
    assert np.array_equal(X, ref)


def test_mode0_weights_and_means(rng):
    X, modes, w = _cloud(rng, 0.6)
    w0 = K.mode0_weights(modes, w)
    assert np.array_equal(w0, ~modes * w)
    total = w0.sum(axis=1)
    total[2] = 0.0
    s = np.einsum("jn,jn->j", w0, X[5:])
    mean, share = K.share_means(s, total, float(w.sum()))
    assert np.array_equal(mean, np.divide(s, total, out=np.zeros_like(s), where=total > 1e-12))
    assert np.array_equal(share, total / w.sum()) and mean[2] == 0.0


def test_add_held_keeps_mode_zero_entries(rng):
    X, modes, _ = _cloud(rng)
    dX = rng.standard_normal(X.shape)
    ref = X.copy()
    held = dX.copy()
    held[5:] *= modes
    ref += held
    K.add_held(X, dX, modes)
    assert np.array_equal(X, ref)


def test_small_matrix_helpers(rng):
    A = rng.standard_normal((6, 6))
    ref = A.copy()
    ref += ref.T
    ref *= 0.5
    assert np.array_equal(K.symmetrised(A), ref)
    B = A.copy()
    B[4, 1] = np.nan
    assert K.all_finite(A) and not K.all_finite(B)
    assert not K.all_finite(np.full((2, 3), np.inf))


def test_fold_arming_counts_as_the_python_loop(rng):
    p = np.array([0.2, 0.35, 0.6, 0.1, 0.3])
    arming, arming_end = np.array([2, 0, 1]), np.array([1, 3])
    own, own_end = np.array([3, 4, 1, 4]), np.array([2, 4])
    since, blamed = np.array([4, 0]), np.array([K_FAR := 10 ** 9, 3])
    window, young, gated = np.array([2, 2]), np.array([5, 5]), np.array([3, 4])
    armed = np.ones(5, dtype=bool)
    K.arm_folds(p, arming, arming_end, own, own_end, since, blamed, window, young, gated, armed, K_FAR)
    # fault 3: arming p[2] = 0.6 -> 0 steps; own 0.1 + 0.3 < 0.5 -> far; armed by its window
    # fault 4: arming 0.2 + 0.35 >= 0.5 -> 0; own 0.35 + 0.3 >= 0.5 -> 3 + 1 = 4 <= 5
    assert since.tolist() == [0, 0] and blamed.tolist() == [K_FAR, 4]
    assert armed.tolist() == [True, True, True, True, True]
    p[:] = 0.0
    K.arm_folds(p, arming, arming_end, own, own_end, since, blamed, window, young, gated, armed, K_FAR)
    K.arm_folds(p, arming, arming_end, own, own_end, since, blamed, window, young, gated, armed, K_FAR)
    K.arm_folds(p, arming, arming_end, own, own_end, since, blamed, window, young, gated, armed, K_FAR)
    assert since.tolist() == [3, 3] and armed[3:].tolist() == [False, False]


@pytest.mark.parametrize("n", [1, 5, 7, 8, 9, 16, 25, 63, 128])
def test_window_means_are_numpys_sums(rng, n):
    buffer = rng.standard_normal((130, 3)) * 10.0 ** rng.uniform(-4, 6, (130, 3))
    t, th, q = buffer[:n].T
    tc, thc, q_mean = K.window_centred(buffer, 0, n)
    assert np.array_equal(tc, t - np.add.reduce(t) / n)
    assert np.array_equal(thc, th - np.add.reduce(th) / n)
    assert q_mean == np.add.reduce(q) / n


def test_any_related_is_the_matrix_products_test(rng):
    M = (rng.random((NF, NF)) < 0.3).astype(float)
    _, modes, _ = _cloud(rng, 0.2)
    assert np.array_equal(K.any_related(M, modes), (M @ modes) > 0.0)


def test_hand_over_is_the_pairwise_loop(rng):
    X, modes, _ = _cloud(rng, 0.4)
    F = X[5:].copy()
    pairs = np.array([[0, 1], [1, 0], [2, 3], [3, 2], [1, 4]])
    rates = np.array([0.3, 0.2, 0.5, 0.1, 0.4])
    v = rng.random((len(pairs), N))
    back = rng.standard_normal(NF)
    F2, modes2 = F.copy(), modes.copy()
    for (a, b), vv, rate in zip(pairs.tolist(), v, rates.tolist(), strict=True):
        go = modes[a] & ~modes[b] & (vv < rate)
        F[b, go] += F[a, go] - back[a]
        F[a, go] = back[a]
        modes[a, go] = False
        modes[b, go] = True
    K.hand_over(F2, modes2, v, pairs, rates, back)
    assert np.array_equal(F2, F) and np.array_equal(modes2, modes)


def test_a_singular_innovation_covariance_still_gives_a_finite_inverse():
    from fdir_service.estimation.correction import _spd_inverse

    S = np.array([[1.0, 1.0], [1.0, 1.0]])            # singular, though its trace passes the test
    R = np.diag([1e-3, 1e-3])
    with np.errstate(invalid="ignore"):
        inv = _spd_inverse(S, R)
    assert inv is not None and np.isfinite(inv).all() and np.allclose(inv, inv.T)


def test_without_a_folder_for_numbas_cache_the_kernels_compile_anyway(monkeypatch):
    calls = []

    def njit(**options):
        calls.append(options)
        if options.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available")
        return lambda fn: fn

    monkeypatch.setattr(K, "njit", njit)
    assert K._compiled(abs)(-2) == 2
    assert calls == [{"cache": True, "nogil": True}, {"nogil": True}]


def test_the_rate_windows_ring_gives_the_shifted_windows_bias(rng):
    from fdir_service.estimation.rate_window import RateWindow

    win, shifted = RateWindow(25, 12), []
    for k in range(80):
        theta, q = float(rng.standard_normal()) * 0.01, 0.002 + float(rng.standard_normal()) * 0.002
        sample = (0.05 * k, theta, q)
        win.add(*sample)
        shifted = (shifted + [sample])[-25:]
        if len(shifted) >= 12:
            t, th, q = np.array(shifted).T
            n = len(t)
            tc = t - np.add.reduce(t) / n
            ref = float(np.add.reduce(q) / n) - float(tc @ (th - np.add.reduce(th) / n) / (tc @ tc))
            assert win.bias() == ref
        else:
            assert win.bias() is None


@pytest.mark.parametrize("m", [1, 3, 6, 8, 11])
def test_inverse_checks_are_numpys(rng, m):
    A = rng.standard_normal((m, m)) * 10.0 ** rng.uniform(-3, 3, (m, m))
    R = np.diag(rng.random(m) + 0.01)
    assert K.inverse_checks(A, R) == (True, float(np.min(np.diag(R))), float(A.trace()))
    A[0, -1] = np.inf
    assert not K.inverse_checks(A, R)[0]
    assert K.inverse_checks(np.zeros((0, 0)), np.zeros((0, 0))) == (True, 0.0, 0.0)


def test_a_covariance_past_128_rows_takes_numpys_checks(rng):
    from fdir_service.estimation.correction import _spd_inverse

    A = rng.standard_normal((130, 130))
    R = np.eye(130) * 0.5
    S = A @ A.T + R
    inv = _spd_inverse(S, R)
    assert inv is not None and np.allclose(inv @ S, np.eye(130), atol=1e-8)
