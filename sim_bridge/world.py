"""The true airframe of a scenario (SPEC sections 2 and 7).

Linear truth: the discrete model dz_{k+1} = F dz_k + B du_k about trim, with the thesis's printed
or the derived F, B (`scenario.truth.linear_matrices`). Nonlinear truth: one classical RK4 step of
`fdir_service.airframe.derivatives` per frame, input held over the frame (zero-order hold).
Both start at the trim of `scenario.truth` (airspeed, altitude, level flight). Actuator faults act
on the commanded input (`fault_types.ActuatorFaults`): a bias adds, u_applied = u_cmd + f_a
(elevator in rad, throttle as a fraction); a jam holds the input, a loss of effectiveness scales it.

Speed: the nonlinear truth steps with `rk4_step_scalar` (Python floats; equal to `rk4_step` to
~1e-15), and the trim / linear model of a (airframe, trim point, dt) is solved once per process.

Real sky (`scenario.sky`, docs/real-world.md; off in the thesis experiments): the state stays the
inertial one (u, w over the ground, body axes), the aerodynamics see the air. With the wind's body
components (u_w, w_w) (steady + shear + gusts from `wind.py`, plus Dryden u_g, w_g) and
z_air = [p_d, u - u_w, w - w_w, theta, q]:
    z' = f(z_air) + [-u_w sin(theta) + w_w cos(theta), -q w_w, q u_w, 0, dq_gust]
(f the airframe's equations; the kinematic terms of f use the air-relative velocity, the
correction puts the inertial ones back), with the pitch-rate gust q_g entering the pitch damping,
dq_gust = -rho V S c^2 C_m_q q_g / (4 Jy). The wind is held over each frame. Dispersion: each run's
airframe is drawn (`dispersed_airframe`) from the world's declared fractions; the truth starts at
that airframe's own trim. The autopilot and the estimator keep the nominal airframe.
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from typing import Protocol

import numpy as np

from fdir_service.airframe import AirframeParams, trim
from fdir_service.airframe.dynamics import derivatives_scalar, rk4_step_scalar
from fdir_service.airframe.linearize import linear_model
from sim_bridge.fault_types import ActuatorFaults, unit_gain
from sim_bridge.scenario import Scenario
from sim_bridge.turbulence import Dryden
from sim_bridge.wind import ned_to_body, wind_ned
from sim_bridge.world_config import DispersionConfig


@lru_cache(maxsize=32)
def _trim(params: AirframeParams, airspeed: float, altitude: float):
    return trim(params, airspeed, altitude)


@lru_cache(maxsize=32)
def _linear(params: AirframeParams, which: str, airspeed: float, altitude: float, dt: float):
    return linear_model(params, which, airspeed, altitude, dt)


def _cached(fn, *args):
    """fn(*args) once per process for hashable args (AirframeParams is frozen); else uncached."""
    try:
        return fn(*args)
    except TypeError:       # unhashable (a parameter set built with array fields)
        return fn.__wrapped__(*args)


class TruthEngine(Protocol):
    """What the simulator needs of a truth aircraft (`Truth`, `jsbsim_truth.JSBSimTruth`).

    trim: .z (5,), .u (2,) where it starts; z (5,) = [p_d, u, w, theta, q] now (SI; u, w over the
    ground, body axes); u_applied (2,) [delta_e rad, delta_t 0..1] over the last frame.
    """

    trim: object
    z: np.ndarray
    u_applied: np.ndarray

    def reset(self) -> None: ...

    def step(self, u_cmd: np.ndarray, fault_values: np.ndarray,
             active: np.ndarray | None = None) -> np.ndarray:
        """Advance one frame with u_cmd (2,) and the actuator faults' profile values (nf,) and
        activity (nf,) bool (None: value != 0) held; the new z."""
        ...

    def air_data(self) -> AirData:
        """The air-relative quantities at the current state (for the pitot and accelerometer)."""
        ...


@dataclasses.dataclass(frozen=True)
class AirData:
    """airspeed_mps: |air-relative velocity|; specific_force (2,): body [a_x, a_z] m/s^2 that an
    accelerometer measures (acceleration minus gravity); wind_ned (2,): (north, down) m/s of the
    air at the aircraft, turbulence included; lateral (4,): the roll attitude (rad), the body-y
    velocity over the ground (m/s) and the roll and yaw rates p, r (rad/s), 0 for the longitudinal
    internal aircraft (wings level)."""

    airspeed_mps: float
    specific_force: np.ndarray
    wind_ned: np.ndarray
    lateral: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4))


def make_truth(scenario: Scenario, params: AirframeParams, rng: np.random.Generator) -> TruthEngine:
    """The world's truth aircraft: the internal equations, or JSBSim (`[world] engine`)."""
    if scenario.sky.engine == "jsbsim":
        from sim_bridge.jsbsim_truth import JSBSimTruth

        return JSBSimTruth(scenario, params, rng)
    return Truth(scenario, params, rng)


def dispersed_airframe(params: AirframeParams, dispersion: DispersionConfig,
                       rng: np.random.Generator) -> AirframeParams:
    """params with each dispersed field scaled by 1 + U(-fraction, +fraction), in sorted key order."""
    changes = {k: getattr(params, k) * (1.0 + rng.uniform(-f, f))
               for k, f in sorted(dispersion.fractions.items())}
    return dataclasses.replace(params, **changes)


def derivatives_in_wind(z, u, p: AirframeParams, wind_body, q_gust: float) -> tuple[float, ...]:
    """dz/dt (5 floats) of the inertial state z in air moving at wind_body (u_w, w_w) m/s with the
    pitch-rate gust q_gust rad/s (module docstring)."""
    pd, ub, wb, th, q = z
    uw, ww = wind_body
    f = derivatives_scalar(ub - uw, wb - ww, th, q, u[0], u[1], p)
    va = math.hypot(ub - uw, wb - ww)
    dq = -p.rho * va * p.S * p.c * p.c * p.C_mq * q_gust / (4.0 * p.Jy)
    return (f[0] - uw * math.sin(th) + ww * math.cos(th), f[1] - q * ww, f[2] + q * uw, f[3], f[4] + dq)


def rk4_in_wind(z, u, dt: float, p: AirframeParams, wind_ned_held, gust) -> tuple[float, ...]:
    """One RK4 step (dt s) with the NED wind (2,) and the Dryden gust (u_g, w_g, q_g) held."""
    n, d = wind_ned_held
    ug, wg, qg = gust

    def rhs(x):
        wb = ned_to_body(n, d, x[3])
        return derivatives_in_wind(x, u, p, (wb[0] + ug, wb[1] + wg), qg)

    k1 = rhs(z)
    k2 = rhs([a + 0.5 * dt * b for a, b in zip(z, k1, strict=True)])
    k3 = rhs([a + 0.5 * dt * b for a, b in zip(z, k2, strict=True)])
    k4 = rhs([a + dt * b for a, b in zip(z, k3, strict=True)])
    return tuple(a + dt / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
                 for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4, strict=True))


class Truth:
    """The true state z (5,) = [p_d, u, w, theta, q] (SI), stepped once per frame of scenario.dt_s."""

    def __init__(self, scenario: Scenario, params: AirframeParams, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.rng = rng            # disturbances only (none in the thesis scenarios)
        sky = scenario.sky
        dispersion_ss, turbulence_ss = np.random.SeedSequence(int(rng.integers(2**63))).spawn(2) \
            if (sky.dispersion.active or sky.turbulence.active) else (None, None)
        self.nominal = params
        one = sky.dispersion.aircraft_seed
        aircraft = np.random.default_rng(dispersion_ss if one is None else one)
        self.params = (dispersed_airframe(params, sky.dispersion, aircraft) if sky.dispersion.active
                       else params)
        params = self.params
        self._turbulence_ss = turbulence_ss
        self.dt = scenario.dt_s
        tc = scenario.truth
        self.kind = tc.model
        if tc.model == "linear":
            self.model = _cached(_linear, params, tc.linear_matrices, tc.airspeed_mps,
                                 tc.altitude_m, self.dt)
            self.trim = self.model.trim
        else:
            self.model = None
            self.trim = _cached(_trim, params, tc.airspeed_mps, tc.altitude_m)
        self.actuator_faults = ActuatorFaults(scenario.faults, engine_out=self.engine_out)
        self.reset()

    def engine_out(self, delta_t: float, g: float) -> float:
        """The throttle at which the airframe's propeller gives g (clipped to [0, 1]) of the thrust of
        delta_t at the frame's airspeed: k_T (k_m^2 d'^2 - V^2) = g k_T (k_m^2 delta_t^2 - V^2)
        (SPEC section 2), so g = 0 is zero thrust, not the model's windmill drag at delta_t = 0."""
        g = unit_gain(g)
        zero = self.airspeed() / self.params.k_motor
        return math.sqrt(g * delta_t * delta_t + (1.0 - g) * zero * zero)

    def airspeed(self) -> float:
        """|air-relative velocity| (m/s) now, in the wind and gust held over the frame."""
        z = self.z
        wb = ned_to_body(self.wind[0], self.wind[1], float(z[3])) + self.gust[:2]
        return math.hypot(z[1] - wb[0], z[2] - wb[1])

    def reset(self) -> None:
        """Back to trim (and the wind's clock to 0; the turbulence restarts from its stream)."""
        self.z = self.trim.z.copy()
        self.u_applied = self.trim.u.copy()
        self.actuator_faults.reset()
        self.t = 0.0
        sky, tc = self.scenario.sky, self.scenario.truth
        self.dryden = (Dryden(sky.turbulence.wind_6m_mps, tc.altitude_m, tc.airspeed_mps, self.params.b,
                              self.dt, np.random.default_rng(self._turbulence_ss))
                       if sky.turbulence.active else None)
        self.gust = np.zeros(3)
        self.wind = np.zeros(2)
        if sky.moving_air and self.model is None:
            self._air()                  # start in trim with the air: the ground velocity carries the wind
            self.z[1:3] += ned_to_body(self.wind[0], self.wind[1], float(self.z[3])) + self.gust[:2]

    def applied_input(self, u_cmd: np.ndarray, fault_values: np.ndarray,
                      active: np.ndarray | None = None) -> np.ndarray:
        """The input (2,) the airframe feels: u_cmd (2,) with the actuator faults (profile values
        (nf,) SI, activity (nf,) bool or None: value != 0), `fault_types.ActuatorFaults.applied`."""
        return self.actuator_faults.applied(u_cmd, fault_values, active, self.u_applied)

    def _air(self) -> None:
        """The wind (NED) and the gust held over the frame starting now (at self.t)."""
        tc = self.scenario.truth
        self.wind = np.array(wind_ned(self.scenario.sky.wind, self.t, -float(self.z[0]), tc.airspeed_mps))
        if self.dryden is not None:
            self.gust = self.dryden.step()

    def step(self, u_cmd: np.ndarray, fault_values: np.ndarray,
             active: np.ndarray | None = None) -> np.ndarray:
        """Advance one frame with u_cmd (2,) and the faults' profile values (nf,) and activity
        (nf,) bool (None: value != 0) held; returns the new z."""
        u = self.applied_input(u_cmd, fault_values, active)
        self.actuator_faults.commit(fault_values, active, self.u_applied)
        if self.model is not None:
            self.z = self.model.step(self.z, u)
        elif self.scenario.sky.moving_air:
            self.z = np.array(rk4_in_wind(self.z.tolist(), u.tolist(), self.dt, self.params,
                                          self.wind.tolist(), self.gust.tolist()))
        else:
            self.z = np.array(rk4_step_scalar(self.z.tolist(), u.tolist(), self.dt, self.params))
        self.u_applied = u
        self.t += self.dt
        if self.scenario.sky.moving_air and self.model is None:
            self._air()
        return self.z

    def air_data(self) -> AirData:
        """Airspeed, specific force and wind at the current state with the last applied input."""
        z = self.z.tolist()
        wb = ned_to_body(self.wind[0], self.wind[1], z[3]) + self.gust[:2]
        d = derivatives_in_wind(z, self.u_applied.tolist(), self.params, wb, float(self.gust[2]))
        g, th, q = self.params.g, z[3], z[4]
        ax = d[1] + q * z[2] + g * math.sin(th)
        az = d[2] - q * z[1] - g * math.cos(th)
        c, s = math.cos(th), math.sin(th)       # the Dryden gust back to NED, for the total wind
        ug, wg = float(self.gust[0]), float(self.gust[1])
        wind = self.wind + np.array([ug * c + wg * s, -ug * s + wg * c])
        return AirData(math.hypot(z[1] - wb[0], z[2] - wb[1]), np.array([ax, az]), wind)
