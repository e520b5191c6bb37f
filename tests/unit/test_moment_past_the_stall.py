"""parts.moment_alpha = "stall_blend" (`kinematic.PitchMoment`, `KinematicProcess._stalled_alpha`,
`predict.DriftPredict`): past the airframe's stall angle the lift falls and no longer reads the
angle of attack, so the pitching moment takes each particle's velocity's angle of attack and
airspeed, and its pitch rate takes the tail's process noise; near trim nothing changes, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.airframe.dynamics import derivatives
from fdir_service.airframe.params import load_airframe
from fdir_service.estimation.kinematic import KinematicProcess, PitchMoment
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimation.predict import DriftPredict

DT = 0.05
P = load_airframe()


def test_the_stall_share_is_the_airframes_own_blend():
    m = PitchMoment(P, stall_aware=True)
    share = m.stall_share(np.radians([3.0, 15.0, 40.0, -40.0]))
    assert share[0] < 1e-9 and share[1] < 1e-3 and share[2] > 0.999 and share[3] > 0.999
    assert m.stall_share(np.array([P.alpha0]))[0] == pytest.approx(0.5, abs=1e-6)


def stalled_state(alpha_deg: float, V: float = 43.0, q: float = 1.0) -> tuple[np.ndarray, float, float]:
    """(state z (5,), a_z m/s^2, elevator rad) of the airframe at alpha_deg, V m/s, q rad/s."""
    a = np.radians(alpha_deg)
    z = np.array([-500.0, V * np.cos(a), V * np.sin(a), 0.3, q])
    de = np.radians(-30.0)
    zdot = derivatives(z, np.array([de, 0.5]), P)
    a_z = zdot[2] - z[4] * z[1] - P.g * np.cos(z[3])          # specific force: w' - q u - g cos(theta)
    return z, a_z, de


def test_past_the_stall_the_moment_is_the_airframes_and_the_lift_read_is_far_off():
    z, a_z, de = stalled_state(40.0)
    true_qdot = derivatives(z, np.array([de, 0.5]), P)[4]
    V = np.hypot(z[1], z[2])
    m = PitchMoment(P, stall_aware=True)
    blended = m.qdot(np.array([z[4]]), de, a_z, np.array([V]), np.array([np.radians(40.0)]))[0]
    lift_read = m.qdot(np.array([z[4]]), de, a_z, V)[0]
    assert blended == pytest.approx(true_qdot, rel=1e-3)
    assert abs(lift_read - true_qdot) > 10.0                  # rad/s^2: ~600 deg/s^2 off


def process(stall_aware: bool) -> KinematicProcess:
    return KinematicProcess(DT, FaultLayout((), (), (), ()), PitchMoment(P, stall_aware), rotation=True)


def cloud(alpha_deg: float, n: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """A cloud (5, n) about the stalled state and the input u (5,) [de, dt, a_x, a_z, V]."""
    z, a_z, de = stalled_state(alpha_deg)
    X = z[:, None] + np.random.default_rng(3).normal(0.0, 0.01, (5, n))
    return X, np.array([de, 0.5, 0.0, a_z, np.hypot(z[1], z[2])])


def test_near_trim_the_step_is_the_lift_reads_bit_for_bit():
    X, u = cloud(3.0)
    aware, plain = process(True), process(False)
    assert np.array_equal(aware.propagate(X, u), plain.propagate(X, u))
    assert aware.stall_share is None


def test_past_the_stall_the_step_takes_the_velocitys_angle_and_marks_the_particles():
    X, u = cloud(40.0)
    aware = process(True)
    stepped = aware.propagate(X, u)
    assert aware.stall_share.shape == (X.shape[1],) and aware.stall_share.min() > 0.999
    z, a_z, de = stalled_state(40.0)
    qdot = derivatives(z, np.array([de, 0.5]), P)[4]
    true_q = z[4] + DT * qdot
    assert abs(np.median(stepped[4]) - true_q) < 0.05 * DT * abs(qdot) + 0.02
    assert abs(np.median(process(False).propagate(X, u)[4]) - true_q) > 0.5    # rad/s: the lift read


def pitch_rate_noise(predict: DriftPredict, alpha_deg: float) -> float:
    """The std (rad/s) of the pitch rate's process noise of one predict over a cloud at alpha_deg."""
    X, u = cloud(alpha_deg, n=20000)
    deterministic = predict.process.propagate(X, u)
    modes = np.zeros((0, X.shape[1]), dtype=bool)
    return float(np.std(predict.predict(X, modes, u, np.random.default_rng(4))[4] - deterministic[4]))


def test_stalled_particles_take_the_tails_pitch_rate_noise():
    q_std = np.array([0.0, 0.0, 0.0, 0.0, 0.01])
    predict = DriftPredict(process(True), q_std, np.zeros(0), np.zeros(0), q_tail=(0.0, 5.0))
    assert pitch_rate_noise(predict, 40.0) == pytest.approx(0.05, rel=0.03)
    assert pitch_rate_noise(predict, 3.0) == pytest.approx(0.01, rel=0.03)
