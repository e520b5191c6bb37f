"""The kinematic process model: the longitudinal equations any aircraft obeys, driven by its IMU.

With the accelerometer's specific force [a_x, a_z] (body forward, down; m/s^2) as an input, the
velocity equations of SPEC section 2 need no aerodynamic model (this is why PX4's EKF2 and
ArduPilot's EKF3 are IMU-driven):

    p_d' = -u sin(theta) + w cos(theta)     u' = a_x - q w - g sin(theta)
    theta' = q                              w' = a_z + q u + g cos(theta)
    q'   = 0 (a random walk: the pitch acceleration is process noise; the gyro row observes q)

u, w are the body-axis velocities over the ground (what GNSS-aided ODOMETRY reports), so wind and
gusts appear only through the measured specific force: this model has nothing to mis-model in
moving air or on another airframe. It sees no actuator (an elevator acts on q through the
pitching moment, which this model leaves out): `B_actuator` is zero. One step over dt with the
attitude at mid-step (theta + q dt / 2) in the gravity and climb terms.
"""

from __future__ import annotations

import numpy as np

from fdir_service.estimation.inputs import G
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout


class KinematicProcess:
    """x+ = x + dt f_kin(x, a) on the extended state (faults: random walk); inputs u (4,) =
    [delta_e, delta_t, a_x, a_z] (the first two unused)."""

    kind = "kinematic"

    def __init__(self, dt: float, layout: FaultLayout) -> None:
        self.dt = float(dt)
        self.layout = layout
        self.B_actuator = np.zeros((N_AIRFRAME, layout.nf))

    def propagate(self, X: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Deterministic step of a cloud X (n, N) (or one state (n,)) with input u (4,)."""
        one = X.ndim == 1
        if one:
            X = X[:, None]
        ax, az = float(u[2]), float(u[3])
        _, vu, vw, th, q = X[:N_AIRFRAME]
        h = self.dt
        mid = th + (0.5 * h) * q
        s, c = np.sin(mid), np.cos(mid)
        out = X.copy()
        out[0] += h * (vw * c - vu * s)
        out[1] += h * (ax - q * vw - G * s)
        out[2] += h * (az + q * vu + G * c)
        out[3] += h * q
        return out[:, 0] if one else out
