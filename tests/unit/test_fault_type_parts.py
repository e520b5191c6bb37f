"""The fault-type parts on their own (fdir_service/estimation/fault_types.py): how stuck, jammed,
weakened and noisy entries evolve, how the correction treats them, how a noisy fault is proposed,
what a user reads, and the estimator file's checks."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.correction import Likelihood
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.fault_types import (
    NoisySentinels,
    TypedCorrection,
    TypedEvolution,
    TypedPredict,
)
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.sentinels import ThesisSentinels
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator

ROWS = ("baro_alt", "theta", "q")
SIGMA = np.array([1.5, 0.015, 0.003])
# theta bias, theta stuck, baro noisy, elevator jammed, throttle effectiveness
LAYOUT = FaultLayout(("th", "th_st", "baro_nz", "de_jam", "dt_eff"),
                     ("sensor", "sensor", "sensor", "actuator", "actuator"),
                     ("theta", "theta", "baro_alt", "delta_e", "delta_t"), ROWS,
                     ("bias", "stuck", "noisy", "jammed", "effectiveness"))
MEAS = MeasurementModel.build(LAYOUT, SIGMA)


def cloud(N: int = 4) -> np.ndarray:
    X = np.zeros((LAYOUT.n, N))
    X[0] = -500.0
    X[3] = 0.05
    return X


def test_a_noisy_entry_is_not_in_the_measurement_matrix_and_the_others_add_to_their_row():
    H = MEAS.H
    assert H[1, N_AIRFRAME + 0] == 1.0 and H[1, N_AIRFRAME + 1] == 1.0
    assert not H[:, N_AIRFRAME + 2].any()
    assert LAYOUT.noisy_row.tolist() == [-1, -1, 0, -1, -1]
    assert LAYOUT.sensor_row.tolist() == [1, 1, -1, -1, -1]


def test_stuck_entries_in_mode_1_hold_their_reading_while_the_state_moves():
    ev = TypedEvolution(LAYOUT, MEAS.H)
    X = cloud()
    X[N_AIRFRAME + 1] = [0.01, 0.01, 0.0, 0.0]
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    modes[1, :2] = True
    z_before = X[:N_AIRFRAME].copy()
    reading_before = MEAS.H[1] @ X
    X[3] += 0.1                                        # every particle pitches up 0.1 rad
    ev.apply(z_before, X, modes, np.zeros(2), None)
    reading = MEAS.H[1] @ X
    np.testing.assert_allclose(reading[:2], reading_before[:2])          # stuck: held
    np.testing.assert_allclose(reading[2:] - reading_before[2:], 0.1)    # working: follows


def test_a_jammed_actuator_holds_its_position_and_a_weak_one_scales_the_command_change():
    ev = TypedEvolution(LAYOUT, MEAS.H)
    X = cloud(2)
    modes = np.ones((LAYOUT.nf, 2), dtype=bool)
    X[N_AIRFRAME + 3] = 0.02                            # jammed 0.02 rad off the command -0.03
    X[N_AIRFRAME + 4] = -0.3 * 0.5                      # throttle at 70 % effectiveness, command 0.5
    u_prev, u = np.array([-0.03, 0.5]), np.array([0.01, 0.6])
    ev.apply(X[:N_AIRFRAME].copy(), X, modes, u, u_prev)
    np.testing.assert_allclose(u[0] + X[N_AIRFRAME + 3], -0.03 + 0.02)     # held at -0.01
    np.testing.assert_allclose(u[1] + X[N_AIRFRAME + 4], 0.7 * 0.6)         # 70 % of the new command


def test_effectiveness_gain_loss_is_clipped_to_a_physical_gain():
    phi = TypedEvolution.gain_loss(np.array([-0.9, 0.3, -0.2, 0.1]), np.array([0.5, 0.5, 0.0, -0.5]))
    np.testing.assert_allclose(phi, [-1.0, 0.0, 0.0, -0.2])


ENGINE = FaultLayout(("dt", "dt_eng"), ("actuator", "actuator"), ("delta_t", "delta_t"), ROWS,
                     ("bias", "engine"))
K_MOTOR = 80.0                                           # the Aerosonde's: zero thrust at V / 80


def test_a_dead_engine_entry_holds_the_delivered_throttle_at_the_airspeed_over_k_m():
    ev = TypedEvolution(ENGINE, MeasurementModel.build(ENGINE, SIGMA).H, k_motor=K_MOTOR)
    X = np.zeros((ENGINE.n, 2))
    modes = np.zeros((ENGINE.nf, 2), dtype=bool)
    modes[1, 0] = True                                   # particle 0 holds the engine dead
    X[N_AIRFRAME + 1] = 40.0 / K_MOTOR - 0.6             # delivers V / k_m = 0.5 at the command 0.6
    u_prev = np.array([0.0, 0.6, 0.0, -9.8, 40.0])       # [de, dt, ax, az, V]: the process input
    u = np.array([0.0, 1.0, 0.0, -9.8, 38.0])            # the autopilot opens the throttle, V decays
    ev.apply(None, X, modes, u, u_prev)
    np.testing.assert_allclose(u[1] + X[N_AIRFRAME + 1, 0], 38.0 / K_MOTOR)    # still no thrust
    assert X[N_AIRFRAME + 1, 1] == 40.0 / K_MOTOR - 0.6                        # mode 0: unmoved


def test_an_engine_entry_reads_as_the_share_of_the_commanded_thrust_it_gives():
    ev = TypedEvolution(ENGINE, MeasurementModel.build(ENGINE, SIGMA).H, k_motor=K_MOTOR)
    u = np.array([0.0, 1.0, 0.0, -9.8, 40.0])            # full throttle at 40 m/s: c = 0.5
    f = np.array([0.5 - 1.0, 0.0, np.sqrt(0.5 * 1.0 + 0.5 * 0.25) - 1.0, 0.3])
    np.testing.assert_allclose(ev.thrust_share(f, u), [0.0, 1.0, 0.5, 1.0])   # dead, healthy, half, clipped
    idle = np.array([0.0, 0.5, 0.0, -9.8, 40.0])         # the command asks for no thrust: nothing to share
    np.testing.assert_array_equal(ev.thrust_share(f, idle), 0.0)


ENGINE_ENTRY = {"id": "dt_eng", "target": "delta_t", "type": "engine", "unit": "1", "sigma_f": 0.002,
                "amplitude_max": 1.0}


@pytest.mark.parametrize("estimator, change, match", [
    ("aerosonde-catalogue", lambda d: d["faults"][4].update(type="engine"), r"faults\[4\]\.type.*throttle"),
    ("aerosonde", lambda d: d["faults"].append(ENGINE_ENTRY), r"engine fault.*kinematic"),
])
def test_an_engine_fault_needs_the_throttle_and_the_thrust_check(estimator, change, match):
    doc, _ = estimator_document(estimator)
    change(doc)
    with pytest.raises(ConfigError, match=match):
        parse_estimator(doc, "x.toml")


def test_an_entry_is_held_within_its_value_max_not_its_jump_prior():
    est = load_estimator("aerosonde-catalogue")
    spec = {f.id: f for f in est.faults}
    assert spec["de_jam"].amplitude_max == pytest.approx(np.radians(15.0))
    assert spec["de_jam"].bound == pytest.approx(np.radians(60.0))          # the surface's travel
    assert spec["de"].bound == spec["de"].amplitude_max                    # default: the prior
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=50)
    np.testing.assert_allclose(filt.parts.predict.inner.bound[:, 0], [f.bound for f in est.faults])


def test_a_value_max_below_the_jump_prior_fails_naming_the_key():
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["faults"][4]["value_max"] = 5.0                                    # de: amplitude_max 15 deg
    with pytest.raises(ConfigError, match=r"faults\[4\]\.value_max: expected at least amplitude_max"):
        parse_estimator(doc, "x.toml")


def frame(y: np.ndarray) -> Frame:
    return Frame.of(1.0, y, np.ones(3, dtype=bool), np.zeros(2), MEAS)


def test_a_noisy_mode_1_particle_wins_on_a_wild_reading_and_loses_on_a_quiet_one():
    ev = TypedEvolution(LAYOUT, MEAS.H)
    corr = TypedCorrection(Likelihood(), ev, np.maximum(LAYOUT.sensor_row, LAYOUT.noisy_row), SIGMA)
    X = cloud(2)
    X[N_AIRFRAME + 2] = [0.0, 3.0]                      # k = 1 and k = 4
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    modes[2, 1] = True
    w = np.full(2, 0.5)
    y_base = MEAS.H @ X[:, 0]
    wild = corr.update(X.copy(), w, modes, frame(y_base + np.array([6.0, 0, 0])))     # 4 sigma off
    quiet = corr.update(X.copy(), w, modes, frame(y_base))
    assert wild[1] - wild[0] > 3.0
    assert quiet[1] - quiet[0] < -1.0


def test_the_correction_holds_a_stuck_reading_and_a_noisy_entry():
    class MoveEverything:
        def update(self, X, w, modes, frame):
            X += 0.1
            return np.zeros(X.shape[1])

    ev = TypedEvolution(LAYOUT, MEAS.H)
    corr = TypedCorrection(MoveEverything(), ev, np.maximum(LAYOUT.sensor_row, LAYOUT.noisy_row), SIGMA)
    X = cloud(2)
    X[N_AIRFRAME + 2] = 2.0
    modes = np.ones((LAYOUT.nf, 2), dtype=bool)
    corr.update(X, np.full(2, 0.5), modes, frame(MEAS.H @ X[:, 0]))
    np.testing.assert_allclose(X[N_AIRFRAME + 0], 0.1)                  # a bias is corrected
    np.testing.assert_allclose(X[3] + X[N_AIRFRAME + 1], 0.05)          # a stuck reading held
    np.testing.assert_allclose(X[N_AIRFRAME + 2], 2.0)                  # a noisy k held


def test_a_new_noisy_fault_is_drawn_from_its_prior_of_k():
    part = NoisySentinels(ThesisSentinels(), np.array([2]), np.array([1.0]), np.array([9.0]))
    X = cloud(1000)
    sent = np.zeros((LAYOUT.nf, 1000), dtype=bool)
    sent[2, :500] = True
    part.weigh(X, frame(np.zeros(3)), sent, np.random.default_rng(0))
    k1 = X[N_AIRFRAME + 2]
    k = 1.0 + k1[:500]                                  # log-uniform on [2, 10]: P(k < 4) = ln 2 / ln 5
    assert 2.0 <= k.min() and k.max() <= 10.0 and abs((k < 4.0).mean() - np.log(2) / np.log(5)) < 0.05
    assert not k1[500:].any()


def test_what_a_user_reads_per_type():
    class Still:
        process = None

        def predict(self, X, modes, u, rng):
            return X.copy()

        def annotate(self, out):
            pass

    from fdir_service.estimation.base import StepOutput

    pred = TypedPredict(Still(), TypedEvolution(LAYOUT, MEAS.H), LAYOUT)
    pred.predict(cloud(1), np.zeros((LAYOUT.nf, 1), dtype=bool), np.array([-0.03, 0.5]), None)
    x = cloud(1)[:, 0]
    x[N_AIRFRAME:] = [0.01, 0.02, 3.0, 0.02, -0.25]
    out = StepOutput(1.0, x, None, LAYOUT.fault_ids, x[N_AIRFRAME:].copy(), np.zeros(5), 1.0, False)
    pred.annotate(out)
    assert out.fault_types == LAYOUT.types and out.type_of(2) == "noisy"
    np.testing.assert_allclose(out.fault_value, [0.01, 0.05 + 0.02, 4.0, -0.03 + 0.02, 0.5])


def test_the_catalogue_estimator_runs_one_step_with_every_type_and_reports_them():
    est = load_estimator("aerosonde-catalogue")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=200)
    m = len(est.measurements)
    y = np.array([500.0, 500.0, 40.0, 1.0, 0.03, 0.0, 0.0, -9.8, 40.0, 0.0, 0.0])[:m]
    out = filt.step(0.05, y, np.ones(m, dtype=bool), np.array([-0.03, 0.5]))
    assert set(out.fault_types) == {"bias", "stuck", "noisy", "drift", "jammed", "effectiveness", "blocked",
                                    "engine"}
    assert np.isfinite(out.fault_value).all()


@pytest.mark.parametrize("target, kind", [("delta_e", "noisy"), ("theta", "jammed"), ("q", "blocked")])
def test_a_fault_type_that_does_not_fit_its_target_fails_naming_the_key(target, kind):
    doc, _ = estimator_document("aerosonde-robust")
    doc["faults"][2]["target"] = target
    doc["faults"][2]["type"] = kind
    doc["faults"][2]["on_exit"] = "reset"
    with pytest.raises(ConfigError, match=r"faults\[2\]\.type"):
        parse_estimator(doc, "x.toml")


def test_only_a_bias_folds_into_the_state():
    doc, _ = estimator_document("aerosonde-robust")
    doc["faults"][2]["type"] = "stuck"                  # theta, on_exit = "reset_or_fold"
    with pytest.raises(ConfigError, match="only a bias"):
        parse_estimator(doc, "x.toml")


def test_a_stuck_sensor_that_leaves_mode_1_re_anchors_half_its_particles_on_the_reading():
    from fdir_service.estimation.fault_types import TypeSwitch, sibling_pairs

    ev = TypedEvolution(LAYOUT, MEAS.H)
    part = TypeSwitch(sibling_pairs(LAYOUT), 0.0, ev, LAYOUT.sensor_row)
    X = cloud(3)
    X[N_AIRFRAME + 1] = 0.02                            # held 0.02 rad above each particle's theta
    modes = np.zeros((LAYOUT.nf, 3), dtype=bool)
    modes[1] = True
    v = np.full((LAYOUT.nf, 3), 0.9)
    v[1] = [0.001, 0.009, 0.5]              # pi10 = 0.01: anchors (< 0.005), resets, stays
    y = MEAS.H @ X[:, 0] - X[N_AIRFRAME + 1, 0] + 0.1   # the sensor is back, reading theta + 0.1
    innov = y[:, None] - MEAS.H @ X
    vals = part.anchor(X[N_AIRFRAME:], modes, v, np.full((LAYOUT.nf, 1), 0.01), innov, frame(y))
    part.apply_anchor(X, vals)
    np.testing.assert_allclose(X[3], [0.05 + 0.1, 0.05, 0.05])       # only the first moved, onto it
    no_theta = Frame.of(1.0, y, np.array([True, False, True]), np.zeros(2), MEAS)
    assert part.anchor(X[N_AIRFRAME:], modes, v, np.full((LAYOUT.nf, 1), 0.01), innov,
                       no_theta) is None                             # its row did not arrive


def test_a_noisy_faults_pfa_and_pmd_come_from_the_variance_test():
    from fdir_service.estimation.adaptive import AdaptiveTransition

    tr = AdaptiveTransition(np.array([1.0, 1.0]), window=3, noisy=np.array([False, True]))
    for _ in range(3):
        tr.update(np.array([3.0, 3.0]), np.array([3.0, 3.0]))      # a 3-sigma shift; k - 1 = 3
    shift, variance = tr.pfa.copy(), tr.pfa[1]
    assert 0.0 < variance < 0.2 and 0.0 < tr.pmd[1] < 0.2           # k = 4 over 3 samples: separable
    assert abs(variance - shift[0]) > 0.01                          # not the mean-shift test's figure
    weak = AdaptiveTransition(np.array([1.0]), window=3, noisy=np.array([True]))
    for _ in range(3):
        weak.update(np.array([0.2]), np.array([0.2]))               # k = 1.2: hardly told apart
    assert weak.pfa[0] > tr.pfa[1] and weak.pmd[0] > tr.pmd[1]


def test_the_adaptive_filters_publish_pfa_and_pmd_for_noisy_faults():
    est = load_estimator("aerosonde-catalogue")
    filt = build_filter("ARJMRPF", est, np.random.default_rng(0), particles=200)
    m = len(est.measurements)
    y = np.array([500.0, 500.0, 40.0, 1.0, 0.03, 0.0, 0.0, -9.8, 40.0, 0.0, 0.0])[:m]
    for k in range(4):
        out = filt.step(0.05 * (k + 1), y, np.ones(m, dtype=bool), np.array([-0.08, 0.5]))
    nz = [f.id for f in est.faults].index("baro_nz")
    assert np.isfinite(out.pfa[nz]) and np.isfinite(out.pmd[nz]) and 0.0 <= out.pfa[nz] <= 1.0


def test_a_heavy_pitch_rate_tail_gives_a_share_of_the_particles_wider_pitch_rate_noise():
    from fdir_service.estimation.predict import DriftPredict

    class Still:
        def propagate(self, X, u, modes=None):
            return X.copy()

    q_std = np.r_[np.zeros(4), 0.01, np.zeros(LAYOUT.nf)]
    zeros = np.zeros(LAYOUT.nf)
    plain = DriftPredict(Still(), q_std, zeros, np.full(LAYOUT.nf, np.inf))
    tail = DriftPredict(Still(), q_std, zeros, np.full(LAYOUT.nf, np.inf), (0.05, 15.0))
    X, modes = cloud(20000), np.zeros((LAYOUT.nf, 20000), bool)
    dq = tail.predict(X, modes, np.zeros(2), np.random.default_rng(0))[4]
    dq0 = plain.predict(X, modes, np.zeros(2), np.random.default_rng(0))[4]
    assert abs(np.std(dq0) - 0.01) < 0.0005
    assert abs(np.std(dq) - 0.01 * np.sqrt(0.95 + 0.05 * 225)) < 0.003     # the mixture's spread
    assert (np.abs(dq) > 0.05).mean() > 0.03 > (np.abs(dq0) > 0.05).mean()


def test_each_entry_hands_over_at_its_own_rate():
    """Pair (a, b) hands over at a's pi_switch: theta bias -> stuck always, stuck -> bias never."""
    from fdir_service.estimation.fault_types import TypeSwitch

    pairs = np.array([[0, 1], [1, 0]])
    part = TypeSwitch(pairs, np.array([1.0, 0.0, 0.5, 0.5, 0.5]))
    assert part.rates.tolist() == [1.0, 0.0]
    F = np.zeros((LAYOUT.nf, 4))
    F[0, :2] = 0.03
    F[1, 2:] = 0.04
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    modes[0, :2] = modes[1, 2:] = True
    part.apply(F, modes, None, np.random.default_rng(0))
    assert modes[1].all() and not modes[0].any()               # the bias particles moved, the stuck stayed
    np.testing.assert_allclose(F[1], [0.03, 0.03, 0.04, 0.04])


def test_a_faults_pi_switch_defaults_to_the_filters_and_is_checked():
    doc, _ = estimator_document("aerosonde-catalogue")
    est = parse_estimator(doc, "x.toml")
    rates = dict(zip([f.id for f in est.faults], est.switch_rates(), strict=True))
    assert rates["th_dr"] == 0.002 and rates["th_st"] == est.settings.pi_switch == 0.01
    doc["faults"][0]["pi_switch"] = 1.5
    with pytest.raises(ConfigError, match="pi_switch"):
        parse_estimator(doc, "x.toml")
