"""The kinematic process model: the longitudinal equations any aircraft obeys, driven by its IMU.

With the accelerometer's specific force [a_x, a_z] (body forward, down; m/s^2) as an input, the
velocity equations of SPEC section 2 need no aerodynamic model (this is why PX4's EKF2 and
ArduPilot's EKF3 are IMU-driven):

    p_d' = -u sin(theta) + w cos(theta)     u' = a_x - q w - g sin(theta)
    theta' = q                              w' = a_z + q u + g cos(theta)
    q'   = 0 (a random walk: the pitch acceleration is process noise; the gyro row observes q)

An aircraft that banks and sideslips climbs at u sin(theta) - (v sin(phi) + w cos(phi)) cos(theta):
with the roll attitude phi and the body-y velocity v as inputs too (`LATERAL_ROWS`, rows "roll" and
"v") the altitude takes them. In JSBSim's moderate turbulence (phi 2.9 deg rms, v -1.1 +- 2.3 m/s)
the longitudinal climb rate was 0.05 m/s off on average, 6 m of altitude in two minutes that the
barometer was blamed for; with phi and v the mean error is 0.000 m/s and its spread 0.027 instead of
0.137 m/s (`docs/robustness.md`, "Banks and sideslip"). With the roll and yaw rates p, r as inputs
as well (`BODY_RATE_ROWS`, rows "p" and "r": the gyro's x and z) the velocity and attitude equations
are a 6-DOF aircraft's:

    u' = a_x - q w + r v - g sin(theta)     w' = a_z + q u - p v + g cos(theta) cos(phi)
    theta' = q cos(phi) - r sin(phi)

Their means hardly move, and the frame-to-frame residuals are the accelerometer's noise; but in
JSBSim's turbulence (p 11 deg/s rms, r 7 deg/s) the lateral terms are most of how far the
attitude drifts in 10 s with nothing to correct it (0.19 -> 0.06 deg rms) and a fifth to a third
of u's and w's (0.17 -> 0.14, 0.25 -> 0.16 m/s; `benchmarks/kinematic_residuals.py`). While an
attitude fault hides the attitude, that drift is what the state is left with when it ends. The
estimators in config/ do not list p and r: on JSBSim's flights the terms made the velocities and
the attitude more accurate but did not lower the false alarms (measured: docs/robustness.md, "Body
rates").

u, w are the body-axis velocities over the ground (what GNSS-aided ODOMETRY reports), so wind and
gusts appear only through the measured specific force: this model has nothing to mis-model in
moving air or on another airframe. One step over dt with the attitude at mid-step
(theta + q dt / 2) in the gravity and climb terms; once the gyro has corrected the frame's pitch
rate, theta takes the trapezoid of the two rates (`close_frame`). With parts.velocity_step = "rotation"
(`_velocity_step`) the body velocity (u, w) turns by the frame's pitch angle q dt exactly instead
of the Euler step, and at `close_frame` by the trapezoid's extra angle as theta does: the same to
1.5 mm/s a frame in steady flight, but when a jammed elevator frees and the aircraft pitches at
200 deg/s the Euler step lost 3-4 m/s of u and w within a second (docs/faults.md, "The body
velocity turned exactly").

An elevator acts on q only through the pitching moment. With a `PitchMoment` the q row becomes

    q' = (qbar S c / J_y) [C_m0 + C_ma alpha + C_mq c q / (2 V) + C_mde (delta_e + f_de)]

with V the pitot's airspeed, qbar = rho V^2 / 2, and the angle of attack read from the lift the
accelerometer measures, alpha = (-a_z m / (qbar S) - C_L0 - C_Lq c q / (2 V) - C_Lde delta_e) / C_La
(SPEC section 2's coefficients, linear below stall; drag's share of a_z neglected): the air's
own angle, gusts included, with no wind state. What the airframe file gets wrong of this balance
is slow and acts like an elevator offset: the elevator fault's mode-0 drift carries it
(parts.mode0 = "drift"); a jump of it is the fault.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.airframe.params import AirframeParams
from fdir_service.estimation.inputs import G
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame


class PitchMoment:
    """q' (rad/s^2) from the pitching moment of `params` (module docstring), vectorised."""

    def __init__(self, params: AirframeParams, stall_aware: bool = False) -> None:
        p = params
        self.p = p
        self.elevator_gain = p.C_mde - p.C_ma * p.C_Lde / p.C_La
        """dC_m / d delta_e with alpha read from the measured lift (1/rad)."""
        self.stall_aware = bool(stall_aware)
        """parts.moment_alpha = "stall_blend": past the airframe's stall angle the moment takes the
        angle of attack of the velocity (`stall_share`), not the one the lift reads."""

    def stall_share(self, alpha: np.ndarray) -> np.ndarray:
        """sigma(alpha) (N,), 0 below the stall angle alpha0 and 1 beyond it (either sign): the
        airframe's own stall blend (SPEC section 2, Beard & McLain eq. 4.10), M its sharpness."""
        p = self.p
        lo = np.exp(np.clip(-p.M * (alpha - p.alpha0), -700.0, 700.0))
        hi = np.exp(np.clip(p.M * (alpha + p.alpha0), -700.0, 700.0))
        return (1.0 + lo + hi) / ((1.0 + lo) * (1.0 + hi))

    def scale(self, V: float) -> float:
        """qbar S c / J_y (rad/s^2 per unit C_m) at airspeed V (m/s)."""
        p = self.p
        return 0.5 * p.rho * V * V * p.S * p.c / p.Jy

    def qdot(self, q: np.ndarray, de, a_z: float, V, alpha_air: np.ndarray | None = None) -> np.ndarray:
        """q' (N,) for pitch rates q (N,), elevator de (scalar or (N,)) rad, a_z m/s^2, V m/s (scalar
        or (N,): each particle's own airspeed). alpha is read from the measured lift; with
        alpha_air (N,) rad, the angle of attack of each particle's velocity, it is blended towards
        alpha_air by the stall share: past the stall the lift falls and no longer reads alpha (a
        linear read gives ~6 deg at 40 deg), while the pitching moment stays linear in it."""
        p = self.p
        V = max(float(V), 1.0) if np.ndim(V) == 0 else np.maximum(V, 1.0)
        qbar_S = 0.5 * p.rho * V * V * p.S
        qc = q * (p.c / (2.0 * V))
        alpha = (-a_z * p.m / qbar_S - p.C_L0 - p.C_Lq * qc - p.C_Lde * de) / p.C_La
        if alpha_air is not None:
            alpha = alpha + self.stall_share(alpha_air) * (alpha_air - alpha)
        return (qbar_S * p.c / p.Jy) * (p.C_m0 + p.C_ma * alpha + p.C_mq * qc + p.C_mde * de)


class KinematicProcess:
    """x+ = x + dt f_kin(x, a) on the extended state (faults: random walk); inputs u (4,) =
    [delta_e, delta_t, a_x, a_z], or (5,) with the airspeed (m/s) when a `PitchMoment` drives q,
    then the roll and the body-y velocity if listed (`lateral`), then the roll and yaw rates
    (`rates`, only with `lateral`).

    moment: None (q a random walk) or the pitch-moment model; v_ref (m/s): the airspeed of the
    one-frame elevator response `B_actuator` (5, nf) (zero without a moment).
    """

    kind = "kinematic"
    stall_share = None
    """(N,) each particle's stall share this frame (`PitchMoment.stall_share`, parts.moment_alpha =
    "stall_blend"); None while no particle is near the stall: the predict's pitch-rate noise
    widens with it (`predict.DriftPredict`)."""
    pitot = None
    """The pitot's `pitot.PitotRow` (`use_wind`): the moment's airspeed per particle; None: the reading."""

    def __init__(self, dt: float, layout: FaultLayout, moment: PitchMoment | None = None,
                 v_ref: float = 40.0, lateral: tuple[int, int] | None = None,
                 rates: tuple[int, int] | None = None, rotation: bool = False,
                 angle_spread: float | None = None, snap: GyroSnap | None = None) -> None:
        self.dt = float(dt)
        self.rotation = rotation
        """parts.velocity_step = "rotation": (u, w) turn by the frame's pitch angle exactly
        (`_velocity_step`); False: the Euler step (u - q w dt, w + q u dt)."""
        self.angle_spread = angle_spread
        """parts.frame_angle = "spread": theta's process noise over a frame (rad), above which the
        frame's angle is drawn between its two rectangle rules (`close_frame`); None: the trapezoid;
        0 with `snap`."""
        self.snap = snap
        """parts.frame_angle = "snap": the `GyroSnap` that says when to draw, in place of any
        particle's bound exceeding `angle_spread`."""
        self.layout = layout
        self.moment = moment
        self.lateral = lateral
        """The positions of the roll (rad) and body-y velocity (m/s) in the input u; None: level."""
        self.rates = rates if lateral is not None else None
        """The positions of the roll and yaw rates p, r (rad/s) in u; None: the longitudinal
        velocity and attitude equations."""
        self.B_actuator = np.zeros((N_AIRFRAME, layout.nf))
        self._elevator = np.flatnonzero(layout.actuator_input == 0)
        if moment is not None and self._elevator.size:
            gain = self.dt * moment.scale(v_ref) * moment.elevator_gain
            self.B_actuator[4, self._elevator] = gain      # theta takes it at close_frame

    def use_wind(self, pitot, fault_free: bool = False) -> None:
        """Take each particle's own airspeed u + W from the pitot's wind (a `pitot.PitotRow`) once
        it has started: a particle that holds the pitot blocked then predicts the pitching moment
        of the airspeed it believes, not of the reading. fault_free (parts.moment_wind =
        "fault_free"): a particle that holds the pitot biased takes the fault-free wind too
        (`pitot.PitotRow.fault_free_wind`) rather than its entry, the wind plus the offset, whose
        u + W is the biased reading."""
        self.pitot = pitot
        self.fault_free_wind = bool(fault_free)

    fault_free_wind = False
    """parts.moment_wind = "fault_free" (`use_wind`)."""

    def _airspeed(self, X: np.ndarray, V: float, modes: np.ndarray | None = None):
        """The pitching moment's airspeed (m/s): the trusted reading V, or per particle u + W;
        modes (nf, N) bool: the cloud's fault modes (needed by parts.moment_wind = "fault_free")."""
        if self.pitot is None or self.pitot.mean is None:
            return V
        if self.fault_free_wind and modes is not None:
            return X[1] + self.pitot.fault_free_wind(X, modes)
        return X[1] + X[N_AIRFRAME + self.pitot.wind]

    def _elevator_of(self, X: np.ndarray, de: float):
        """delta_e each particle's elevator sees: the command plus its elevator fault entries."""
        for j in self._elevator:
            de = de + X[N_AIRFRAME + j]
        return de

    def _down_velocity(self, vw: np.ndarray, u: np.ndarray) -> np.ndarray:
        """v sin(phi) + w cos(phi) (N,), m/s: the body z-y plane's velocity along the tilted
        vertical (w itself, bit for bit, wings level with no sideslip or without the rows)."""
        if self.lateral is None:
            return vw
        phi, v = float(u[self.lateral[0]]), float(u[self.lateral[1]])
        return v * np.sin(phi) + vw * np.cos(phi)

    def _add_body_rate_terms(self, out: np.ndarray, u: np.ndarray, q: np.ndarray, c: np.ndarray) -> None:
        """out[1:4] += dt (r v, g cos(theta) (cos(phi) - 1) - p v, q (cos(phi) - 1) - r sin(phi)),
        in place: the 6-DOF velocity and attitude terms (module docstring) for the cloud's q and
        cos(theta at mid-step) c (N,). Nothing moves wings level with no sideslip or rates (the
        longitudinal step bit for bit)."""
        phi, v = float(u[self.lateral[0]]), float(u[self.lateral[1]])
        p, r = float(u[self.rates[0]]), float(u[self.rates[1]])
        if phi == 0.0 and v == 0.0 and p == 0.0 and r == 0.0:
            return
        h, tilt = self.dt, np.cos(phi) - 1.0
        out[1] += h * (r * v)
        out[2] += h * (G * tilt * c - p * v)
        out[3] += h * (tilt * q - r * np.sin(phi))

    def propagate(self, X: np.ndarray, u: np.ndarray, modes: np.ndarray | None = None) -> np.ndarray:
        """Deterministic step of a cloud X (n, N) (or one state (n,)) with input u (4,); modes
        (nf, N) bool or None: the cloud's fault modes (the moment's wind, `_airspeed`)."""
        one = X.ndim == 1
        if one:
            X = X[:, None]
        ax, az = float(u[2]), float(u[3])
        _, vu, vw, th, q = X[:N_AIRFRAME]
        h = self.dt
        mid = th + (0.5 * h) * q
        s, c = np.sin(mid), np.cos(mid)
        out = X.copy()
        out[0] += h * (self._down_velocity(vw, u) * c - vu * s)
        if self.rotation:
            out[1], out[2] = self._velocity_step(vu, vw, q, ax - G * s, az + G * c)
        else:
            out[1] += h * (ax - q * vw - G * s)
            out[2] += h * (az + q * vu + G * c)
        out[3] += h * q
        if self.rates is not None:
            self._add_body_rate_terms(out, u, q, c)
        if self.moment is not None:
            de = self._elevator_of(X, float(u[0]))
            V = self._airspeed(X, float(u[4]), None if one else modes)
            alpha_air = self._stalled_alpha(V if np.ndim(V) == 1 else vu, vw)
            self.stall_share = None if alpha_air is None else self.moment.stall_share(alpha_air)
            if alpha_air is not None and np.ndim(V) == 1:
                V = np.hypot(V, vw)              # the whole air-relative speed, not its u part
            out[4] += h * self.moment.qdot(q, de, az, V, alpha_air)
        return out[:, 0] if one else out

    STALL_MARGIN = 0.2
    """rad: the velocity's angle of attack is looked at once some particle's is within this of the
    stall angle (the stall share is below 5e-5 there at M = 50: below it the lift's read stands)."""

    def _stalled_alpha(self, ua: np.ndarray, vw: np.ndarray) -> np.ndarray | None:
        """The angle of attack of each particle's air-relative velocity (N,) rad, atan2(w, ua) with
        ua = u + W (`_airspeed`'s per particle, W the pitot's head wind) or u, when the moment is
        stall-aware and some particle is near or past the stall; None otherwise (the lift's read
        alone, bit for bit)."""
        if not self.moment.stall_aware:
            return None
        alpha = np.arctan2(vw, ua)
        if not np.abs(alpha).max() > self.moment.p.alpha0 - self.STALL_MARGIN:
            return None
        return alpha

    def _velocity_step(self, vu: np.ndarray, vw: np.ndarray, q: np.ndarray, fu, fw
                       ) -> tuple[np.ndarray, np.ndarray]:
        """(u+, w+) (N,) m/s: the body velocity turned by the frame's pitch angle q dt, plus the
        specific force and gravity (fu, fw) of mid-frame turned by half of it. The exact solution
        of u' = fu - q w, w' = fw + q u for q constant over the frame and (fu, fw) taken at its
        middle; the Euler step lengthens (u, w) by sqrt(1 + (q dt)^2) a frame, 0.7 m/s at 40 m/s
        and 220 deg/s (a jammed elevator that frees; docs/faults.md, "The body velocity turned
        exactly")."""
        h = self.dt
        turn = h * q
        cf, sf = np.cos(turn), np.sin(turn)
        ch, sh = np.cos(0.5 * turn), np.sin(0.5 * turn)
        return (vu * cf - vw * sf + h * (fu * ch - fw * sh),
                vu * sf + vw * cf + h * (fu * sh + fw * ch))

    def close_frame(self, prior: np.ndarray, X: np.ndarray, rng: np.random.Generator | None = None,
                    frame: Frame | None = None) -> None:
        """In place, once the frame's correction has moved X (n, N): theta += dt (q+ - q) / 2, so
        that theta over the frame is the trapezoid of its pitch rates, q of the prior (n, N) (the same
        particles before the step) and q+ as the gyro corrected it, not as the moment predicted it.
        A surface that snaps pitches the aircraft at ~100 deg/s within a frame; theta + q dt alone
        then lags by dt (q+ - q) / 2 per frame. With `rotation` the body velocity (u, w) turns by
        that angle too. With `angle_spread` (parts.frame_angle = "spread") the angle is drawn
        between the rectangle rules (`_spread_angle`); with `snap`, only in a frame whose gyro reading
        (frame: this step's) snapped."""
        turn = (0.5 * self.dt) * (X[4] - prior[4])
        if self.angle_spread is not None and rng is not None:
            turn = self._spread_angle(turn, rng, frame)
        X[3] += turn
        if self.rotation:
            c, s = np.cos(turn), np.sin(turn)
            X[1], X[2] = X[1] * c - X[2] * s, X[1] * s + X[2] * c

    def _spread_angle(self, turn: np.ndarray, rng: np.random.Generator, frame: Frame | None = None
                      ) -> np.ndarray:
        """The frame's extra angle (N,) rad, drawn per particle between the rectangle rules.

        The pitch angle over a frame, the integral of q, lies between dt q and dt q+ when q moves
        one way within it: the trapezoid plus or minus |turn|. A surface that snaps changes q by
        100 deg/s within a frame, somewhere in it, and the trapezoid is then up to 2.5 deg off
        (docs/faults.md, "The frame's angle spread"). Where that bound exceeds theta's process
        noise over a frame (`angle_spread`) on some particle, each particle's angle is drawn
        uniform on it, so the cloud spans the attitude the aircraft may have and the attitude
        sensor picks it; elsewhere the trapezoid stands and no draw is made. With `snap`
        (parts.frame_angle = "snap") the test is the gyro's reading: in turbulence, where it moves
        by at most ~10 deg/s a frame, no draw is ever made, nor where the cloud's own q swings
        while the gyro is held faulty."""
        half = np.abs(turn)
        fire = self.snap.snapped(frame) if self.snap is not None else half.max() > self.angle_spread
        if not fire:
            return turn
        return turn + half * rng.uniform(-1.0, 1.0, turn.shape)


class GyroSnap:
    """Whether the aircraft's pitch rate snapped within a frame, read from the gyro (parts.frame_angle
    = "snap"): its reading moved by more than `limit` (rad/s) since its last frame. A surface that
    frees moves it by 30-75 deg/s a frame; moderate turbulence by at most ~10 (p99.9 ~4) in the
    real worlds. The cloud's own pitch rates are no test: while most of the cloud holds the gyro
    faulty, its q follows the moment model and swings by tens of deg/s a frame with no snap
    (real-actuators run 15 during a jam).

    row: the gyro's row among the estimator's observed rows; limit: rad/s."""

    def __init__(self, row: int, limit: float) -> None:
        self.row = int(row)
        self.limit = float(limit)
        self.last: float | None = None
        """The gyro's last reading (rad/s); None before the first."""

    def snapped(self, frame: Frame | None) -> bool:
        """True when this frame's gyro reading is more than `limit` from the last one (and keep it)."""
        if frame is None or not frame.mask[self.row]:
            return False
        q = float(frame.yv[frame.row_of[self.row]])
        moved = self.last is not None and abs(q - self.last) > self.limit
        self.last = q
        return moved
