"""JSBSim as the truth aircraft: `[world] engine = "jsbsim"` (docs/simulator.md, "JSBSim engine").

An independent flight-dynamics engine for the world: JSBSim's 6-DOF equations, standard
atmosphere, WGS84 gravity and its own propulsion fly the Aerosonde model of
config/jsbsim/aircraft/aerosonde/aerosonde.xml (JSBSim root: `jsbsim_root()`, beside the airframe
files). `JSBSimTruth` honours `world.TruthEngine` as `world.Truth` does:

- z (5,) = [p_d, u, w, theta, q], SI: p_d = -altitude above sea level (m), u, w the body-axis
  velocity over the ground (m/s), theta pitch (rad), q body pitch rate (rad/s);
- inputs in the project's convention: delta_e (rad, positive pitches nose down) is
  fcs/elevator-pos-rad; delta_t (0..1, more is more thrust) is fcs/throttle-cmd-norm, which the
  model's motor controller reads as a propeller speed command (aerosonde.xml, channel "Throttle");
  actuator faults act on the command exactly as in `Truth.applied_input`; the input is held over
  each frame;
- one frame of scenario.dt_s runs ceil(120 dt) JSBSim steps (120 Hz at dt = 0.05 s).

Start (`reset`): a fresh JSBSim instance at scenario.truth.airspeed_mps (true airspeed) and
altitude_m, wings level, heading north, at 45 deg N; the propeller is spun up (JSBSim's trim
searches the propeller's speed from where it is, with 0.5-s steps that do not converge from rest),
then JSBSim's own longitudinal trim (alpha, throttle, pitch trim for u', w', q' = 0), the aileron
and rudder trims for p' = r' = 0 (the propeller's torque), and the longitudinal trim again; then
the motor controller's speed feedback is switched on (it is off while JSBSim trims, since its
propeller search holds the motor power fixed). The lateral axes are held by the model's wing
leveller (aileron / rudder on roll, heading and sideslip; the project's autopilot is longitudinal
only).

Air (`scenario.sky`): the world's steady wind, shear and 1-cosine gusts (`wind.wind_ned`, at the
frame's start, held over the frame) are JSBSim's steady wind (atmosphere/wind-north-fps,
wind-down-fps); the run starts in trim with the air, as `Truth` (the still-air trim with the wind
at t = 0 added to the velocity over the ground). Turbulence is JSBSim's MIL-F-8785C Dryden model
(atmosphere/turb-type 4, Tustin discretisation) with the world's wind at 20 ft (6 m) and the
severity (probability-of-exceedance curve) of that wind's class, light / moderate / severe =
curves 3 / 4 / 6 (1e-2 / 1e-3 / 1e-5; MIL-F-8785C); it starts after the trim, from rest. Between
1000 and 2000 ft JSBSim interpolates towards the medium/high-altitude intensities, so at 500 m
(1640 ft) its turbulence is ~1.6x the internal model's (which holds the 1000-ft values).

Randomness: only the turbulence's, from JSBSim's generator seeded (simulation/randomseed) with
one draw from `rng` when the world has turbulence: same seed, same bits. Airframe dispersion is
not modelled (the JSBSim aircraft is its own airframe): a world asking for it is refused.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import jsbsim
import numpy as np

from fdir_service.airframe import AirframeParams
from fdir_service.paths import config_dir
from sim_bridge.fault_types import ActuatorFaults
from sim_bridge.scenario import Scenario
from sim_bridge.wind import wind_ned
from sim_bridge.world import AirData

MODEL = "aerosonde"
RATE_HZ = 120.0
"""JSBSim steps per second (at least): a frame of dt runs ceil(RATE_HZ dt) steps."""
FT = 0.3048
KNOT = 0.514444
ELEVATOR_RANGE_RAD = math.radians(30.0)
"""fcs/elevator-pos-rad per unit of fcs/elevator-cmd-norm (the model's pitch channel)."""
SEVERITY = ((22.5 * KNOT, 3), (37.5 * KNOT, 4), (math.inf, 6))
"""(wind at 6 m below which, MIL-F-8785C probability-of-exceedance curve): light 15 kt -> 3
(1e-2), moderate 30 kt -> 4 (1e-3), severe 45 kt -> 6 (1e-5)."""
TURB_TUSTIN = 4
TRIM_LONGITUDINAL, TRIM_NONE = 0, 6
"""JSBSim's trim modes used (tLongitudinal: alpha, throttle, pitch trim; tNone: no control)."""
ESC_SPEED_GAIN = 40.0 * 0.737562
"""The motor controller's speed feedback in flight, ft lbf/s per rad/s (40 W per rad/s)."""
LATITUDE_DEG = 45.0
"""Where the flight starts (longitude 0): WGS84 gravity 9.806 m/s^2 at 500 m, beside the airframe's 9.81."""
SPIN_UP_RPM = 3000.0
"""Propeller speed reached before the trim (its steady-state search steps 0.5 s at a time)."""

_P = {  # short name -> JSBSim property
    "h": "position/h-sl-meters", "u": "velocities/u-fps", "w": "velocities/w-fps",
    "theta": "attitude/theta-rad", "q": "velocities/q-rad_sec", "vt": "velocities/vt-fps",
    "fx": "forces/fbx-total-lbs", "fz": "forces/fbz-total-lbs", "mass": "inertia/mass-slugs",
    "wind_n": "atmosphere/wind-north-fps", "wind_d": "atmosphere/wind-down-fps",
    "total_n": "atmosphere/total-wind-north-fps", "total_d": "atmosphere/total-wind-down-fps",
    "elevator": "fcs/elevator-cmd-norm", "throttle": "fcs/throttle-cmd-norm",
    "elevator_rad": "fcs/elevator-pos-rad", "pitch_trim": "fcs/pitch-trim-cmd-norm",
    "aileron": "fcs/aileron-cmd-norm", "rudder": "fcs/rudder-cmd-norm",
    "pdot": "accelerations/pdot-rad_sec2", "rdot": "accelerations/rdot-rad_sec2",
    "rpm": "propulsion/engine/propeller-rpm", "alpha": "aero/alpha-rad",
    "phi": "attitude/phi-rad", "v": "velocities/v-fps",
    "p": "velocities/p-rad_sec", "r": "velocities/r-rad_sec",
}

_CARRIED = {  # initial condition <- the trimmed state it is set from (the wind is added to vn, vd)
    "h-sl-ft": "position/h-sl-ft", "theta-rad": "attitude/theta-rad", "phi-rad": "attitude/phi-rad",
    "psi-true-rad": "attitude/psi-rad", "vn-fps": "velocities/v-north-fps",
    "ve-fps": "velocities/v-east-fps", "vd-fps": "velocities/v-down-fps", "p-rad_sec": "velocities/p-rad_sec",
    "q-rad_sec": "velocities/q-rad_sec", "r-rad_sec": "velocities/r-rad_sec",
}


def jsbsim_root() -> Path:
    """JSBSim's root folder: config/jsbsim (aircraft/, engine/), beside the airframe files."""
    return config_dir() / "jsbsim"


def turbulence_severity(wind_6m_mps: float) -> int:
    """JSBSim's milspec severity (MIL-F-8785C exceedance curve, 1..7) for the wind at 6 m (m/s)."""
    return next(s for limit, s in SEVERITY if wind_6m_mps < limit)


@dataclasses.dataclass(frozen=True)
class JSBSimTrim:
    """JSBSim's trim: z (5,) [p_d, u, w, theta, q] SI, u (2,) [delta_e rad, delta_t], alpha and
    gamma (rad, air-relative), airspeed (m/s) and altitude (m) asked for."""

    airspeed: float
    altitude: float
    alpha: float
    gamma: float
    z: np.ndarray
    u: np.ndarray

    def as_dict(self) -> dict[str, float]:
        """In readable units (m, m/s, deg, throttle fraction), as `Trim.as_dict`."""
        return {"airspeed_mps": self.airspeed, "altitude_m": self.altitude,
                "alpha_deg": math.degrees(self.alpha), "gamma_deg": math.degrees(self.gamma),
                "u_mps": float(self.z[1]), "w_mps": float(self.z[2]),
                "theta_deg": math.degrees(self.z[3]), "delta_e_deg": math.degrees(self.u[0]),
                "delta_t": float(self.u[1])}


def _quiet() -> None:
    """No JSBSim banner or loading report (its debug level is process-wide)."""
    jsbsim.FGJSBBase().debug_lvl = 0


class JSBSimTruth:
    """The true state z (5,) from JSBSim, stepped once per frame of scenario.dt_s (module docstring)."""

    def __init__(self, scenario: Scenario, params: AirframeParams, rng: np.random.Generator) -> None:
        sky = scenario.sky
        if sky.dispersion.active:
            raise ValueError(f"{scenario.id}: [world.dispersion] is not modelled by the JSBSim engine "
                             "(its aircraft is config/jsbsim/aircraft/aerosonde)")
        self.scenario = scenario
        self.rng = rng
        self.nominal = self.params = params       # the autopilot's airframe; JSBSim flies its own
        self.dt = scenario.dt_s
        self.substeps = max(1, math.ceil(RATE_HZ * self.dt - 1e-9))
        self._seed = int(rng.integers(1, 2**31 - 1)) if sky.turbulence.active else 0
        self.actuator_faults = ActuatorFaults(scenario.faults)
        self.reset()

    # ------------------------------------------------------------------ TruthEngine

    def reset(self) -> None:
        """A fresh JSBSim instance trimmed at the scenario's airspeed and altitude (the wind's
        clock to 0; the turbulence restarts from its seed)."""
        _quiet()
        self.fdm = jsbsim.FGFDMExec(str(jsbsim_root()))
        self.fdm.set_debug_level(0)
        if not self.fdm.load_model(MODEL):
            raise RuntimeError(f"JSBSim could not load {MODEL} from {jsbsim_root()}")
        self.fdm.set_dt(self.dt / self.substeps)
        pm = self.fdm.get_property_manager()
        self._n = {k: pm.get_node(v) for k, v in _P.items()}
        self.t = 0.0
        self._initial_conditions()
        self._spin_up()
        self._initial_conditions()
        self.trim = self._trim()
        self._carry_the_wind()
        self.fdm["fcs/esc-speed-gain"] = ESC_SPEED_GAIN
        self._start_turbulence()
        self.z = self._read_z()
        self.u_applied = self.trim.u.copy()
        self.actuator_faults.reset()

    def applied_input(self, u_cmd: np.ndarray, fault_values: np.ndarray,
                      active: np.ndarray | None = None) -> np.ndarray:
        """The input (2,) the airframe feels: u_cmd (2,) with the actuator faults (profile values
        (nf,) SI, activity (nf,) bool or None: value != 0), as `Truth`."""
        return self.actuator_faults.applied(u_cmd, fault_values, active, self.u_applied)

    def step(self, u_cmd: np.ndarray, fault_values: np.ndarray,
             active: np.ndarray | None = None) -> np.ndarray:
        """Advance one frame with u_cmd (2,) and the faults' profile values (nf,) and activity
        (nf,) bool (None: value != 0) held; returns the new z (5,)."""
        u = self.applied_input(u_cmd, fault_values, active)
        self.actuator_faults.commit(fault_values, active, self.u_applied)
        n = self._n
        n["elevator"].set_double_value(float(u[0]) / ELEVATOR_RANGE_RAD)
        n["throttle"].set_double_value(float(u[1]))
        if self.scenario.sky.wind.active:
            self._set_wind(-float(self.z[0]))
        run = self.fdm.run
        for _ in range(self.substeps):
            run()
        self.u_applied = u
        self.t += self.dt
        self.z = self._read_z()
        return self.z

    def air_data(self) -> AirData:
        """JSBSim's true airspeed (m/s), the body-axis specific force [a_x, a_z] (m/s^2; the
        non-gravitational forces over the mass, as an accelerometer at the CG reads them) and the
        NED (north, down) wind at the aircraft, turbulence included (m/s); the roll (rad), the
        body-y velocity over the ground (m/s) and the roll and yaw rates (rad/s)."""
        g = self._get
        k = FT / g("mass")
        return AirData(g("vt") * FT, np.array([g("fx") * k, g("fz") * k]),
                       np.array([g("total_n") * FT, g("total_d") * FT]),
                       np.array([g("phi"), g("v") * FT, g("p"), g("r")]))

    # ------------------------------------------------------------------ internals

    def _get(self, name: str) -> float:
        return self._n[name].get_double_value()

    def _set(self, name: str, value: float) -> None:
        self._n[name].set_double_value(float(value))

    def _read_z(self) -> np.ndarray:
        """[p_d, u, w, theta, q] (SI) now."""
        g = self._get
        return np.array([-g("h"), g("u") * FT, g("w") * FT, g("theta"), g("q")])

    def _wind(self, altitude_m: float) -> tuple[float, float]:
        """The world's NED wind (north, down), ft/s, at self.t (s) and altitude_m (m)."""
        north, down = wind_ned(self.scenario.sky.wind, self.t, altitude_m, self.scenario.truth.airspeed_mps)
        return north / FT, down / FT

    def _set_wind(self, altitude_m: float) -> None:
        """JSBSim's steady wind: the world's wind at self.t and altitude_m (m), held until the next."""
        north, down = self._wind(altitude_m)
        self._set("wind_n", north)
        self._set("wind_d", down)

    def _initial_conditions(self) -> None:
        """Level flight heading north at the truth's airspeed and altitude, wings level."""
        tc, fdm = self.scenario.truth, self.fdm
        for prop, value in (("ic/h-sl-ft", tc.altitude_m / FT), ("ic/lat-geod-deg", LATITUDE_DEG),
                            ("ic/vt-fps", tc.airspeed_mps / FT), ("ic/psi-true-deg", 0.0),
                            ("ic/phi-deg", 0.0), ("ic/gamma-deg", 0.0), ("ic/beta-deg", 0.0),
                            ("ic/p-rad_sec", 0.0), ("ic/q-rad_sec", 0.0), ("ic/r-rad_sec", 0.0)):
            fdm[prop] = value
        if not fdm.run_ic():
            raise RuntimeError("JSBSim: initial conditions failed")

    def _spin_up(self) -> None:
        """Bring the propeller to SPIN_UP_RPM at half throttle (the motor's torque limit makes
        the start gentle); the aircraft's motion meanwhile is discarded by the next initial
        conditions."""
        self._set("throttle", 0.5)
        for _ in range(2000):
            if self._get("rpm") >= SPIN_UP_RPM:
                return
            self.fdm.run()
        raise RuntimeError(f"JSBSim: the propeller did not spin up (rpm {self._get('rpm'):.0f})")

    def _trim(self) -> JSBSimTrim:
        """JSBSim's longitudinal trim, the lateral trims, the longitudinal trim again; then the
        elevator moved from the pitch trim to the elevator command (same deflection)."""
        self._trim_longitudinal()
        self._trim_lateral()
        self._trim_longitudinal()
        de = self._get("elevator_rad")
        self._set("pitch_trim", 0.0)
        self._set("elevator", de / ELEVATOR_RANGE_RAD)
        z = self._read_z()
        alpha = self._get("alpha")
        tc = self.scenario.truth
        return JSBSimTrim(tc.airspeed_mps, tc.altitude_m, alpha, float(z[3]) - alpha, z,
                          np.array([de, self._get("throttle")]))

    def _carry_the_wind(self) -> None:
        """Start in trim with the air, as `Truth`: the trimmed state (found in still air) with the
        world's wind at t = 0 added to its velocity over the ground, then that wind set and the
        integrators' derivative history taken at that state (JSBSim's trim mode "none"). The
        initial-condition wind of JSBSim itself is not used."""
        north, down = self._wind(self.scenario.truth.altitude_m)
        if north == 0.0 and down == 0.0:
            return
        fdm = self.fdm
        ic = {f"ic/{k}": fdm[v] for k, v in _CARRIED.items()}
        ic["ic/vn-fps"] += north
        ic["ic/vd-fps"] += down
        for prop, value in ic.items():
            fdm[prop] = value
        fdm.run_ic()
        self._set("wind_n", north)
        self._set("wind_d", down)
        self._evaluate()
        fdm.do_trim(TRIM_NONE)

    def _trim_longitudinal(self) -> None:
        try:
            self.fdm.do_trim(TRIM_LONGITUDINAL)
        except jsbsim.TrimFailureError as exc:
            tc = self.scenario.truth
            raise RuntimeError(f"JSBSim cannot trim the {MODEL} at {tc.airspeed_mps} m/s, "
                               f"{tc.altitude_m} m: {exc}") from None

    def _trim_lateral(self) -> None:
        """Aileron and rudder trims (fcs/aileron-cmd-norm, rudder-cmd-norm) for p' = r' = 0 at
        the trimmed state: one Newton step on the (linear) roll and yaw accelerations."""
        x0 = np.array([self._get("aileron"), self._get("rudder")])
        r0 = self._lateral_residual(x0)
        jac = np.column_stack([(self._lateral_residual(x0 + 0.01 * e) - r0) / 0.01 for e in np.eye(2)])
        self._lateral_residual(x0 - np.linalg.solve(jac, r0))

    def _lateral_residual(self, x: np.ndarray) -> np.ndarray:
        """(p', r') rad/s^2 with the aileron and rudder trims x (2,)."""
        self._set("aileron", x[0])
        self._set("rudder", x[1])
        self._evaluate()
        return np.array([self._get("pdot"), self._get("rdot")])

    def _evaluate(self) -> None:
        """Every model once at the current state, without integrating (dt = 0)."""
        self.fdm.suspend_integration()
        try:
            self.fdm.run()
        finally:
            self.fdm.resume_integration()

    def _start_turbulence(self) -> None:
        """JSBSim's MIL-F-8785C turbulence (Tustin) with the world's wind at 20 ft, seeded from rng."""
        w6 = self.scenario.sky.turbulence.wind_6m_mps
        if w6 <= 0.0:
            return
        fdm = self.fdm
        fdm["simulation/randomseed"] = self._seed
        fdm["atmosphere/turb-type"] = TURB_TUSTIN
        fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = w6 / FT
        fdm["atmosphere/turbulence/milspec/severity"] = turbulence_severity(w6)
