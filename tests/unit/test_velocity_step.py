"""parts.velocity_step (`kinematic.KinematicProcess`): the body velocity (u, w) of the kinematic
model turned by the frame's pitch angle exactly ("rotation") or by the Euler step ("euler"); and
the kinematic-only parts refused on another process model."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.inputs import G
from fdir_service.estimation.kinematic import KinematicProcess
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimator_config import estimator_document, parse_estimator

DT = 0.05
V = 40.0                                    # m/s, flown level: the inertial velocity is horizontal


def process(rotation: bool) -> KinematicProcess:
    return KinematicProcess(DT, FaultLayout((), (), (), ()), rotation=rotation)


def spinning(theta: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """A body pitching at q (rad/s) while it moves level at V: the state (5,) at attitude theta and the
    input (4,) with the specific force -g in body axes at mid-frame (inertial acceleration 0)."""
    z = np.array([-500.0, V * np.cos(theta), V * np.sin(theta), theta, q])
    mid = theta + 0.5 * DT * q
    return z, np.array([0.0, 0.5, G * np.sin(mid), -G * np.cos(mid)])


def test_a_body_that_snaps_at_220_deg_per_s_keeps_its_speed_with_the_rotation_and_gains_with_euler():
    z, u = spinning(0.3, np.radians(-220.0))
    theta = 0.3 + DT * z[4]
    exact = [V * np.cos(theta), V * np.sin(theta)]
    turned = process(True).propagate(z, u)
    np.testing.assert_allclose(turned[1:3], exact, atol=1e-9)
    euler = process(False).propagate(z, u)
    assert np.hypot(*euler[1:3]) - V == pytest.approx(V * (np.hypot(1.0, DT * z[4]) - 1.0), rel=1e-9)
    assert np.hypot(*(euler[1:3] - exact)) > 0.5                        # m/s lost in one frame


def test_in_steady_flight_the_two_steps_agree_well_below_the_accelerometers_noise():
    rng = np.random.default_rng(3)
    spread = rng.normal(0.0, [[1.0], [1.0], [1.0], [0.02], [0.05]], (5, 200))    # q within ~9 deg/s
    X = np.array([-500.0, 40.0, 2.0, 0.05, 0.0])[:, None] + spread
    u = np.array([-0.05, 0.5, 0.4, -9.6])
    diff = process(True).propagate(X, u) - process(False).propagate(X, u)
    # (q dt)^2 V / 2 <= 1.5 mm/s a frame, against dt x 0.2 m/s^2 = 10 mm/s of accelerometer noise
    assert 1e-4 < np.abs(diff[1:3]).max() < 2e-3 and not diff[[0, 3, 4]].any()


def test_close_frame_turns_the_velocity_by_the_trapezoids_extra_angle_as_it_moves_theta():
    prior = np.array([[-500.0], [40.0], [2.0], [0.05], [0.0]])
    X = prior.copy()
    X[4] = -2.0                                        # the gyro corrected q to -2 rad/s
    turned, euler = X.copy(), X.copy()
    process(True).close_frame(prior, turned)
    process(False).close_frame(prior, euler)
    angle = 0.5 * DT * -2.0
    assert turned[3, 0] == euler[3, 0] == pytest.approx(0.05 + angle)
    assert np.array_equal(euler[1:3], X[1:3])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    np.testing.assert_allclose(turned[1:3, 0], rot @ X[1:3, 0], atol=1e-12)


def test_the_catalogue_turns_the_velocity():
    doc, _ = estimator_document("aerosonde-catalogue")
    assert parse_estimator(doc, "test.toml").settings.velocity_step == "rotation"


@pytest.mark.parametrize("key,value,bad", [("az_input", "frame_mean", "frame_start"),
                                           ("velocity_step", "rotation", "rk4"),
                                           ("frame_angle", "spread", "simpson"),
                                           ("moment_alpha", "stall_blend", "stall"),
                                           ("moment_wind", "fault_free", "reading")])
def test_only_the_kinematic_model_takes_its_parts_and_a_bad_value_names_the_key(key, value, bad):
    doc, _ = estimator_document("aerosonde")
    doc.setdefault("parts", {})[key] = value
    with pytest.raises(ConfigError, match=f"parts.{key} = \"{value}\".*kinematic"):
        parse_estimator(doc, "test.toml")
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"][key] = bad
    with pytest.raises(ConfigError, match=key):
        parse_estimator(doc, "test.toml")
