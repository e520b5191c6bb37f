"""The robust monitor's parts on their own: the kinematic process model, the IMU rows as inputs,
sensor drift in mode 0 with bounded faults, and the estimator file that assembles them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.inputs import G, RowSplit, trim_specific_force
from fdir_service.estimation.kinematic import KinematicProcess
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimation.predict import DriftPredict
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run

LAYOUT = FaultLayout(("theta",), ("sensor",), ("theta",), ("gnss_alt", "theta"))


@pytest.fixture(scope="module")
def robust():
    return load_estimator("aerosonde-robust")


@pytest.fixture(scope="module")
def turbulent_flight():
    """30 s of a fault-free flight in moderate Dryden turbulence (truth and sensor rows)."""
    sc = load_scenario("real-turbulence-faultfree")
    return sc, run(sc, 5, seconds=30.0)


def test_kinematic_model_predicts_the_truth_in_turbulence_to_the_accelerometer_noise(turbulent_flight):
    sc, tr = turbulent_flight
    names = sc.sensors.measurements
    proc = KinematicProcess(sc.dt_s, FaultLayout((), (), (), ()))
    X = tr.z[:-1].T                                     # (5, K-1): every frame's truth as one cloud
    a = tr.y[1:, [names.index("ax"), names.index("az")]]
    err = np.empty((5, X.shape[1]))
    for k in range(X.shape[1]):                         # one input per frame (the accelerometer's)
        err[:, k] = proc.propagate(X[:, k], np.r_[0.0, 0.0, a[k]]) - tr.z[k + 1]
    dt = sc.dt_s
    # velocity error per frame = dt x (accelerometer noise 0.2 + gust-rate lag): well under 0.05 m/s
    assert np.std(err[1]) < 0.03 and np.std(err[2]) < 0.05
    assert np.std(err[3]) < 1e-3     # theta' = q with q held over the frame (the gusts move q: process noise)
    assert np.std(err[0]) < 0.01                        # the climb rate
    # while the airframe's own aerodynamic model would be off by the gusts (w' std ~ g's order)
    assert np.std(np.diff(tr.z[:, 2]) / dt) > 1.0


def test_kinematic_model_holds_level_flight_on_the_trim_specific_force():
    z = np.array([-500.0, 39.9, 1.9, 0.0476, 0.0])
    proc = KinematicProcess(0.05, FaultLayout((), (), (), ()))
    a = trim_specific_force(z)
    assert a[1] == pytest.approx(-G * np.cos(z[3]))
    nxt = proc.propagate(z, np.r_[0.0, 0.5, a])
    # u, w, theta, q unchanged; the altitude moves by the (tiny) climb rate of this state
    np.testing.assert_allclose(nxt[1:], z[1:], atol=1e-12)
    assert nxt[0] - z[0] == pytest.approx(0.05 * (z[2] * np.cos(z[3]) - z[1] * np.sin(z[3])))


def test_kinematic_model_sees_no_actuator():
    proc = KinematicProcess(0.05, FaultLayout(("de",), ("actuator",), ("delta_e",), ("q",)))
    assert proc.B_actuator.shape == (5, 1) and not proc.B_actuator.any()


def test_row_split_takes_the_accelerometer_out_of_the_rows_and_holds_it(robust):
    split = RowSplit.of(robust, True, np.array([-500.0, 40.0, 2.0, 0.05, 0.0]))
    rows = robust.measurements
    y = np.arange(len(rows), dtype=float)
    mask = np.ones(len(rows), dtype=bool)
    yo, mo, u = split.split(y, mask, np.array([0.1, 0.6]))
    assert list(yo) == [rows.index(r) for r in robust.observed]
    assert mo.all() and list(u) == [0.1, 0.6] + [rows.index(r) for r in ("ax", "az", "airspeed", "roll", "v")]
    mask[rows.index("az")] = False                      # no new az: the last one is held
    y2 = y + 100.0
    _, _, u2 = split.split(y2, mask, np.array([0.1, 0.6]))
    assert u2[2] == rows.index("ax") + 100.0 and u2[3] == rows.index("az")


def test_row_split_drops_the_accelerometer_for_filters_that_do_not_integrate_it(robust):
    split = RowSplit.of(robust, False, np.zeros(5))
    y = np.ones(len(robust.measurements))
    yo, mo, u = split.split(y, y > 0, np.array([0.0, 0.5]))
    assert yo.size == len(robust.observed) == 6 and u.size == 2 and mo.all()


def test_row_split_starts_on_the_trim_specific_force(robust):
    split = RowSplit.of(robust, True, np.array([-500.0, 40.0, 2.0, 0.05, 0.0]))
    np.testing.assert_allclose(split.hold, [G * np.sin(0.05), -G * np.cos(0.05), np.hypot(40.0, 2.0),
                                            0.0, 0.0])


class Still:
    B_actuator = np.zeros((5, 1))

    def propagate(self, X, u, modes=None):
        return X.copy()


def test_drift_predict_gives_mode0_the_drift_noise_and_mode1_the_fault_noise():
    n, N = 6, 200_000
    part = DriftPredict(Still(), np.r_[np.zeros(5), 0.01], np.array([0.001]), np.array([np.inf]))
    modes = np.zeros((1, N), dtype=bool)
    modes[0, N // 2:] = True
    X = part.predict(np.zeros((n, N)), modes, np.zeros(4), np.random.default_rng(0))
    assert np.std(X[5, : N // 2]) == pytest.approx(0.001, rel=0.02)
    assert np.std(X[5, N // 2:]) == pytest.approx(0.01, rel=0.02)
    assert not X[:5].any()


def test_drift_predict_keeps_faults_within_their_prior():
    part = DriftPredict(Still(), np.r_[np.zeros(5), 1.0], np.array([1.0]), np.array([0.3]))
    X = part.predict(np.zeros((6, 10_000)), np.ones((1, 10_000), bool), np.zeros(4),
                     np.random.default_rng(1))
    assert np.abs(X[5]).max() == pytest.approx(0.3)


def test_the_pitch_rate_tail_gives_its_share_of_particles_scaled_noise_and_nothing_else():
    n, N, q = 6, 100_000, 0.01
    q_std = np.array([0.0, 0.0, 0.0, 0.0, q, 0.0])
    args = (Still(), q_std, np.array([0.0]), np.array([np.inf]))
    modes = np.zeros((1, N), dtype=bool)
    plain = DriftPredict(*args).predict(np.zeros((n, N)), modes, np.zeros(4), np.random.default_rng(2))
    off = DriftPredict(*args, q_tail=(0.0, 5.0)).predict(np.zeros((n, N)), modes, np.zeros(4),
                                                         np.random.default_rng(2))
    assert np.array_equal(plain, off)                       # share 0: the plain step, bit for bit
    tail = DriftPredict(*args, q_tail=(0.05, 5.0)).predict(np.zeros((n, N)), modes, np.zeros(4),
                                                           np.random.default_rng(2))
    wide = np.abs(tail[4]) > 3.5 * q                        # 0.05 P(|z| > 0.7) + 0.95 P(|z| > 3.5)
    assert wide.mean() == pytest.approx(0.05 * 0.4839 + 0.95 * 0.000465, rel=0.1)
    assert (np.abs(plain[4]) > 3.5 * q).mean() < 0.001
    assert np.std(tail[4]) == pytest.approx(q * np.sqrt(0.95 + 0.05 * 25.0), rel=0.03)
    assert not tail[[0, 1, 2, 3, 5]].any()                  # only the pitch rate


def test_robust_estimator_builds_a_kinematic_filter_with_drift(robust):
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    assert f.parts.predict.process.kind == "kinematic"
    assert isinstance(f.parts.predict, DriftPredict)
    assert f.meas.names == robust.observed and "ax" not in f.meas.names
    rows = len(robust.measurements)
    y = np.array([500.0, 500.0, 40.0, 2.0, 0.05, 0.0, 0.48, -9.79, 40.0, 0.0, 0.0])
    out = f.step(0.05, y, np.ones(rows, bool), np.array([-0.08, 0.5]))
    assert np.isfinite(out.x_mean).all() and out.fault_probability.max() < 0.5


@pytest.mark.parametrize("name", ["KF", "IMM-KF", "EKF-GATE", "RPF"])
def test_every_filter_runs_on_an_estimator_with_accelerometer_rows(robust, name):
    f = build_filter(name, robust, np.random.default_rng(0), particles=50)
    y = np.array([500.0, 500.0, 40.0, 2.0, 0.05, 0.0, 0.48, -9.79, 40.0, 0.0, 0.0])
    out = f.step(0.05, y, np.ones(11, bool), np.array([-0.08, 0.5]))
    assert np.isfinite(out.x_mean).all() and np.isfinite(out.fault_probability).all()


def _robust_doc():
    doc, _ = estimator_document("aerosonde-robust")
    return doc


def test_kinematic_model_needs_the_accelerometer_rows():
    doc = _robust_doc()
    doc["measurements"]["rows"] = ["gnss_alt", "baro_alt", "u", "w", "theta", "q"]
    with pytest.raises(ConfigError, match="measurements.rows must list ax, az"):
        parse_estimator(doc)


def test_kinematic_model_sees_the_throttle_only_with_the_pitot():
    doc = _robust_doc()
    doc["faults"] = doc["faults"][:4]                    # no elevator: only the throttle needs the pitot
    doc["faults"].append({"id": "dt", "target": "delta_t", "unit": "1", "sigma_f": 0.001})
    assert parse_estimator(doc).derived_rows == ("throttle",)
    doc["measurements"]["rows"].remove("airspeed")
    with pytest.raises(ConfigError, match="cannot see actuator faults"):
        parse_estimator(doc)


def test_kinematic_model_needs_the_pitot_to_see_the_elevator():
    doc = _robust_doc()
    doc["measurements"]["rows"].remove("airspeed")
    with pytest.raises(ConfigError, match="must list airspeed"):
        parse_estimator(doc)


def test_pitch_moment_balances_at_the_airframes_trim(params):
    from fdir_service.airframe.trim import trim as trim_of
    from fdir_service.estimation.kinematic import PitchMoment

    tr = trim_of(params, 40.0, 500.0)
    z, u = tr.z, tr.u
    pm = PitchMoment(params)
    a_z = -params.g * np.cos(z[3])          # level trim: the lift carries the weight
    qdot = pm.qdot(np.array([0.0]), u[0], a_z, float(np.hypot(z[1], z[2])))
    # one degree of elevator moves q' by ~1.6 rad/s^2; the trim balances to a few hundredths of it
    assert abs(qdot[0]) < 0.05 * abs(pm.scale(40.0) * pm.elevator_gain * np.radians(1.0))
    assert pm.elevator_gain < 0                                     # trailing edge down: nose down


def test_pitch_moment_explains_the_pitch_acceleration_in_turbulence(turbulent_flight):
    from fdir_service.estimation.kinematic import PitchMoment

    sc, tr = turbulent_flight
    names = sc.sensors.measurements
    pm = PitchMoment(sc.estimator.airframe_params())
    q = tr.z[:, 4]
    dq = np.diff(q) / sc.dt_s
    a_z, V = tr.y[:-1, names.index("az")], tr.y[:-1, names.index("airspeed")]
    pred = np.array([pm.qdot(q[k:k + 1], tr.u[k, 0], a_z[k], V[k])[0] for k in range(len(dq))])
    # the gusts swing q' by ~0.4 rad/s^2; the moment read from the accelerometer explains most of it
    assert np.std(dq) > 0.3 and np.std(dq - pred) < 0.5 * np.std(dq)


def test_kinematic_elevator_response_is_the_moments():
    from fdir_service.airframe.params import AirframeParams
    from fdir_service.estimation.kinematic import PitchMoment

    pm = PitchMoment(AirframeParams())
    lay = FaultLayout(("de",), ("actuator",), ("delta_e",), ("q",))
    proc = KinematicProcess(0.05, lay, pm, 40.0)
    X = np.zeros((6, 2))
    X[1], X[5, 1] = 40.0, 0.01                          # particle 1: a 0.01 rad elevator fault
    u = np.array([0.0, 0.5, 0.0, -9.8, 40.0])
    nxt = proc.propagate(X, u)
    assert nxt[4, 1] - nxt[4, 0] == pytest.approx(proc.B_actuator[4, 0] * 0.01, rel=1e-9)
    assert nxt[3, 1] == nxt[3, 0] and proc.B_actuator[3, 0] == 0.0     # theta takes it at close_frame


def test_close_frame_gives_theta_the_trapezoid_of_the_pitch_rates(turbulent_flight):
    proc = KinematicProcess(0.05, FaultLayout((), (), (), ()))
    prior = np.array([[-500.0], [40.0], [2.0], [0.05], [0.1]])
    X = proc.propagate(prior, np.array([0.0, 0.5, 0.0, -9.8]))
    X[4] = 0.3                                            # the gyro's correction of the end rate
    proc.close_frame(prior, X)
    assert X[3, 0] == pytest.approx(0.05 + 0.05 * (0.1 + 0.3) / 2, rel=1e-12)
    # on a turbulent flight's truth: theta + dt (q_k + q_k+1) / 2 against theta + dt q_k
    _, tr = turbulent_flight
    th, q = tr.z[:, 3], tr.z[:, 4]
    euler = th[:-1] + 0.05 * q[:-1] - th[1:]
    trapezoid = th[:-1] + 0.025 * (q[:-1] + q[1:]) - th[1:]
    assert np.std(trapezoid) < 0.2 * np.std(euler)


def test_a_fault_cannot_target_an_accelerometer_row():
    doc = _robust_doc()
    doc["faults"][0]["target"] = "ax"
    with pytest.raises(ConfigError, match="target"):
        parse_estimator(doc)


def test_drift_sigma_is_read_per_fault_in_si(robust):
    q = next(f for f in robust.faults if f.id == "q")
    assert q.drift_sigma == pytest.approx(0.0002)
    assert dataclasses.replace(q, drift_sigma=0.0).drift_sigma == 0.0
    assert robust.settings.mode0 == "drift" and robust.settings.process_model == "kinematic"


def test_rate_window_finds_a_gyro_bias_from_the_attitude_slope():
    from fdir_service.estimation.rate_window import RateWindow

    rng = np.random.default_rng(3)
    win = RateWindow(40, 20)
    assert win.bias() is None
    for k in range(40):                                 # 2 s at 20 Hz: q = 0.1 rad/s, gyro +0.03 bias
        t = 0.05 * k
        win.add(t, 0.1 * t + 0.01 * rng.standard_normal(), 0.1 + 0.03 + 0.003 * rng.standard_normal())
    # std of the estimate: sqrt(0.003^2/40 + 12 0.01^2 / (0.05^2 40 (40^2 - 1))) = 0.0028 rad/s
    assert win.bias() == pytest.approx(0.03, abs=3 * 0.0028)


def test_robust_estimator_proposes_gyro_sentinels_from_the_window_and_moves_their_q(robust):
    from fdir_service.estimation.jump import ActuatorCarry
    from fdir_service.estimation.rate_window import RateWindowAmplitude

    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    amp, carry = f.parts.jump.amplitude, f.parts.jump.carry
    assert isinstance(amp, RateWindowAmplitude) and amp.window.buffer.shape[0] == 40
    assert isinstance(carry, ActuatorCarry)
    j = robust.observed.index("q")
    gyro = [k for k, x in enumerate(robust.faults) if x.target == "q"][0]
    elevator = [k for k, x in enumerate(robust.faults) if x.target == "delta_e"][0]
    assert j >= 0 and list(carry.columns) == [elevator, gyro]
    np.testing.assert_array_equal(carry.B[:, 1], [0, 0, 0, 0, -1])   # f_q up by dA: q down by dA
    assert carry.B[4, 0] < 0 and carry.B[:3, 0].tolist() == [0, 0, 0]  # the elevator moves q


def test_exit_fold_moves_the_state_by_what_keeps_the_sensors_prediction(robust):
    from fdir_service.estimation.jump import ExitFold

    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    fold = f.parts.jump.fold
    assert isinstance(fold, ExitFold)
    ids = [x.id for x in robust.faults]
    assert [ids[j] for j in fold.columns] == ["gnss", "baro", "theta", "q"]   # on_exit = "reset_or_fold"
    H = f.meas.H[:, :5]
    for j in fold.columns:
        r = f.meas.names.index(robust.faults[j].target)
        assert H[r] @ fold.G[:, j] == pytest.approx(1.0)                  # this row's prediction kept
    np.testing.assert_array_equal(fold.G[:, ids.index("de")], 0.0)     # actuators never fold


def test_half_the_exits_fold_the_altimeter_fault_into_the_altitude(robust):
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=2000)
    jump = f.parts.jump
    ids = [x.id for x in robust.faults]
    b = ids.index("baro")
    X = np.zeros((5 + len(ids), 2000))
    X[0] = -500.0                                        # p_d: 500 m up
    X[5 + b] = 3.0                                       # the baro reads 3 m high, in mode 1
    modes = np.zeros((len(ids), 2000), bool)
    modes[b] = True
    v = np.random.default_rng(1).random(modes.shape)
    pi10 = np.ones((len(ids), 1))                        # every particle exits this step
    folded = jump.fold.capture(X[5:], modes, v, pi10)
    X[5:][modes] = 0.0                                   # what the jump does to an exit
    jump.fold.apply(X, folded)
    r = f.meas.names.index("baro_alt")
    pred = f.meas.H[r] @ X
    kept = np.isclose(pred, 503.0)                       # folded: the altitude moved, the reading kept
    reset = np.isclose(pred, 500.0)                      # reset: the fault ended
    assert (kept | reset).all()
    assert kept.mean() == pytest.approx(0.5, abs=0.04)


def _modes_with(p_theta: float, p_q: float, ids: list[str], N: int = 100) -> np.ndarray:
    """Modes (nf, N) whose theta and q entries are in mode 1 on those shares of N equal weights."""
    modes = np.zeros((len(ids), N), bool)
    modes[ids.index("theta"), :int(round(p_theta * N))] = True
    modes[ids.index("q"), :int(round(p_q * N))] = True
    return modes


def test_attitude_folds_wait_for_the_gyro_once_the_declaration_is_old(robust):
    """faults.fold_after = "q" (`jump.FoldArming`): theta folds in its declaration's first
    fold_young_s (3 s = 60 steps) and within fold_window_s (10 s = 200 steps) of a step with
    P(q) >= 0.5; the altimeters and the gyro always may."""
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    arming = f.parts.jump.fold.arming
    ids = [x.id for x in robust.faults]
    th = ids.index("theta")
    w = np.full(100, 0.01)
    arming.observe(_modes_with(0.0, 0.0, ids), w)
    assert not arming.armed[th] and arming.armed[[ids.index(k) for k in ("gnss", "baro", "q")]].all()
    for _ in range(61):                                   # a standing attitude fault: young ...
        arming.observe(_modes_with(0.95, 0.0, ids), w)
        assert arming.armed[th]
    arming.observe(_modes_with(0.95, 0.0, ids), w)        # ... then old: no more folds
    assert not arming.armed[th]
    arming.observe(_modes_with(0.95, 0.6, ids), w)        # the gyro declared: 200 steps of folds
    for _ in range(200):
        arming.observe(_modes_with(0.95, 0.1, ids), w)
        assert arming.armed[th]
    arming.observe(_modes_with(0.95, 0.1, ids), w)
    assert not arming.armed[th]


def test_an_attitude_exit_that_may_not_fold_resets(robust):
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    fold = f.parts.jump.fold
    ids = [x.id for x in robust.faults]
    th, b = ids.index("theta"), ids.index("baro")
    F = np.zeros((len(ids), 1000))
    F[th], F[b] = 0.12, 3.0
    modes = np.zeros((len(ids), 1000), bool)
    modes[[th, b]] = True
    v = np.random.default_rng(3).random(modes.shape)
    fold.arming.armed[:] = True
    fold.arming.armed[th] = False
    folded = fold.capture(F, modes, v, np.ones((len(ids), 1)))
    rows = list(fold.columns)
    assert not folded[rows.index(th)].any()                            # reset, every one
    np.testing.assert_array_equal(folded[rows.index(b)] != 0, v[b] < 0.5)  # half fold, as before


@pytest.mark.parametrize("change, message", [
    ({"on_exit": "reset"}, "fold_after"),                 # only a fault that folds waits
    ({"fold_after": "theta"}, "another sensor"),          # not its own row
    ({"fold_after": "u"}, "row of another fault"),        # a row no fault watches
])
def test_fold_after_names_another_watched_row(change, message):
    doc = _robust_doc()
    next(f for f in doc["faults"] if f["id"] == "theta").update(change)
    with pytest.raises(ConfigError, match=message):
        parse_estimator(doc)


def test_an_actuator_fault_cannot_fold():
    doc = _robust_doc()
    doc["faults"][-1]["on_exit"] = "reset_or_fold"
    with pytest.raises(ConfigError, match="on_exit"):
        parse_estimator(doc)


def test_a_faint_mode1_fault_exits_faster_than_a_clear_one():
    from fdir_service.estimation.jump import FaintExit, ModelExit

    F = np.array([[0.001, -0.002, 0.05, -0.03]])          # theta faults, rad; noise sigma 0.015
    pi10 = np.array([0.01])
    np.testing.assert_array_equal(ModelExit().pi10(F, pi10), [[0.01]])
    faint = FaintExit(np.array([0.015]), 0.05)
    np.testing.assert_array_equal(faint.pi10(F, pi10), [[0.05, 0.05, 0.01, 0.01]])


def test_pi10_faint_is_read_and_builds_a_faint_exit(robust):
    from fdir_service.estimation.jump import FaintExit, ModelExit

    assert robust.settings.pi10_faint == pytest.approx(0.05)
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    assert isinstance(f.parts.jump.exit, FaintExit)
    np.testing.assert_allclose(f.parts.jump.exit.threshold[:, 0], f.parts.jump.amplitude.sigma)
    thesis = build_filter("RJMRPF", load_estimator("aerosonde"), np.random.default_rng(0), particles=50)
    assert isinstance(thesis.parts.jump.exit, ModelExit)


def test_drift_memory_keeps_the_fault_free_value_through_a_fault():
    from fdir_service.estimation.jump import DriftMemory, mode0_mean

    N = 1000
    w = np.full(N, 1.0 / N)
    F = np.full((1, N), 0.016)                           # an elevator mis-trim of 0.9 deg in mode 0
    modes = np.zeros((1, N), bool)
    mem = DriftMemory(1)
    assert mem.update(F, modes, w)[0] == pytest.approx(0.016)
    modes[0, :950] = True                                # a fault: 95 % of the weight in mode 1 ...
    F[0, :950] = 0.07
    F[0, 950:] = 0.0                                     # ... and the few mode-0 particles left wrong
    mean, share = mode0_mean(F, modes, w)
    assert mean[0] == pytest.approx(0.0) and share[0] == pytest.approx(0.05)
    assert mem.update(F, modes, w)[0] == pytest.approx(0.016)   # not taken: mode 0 is a minority


def test_a_rolled_back_memory_freezes_at_its_value_from_before_the_onset():
    from fdir_service.estimation.jump import DriftMemory, MemoryRollback

    N = 100
    w = np.full(N, 1.0 / N)
    modes = np.zeros((2, N), bool)
    plain, rolled = DriftMemory(2), DriftMemory(2)
    rolled.rollback = MemoryRollback(2, steps=3)
    for k in range(10):                                  # fault-free: both follow the mode-0 mean
        F = np.full((2, N), 0.01 * k)
        np.testing.assert_array_equal(plain.update(F, modes, w), rolled.update(F, modes, w))
    for k in range(10, 12):                              # an onset the mode-0 particles absorb
        F = np.full((2, N), 0.1 * k)
        plain.update(F, modes, w), rolled.update(F, modes, w)
    modes[0, :80] = True                                 # the first entry's fault wins: it freezes
    F = np.full((2, N), 2.0)
    assert plain.update(F, modes, w)[0] == pytest.approx(1.1)      # the absorbed onset
    value = rolled.update(F, modes, w)
    assert value[0] == pytest.approx(0.09)               # three frames before it froze
    assert value[1] == pytest.approx(2.0)                # the second still follows its mean
    for _ in range(5):                                   # frozen: it stays there
        assert rolled.update(F, modes, w)[0] == pytest.approx(0.09)


def test_fault_free_rollback_s_is_read_and_gives_the_memory_its_rollback(robust):
    doc = _robust_doc()
    doc["parts"]["fault_free_rollback_s"] = 2.0
    est = parse_estimator(doc, "rollback.toml")
    f = build_filter("RJMRPF", est, np.random.default_rng(0), particles=50)
    assert f.parts.jump.drift.rollback.past.shape == (round(2.0 / est.dt_s), len(est.faults))
    plain = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=50)
    assert plain.parts.jump.drift.rollback is None
    doc["parts"]["fault_free_rollback_s"] = -1.0
    with pytest.raises(ConfigError, match="fault_free_rollback_s"):
        parse_estimator(doc, "rollback.toml")


def test_under_drift_an_exit_returns_to_the_fault_free_value_and_the_estimate_is_the_change(robust):
    f = build_filter("RJMRPF", robust, np.random.default_rng(0), particles=1000)
    jump = f.parts.jump
    assert jump.drift is not None
    de = [x.id for x in robust.faults].index("de")
    jump.drift.value[de] = 0.016
    F = np.full((len(robust.faults), 1000), 0.0)
    F[de] = 0.016
    modes = np.zeros_like(F, dtype=bool)
    modes[de, :500] = True
    F[de, :500] = 0.07
    v = np.zeros_like(F)                                 # every mode-1 particle exits
    from fdir_service.estimation.jump import jump as jump_fn
    pi = np.zeros(len(robust.faults))
    jump_fn(F, modes, F.copy(), np.ones(len(robust.faults), bool), pi, pi + 1.0, v, False,
            jump.drift.value)
    np.testing.assert_allclose(F[de], 0.016)
    from fdir_service.estimation.base import StepOutput
    out = StepOutput(0.0, np.zeros(10), None, tuple(x.id for x in robust.faults), F.mean(axis=1),
                     np.zeros(5), 1000.0, False)
    jump.annotate(out)
    assert out.fault_estimate[de] == pytest.approx(0.0)
