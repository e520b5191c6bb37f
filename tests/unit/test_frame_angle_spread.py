"""parts.frame_angle = "spread" (`kinematic.KinematicProcess.close_frame`): where the gyro's
correction moves q by more within a frame than theta's process noise allows, the frame's pitch
angle is drawn per particle between its two rectangle rules, dt q and dt q+, and (u, w) turn with
it; in steady flight the trapezoid stands and no random number is drawn."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.kinematic import KinematicProcess
from fdir_service.estimation.layout import FaultLayout

DT = 0.05
FLOOR = 0.002 * np.sqrt(DT)                # rad: theta's process noise over a frame (the catalogue's)


def process() -> KinematicProcess:
    return KinematicProcess(DT, FaultLayout((), (), (), ()), rotation=True, angle_spread=FLOOR)


def cloud(q_before: float, q_after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(prior, corrected) clouds (5, N) at 40 m/s, theta 0.05 rad, q from q_before to q_after (rad/s)."""
    n = q_after.size
    prior = np.tile(np.array([[-500.0], [40.0], [2.0], [0.05], [q_before]]), (1, n))
    X = prior.copy()
    X[4] = q_after
    return prior, X


def test_a_snap_spreads_the_angle_between_the_rectangle_rules_and_turns_the_velocity_with_it():
    prior, X = cloud(0.0, np.full(4000, np.radians(-120.0)))      # an elevator that frees: -120 deg/s
    rng = np.random.default_rng(1)
    process().close_frame(prior, X, rng)
    angle = X[3] - 0.05                                           # the frame's extra angle, per particle
    low, high = 0.5 * DT * np.radians(-120.0) * 2.0, 0.0          # dt q+ - dt q ... the rectangle rules
    assert angle.min() >= low - 1e-12 and angle.max() <= high + 1e-12
    assert angle.min() < 0.95 * low and angle.max() > 0.05 * low  # it spans them ...
    assert angle.mean() == pytest.approx(0.5 * low, abs=0.02 * abs(low))   # ... about the trapezoid
    np.testing.assert_allclose(np.hypot(X[1], X[2]), np.hypot(40.0, 2.0), rtol=1e-12)
    np.testing.assert_allclose(np.arctan2(X[2], X[1]) - np.arctan2(2.0, 40.0), angle, atol=1e-12)


def test_in_steady_flight_the_trapezoid_stands_and_no_number_is_drawn():
    rng = np.random.default_rng(2)
    q_after = rng.normal(0.0, np.radians(0.2), 1000)             # the gyro moves q by ~0.2 deg/s a frame
    prior, X = cloud(0.0, q_after)
    trapezoid = X.copy()
    KinematicProcess(DT, FaultLayout((), (), (), ()), rotation=True).close_frame(prior.copy(), trapezoid)
    state = rng.bit_generator.state
    process().close_frame(prior, X, rng)
    assert np.abs(0.5 * DT * q_after).max() < FLOOR
    assert np.array_equal(X, trapezoid) and rng.bit_generator.state == state
