"""The thrust check: the throttle the accelerometer implies, so an IMU-driven monitor sees its engine.

The kinematic process model takes the accelerometer as an input (kinematic.py), so thrust never
enters it and an engine that quits looks like any other deceleration. The airframe's axial force
balance (SPEC section 2) says what the specific force along the body x axis should be:

    a_x = k_T (k_m^2 delta_t^2 - V^2) + f_x(alpha, V, delta_e),    k_T = rho S_prop C_prop / (2 m)

with f_x = (C_L sin(alpha) - C_D cos(alpha)) qbar S / m the aerodynamic force per unit mass and
the angle of attack read from the lift the accelerometer measures (as `kinematic.PitchMoment`
does). Solved for the throttle, the measured a_x, a_z and the pitot's V give the throttle the
propeller is delivering; minus the commanded one it is a derived row ("throttle") that a throttle
fault entry (bias, jammed, effectiveness: an engine that quits reads g = V / (k_m u)) adds to
directly. What the airframe file gets wrong of the drag and the propeller is slow: the throttle
fault's mode-0 drift carries it. At the Aerosonde's cruise one unit of throttle is ~65 m/s^2 of a_x, so the
accelerometer's 0.3 m/s^2 is ~0.005 of throttle.

Linear lift and a parabolic polar hold below the stall, near level flight: the row is read within
the pitot's limits only (pitch attitude 25 deg, pitch rate 15 deg/s: `pitot.near_level_flight`,
`inputs.RowSplit`). When a jammed elevator frees, the aircraft tumbles through 30 deg of angle of
attack; read there, the row put the throttle's entries and the mode-0 drift off for tens of seconds
after (docs/faults.md, "The body velocity turned exactly").
"""

from __future__ import annotations

import math

from fdir_service.airframe.params import AirframeParams


class ThrustCheck:
    """The throttle (0..1 scale) a frame's specific force implies, from the airframe `params`."""

    def __init__(self, params: AirframeParams) -> None:
        p = params
        self.p = p
        self.k_thrust = p.rho * p.S_prop * p.C_prop / (2.0 * p.m)
        self.k_motor2 = p.k_motor ** 2
        self.cd_k = 1.0 / (math.pi * p.e * p.AR)

    def alpha(self, a_z: float, V: float, de: float) -> float:
        """Angle of attack (rad) from the lift the accelerometer measures, a_z (m/s^2) at V (m/s)."""
        p = self.p
        qbar_s = 0.5 * p.rho * V * V * p.S
        return (-a_z * p.m / qbar_s - p.C_L0 - p.C_Lde * de) / p.C_La

    def aero_axial(self, a_z: float, V: float, de: float) -> float:
        """f_x (m/s^2): the aerodynamic force along body x per unit mass (linear lift, polar drag)."""
        p = self.p
        a = self.alpha(a_z, V, de)
        c_l0 = p.C_L0 + p.C_La * a                 # the polar's lift (SPEC section 2: no elevator)
        c_l = c_l0 + p.C_Lde * de
        c_d = p.C_Dp + c_l0 * c_l0 * self.cd_k + p.C_Dde * de
        return (c_l * math.sin(a) - c_d * math.cos(a)) * 0.5 * p.rho * V * V * p.S / p.m

    def implied_throttle(self, a_x: float, a_z: float, V: float, de: float) -> float:
        """The throttle (0..1 scale, >= 0) whose thrust explains a_x (m/s^2) at V (m/s)."""
        V = max(float(V), 1.0)
        thrust = (a_x - self.aero_axial(a_z, V, de)) / self.k_thrust + V * V
        return math.sqrt(max(thrust, 0.0) / self.k_motor2)
