"""Longitudinal autopilot: LQR with integral action plus an altitude guidance loop.

Thesis [3.7]-[3.8] and Appendix C, SPEC section 4; designed in discrete time (python-control
`lqr` on a discrete state-space model) at the model's sample time dt.

Inner loop (control, [3.7]): on the reduced deviation state dzr = [du, dw, dtheta, dq] (p_d does
not enter the other rows of F) augmented with two integrators of the tracking errors
    x_gamma_{k+1} = x_gamma_k + dt (gamma_c - gamma_k),  gamma = theta - alpha,
    x_V_{k+1}     = x_V_k     + dt (V_c - V_k),
with alpha and V linearised at trim as in eq. 3.54-3.55 (alpha ~ alpha* + (-w* du + u* dw) / Va*^2,
V ~ Va* + (u* du + w* dw) / Va*), the LQR gain K gives [d delta_e, d delta_t] = -K [dzr, x_gamma, x_V].

Outer loop (guidance, [3.8]): the inner closed loop plus p_d and an altitude-error integrator
x_h_{k+1} = x_h_k + dt (h_c - h); a second LQR gives the flight-path-angle command
gamma_raw = -L [p_d - p_d_c, dzr, x_gamma, x_V, x_h], saturated to +-28 deg. Anti-windup by
back-calculation with gain K_aw = 2 (1/s): x_h also integrates K_aw (gamma_sat - gamma_raw) / g_h,
g_h = d gamma_raw / d x_h, so the unsaturated command relaxes to the limit with a 0.5 s time
constant while saturated.

Actuator limits: delta_e in +-30 deg, delta_t in [0, 1]. Conditional integration: while an actuator
sits on its limit, an inner integrator is held when its step would push that actuator further past
the limit (through its column of K), and integrates otherwise. (Holding both whenever either
actuator saturated locked the loop in a dive: an overspeed held the throttle at 0, and the frozen
flight-path integrator then ignored a climb command all the way to the ground, real-jsbsim run 78.)

Speed: the gains of a design model are computed once per process (`design_gains` is cached by
the model's F, B, trim and dt), and `update` runs on Python floats (no per-step numpy calls).
"""

from __future__ import annotations

import math

import control
import numpy as np

from fdir_service.airframe.linearize import LinearModel
from sim_bridge.scenario import CommandConfig

GAMMA_LIMIT_RAD = np.radians(28.0)
ELEVATOR_LIMIT_RAD = np.radians(30.0)
THROTTLE_LIMITS = (0.0, 1.0)
ANTI_WINDUP_GAIN = 2.0

# LQR weights (discrete design; states in SI). Chosen for a well-damped response: see docs/simulator.md.
# Inner: [du, dw, dtheta, dq, x_gamma, x_V]; inputs [delta_e, delta_t].
INNER_Q = np.diag([0.5, 0.1, 10.0, 1.0, 1000.0, 2.0])
INNER_R = np.diag([20.0, 20.0])
# Outer: [e_pd, du, dw, dtheta, dq, x_gamma, x_V, x_h]; input gamma_c.
OUTER_Q = np.diag([0.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.002])
OUTER_R = np.array([[50.0]])


def design_gains(model: LinearModel, inner_q: np.ndarray = INNER_Q, inner_r: np.ndarray = INNER_R,
                 outer_q: np.ndarray = OUTER_Q, outer_r: np.ndarray = OUTER_R) -> dict[str, np.ndarray]:
    """The inner gain K (2, 6), the outer gain L (1, 8) and the linearised output rows."""
    F, B, dt = model.F, model.B, model.dt
    zs = model.trim.z
    us, ws = zs[1], zs[2]
    va2 = us * us + ws * ws
    va = np.sqrt(va2)
    h_gamma = np.array([ws / va2, -us / va2, 1.0, 0.0])     # gamma = theta - alpha (linearised)
    h_v = np.array([us / va, ws / va, 0.0, 0.0])             # airspeed (linearised)
    Fr, Br = F[1:, 1:], B[1:, :]
    Fa = np.zeros((6, 6))
    Fa[:4, :4] = Fr
    Fa[4, :4] = -dt * h_gamma
    Fa[5, :4] = -dt * h_v
    Fa[4, 4] = Fa[5, 5] = 1.0
    Ba = np.vstack([Br, np.zeros((2, 2))])
    K, _, _ = control.lqr(control.ss(Fa, Ba, np.eye(6), np.zeros((6, 2)), dt), inner_q, inner_r)
    K = np.asarray(K)
    # Inner closed loop with gamma_c as input, extended with e_pd and x_h (outer design model).
    Fo = np.zeros((8, 8))
    Fo[0, 0] = 1.0
    Fo[0, 1:5] = F[0, 1:]
    Fo[0, 1:7] -= B[0] @ K                       # p_d row sees the inner control too
    Fo[1:7, 1:7] = Fa - Ba @ K
    Fo[7, 0] = dt                                # x_h integrates h_c - h = p_d - p_d_c
    Fo[7, 7] = 1.0
    Bo = np.zeros((8, 1))
    Bo[5, 0] = dt                                # gamma_c enters the gamma integrator
    L, _, _ = control.lqr(control.ss(Fo, Bo, np.eye(8), np.zeros((8, 1)), dt), outer_q, outer_r)
    return {"K": K, "L": np.asarray(L), "h_gamma": h_gamma, "h_v": h_v,
            "inner_closed": Fa - Ba @ K, "outer_closed": Fo - Bo @ np.asarray(L)}


_GAINS: dict[bytes, dict[str, np.ndarray]] = {}


def _default_gains(model: LinearModel) -> dict[str, np.ndarray]:
    """design_gains(model) with the default weights, once per (F, B, trim, dt) in this process."""
    key = b"".join(np.ascontiguousarray(a, dtype=float).tobytes()
                   for a in (model.F, model.B, model.trim.z, model.trim.u, np.array([model.dt])))
    g = _GAINS.get(key)
    if g is None:
        g = design_gains(model)
        if len(_GAINS) > 32:
            _GAINS.clear()
        _GAINS[key] = g
    return {k: v.copy() for k, v in g.items()}


class Autopilot:
    """Altitude and airspeed hold on a navigation estimate; `update` once per frame."""

    def __init__(self, model: LinearModel, command: CommandConfig, dt: float) -> None:
        if abs(dt - model.dt) > 1e-12:
            raise ValueError(f"autopilot dt {dt} s differs from the design model's {model.dt} s")
        self.model = model
        self.command = command
        self.dt = dt
        g = _default_gains(model)
        self.K, self.L = g["K"], g["L"][0]
        self.h_gamma, self.h_v = g["h_gamma"], g["h_v"]
        self.z_trim = model.trim.z.copy()
        self.u_trim = model.trim.u.copy()
        self.va_trim = float(np.hypot(self.z_trim[1], self.z_trim[2]))
        self.gamma_trim = float(model.trim.gamma)
        self._g_h = -self.L[7]        # d gamma_raw / d x_h
        self._steps = sorted(command.altitude_steps, key=lambda s: s.t_s)
        # Python-float copies for `update`.
        self._k = [list(map(float, row)) for row in self.K]
        self._l = list(map(float, self.L))
        self._hg = list(map(float, self.h_gamma))
        self._hv = list(map(float, self.h_v))
        self._zt = list(map(float, self.z_trim))
        self._ut = list(map(float, self.u_trim))
        self._va_c = float(command.airspeed_mps)
        self.reset()

    def reset(self) -> None:
        """Integrators to zero, commands to the trim."""
        self.x_gamma = 0.0
        self.x_v = 0.0
        self.x_h = 0.0
        self.gamma_command = self.gamma_trim
        self.gamma_raw = self.gamma_trim
        self.saturated = False
        self.u = self.u_trim.copy()

    def altitude_command(self, t: float) -> float:
        """Commanded altitude (m) at time t (s): the last altitude step reached, else command.altitude_m;
        with command.climb_rate_mps, each step is a ramp at that rate from where the command was."""
        h = self.command.altitude_m
        rate = self.command.climb_rate_mps
        for st in self._steps:
            if t < st.t_s - 1e-9:
                break
            if rate is None:
                h = st.altitude_m
            else:
                dh = st.altitude_m - h
                h += math.copysign(min(abs(dh), rate * (t - st.t_s)), dh)
        return h

    def update(self, t: float, z_nav: np.ndarray) -> np.ndarray:
        """Input u (2,) = [delta_e rad, delta_t] for the navigation state z_nav (5,) at time t (s)."""
        pd, zu, zw, zth, zq = (z_nav.tolist() if isinstance(z_nav, np.ndarray)
                               else [float(v) for v in z_nav])
        zt = self._zt
        d1, d2, d3, d4 = zu - zt[1], zw - zt[2], zth - zt[3], zq - zt[4]
        e_pd = pd + self.altitude_command(t)                       # p_d - p_d_c
        hg, hv = self._hg, self._hv
        gamma = self.gamma_trim + (hg[0] * d1 + hg[1] * d2 + hg[2] * d3 + hg[3] * d4)
        va = self.va_trim + (hv[0] * d1 + hv[1] * d2 + hv[2] * d3 + hv[3] * d4)
        xg, xv, xh = self.x_gamma, self.x_v, self.x_h
        # Outer loop: flight-path-angle command, saturated, with back-calculation anti-windup.
        L = self._l
        gamma_dev = -(L[0] * e_pd + L[1] * d1 + L[2] * d2 + L[3] * d3 + L[4] * d4
                      + L[5] * xg + L[6] * xv + L[7] * xh)
        self.gamma_raw = self.gamma_trim + gamma_dev
        gamma_c = _clip(self.gamma_raw, -GAMMA_LIMIT_RAD, GAMMA_LIMIT_RAD)
        self.gamma_command = gamma_c
        # Inner loop.
        k0, k1 = self._k
        u0 = self._ut[0] - (k0[0] * d1 + k0[1] * d2 + k0[2] * d3 + k0[3] * d4 + k0[4] * xg
                            + k0[5] * xv)
        u1 = self._ut[1] - (k1[0] * d1 + k1[1] * d2 + k1[2] * d3 + k1[3] * d4 + k1[4] * xg
                            + k1[5] * xv)
        s0 = _clip(u0, -ELEVATOR_LIMIT_RAD, ELEVATOR_LIMIT_RAD)
        s1 = _clip(u1, THROTTLE_LIMITS[0], THROTTLE_LIMITS[1])
        self.saturated = s0 != u0 or s1 != u1          # NaN counts as saturated, as in numpy
        # Integrators (forward Euler, as in the design model).
        self.x_h = xh + self.dt * (e_pd + ANTI_WINDUP_GAIN * (gamma_c - self.gamma_raw) / self._g_h)
        dxg, dxv = self.dt * (gamma_c - gamma), self.dt * (self._va_c - va)
        if not self.saturated:
            self.x_gamma = xg + dxg
            self.x_v = xv + dxv
        else:
            over = (_past_limit(u0, s0), _past_limit(u1, s1))
            if not _deepens(over, k0[4] * dxg, k1[4] * dxg):
                self.x_gamma = xg + dxg
            if not _deepens(over, k0[5] * dxv, k1[5] * dxv):
                self.x_v = xv + dxv
        self.u = np.array([s0, s1])
        return np.array([s0, s1])


def _past_limit(u: float, sat: float) -> int:
    """+1 if the unsaturated command u is above its limit sat, -1 if below, 0 if within (NaN: +1)."""
    if u == sat:
        return 0
    return -1 if u < sat else 1


def _deepens(over: tuple[int, int], k_e: float, k_t: float) -> bool:
    """True if an integrator step whose K entries times the step are k_e, k_t (the actuators move by
    -k_e, -k_t) pushes a saturated actuator further past its limit; True for a NaN step (held)."""
    if math.isnan(k_e) or math.isnan(k_t):
        return True
    return (over[0] != 0 and -k_e * over[0] > 0) or (over[1] != 0 and -k_t * over[1] > 0)


def _clip(x: float, lo: float, hi: float) -> float:
    """np.clip for one float (NaN stays NaN)."""
    if x < lo:
        return float(lo)
    if x > hi:
        return float(hi)
    return x


class ElevatorDoublet:
    """Identification excitation on top of the autopilot's elevator (`sim-bridge fly --doublet DEG`):
    +amplitude for width_s, then -amplitude for width_s, every period_s from start_s (the flight
    time, s); the sum stays within the elevator's travel. The doublet moves the elevator
    independently of the state, which the autopilot's own corrections do not (`fdir identify`)."""

    def __init__(self, amplitude_rad: float, period_s: float = 10.0, width_s: float = 0.5,
                 start_s: float = 5.0) -> None:
        if not (math.isfinite(amplitude_rad) and 0.0 <= amplitude_rad <= ELEVATOR_LIMIT_RAD):
            raise ValueError(f"--doublet: expected 0 to {math.degrees(ELEVATOR_LIMIT_RAD):g} deg, "
                             f"got {math.degrees(amplitude_rad):g}")
        self.amplitude = float(amplitude_rad)
        self.period, self.width, self.start = float(period_s), float(width_s), float(start_s)

    def offset(self, t: float) -> float:
        """The doublet's elevator (rad) at flight time t (s)."""
        if self.amplitude == 0.0 or t < self.start - 1e-9:
            return 0.0
        phase = (t - self.start + 1e-9) % self.period
        if phase < self.width:
            return self.amplitude
        return -self.amplitude if phase < 2.0 * self.width else 0.0

    def add(self, t: float, u: np.ndarray) -> np.ndarray:
        """u (2,) = [delta_e rad, delta_t] with the doublet added to the elevator (a new array)."""
        out = np.array(u, dtype=float)
        out[0] = _clip(out[0] + self.offset(t), -ELEVATOR_LIMIT_RAD, ELEVATOR_LIMIT_RAD)
        return out


class ExcitedAutopilot:
    """An autopilot with an `ElevatorDoublet` added to its output (`sim-bridge fly --doublet`);
    everything else is the autopilot's own."""

    def __init__(self, autopilot: Autopilot, doublet: ElevatorDoublet) -> None:
        self.autopilot, self.doublet = autopilot, doublet

    def __getattr__(self, name: str):
        return getattr(self.autopilot, name)

    def update(self, t: float, z_nav: np.ndarray) -> np.ndarray:
        """The autopilot's input u (2,) for z_nav at time t (s), the doublet added to its elevator."""
        return self.doublet.add(t, self.autopilot.update(t, z_nav))
