"""The drift fault type on its own (fdir_service/estimation/drift_type.py): a mode-1 drift entry
ramps at its particle's rate, the rates follow their particles through resampling, exits and a
fresh cloud, a new drift fault gets a rate from its offset, the user reads the rate, and an
estimator without drift entries is built exactly as before."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.drift_type import (
    RATE_LOG_WEIGHT_FLOOR,
    T_MAX_S,
    T_MIN_S,
    ClimbOffsetSlope,
    DriftAnchor,
    DriftCorrection,
    DriftJump,
    OffsetSlope,
    alpha_beta,
    rate_log_weight,
)
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.jump import MarkovJump
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimator_config import ConfigError, estimator_document, load_estimator, parse_estimator
from fdir_service.runtime.items import TYPE_NAMES, type_code
from fdir_service.runtime.publishing import statustext_for

DT = 0.05
ROWS = ("baro_alt", "theta")
LAYOUT = FaultLayout(("baro", "baro_dr"), ("sensor", "sensor"), ("baro_alt", "baro_alt"), ROWS,
                     ("bias", "drift"))
MEAS = MeasurementModel.build(LAYOUT, np.array([1.5, 0.015]))


class StillJump:
    """A jump that changes no mode (what DriftJump wraps, reduced to its interface)."""

    sentinels = np.zeros((2, 0), dtype=bool)

    def jump(self, X, modes, w, frame, rng):
        return None

    def pin(self, X, modes):
        pass

    def reinitialise(self, modes):
        pass

    def resample_modes(self, modes, idx):
        return np.take(modes, idx, axis=1)

    def fault_probability(self, X, modes, w):
        return modes @ w

    def annotate(self, out):
        pass


def frame(t: float = 1.0, y=(500.0, 0.05)) -> Frame:
    return Frame.of(t, np.array(y), np.ones(2, dtype=bool), np.zeros(2), MEAS)


def drift_estimator(**fault):
    """aerosonde-robust plus a barometer drift entry (its keys overridden by `fault`)."""
    doc, _ = estimator_document("aerosonde-robust")
    entry = {"id": "baro_dr", "target": "baro_alt", "type": "drift", "unit": "m", "sigma_f": 0.02,
             "rate_sigma": 0.03, "amplitude_max": 500.0} | fault
    doc["faults"] = list(doc["faults"]) + [entry]
    return parse_estimator(doc, "drift.toml")


def test_a_mode_1_drift_entry_ramps_at_its_rate_and_a_mode_0_one_stays():
    part = DriftJump(StillJump(), np.array([1]), DT, np.zeros(1), 3)
    part.R[0] = [0.5, -0.2, 0.0]                         # m/s; particle 2 is in mode 0
    modes = np.array([[False] * 3, [True, True, False]])
    X = np.zeros((LAYOUT.n, 3))
    for _ in range(40):                                  # 2 s
        part.jump(X, modes, np.full(3, 1 / 3), frame(), np.random.default_rng(0))
    np.testing.assert_allclose(X[N_AIRFRAME + 1], [1.0, -0.4, 0.0], atol=1e-12)
    assert not X[N_AIRFRAME].any()                       # the bias entry is no ramp


def test_the_rate_walks_with_rate_sigma_in_mode_1_only():
    part = DriftJump(StillJump(), np.array([1]), DT, np.array([0.1]), 20000)
    modes = np.zeros((2, 20000), dtype=bool)
    modes[1, :10000] = True
    X = np.zeros((LAYOUT.n, 20000))
    part.jump(X, modes, np.full(20000, 1 / 20000), frame(), np.random.default_rng(1))
    assert part.R[0, :10000].std() == pytest.approx(0.1 * np.sqrt(DT), rel=0.05)
    assert not part.R[0, 10000:].any()


def test_the_rates_follow_their_particles_when_resampled_and_vanish_on_exit():
    part = DriftJump(StillJump(), np.array([1]), DT, np.zeros(1), 4)
    part.R[0] = [0.1, 0.2, 0.3, 0.4]
    modes = np.ones((2, 4), dtype=bool)
    out = part.resample_modes(modes, np.array([3, 3, 0, 2]))
    np.testing.assert_array_equal(part.R[0], [0.4, 0.4, 0.1, 0.3])
    out[1, 1] = False                                    # particle 1 left mode 1
    part.pin(np.zeros((LAYOUT.n, 4)), out)
    np.testing.assert_array_equal(part.R[0], [0.4, 0.0, 0.1, 0.3])


def test_the_filter_resamples_the_rates_with_the_cloud():
    filt = build_filter("RJMRPF", drift_estimator(), np.random.default_rng(0), particles=50)
    jump = filt.parts.jump
    assert isinstance(jump, DriftJump) and isinstance(filt.parts.correction, DriftCorrection)
    j = jump.faults[0]
    filt.modes[j] = True
    jump.R[0] = np.arange(50.0)
    w = np.zeros(50)
    w[7] = 1.0
    filt._resample(w)                                    # every particle is a copy of particle 7
    np.testing.assert_array_equal(jump.R[0], np.full(50, 7.0))


def test_a_fresh_cloud_gives_its_mode_1_particles_the_last_mean_rate():
    part = DriftJump(StillJump(), np.array([1]), DT, np.zeros(1), 4)
    part.R[0] = [0.2, 0.4, 0.0, 0.0]
    modes = np.array([[False] * 4, [True, True, False, False]])
    part.fault_probability(np.zeros((LAYOUT.n, 4)), modes, np.array([0.25, 0.75, 0.0, 0.0]))
    assert part.rate_if_faulty[0] == pytest.approx(0.35)
    part.reinitialise(np.ones((2, 4), dtype=bool))
    np.testing.assert_allclose(part.R[0], 0.35)


def test_a_new_drift_fault_takes_a_rate_from_its_offset():
    """Proposal offset / T, T log-uniform on [1, 30] s (no window): same sign, |r| <= |offset|."""
    class Enter(StillJump):
        def jump(self, X, modes, w, frame, rng):
            modes[1] = True
            X[N_AIRFRAME + 1] = 6.0                         # the jump's amplitude A
    part = DriftJump(Enter(), np.array([1]), DT, np.zeros(1), 5000)
    X = np.zeros((LAYOUT.n, 5000))
    part.jump(X, np.zeros((2, 5000), dtype=bool), np.full(5000, 2e-4), frame(), np.random.default_rng(2))
    r = part.R[0]
    assert (r > 6.0 / 30 - 1e-9).all() and (r < 6.0 + 1e-9).all()
    assert np.median(r) == pytest.approx(6.0 / np.sqrt(30.0), rel=0.1)


def test_a_rate_is_weighed_by_its_prior_over_its_proposal():
    """faults.rate_max: log p(r) - log q(r) with p uniform on +-rate_max and q the proposal's
    density, capped at 0; a rate the proposal could not draw takes the floor."""
    log_p = np.full(3, -np.log(10.0))                                # rate_max 5
    offset = np.full(3, 6.0)
    r = np.array([1.0, 6.0, -1.0])
    term = rate_log_weight(r, offset, log_p, None)
    q1 = 1.0 / (1.0 * np.log(T_MAX_S / T_MIN_S))                      # offset / T, T log-uniform
    assert term[0] == pytest.approx(-np.log(10.0) - np.log(q1))       # about -1.1 nats
    assert term[1] == 0.0                                             # p > q there: capped
    assert term[2] == RATE_LOG_WEIGHT_FLOOR                           # the wrong sign: never drawn
    b, s = np.full(3, 1.0), np.full(3, 0.2)                           # a window's slope 1 +- 0.2
    mixed = rate_log_weight(r, offset, log_p, (b, s))
    qn = np.exp(0.0) / (np.sqrt(2 * np.pi) * 0.2)
    assert mixed[0] == pytest.approx(-np.log(10.0) - np.log(0.5 * q1 + 0.5 * qn))   # about -2.3


def test_new_drift_faults_carry_their_rate_weight_and_no_other_particle_does():
    class Enter(StillJump):
        def jump(self, X, modes, w, frame, rng):
            modes[1, ::2] = True
            X[N_AIRFRAME + 1, ::2] = 6.0
    X = np.zeros((LAYOUT.n, 10))
    args = (X, np.zeros((2, 10), dtype=bool), np.full(10, 0.1), frame())
    plain = DriftJump(Enter(), np.array([1]), DT, np.zeros(1), 10)
    assert plain.jump(*args, np.random.default_rng(4)) is None       # no rate_max: as before
    X[:] = 0.0
    args[1][:] = False
    part = DriftJump(Enter(), np.array([1]), DT, np.zeros(1), 10, rate_max=np.array([5.0]))
    lw = part.jump(*args, np.random.default_rng(4))
    np.testing.assert_array_equal(part.R, plain.R)                   # the same draws
    expected = rate_log_weight(part.R[0, ::2], np.full(5, 6.0), np.full(5, -np.log(10.0)), None)
    np.testing.assert_allclose(lw[::2], expected)
    assert (lw[::2] < 0).all() and not lw[1::2].any()


def test_a_rate_max_belongs_to_a_drift():
    with pytest.raises(ConfigError, match=r"rate_max.*only a drift has a rate"):
        drift_estimator(type="bias", rate_max=2.0)
    assert drift_estimator(rate_max=2.0).faults[-1].rate_max == 2.0


def test_the_offset_window_measures_a_ramps_slope():
    win = OffsetSlope(np.array([0]), MEAS.H, 60)
    X = np.zeros((LAYOUT.n, 1))
    X[0] = -500.0                                        # p_d: 500 m up
    noise = np.random.default_rng(3).normal(0.0, 1.0, 60)
    for k in range(60):
        win.observe(X, np.ones(1), frame(k * DT, (500.0 + 0.8 * k * DT + noise[k], 0.0)))
    b, se = win.slope()
    assert abs(b[0] - 0.8) < 3 * se[0] and se[0] < 0.3


def test_the_climb_window_sees_a_ramp_the_cloud_followed():
    """parts.drift_window = "climb" (`ClimbOffsetSlope`): the barometer ramps 1 m/s above a 2 m/s
    climb and the cloud's altitude has followed it; against the cloud the window sees no slope,
    against the climb the u, w, theta readings integrate to it sees the ramp."""
    rows = ("baro_alt", "u", "w", "theta")
    layout = FaultLayout(("baro_dr",), ("sensor",), ("baro_alt",), rows, ("drift",))
    meas = MeasurementModel.build(layout, np.array([1.5, 1.5, 1.5, 0.015]))
    plain = OffsetSlope(np.array([0]), meas.H, 60)
    climb = ClimbOffsetSlope(np.array([0]), meas.H, 60, (1, 2, 3), DT)
    theta = np.arcsin(2.0 / 40.0)                      # u = 40 m/s, w = 0: a 2 m/s climb
    noise = np.random.default_rng(3).normal(0.0, 1.0, 60)
    for k in range(60):
        baro = 500.0 + 3.0 * k * DT + noise[k]          # 2 m/s climb + 1 m/s ramp
        X = np.zeros((layout.n, 1))
        X[0] = -(500.0 + 3.0 * k * DT)                  # the cloud bent to the barometer
        f = Frame.of(k * DT, np.array([baro, 40.0, 0.0, theta]), np.ones(4, bool), np.zeros(2), meas)
        plain.observe(X, np.ones(1), f)
        climb.observe(X, np.ones(1), f)
    (b0,), (se0,) = plain.slope()
    (b1,), (se1,) = climb.slope()
    assert abs(b0) < 3 * se0 and abs(b1 - 1.0) < 3 * se1 and se1 < 0.3
    assert load_estimator("aerosonde-catalogue").settings.drift_window == "offset"


def _climb_flight(climb: ClimbOffsetSlope, layout: FaultLayout, meas: MeasurementModel, frames: int,
                  baro, theta_read: float, theta_entry: float) -> None:
    """Feed `climb` frames of a level cloud at 500 m (u = 40 m/s, w = 0) whose attitude entry holds
    theta_entry; baro(k) the barometer's reading at frame k, theta_read the attitude reading."""
    X = np.zeros((layout.n, 1))
    X[0] = -500.0
    X[N_AIRFRAME + 1] = theta_entry
    for k in range(frames):
        f = Frame.of(k * DT, np.array([baro(k), 40.0, 0.0, theta_read]), np.ones(4, bool), np.zeros(2), meas)
        climb.observe(X, np.ones(1), f)


def _climb_layout() -> tuple[FaultLayout, MeasurementModel]:
    rows = ("baro_alt", "u", "w", "theta")
    layout = FaultLayout(("baro_dr", "theta"), ("sensor", "sensor"), ("baro_alt", "theta"), rows,
                         ("drift", "bias"))
    return layout, MeasurementModel.build(layout, np.array([1.5, 1.5, 1.5, 0.015]))


def test_the_climb_window_takes_the_attitude_less_its_believed_offset():
    """A 2-deg attitude bias the cloud holds in its entry does not climb: with the entry taken out
    the level barometer shows no slope; read as it stands, the attitude climbs 1.4 m/s."""
    layout, meas = _climb_layout()
    bias = np.radians(2.0)
    noise = np.random.default_rng(5).normal(0.0, 1.0, 60)
    guarded = ClimbOffsetSlope(np.array([0]), meas.H, 60, (1, 2, 3), DT, np.array([1]), np.array([1.5]))
    bare = ClimbOffsetSlope(np.array([0]), meas.H, 60, (1, 2, 3), DT)
    for win in (guarded, bare):
        _climb_flight(win, layout, meas, 60, lambda k: 500.0 + noise[k], bias, bias)
    (b0,), (se0,) = guarded.slope()
    (b1,), (se1,) = bare.slope()
    assert abs(b0) < 3 * se0 and se0 < 0.3
    assert abs(b1 + 40.0 * np.sin(bias)) < 3 * se1


def test_the_climb_window_restarts_at_a_step_of_its_offset():
    """A barometer ramp of 1 m/s that ends with its 15 m step back: the window that spans the
    step reads a slope of metres per second; the guarded one restarts there and reads ~0 after."""
    layout, meas = _climb_layout()
    noise = np.random.default_rng(7).normal(0.0, 1.0, 120)
    ramp = lambda k: 500.0 + noise[k] + (15.0 * k / 59 if k < 60 else 0.0)     # noqa: E731
    guarded = ClimbOffsetSlope(np.array([0]), meas.H, 60, (1, 2, 3), DT, np.array([1]), np.array([1.5]))
    bare = ClimbOffsetSlope(np.array([0]), meas.H, 60, (1, 2, 3), DT)
    for win in (guarded, bare):
        _climb_flight(win, layout, meas, 90, ramp, 0.0, 0.0)       # 30 frames past the step
    (b0,), (se0,) = guarded.slope()
    (b1,), _ = bare.slope()
    assert np.isfinite(guarded.a[0]).sum() == 30                   # only the frames since the step
    assert abs(b0) < 3 * se0 and b1 < -3.0


def test_the_correction_moves_a_lagging_rate_and_its_offset_towards_the_data():
    part = DriftJump(StillJump(), np.array([1]), DT, np.array([0.03]), 2)
    inner_calls = []

    class Inner:
        def update(self, X, w, modes, frame):
            inner_calls.append(1)
            return np.zeros(2)

    corr = DriftCorrection(Inner(), part, np.array([0]), np.array([1.5]))
    X = np.zeros((LAYOUT.n, 2))
    X[0] = -500.0
    modes = np.array([[False, False], [True, False]])
    corr.update(X, np.full(2, 0.5), modes, frame(y=(502.0, 0.0)))  # the reading 2 m above
    assert part.R[0, 0] > 0.0 and part.R[0, 1] == 0.0 and inner_calls
    alpha, beta = alpha_beta(np.array([0.03]), np.array([1.5]), DT)
    assert part.R[0, 0] == pytest.approx(beta[0] / DT * 2.0)
    assert 0 < beta[0] < alpha[0] < 1
    # a mode-1 offset moves by its own alpha gain (whatever the cloud's correction did)
    assert X[N_AIRFRAME + 1, 0] == pytest.approx(alpha[0] * 2.0) and X[N_AIRFRAME + 1, 1] == 0.0


def test_the_user_reads_the_rate_while_the_estimate_stays_the_offset():
    part = DriftJump(StillJump(), np.array([1]), DT, np.zeros(1), 2)
    part.R[0] = [0.3, 0.0]
    modes = np.array([[False, False], [True, False]])
    part.fault_probability(np.zeros((LAYOUT.n, 2)), modes, np.array([0.9, 0.1]))
    x = np.zeros(LAYOUT.n)
    x[N_AIRFRAME:] = [0.0, 4.0]
    out = StepOutput(1.0, x, None, LAYOUT.fault_ids, x[N_AIRFRAME:].copy(), np.array([0.0, 0.9]), 2.0, False)
    part.annotate(out)
    assert out.fault_value[1] == pytest.approx(0.3) and out.fault_estimate[1] == 4.0
    est = drift_estimator()
    text = statustext_for(est.faults[-1], 0.3, 0.95, True, "drift", "baro")
    assert text == "FDIR baro drift +0.30 m/s p=0.95"
    assert TYPE_NAMES[type_code("drift")] == "drift"


def test_a_drift_estimator_runs_and_reports_its_type():
    est = drift_estimator()
    assert est.faults[-1].fault_type == "drift" and est.faults[-1].rate_sigma == 0.03
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=200)
    m = len(est.measurements)
    y = np.array([500.0, 500.0, 40.0, 1.0, 0.03, 0.0, 0.0, -9.8, 40.0, 0.0, 0.0])[:m]
    out = filt.step(0.05, y, np.ones(m, dtype=bool), np.array([-0.03, 0.5]))
    assert out.fault_types[-1] == "drift" and np.isfinite(out.fault_value).all()


@pytest.mark.parametrize("name", ["aerosonde", "aerosonde-robust"])
def test_an_estimator_without_drift_entries_has_no_drift_parts(name):
    filt = build_filter("RJMRPF", load_estimator(name), np.random.default_rng(0), particles=50)
    assert isinstance(filt.parts.jump, MarkovJump)
    assert not isinstance(filt.parts.correction, DriftCorrection)


def test_without_drift_entries_the_same_seed_gives_the_same_bits_after_a_fresh_cloud():
    """The new `reinitialise` hook draws nothing: two filters stay bit-identical through one."""
    est = load_estimator("aerosonde-robust")
    outs = []
    for _ in range(2):
        filt = build_filter("RJMRPF", est, np.random.default_rng(5), particles=100)
        m = len(est.measurements)
        y = np.array([500.0, 500.0, 40.0, 1.0, 0.03, 0.0, 0.0, -9.8, 40.0, 0.0, 0.0])[:m]
        filt._reinitialise(filt.x_mean)
        outs.append(filt.step(0.05, y, np.ones(m, dtype=bool), np.array([-0.03, 0.5])))
    np.testing.assert_array_equal(outs[0].x_mean, outs[1].x_mean)


def test_a_drift_that_ends_re_anchors_half_its_particles_state_on_the_reading():
    """Particles 0-3 leave the drift with their item free; particle 4 hands over to the bias."""
    siblings = np.array([[True, False]])                 # the bias is the drift's sibling
    anchor = DriftAnchor(np.array([0]), MEAS.H, siblings)
    X = np.zeros((LAYOUT.n, 5))
    X[0] = -500.0                                        # the state reads 500 m ...
    y = (506.0, 0.0)                                     # ... the barometer 506 m, after a 20 m drift
    dist = anchor.innovation(X, frame(y=y))
    left = np.array([[True, True, True, True, True]])
    modes = np.array([[False, False, False, False, True], [False] * 5])
    anchor.apply(X, dist, np.full((1, 5), 20.0), left, modes, np.random.default_rng(4))
    moved = X[0] != -500.0
    assert 0 < moved[:4].sum() < 4 and not moved[4]     # about half; never after a hand-over
    np.testing.assert_allclose(X[0, moved], -506.0)     # onto the reading
    X[0] = -500.0                                        # a reading that still carries the drift:
    anchor.apply(X, dist, np.full((1, 5), 8.0), left, modes, np.random.default_rng(4))
    assert (X[0] == -500.0).all()                        # no anchor (|6| >= 8 / 2)
