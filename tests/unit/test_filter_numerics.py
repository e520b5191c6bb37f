"""The estimation parts one by one: regulariser, resamplers, jump, amplitude, dynamics fast path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdir_service.airframe import load_airframe, trim
from fdir_service.airframe.dynamics import derivatives, derivatives_rows
from fdir_service.estimation.adaptive import AdaptiveTransition, phi_fa, phi_md
from fdir_service.estimation.jump import FixedTransition, jump
from fdir_service.estimation.regularize import (
    _solve_or_pinv,
    bandwidth,
    conditioned_on_mode0,
    covariance_factor,
    epanechnikov,
    h_opt,
)
from fdir_service.estimation.resample import effective_sample_size, multinomial, systematic


def test_bandwidth_reproduces_thesis_values():
    assert bandwidth(0.2, 7, 1000) == pytest.approx(0.3115, abs=5e-5)
    assert bandwidth(0.2, 6, 1000) == pytest.approx(0.2817, abs=5e-5)
    # h_opt shrinks with N as N^(-1/(n+4))
    assert h_opt(6, 10000) / h_opt(6, 1000) == pytest.approx(10 ** (-0.1), rel=1e-12)


@pytest.mark.parametrize("n", [1, 3, 6, 7])
def test_epanechnikov_moments_and_support(n):
    N = 200_000
    e = epanechnikov(np.random.default_rng(n), n, N)
    assert e.shape == (n, N)
    r2 = np.einsum("ij,ij->j", e, e)
    assert r2.max() <= 1.0 + 1e-12
    # mean 0, covariance I/(n+4): the std of a sample mean is sqrt(1/((n+4) N)) ~ 0.0007
    assert np.max(np.abs(e.mean(axis=1))) < 5 * math.sqrt(1.0 / ((n + 4) * N))
    cov = np.cov(e)
    np.testing.assert_allclose(cov, np.eye(n) / (n + 4), atol=0.004)
    # radial law: r^2 ~ Beta(n/2, 2), so E r^2 = n/(n+4), E r^4 = n(n+2)/((n+4)(n+6))
    assert r2.mean() == pytest.approx(n / (n + 4), abs=0.003)
    assert (r2**2).mean() == pytest.approx(n * (n + 2) / ((n + 4) * (n + 6)), abs=0.003)


def test_covariance_factor_handles_zero_variance_rows():
    P = np.diag([4.0, 1.0, 0.0])
    P[0, 1] = P[1, 0] = 1.0
    D = covariance_factor(P)
    np.testing.assert_allclose(D @ D.T, P, atol=1e-12)
    assert np.all(D[2] == 0) and np.all(D[:, 2] == 0)


def test_mode0_conditioning_solves_or_takes_the_pseudo_inverse_as_numpy_does():
    """One eigen-decomposition gives the condition and the pseudo-inverse: the same bits as
    numpy's cond (< 1e10: solve) and pinv(hermitian=True) on regular and singular blocks."""
    rng = np.random.default_rng(3)
    for trial in range(200):
        n = int(rng.integers(2, 12))
        A = rng.standard_normal((n, n + 2))
        A = A @ A.T
        if trial % 2:                                   # two entries that co-vary exactly
            A[:, 0] = A[:, 1]
            A[0, :] = A[1, :]
        B = rng.standard_normal((n, 3))
        want = (np.linalg.solve(A, B) if np.linalg.cond(A) < 1e10
                else np.linalg.pinv(A, hermitian=True) @ B)
        assert np.array_equal(_solve_or_pinv(A, B), want)
    P = np.array([[4.0, 1.0, 1.0], [1.0, 2.0, 1.0], [1.0, 1.0, 1.0]])
    C = conditioned_on_mode0(P, [2])                   # Schur complement on entry 2, zeroed
    assert np.allclose(C[:2, :2], P[:2, :2] - np.outer(P[:2, 2], P[:2, 2]) / P[2, 2])
    assert not C[2].any() and not C[:, 2].any()


@pytest.mark.parametrize("resample", [multinomial, systematic])
def test_resamplers_copy_particles_in_proportion_to_weight(resample):
    rng = np.random.default_rng(7)
    N = 20000
    w = rng.random(N) ** 4
    w /= w.sum()
    idx = resample(w, rng)
    counts = np.bincount(idx, minlength=N)
    assert counts.sum() == N
    # aggregate over 20 bins of 1000 particles: binomial std sqrt(N p) -> well within 5 sigma
    expected = N * w.reshape(20, -1).sum(axis=1)
    got = counts.reshape(20, -1).sum(axis=1)
    assert np.all(np.abs(got - expected) < 5 * np.sqrt(expected) + 1)
    if resample is systematic:   # systematic: every count is floor or ceil of N w
        assert np.all(np.abs(counts - N * w) < 1.0 + 1e-9)
    assert effective_sample_size(np.full(10, 0.1)) == pytest.approx(10.0)


def test_jump_fractions_match_pi01_pi10_and_sentinels_sit_at_the_amplitude():
    rng = np.random.default_rng(11)
    N = 100_000
    nf = 2
    modes = np.zeros((nf, N), bool)
    modes[:, N // 2:] = True                       # half the particles already faulty
    F = np.where(modes, 3.0, 0.0)
    A = rng.normal(10.0, 1.0, (nf, N))
    pi01 = np.array([0.01, 0.2])
    pi10 = np.array([0.05, 0.3])
    before = modes.copy()
    sentinels = jump(F, modes, A, np.array([True, True]), pi01, pi10, rng.random((nf, N)), True)
    for j in range(nf):
        n0 = np.count_nonzero(~before[j])
        up = np.count_nonzero(sentinels[j])
        down = np.count_nonzero(before[j] & ~modes[j])
        # binomial fractions within 5 standard deviations
        assert abs(up / n0 - pi01[j]) < 5 * math.sqrt(pi01[j] * (1 - pi01[j]) / n0)
        assert abs(down / (N - n0) - pi10[j]) < 5 * math.sqrt(pi10[j] * (1 - pi10[j]) / (N - n0))
        # sentinels land exactly at the predicted amplitude; exits at 0; mode-0 entries at 0
        np.testing.assert_array_equal(F[j, sentinels[j]], A[j, sentinels[j]])
        assert np.all(F[j, before[j] & ~modes[j]] == 0.0)
        assert np.all(F[j, ~modes[j]] == 0.0)
        assert np.all(F[j, before[j] & modes[j]] == 3.0)
    # an unavailable amplitude (measurement row missing) makes no sentinels
    modes = np.zeros((1, N), bool)
    F = np.zeros((1, N))
    s = jump(F, modes, np.ones((1, N)), np.array([False]), np.array([0.5]), np.array([0.5]),
             rng.random((1, N)), True)
    assert not s.any() and not modes.any()


def test_jump_reset_on_exit_keeps_mode0_values():
    F = np.array([[0.3, 0.4, 5.0]])
    modes = np.array([[False, False, True]])
    jump(F, modes, np.full((1, 3), 9.0), np.array([True]), np.array([0.0]), np.array([1.0]),
         np.full((1, 3), 0.5), forced_zero=False)
    np.testing.assert_array_equal(F, [[0.3, 0.4, 0.0]])   # the 1 -> 0 particle is reset to 0


def test_fixed_transition_matrix():
    T = FixedTransition(0.01, 0.02, 3).matrices()
    assert T.shape == (3, 2, 2)
    np.testing.assert_allclose(T[1], [[0.99, 0.01], [0.02, 0.98]])


def test_adaptive_activation_and_update_with_a_stub_roc():
    # thesis eq. 6.76: no evidence (Pfa 0.5) -> almost no jump; clear fault (Pfa 0) -> 44 % jump
    assert 1 - phi_fa(0.5) < 1e-3
    assert 1 - phi_fa(0.0) == pytest.approx(1 - (0.5 / (1 + math.exp(2.0)) + 0.5), rel=1e-12)
    assert 1 - phi_fa(0.0) == pytest.approx(0.4404, abs=1e-4)
    assert phi_md(0.0) == pytest.approx(0.9404, abs=1e-4)
    calls = []

    def roc(mu0, s0, mu1, s1, n_alpha=50):   # Gaussian closed form for equal variances
        from scipy.stats import norm
        calls.append(len(mu1))
        d = math.sqrt(np.sum((np.asarray(mu1) - mu0) ** 2 / s0**2))
        p = norm.cdf(-d / 2)
        return p, p, 0.0

    at = AdaptiveTransition(np.array([0.015]), window=3, roc=roc)
    at.update(np.array([0.0]), np.array([0.0]))
    assert at.pfa[0] == pytest.approx(0.5) and at.pi01[0] < 1e-3
    for _ in range(3):
        at.update(np.array([0.1]), np.array([0.1]))
    assert calls[-1] == 3                      # window of the last 3 means
    assert at.pfa[0] < 1e-6 and at.pi01[0] == pytest.approx(0.4404, abs=1e-3)
    assert at.matrices().shape == (1, 2, 2)



def test_adaptive_proposal_mode_is_importance_weighted_to_the_model_matrix():
    # "proposal" (not the thesis): the Pfa-driven pi01 proposes the 0 -> 1 moves, pi10 stays the
    # model's, and log P_model / P_proposal on every particle makes the weighted mode fractions
    # those of the fixed matrix (pi01 = 0.01), whatever the proposal's pi01 (here 0.4404).
    def roc(mu0, s0, mu1, s1, n_alpha=50):
        return 0.0, 0.0, 0.0               # clear evidence: Pfa = Pmd = 0

    at = AdaptiveTransition(np.array([0.015]), window=3, roc=roc, pi01=0.01, pi10=0.01, proposal=True)
    at.update(np.array([0.2]), np.array([0.2]))
    assert at.pi01[0] == pytest.approx(0.4404, abs=1e-4)
    assert at.pi10[0] == 0.01                              # the model's, not 1 - phi_md(0) = 0.0596
    thesis = AdaptiveTransition(np.array([0.015]), window=3, roc=roc, pi01=0.01, pi10=0.01)
    thesis.update(np.array([0.2]), np.array([0.2]))
    assert thesis.pi10[0] == pytest.approx(0.0596, abs=1e-4)
    assert thesis.log_weight_correction(np.zeros((1, 4), bool), np.ones((1, 4), bool),
                                        np.array([True])) is None
    rng = np.random.default_rng(3)
    N = 200_000
    before = np.zeros((1, N), dtype=bool)
    before[0, : N // 2] = True                             # half in mode 1, half in mode 0
    modes = before.copy()
    F = np.where(modes, 1.0, 0.0)
    jump(F, modes, np.full((1, N), 2.0), np.array([True]), at.pi01, at.pi10, rng.random((1, N)))
    lw = at.log_weight_correction(before, modes, np.array([True]))
    w = np.exp(lw)
    # exact per-move ratios
    up = ~before[0] & modes[0]
    assert np.allclose(lw[up], math.log(0.01 / at.pi01[0]))
    assert np.allclose(lw[~before[0] & ~modes[0]], math.log(0.99 / (1 - at.pi01[0])))
    assert np.allclose(lw[before[0]], 0.0)                 # pi10 proposal = model: ratio 1
    # the weighted 0 -> 1 fraction among mode-0 particles is the model's pi01 (binomial bound)
    m0 = ~before[0]
    frac = w[m0 & modes[0]].sum() / w[m0].sum()
    p = at.pi01[0]
    se = 0.01 * math.sqrt((1 - p) / (m0.sum() * p))        # from the binomial count of the moves
    assert abs(frac - 0.01) < 5 * se
    assert abs(np.mean(up[m0]) - p) < 0.01                 # while 44 % of them actually moved
    # with no evidence (Pfa 0.5) the proposal's pi01 is eq. 6.76's ~2e-4 (no floor): a sentinel then
    # carries log(0.01 / pi01) ~ +4 in its log-weight
    quiet = AdaptiveTransition(np.array([0.015]), window=3, roc=lambda *a, **k: (0.5, 0.5, 0.0),
                               pi01=0.01, pi10=0.01, proposal=True)
    quiet.update(np.array([0.0]), np.array([0.0]))
    assert quiet.pi01[0] == pytest.approx(1 - phi_fa(0.5)) and quiet.pi01[0] < 3e-4
    lw_q = quiet.log_weight_correction(np.zeros((1, 2), bool), np.array([[True, False]]), np.array([True]))
    assert lw_q[0] == pytest.approx(math.log(0.01 / quiet.pi01[0])) and lw_q[0] > 3.5
    # a fault that could not jump this step (rows missing) gets no correction
    lw_na = at.log_weight_correction(before, before, np.array([False]))
    assert np.all(lw_na == 0.0)

def _derivatives_reference(z, u, p):
    """The SPEC section 2 right-hand side written plainly (the original airframe code)."""
    ub, wb, th, q = z[..., 1], z[..., 2], z[..., 3], z[..., 4]
    de, dt = u[..., 0], u[..., 1]
    va = np.sqrt(ub * ub + wb * wb)
    alpha = np.arctan2(wb, ub)
    ca, sa = np.cos(alpha), np.sin(alpha)
    em = np.exp(-p.M * (alpha - p.alpha0))
    ep = np.exp(p.M * (alpha + p.alpha0))
    sig = (1 + em + ep) / ((1 + em) * (1 + ep))
    cll = p.C_L0 + p.C_La * alpha
    cl = (1 - sig) * cll + sig * (2 * np.sign(alpha) * sa**2 * ca)
    cd = p.C_Dp + cll**2 / (np.pi * p.e * p.AR)
    qbar = p.rho * va**2 * p.S / (2 * p.m)
    qc = p.c * q / (2 * va)
    cx, cxq, cxde = -cd * ca + cl * sa, -p.C_Dq * ca + p.C_Lq * sa, -p.C_Dde * ca + p.C_Lde * sa
    cz, czq, czde = -cd * sa - cl * ca, -p.C_Dq * sa - p.C_Lq * ca, -p.C_Dde * sa - p.C_Lde * ca
    thrust = p.rho * p.S_prop * p.C_prop / (2 * p.m) * ((p.k_motor * dt) ** 2 - va**2)
    return np.stack([
        -np.sin(th) * ub + np.cos(th) * wb,
        -q * wb - p.g * np.sin(th) + qbar * (cx + cxq * qc + cxde * de) + thrust,
        q * ub + p.g * np.cos(th) + qbar * (cz + czq * qc + czde * de),
        q,
        p.rho * va**2 * p.S * p.c / (2 * p.Jy) * (p.C_m0 + p.C_ma * alpha + p.C_mq * qc + p.C_mde * de),
    ], axis=-1)


def test_fast_dynamics_equal_the_plain_equations():
    p = load_airframe()
    tr = trim(p)
    rng = np.random.default_rng(5)
    Z = tr.z + rng.normal(size=(5000, 5)) * [50, 15, 15, 1.0, 2.0]
    U = tr.u + rng.normal(size=(5000, 2)) * [0.3, 0.3]
    ref = _derivatives_reference(Z, U, p)
    got = derivatives(Z, U, p)
    assert np.max(np.abs(got - ref) / (1 + np.abs(ref))) < 1e-12
    rows = derivatives_rows(Z[:, 1], Z[:, 2], Z[:, 3], Z[:, 4], U[:, 0], U[:, 1], p)
    np.testing.assert_array_equal(np.stack(rows, axis=-1), got)
    assert np.max(np.abs(derivatives(tr.z, tr.u, p)[1:])) < 1e-9   # trim is an equilibrium


def test_no_sentinel_is_placed_when_every_particle_is_already_faulty():
    rng = np.random.default_rng(3)
    N = 100_000
    modes = np.ones((1, N), bool)
    F = np.full((1, N), 2.0)
    A = np.full((1, N), 30.0)
    v = rng.random((1, N))
    s = jump(F, modes, A, np.array([True]), np.array([0.05]), np.array([0.01]), v, True)
    assert not s.any() and np.all(F[modes] == 2.0)
    assert np.all(F[~modes] == 0.0) and abs((~modes).mean() - 0.01) < 0.002
