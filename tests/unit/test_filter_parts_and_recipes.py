"""Each part of a particle-filter recipe on its own, and the recipe table that assembles them."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.adaptive import AdaptiveTransition
from fdir_service.estimation.correction import (
    KalmanCorrection,
    Likelihood,
    weighted_mean_cov,
    within_mode_cov,
)
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.jump import ActuatorCarry, FixedTransition, MarkovJump, NoCarry, NoJump
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.predict import GaussianPredict, ModeGatedPredict
from fdir_service.estimation.recipes import FILTER_NAMES, PARTICLE_FILTERS, RECIPES, recipe
from fdir_service.estimation.regularize import (
    GlobalJitter,
    NoJitter,
    PerModeJitter,
    mode_codes,
    pattern_index,
)
from fdir_service.estimation.resample import BelowEffectiveSize, EveryStep
from fdir_service.estimation.sentinels import PriorSentinels, ThesisSentinels, prior_log_constants
from fdir_service.estimator_config import load_estimator

LAYOUT = FaultLayout(("gnss", "theta"), ("sensor", "sensor"), ("gnss_alt", "theta"), ("gnss_alt", "theta"))
SIGMA = np.array([5.0, 0.01])
MEAS = MeasurementModel.build(LAYOUT, SIGMA)
N = 20_000


class Still:
    """A process model that leaves the cloud where it is (isolates the part under test)."""

    B_actuator = np.zeros((5, 2))

    def propagate(self, X, u, modes=None):
        return X.copy()


class FakeAmplitude:
    """An amplitude predictor that predicts `value` for every fault and particle."""

    def __init__(self, value: float, available=(True, True)) -> None:
        self.layout = LAYOUT
        self.value = value
        self.available = np.array(available)
        self.sigma = np.array([5.0, 0.01])

    def observe(self, frame):
        return None

    def predict(self, X, innov, mask):
        return np.full((LAYOUT.nf, X.shape[1]), self.value), self.available

    def gain(self, mask):
        return None, self.available, self.sigma


def _frame(y=(0.0, 0.0), mask=(True, True)) -> Frame:
    return Frame.of(1.0, np.array(y), np.array(mask), np.zeros(2), MEAS)


def _cloud(seed=0, modes_on=0):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((LAYOUT.n, N))
    modes = np.zeros((LAYOUT.nf, N), dtype=bool)
    modes[:, :modes_on] = True
    X[5:] *= modes
    return X, modes, np.full(N, 1.0 / N)


# ----------------------------------------------------------------------------- predict
def test_gaussian_predict_adds_the_assumed_noise_to_every_entry():
    q = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.5, 0.05])
    X, modes, _ = _cloud()
    out = GaussianPredict(Still(), q).predict(X, modes, np.zeros(2), np.random.default_rng(1))
    np.testing.assert_allclose((out - X).std(axis=1), q, rtol=0.03)
    assert out is not X


def test_mode_gated_predict_leaves_mode0_fault_entries_at_zero():
    q = np.full(7, 0.5)
    X, modes, _ = _cloud(modes_on=N // 2)
    out = ModeGatedPredict(Still(), q).predict(X, modes, np.zeros(2), np.random.default_rng(1))
    assert np.all(out[5:][~modes] == 0.0)
    assert (out[5:, : N // 2] - X[5:, : N // 2]).std() == pytest.approx(0.5, rel=0.03)
    assert (out[:5] - X[:5]).std() == pytest.approx(0.5, rel=0.03)


# ----------------------------------------------------------------------------- jump
def test_fixed_markov_jump_places_sentinels_at_pi01_where_the_row_arrived():
    X, modes, w = _cloud()
    amplitude = FakeAmplitude(7.0, (True, False))
    jump = MarkovJump(FixedTransition([0.1, 0.3], 0.01, 2), amplitude, True, NoCarry())
    assert jump.jump(X, modes, w, _frame(), np.random.default_rng(2)) is None   # model's own matrix
    assert modes[0].mean() == pytest.approx(0.1, abs=0.01)
    assert not modes[1].any()                            # no amplitude for fault 1 this frame
    assert np.all(X[5, modes[0]] == 7.0) and np.all(X[5, ~modes[0]] == 0.0)
    assert np.array_equal(jump.sentinels, modes)
    assert jump.fault_probability(X, modes, w)[0] == pytest.approx(modes[0].mean())


def test_markov_jump_pins_and_resamples_modes_no_jump_does_neither():
    X, modes, w = _cloud(modes_on=3)
    X[5:] = 1.0
    jm = MarkovJump(FixedTransition(0.0, 0.0, 2), FakeAmplitude(0.0), True, NoCarry())
    jm.pin(X, modes)
    assert X[5:, :3].sum() == 6.0 and X[5:, 3:].sum() == 0.0
    idx = np.zeros(N, dtype=int)
    assert jm.resample_modes(modes, idx).all()
    nj = NoJump(np.array([0.5, 0.5]))
    X[5:] = 1.0
    nj.pin(X, modes)
    assert X[5:].sum() == 2 * N
    assert nj.resample_modes(modes, idx) is modes
    assert nj.jump(X, modes, w, _frame(), np.random.default_rng(0)) is None
    np.testing.assert_allclose(nj.fault_probability(X, modes, w), [1.0, 1.0])


def test_actuator_carry_moves_the_airframe_state_with_the_jumped_fault():
    B = np.array([[0.0], [1.0], [2.0], [0.0], [-3.0]])
    carry = ActuatorCarry(np.array([1]), B)
    X = np.zeros((7, 4))
    F = X[5:]
    before = carry.capture(F)
    F[1, 2] = 0.5
    carry.apply(X, F, before)
    np.testing.assert_allclose(X[:5, 2], B[:, 0] * 0.5)
    assert np.all(X[:5, [0, 1, 3]] == 0.0)
    assert carry.index == {1: 0}


def test_adaptive_transition_observes_the_h1_means_of_the_cloud():
    seen = []

    def roc(mu0, s0, mu1, s1, n_alpha):
        seen.append(float(mu1[-1]))
        return 0.05, 0.05, 0.0

    tr = AdaptiveTransition(np.array([1.0]), window=1, roc=roc)
    A = np.array([[2.0, 2.0, 4.0, 4.0]])
    F = np.array([[0.0, 0.0, 9.0, 11.0]])
    modes = np.array([[False, False, True, True]])
    tr.observe(A, F, modes, np.full(4, 0.25))
    assert seen == [2.0, 10.0]          # mu1|0 over mode-0 particles' A, mu1|1 over mode-1 f


# ----------------------------------------------------------------------------- sentinels
def test_prior_log_constants_and_which_faults_take_them():
    c = prior_log_constants(np.array([100.0, np.nan, 2.0]), np.array([0, 1, -1]), np.zeros(3, bool))
    assert c[0] == pytest.approx(0.5 * np.log(2 * np.pi) - np.log(200.0))
    assert np.isnan(c[1]) and np.isnan(c[2])        # no amplitude_max; actuator not carried
    c = prior_log_constants(np.array([2.0]), np.array([-1]), np.array([True]))
    assert np.isfinite(c[0])


def test_prior_sentinels_weigh_only_sentinels_of_rows_that_arrived():
    log_c = prior_log_constants(np.array([100.0, 1.0]), LAYOUT.sensor_row, np.zeros(2, bool))
    part = PriorSentinels(log_c, LAYOUT.sensor_row, SIGMA, FakeAmplitude(0.0), NoCarry())
    sentinels = np.zeros((2, N), dtype=bool)
    sentinels[:, :100] = True
    X = np.zeros((7, N))
    bonus = part.weigh(X, _frame(mask=(True, False)), sentinels, np.random.default_rng(3))
    assert np.all(X[6] == 0.0) and np.all(bonus[100:] == 0.0)        # theta row missing: untouched
    eps = X[5, :100] / 5.0
    np.testing.assert_allclose(bonus[:100], log_c[0] + np.log(5.0) + 0.5 * eps**2)
    assert part.weigh(X, _frame(mask=(False, False)), sentinels, np.random.default_rng(3)) is None
    assert ThesisSentinels().weigh(X, _frame(), sentinels, np.random.default_rng(3)) is None


def test_clipped_prior_sentinels_bound_the_draw_and_its_weight():
    """parts.sentinel_clip = 3: the draws beyond 3 sigma sit at 3 sigma, so no sentinel's p / q
    exceeds exp(4.5) sqrt(2 pi) s / L; the draws within are the unclipped part's, bit for bit."""
    log_c = prior_log_constants(np.array([100.0, 1.0]), LAYOUT.sensor_row, np.zeros(2, bool))
    sentinels = np.zeros((2, N), dtype=bool)
    sentinels[0] = True                                  # 20 000 draws: ~54 beyond 3 sigma
    out = {}
    for clip in (0.0, 3.0):
        X = np.zeros((7, N))
        part = PriorSentinels(log_c, LAYOUT.sensor_row, SIGMA, FakeAmplitude(0.0), NoCarry(), clip=clip)
        bonus = part.weigh(X, _frame(), sentinels, np.random.default_rng(3))
        out[clip] = (X[5] / 5.0, bonus)
    (eps0, bonus0), (eps3, bonus3) = out[0.0], out[3.0]
    tail = np.abs(eps0) > 3.0
    assert 20 < tail.sum() < 100 and np.abs(eps0).max() > 3.5
    np.testing.assert_array_equal(eps3[~tail], eps0[~tail])
    np.testing.assert_allclose(eps3[tail], 3.0 * np.sign(eps0[tail]))
    top = log_c[0] + np.log(5.0) + 4.5
    assert bonus3.max() == pytest.approx(top) and bonus0.max() > top + 1.0


# ----------------------------------------------------------------------------- correction
def test_likelihood_is_the_gaussian_of_the_assumed_noise():
    X, modes, w = _cloud()
    ll = Likelihood().update(X, w, modes, _frame(y=(1.0, 0.02)))
    e = np.array([[1.0], [0.02]]) - MEAS.H @ X
    np.testing.assert_allclose(ll, -0.5 * ((e / SIGMA[:, None]) ** 2).sum(axis=0))
    assert np.all(Likelihood().update(X, w, modes, _frame(mask=(False, False))) == 0.0)


def test_kalman_correction_moves_the_cloud_mean_as_a_kalman_update():
    X, modes, w = _cloud(seed=4)
    X[:5] *= np.array([[10.0], [1.0], [1.0], [0.01], [0.01]])
    mean, P = weighted_mean_cov(X, w)
    y = np.array([-40.0, 0.03])
    pinned = []
    ll = KalmanCorrection(lambda X, m: pinned.append(True)).update(X, w, modes, _frame(y=y))
    S = MEAS.H @ P @ MEAS.H.T + MEAS.R
    K = P @ MEAS.H.T @ np.linalg.inv(S)
    np.testing.assert_allclose(X @ w, mean + K @ (y - MEAS.H @ mean), rtol=1e-9, atol=1e-9)
    assert pinned == [True] and ll.shape == (N,)


def test_only_the_altimeters_move_the_altitude_when_asked():
    """parts.altitude_gain = "altimeters": the attitude row's innovation, which the cloud's
    altitude-attitude covariance would turn into metres, leaves the altitude where it was; the
    other states are corrected as before, and a GNSS innovation still moves the altitude."""
    X, modes, w = _cloud(seed=4)
    X[:5] *= np.array([[10.0], [1.0], [1.0], [0.01], [0.01]])
    X[0] += 500.0 * X[3]                                # altitude and pitch correlated in the cloud
    y = np.array([-(X[0] @ w), 0.05])                   # the GNSS reads the mean; theta is off
    plain, gated = X.copy(), X.copy()
    KalmanCorrection(lambda X, m: None).update(plain, w, modes, _frame(y=y))
    KalmanCorrection(lambda X, m: None, altitude_gain="altimeters").update(gated, w, modes, _frame(y=y))
    assert abs((plain[0] - X[0]) @ w) > 0.5                          # the attitude moved it
    assert abs((gated[0] - X[0]) @ w) < 0.05 * abs((plain[0] - X[0]) @ w)
    np.testing.assert_allclose(gated[3], plain[3])                   # theta as before
    moved = X.copy()
    KalmanCorrection(lambda X, m: None, altitude_gain="altimeters").update(
        moved, w, modes, _frame(y=(y[0] - 20.0, X[3] @ w + X[6] @ w), mask=(True, True)))
    assert (moved[0] - X[0]) @ w > 1.0                                # 20 m lower reading: p_d grows


def test_the_pitch_rate_row_alone_can_be_kept_from_moving_the_altitude():
    """parts.altitude_gain = "no_pitch_rate": the gyro row's innovation no longer moves the
    altitude; every other row's gain, and every other state, as the full correction's."""
    layout = FaultLayout(("q",), ("sensor",), ("q",), ("gnss_alt", "q"))
    meas = MeasurementModel.build(layout, np.array([5.0, 0.003]))
    rng = np.random.default_rng(8)
    X = rng.standard_normal((layout.n, 500)) * np.array([[3.0], [0.5], [0.5], [0.01], [0.02], [0.0]])
    X[0] += 100.0 * X[4]                                # altitude and pitch rate correlated
    w = np.full(500, 1 / 500)
    modes = np.zeros((1, 500), bool)
    frame = Frame.of(1.0, np.array([-(X[0] @ w), X[4] @ w + 0.05]), np.ones(2, bool), np.zeros(2), meas)
    plain, gated = X.copy(), X.copy()
    KalmanCorrection(lambda X, m: None).update(plain, w, modes, frame)
    KalmanCorrection(lambda X, m: None, altitude_gain="no_pitch_rate").update(gated, w, modes, frame)
    assert abs((plain[0] - X[0]) @ w) > 1.0 and abs((gated[0] - X[0]) @ w) < 0.05
    np.testing.assert_allclose(gated[1:], plain[1:])


def test_the_altimeters_can_be_kept_to_the_altitude():
    """parts.altimeter_gain = "altitude": a GNSS (altimeter) innovation moves the altitude as the
    full correction does, but no longer u, w, theta or q, which the cloud's covariance with the
    altitude would have bent towards a drifting altimeter; the other rows' gains are the same."""
    layout = FaultLayout(("w",), ("sensor",), ("w",), ("gnss_alt", "w"))
    meas = MeasurementModel.build(layout, np.array([1.5, 1.5]))
    rng = np.random.default_rng(8)
    X = rng.standard_normal((layout.n, 500)) * np.array([[3.0], [0.5], [0.5], [0.01], [0.02], [0.0]])
    X[0] -= 5.0 * X[2]                                  # altitude and w correlated (h integrates -w)
    w = np.full(500, 1 / 500)
    modes = np.zeros((1, 500), bool)
    frame = Frame.of(1.0, np.array([-(X[0] @ w) + 4.0, X[2] @ w]), np.ones(2, bool), np.zeros(2), meas)
    higher = Frame.of(1.0, frame.yv - np.array([10.0, 0.0]), np.ones(2, bool), np.zeros(2), meas)
    plain, kept, kept_higher = X.copy(), X.copy(), X.copy()
    KalmanCorrection(lambda X, m: None).update(plain, w, modes, frame)
    KalmanCorrection(lambda X, m: None, altimeter_gain="altitude").update(kept, w, modes, frame)
    KalmanCorrection(lambda X, m: None, altimeter_gain="altitude").update(kept_higher, w, modes, higher)
    assert abs((plain[2] - X[2]) @ w) > 0.1                          # 4 m of altimeter moved w ...
    np.testing.assert_array_equal(kept_higher[1:5], kept[1:5])       # ... kept: 10 m more moves none
    np.testing.assert_allclose(kept[0], plain[0])                    # h as the full correction's
    assert (kept_higher[0] - kept[0]) @ w > 1.0                      # and the altitude takes it
    with pytest.raises(ValueError, match="altimeter_gain"):
        KalmanCorrection(lambda X, m: None, altimeter_gain="some")


def test_the_within_mode_covariance_pools_each_hypothesis_spread_about_its_own_mean():
    """Two patterns holding 1/3 and 2/3 of the weight are spread about their own means; a
    particle alone in its pattern (a sentinel, under HYPOTHESIS_SHARE) about the cloud's."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((LAYOUT.n, 300))
    modes = np.zeros((LAYOUT.nf, 300), dtype=bool)
    modes[0, 100:] = True                               # two patterns of 100 and 199 particles ...
    modes[1, 299] = True                                # ... and one particle alone in its pattern
    X[:, 100:299] += 7.0                                # the second pattern sits 7 further along
    X[:, 299] = 50.0
    w = np.full(300, 1.0 / 300)
    expected = np.zeros((LAYOUT.n, LAYOUT.n))
    for g in (slice(0, 100), slice(100, 299)):
        dX = X[:, g] - (X[:, g] @ w[g] / w[g].sum())[:, None]
        expected += (dX * w[g]) @ dX.T
    lone = X[:, 299] - X @ w
    expected += w[299] * np.outer(lone, lone)
    np.testing.assert_allclose(within_mode_cov(X, w, modes), expected, rtol=1e-10, atol=1e-12)
    assert np.all(np.diag(weighted_mean_cov(X, w)[1]) > 1.5 * np.diag(expected))
    alone = expected - w[299] * np.outer(lone, lone)   # with the sentinel a hypothesis of its own
    np.testing.assert_allclose(within_mode_cov(X, w, modes, share_min=0.0), alone, rtol=1e-10)


def test_a_gain_from_within_each_hypothesis_keeps_a_gnss_frame_from_dragging_the_altitude():
    """A crowd (80 %) blames the barometer for an altitude 5 m off; the rest are fault-free. With
    the cloud's covariance the 5 m between them reads as altitude uncertainty, so one GNSS frame 7 m
    off (one sigma) drags the fault-free particles' altitude off the barometer they match; with
    parts.gain_covariance = "within_mode" they move as their own Kalman filter would."""
    layout = FaultLayout(("gnss", "baro"), ("sensor", "sensor"), ("gnss_alt", "baro_alt"),
                         ("gnss_alt", "baro_alt"))
    meas = MeasurementModel.build(layout, np.array([7.5, 1.5]))
    rng = np.random.default_rng(5)
    n_all = 2000
    X = np.zeros((layout.n, n_all))
    X[0] = -500.0 + 0.7 * rng.standard_normal(n_all)   # p_d (m): 500 m up, 0.7 m apart
    modes = np.zeros((2, n_all), dtype=bool)
    modes[1, 400:] = True
    X[0, 400:] += 5.0                                   # 5 m lower, ...
    X[6, 400:] = 5.0                                    # ... the barometer's fault makes up for it
    w = np.full(n_all, 1.0 / n_all)
    frame = Frame.of(1.0, np.array([507.0, 500.0]), np.ones(2, bool), np.zeros(2), meas)
    moved = {}
    for cov in ("cloud", "within_mode"):
        Xc = X.copy()
        KalmanCorrection(lambda X, m: None, hold_mode0_faults=True, covariance=cov).update(
            Xc, w, modes, frame)
        moved[cov] = (X[0, :400] - Xc[0, :400]).mean()  # the fault-free particles' climb (m)
    assert moved["cloud"] > 0.4
    assert abs(moved["within_mode"]) < 0.1
    with pytest.raises(ValueError, match="covariance 'pooled'"):
        KalmanCorrection(lambda X, m: None, covariance="pooled")


# ----------------------------------------------------------------------------- resample, regularise
def test_resample_triggers():
    assert BelowEffectiveSize(0.5).due(499.0, 1000) and not BelowEffectiveSize(0.5).due(500.0, 1000)
    assert EveryStep().due(1000.0, 1000)


def test_global_jitter_spreads_by_h2_over_n_plus_4_and_shrinkage_keeps_the_spread():
    rng = np.random.default_rng(5)
    X0 = rng.standard_normal((3, 200_000)) * np.array([[1.0], [2.0], [0.5]])
    P = np.cov(X0)
    for shrink, factor in ((False, 1 + 0.5**2 / 7), (True, 1.0)):
        X = X0.copy()
        GlobalJitter(0.5, shrink).jitter(X, X0, None, None, None, P, rng)
        np.testing.assert_allclose(np.diag(np.cov(X)), np.diag(P) * factor, rtol=0.02)
    X = X0.copy()
    NoJitter().jitter(X, X0, None, None, None, P, rng)
    assert np.array_equal(X, X0)


@pytest.mark.parametrize("nf", [1, 2, 5, 19, 52, 60])
def test_mode_codes_set_bit_j_for_fault_j(nf):
    modes = np.random.default_rng(nf).random((nf, 500)) < 0.5
    expected = sum(modes[j].astype(np.int64) << j for j in range(nf))
    np.testing.assert_array_equal(mode_codes(modes), expected)


@pytest.mark.parametrize("nf", [3, 16, 19, 40])
def test_pattern_index_lists_the_patterns_present_and_each_particles_place_among_them(nf):
    """The same groups and indices by a bincount (nf <= 16) or a sort (beyond, where a bincount
    would span 2^nf codes), and within_mode_cov the same bits as with its one-hot product."""
    rng = np.random.default_rng(nf)
    modes = np.zeros((nf, 500), dtype=bool)
    modes[rng.integers(0, nf, 60), rng.integers(0, 500, 60)] = True
    code = mode_codes(modes)
    groups, inv = pattern_index(code, nf)
    np.testing.assert_array_equal(groups, np.unique(code))
    np.testing.assert_array_equal(groups[inv], code)
    X, w = rng.standard_normal((7, 500)), rng.random(500) / 500
    member = code == groups[:, None]
    means = ((member * w) @ X.T) / (member * w).sum(axis=1)[:, None]
    means[(member * w).sum(axis=1) < 0.05] = X @ w
    dX = X - means.T @ member
    assert np.array_equal(within_mode_cov(X, w, modes), (dX * w) @ dX.T)


def test_per_mode_jitter_leaves_mode0_fault_entries_exactly_zero():
    X_prev, modes, w = _cloud(seed=6, modes_on=N // 4)
    idx = np.random.default_rng(7).integers(0, N, N)
    X = X_prev[:, idx].copy()
    PerModeJitter(0.3, np.array([1.0, 1.0])).jitter(X, X_prev, w, idx, modes, None, np.random.default_rng(8))
    moved = modes[:, idx]
    assert np.all(X[5:][~moved] == 0.0)
    assert np.all(X[5:][moved] != X_prev[5:, idx][moved])
    assert not PerModeJitter.needs_covariance and GlobalJitter.needs_covariance


# ----------------------------------------------------------------------------- recipes
def test_the_recipe_table_is_the_single_list_of_filters():
    assert FILTER_NAMES == tuple(RECIPES)
    assert set(PARTICLE_FILTERS) == {k for k, r in RECIPES.items() if r.family == "particle"}
    with pytest.raises(ValueError, match="unknown filter 'XPF'"):
        recipe("XPF")


@pytest.mark.parametrize("name,jump,transition,correction,regulariser", [
    ("bootstrap", NoJump, None, Likelihood, NoJitter),
    ("RPF", NoJump, None, Likelihood, GlobalJitter),
    ("RRPF", NoJump, None, KalmanCorrection, GlobalJitter),
    ("JMRPF", MarkovJump, FixedTransition, Likelihood, PerModeJitter),
    ("RJMRPF", MarkovJump, FixedTransition, KalmanCorrection, PerModeJitter),
    ("AJMRPF", MarkovJump, AdaptiveTransition, Likelihood, PerModeJitter),
    ("ARJMRPF", MarkovJump, AdaptiveTransition, KalmanCorrection, PerModeJitter),
])
def test_each_recipe_builds_its_parts(name, jump, transition, correction, regulariser):
    f = build_filter(name, load_estimator(), np.random.default_rng(0), particles=50)
    assert type(f.parts.jump) is jump and type(f.parts.correction) is correction
    assert type(f.parts.regulariser) is regulariser
    if transition is not None:
        assert type(f.parts.jump.transition) is transition
    assert isinstance(f.parts.resample_due, EveryStep if name == "bootstrap" else BelowEffectiveSize)
    assert f.adaptive == (transition is AdaptiveTransition)


def test_thesis_recipes_force_the_thesis_adaptive_matrix():
    est = load_estimator()
    assert est.settings.adaptive_transition == "proposal"
    assert build_filter("AJMRPF", est, np.random.default_rng(0), particles=50).parts.jump.transition.proposal
    thesis = build_filter("AJMRPF-thesis", est, np.random.default_rng(0), particles=50)
    assert not thesis.parts.jump.transition.proposal
