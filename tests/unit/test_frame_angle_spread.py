"""parts.frame_angle = "spread" (`kinematic.KinematicProcess.close_frame`): where the gyro's
correction moves q by more within a frame than theta's process noise allows, the frame's pitch
angle is drawn per particle between its two rectangle rules, dt q and dt q+, and (u, w) turn with
it; in steady flight the trapezoid stands and no random number is drawn."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.frame import Frame
from fdir_service.estimation.kinematic import GyroSnap, KinematicProcess
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimation.measurement import MeasurementModel

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


LIMIT = 0.015 / DT                         # rad/s: the gyro's snap, 2 x half the catalogue's attitude
#                                            sigma over a frame (`factory.SNAP_SHARE`, `factory._gyro_snap`)


def snap_process() -> KinematicProcess:
    return KinematicProcess(DT, FaultLayout((), (), (), ()), rotation=True, angle_spread=0.0,
                            snap=GyroSnap(0, LIMIT))


def gyro_frame(q: float) -> Frame:
    """A frame whose only row, the gyro (row 0), reads q (rad/s)."""
    meas = MeasurementModel(("q",), np.zeros((1, 5)), np.array([0.003]))
    return Frame.of(0.0, np.array([q]), np.array([True]), np.zeros(2), meas)


def test_when_the_gyro_snaps_the_angle_is_spread():
    proc = snap_process()
    prior, X = cloud(0.0, np.full(4000, np.radians(-60.0)))       # the cloud's q moves 60 deg/s a frame
    proc.close_frame(prior.copy(), X.copy(), np.random.default_rng(3), gyro_frame(0.0))
    proc.close_frame(prior, X, np.random.default_rng(3), gyro_frame(np.radians(-60.0)))   # ... the gyro too
    angle = X[3] - 0.05
    low = DT * np.radians(-60.0)
    assert angle.min() >= low - 1e-12 and angle.max() <= 1e-12
    assert angle.min() < 0.95 * low and angle.max() > 0.05 * low


def test_the_cloud_swinging_while_the_gyro_holds_spreads_nothing():
    """While most of the cloud holds the gyro faulty its q follows the moment model and can swing by
    tens of deg/s a frame; "spread" then draws every angle, "snap" reads the gyro and draws none."""
    prior, X = cloud(0.0, np.full(1000, np.radians(-60.0)))
    trapezoid = X.copy()
    KinematicProcess(DT, FaultLayout((), (), (), ()), rotation=True).close_frame(prior.copy(), trapezoid)
    rng = np.random.default_rng(4)
    state = rng.bit_generator.state
    proc = snap_process()
    for q in (0.01, 0.02):                                         # the gyro moves 0.6 deg/s
        Xk = X.copy()
        proc.close_frame(prior, Xk, rng, gyro_frame(q))
    assert np.array_equal(Xk, trapezoid) and rng.bit_generator.state == state
    prior2, spread = cloud(0.0, np.full(1000, np.radians(-60.0)))
    process().close_frame(prior2, spread, rng)
    assert rng.bit_generator.state != state                       # "spread" draws for them


def test_the_catalogue_reads_the_gyro_for_a_snap_of_17_deg_per_second():
    from fdir_service.errors import ConfigError
    from fdir_service.estimation.factory import build_filter
    from fdir_service.estimator_config import estimator_document, parse_estimator

    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"]["frame_angle"] = "snap"
    est = parse_estimator(doc, "test.toml")
    proc = build_filter("RJMRPF", est, np.random.default_rng(0), particles=20).parts.predict.process
    theta_sigma = est.sigma[est.measurements.index("theta")]
    assert proc.snap.limit == pytest.approx(theta_sigma / est.dt_s)
    assert np.degrees(proc.snap.limit) == pytest.approx(17.2, abs=0.1)
    assert est.observed[proc.snap.row] == "q"
    doc["measurements"]["rows"] = [r for r in doc["measurements"]["rows"] if r != "theta"]
    doc["measurements"]["sigma"].pop("theta", None)
    doc["faults"] = [f for f in doc["faults"] if f.get("target") != "theta"]
    doc["parts"]["exclusive_items"] = []
    with pytest.raises(ConfigError, match="frame_angle = \"snap\".*theta"):
        build_filter("RJMRPF", parse_estimator(doc, "test.toml"), np.random.default_rng(0), particles=20)
