"""Closed-loop simulation of a scenario: truth, faults, sensors, navigation and autopilot.

Frame k at t_k = k dt: faults f_k = f(t_k) (profile values and activity); y_k = sensors(z_k, f_k);
the navigation estimate is nav(t_k, y_k, mask_k, u_{k-1}) (a filter) or the truth z_k; u_k =
autopilot(t_k, z_nav), or, under scenario.navigation "onboard" | "truth", autopilot(t_k, the
autopilot's own navigation) whatever nav says (`onboard_nav`); the truth steps over
[t_k, t_k+1) with u_k and the actuator faults f_k. What
each fault type does, and the additive-equivalent truth recorded: `sim_bridge.fault_types`.

Randomness: `SeedSequence(seed).spawn(3)` -> [sensor noise, the world (turbulence, dispersion),
the run's draw of varying fault profiles], so the sensor noise of a run depends only on the seed,
whatever the navigation does. Same seed, same bits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from fdir_service.airframe import AirframeParams, linearize, load_airframe
from sim_bridge.autopilot import Autopilot
from sim_bridge.fault_types import activity, is_typed
from sim_bridge.faults import fault_vector, vary_profiles
from sim_bridge.onboard_nav import autopilot_navigation
from sim_bridge.scenario import Scenario
from sim_bridge.sensors import SensorSuite
from sim_bridge.wind import ned_to_body
from sim_bridge.world import make_truth

NavFn = Callable[[float, np.ndarray, np.ndarray, np.ndarray], Any]


@dataclass
class Frame:
    """One sensor frame.

    t (s); y (m,) SI in scenario measurement order; mask (m,) bool (False: a row without a new
    sample this frame, e.g. between GNSS fixes);
    static_pressure_pa: the barometer's static pressure (Pa); z_true (5,); faults (nf,) SI at t:
    each fault's additive-equivalent truth (`fault_types`; a bias's profile value), except a jammed
    actuator's (applied - commanded), NaN until the command is known (`SimStepper.fault_truth`);
    u_applied (2,): the commanded input [delta_e rad, delta_t] applied over the previous interval
    (what the onboard system knows; actuator faults excluded), the trim input at k = 0.
    """

    t: float
    y: np.ndarray
    mask: np.ndarray
    static_pressure_pa: float
    z_true: np.ndarray
    faults: np.ndarray
    u_applied: np.ndarray
    wind_body: np.ndarray | None = None
    """(2,) the air's velocity in body axes (m/s) at the frame; None in still air."""
    profile: np.ndarray | None = None
    """(nf,) the faults' profile values a(t) (SI; the factor k or g of a noisy or effectiveness);
    None: equal to `faults` (a world of bias faults)."""
    active: np.ndarray | None = None
    """(nf,) bool: each fault active at t (`fault_types.activity`)."""

    def autopilot_view(self, z_nav: np.ndarray) -> np.ndarray:
        """What the autopilot flies on: the navigation state (5,) with u, w made air-relative by
        the wind (an autopilot holds airspeed with its pitot and its own wind estimate; the
        world's wind stands for that estimate). In still air z_nav itself."""
        if self.wind_body is None:
            return z_nav
        z = np.array(z_nav, dtype=float)
        z[1:3] -= self.wind_body
        return z


@dataclass
class Trajectory:
    """A closed-loop run, K frames: t (K,), z (K, 5) truth, y (K, m), mask (K, m), u (K, 2)
    commanded input at each frame, faults (K, nf) the additive-equivalent truth (`fault_types`),
    nav (K, 5) the navigation's state (what the autopilot flew on under navigation "monitor"),
    gamma_cmd (K,) rad, static_pressure_pa (K,),
    outputs: what nav returned at each frame, active (K, nf) bool each fault's activity."""

    t: np.ndarray
    z: np.ndarray
    y: np.ndarray
    mask: np.ndarray
    u: np.ndarray
    faults: np.ndarray
    nav: np.ndarray
    gamma_cmd: np.ndarray
    static_pressure_pa: np.ndarray
    seed: int
    outputs: list = field(default_factory=list)
    active: np.ndarray | None = None


@lru_cache(maxsize=32)
def _design_model(airframe: AirframeParams, airspeed: float, altitude: float, dt: float):
    return linearize(airframe, airspeed, altitude, dt)


def default_autopilot(scenario: Scenario, airframe: AirframeParams) -> Autopilot:
    """The autopilot designed on the derived linear model at the scenario's trim and dt.

    The linearisation and the LQR gains are computed once per process for a given airframe, trim
    point and dt (a campaign flies hundreds of runs with the same design).
    """
    args = (airframe, scenario.truth.airspeed_mps, scenario.truth.altitude_m, scenario.dt_s)
    try:
        model = _design_model(*args)
    except TypeError:       # an unhashable parameter set: design afresh
        model = linearize(*args)
    return Autopilot(model, scenario.command, scenario.dt_s)


def run_faults(scenario: Scenario, seed: int) -> Scenario:
    """The scenario with the faults run `seed` flies (its draw of any varying fault profile)."""
    return vary_profiles(scenario, np.random.default_rng(np.random.SeedSequence(seed).spawn(3)[2]))


class SimStepper:
    """The world one frame at a time: `frame()` then `advance(u_cmd)`, repeatedly. `airframe` is the
    nominal airframe (the autopilot's); the truth may fly a dispersed one (`truth.params`)."""

    def __init__(self, scenario: Scenario, seed: int, airframe: AirframeParams | None = None) -> None:
        self.scenario = scenario
        self.seed = seed
        self.airframe = airframe if airframe is not None else load_airframe(scenario.truth.airframe)
        sensor_ss, world_ss, _ = np.random.SeedSequence(seed).spawn(3)
        scenario = self.scenario = run_faults(scenario, seed)
        self.sensors = SensorSuite(scenario, np.random.default_rng(sensor_ss))
        self.truth = make_truth(scenario, self.airframe, np.random.default_rng(world_ss))
        self.dt = scenario.dt_s
        self.k = 0
        self.u_prev = self.truth.trim.u.copy()
        self.typed = is_typed(scenario.faults)
        self._frame: Frame | None = None

    @property
    def t(self) -> float:
        """Time of the current frame (s)."""
        return self.k * self.dt

    def frame(self) -> Frame:
        """The current frame (made once per step; calling again returns the same frame)."""
        if self._frame is None:
            t = self.t
            f = fault_vector(self.scenario, t)
            act = activity(self.scenario.faults, f, t)
            moving = self.scenario.sky.moving_air
            air = self.truth.air_data() if (self.sensors.air_rows or moving) else None
            y = self.sensors.measure(self.truth.z, t, f, air, act)
            wind = ned_to_body(air.wind_ned[0], air.wind_ned[1], float(self.truth.z[3])) if moving else None
            self._frame = Frame(t, y, self.sensors.last_mask.copy(),
                                float(self.sensors.last_static_pressure_pa), self.truth.z.copy(),
                                self._truth_at_frame(f, act), self.u_prev.copy(), wind, f, act)
        return self._frame

    def _truth_at_frame(self, f: np.ndarray, act: np.ndarray) -> np.ndarray:
        """(nf,) the faults' additive-equivalent truth known at the frame: the profile values f
        with the typed channels' truth laid over (jammed actuators NaN: they need the command)."""
        if not self.typed:
            return f
        out = f.copy()
        known = np.isfinite(self.sensors.last_fault_truth)
        out[known] = self.sensors.last_fault_truth[known]
        for j, ch in enumerate(self.scenario.faults):
            if ch.kind == "actuator" and ch.fault_type != "bias":
                out[j] = np.nan
        return out

    def fault_truth(self, u_cmd: np.ndarray) -> np.ndarray:
        """(nf,) the current frame's additive-equivalent fault truth (`fault_types`) when flown with
        the command u_cmd (2,): `Frame.faults` with the typed actuators' entries filled in."""
        fr = self.frame()
        if not self.typed:
            return fr.faults
        act_truth = self.truth.actuator_faults.truth(np.asarray(u_cmd, dtype=float), fr.profile,
                                                     fr.active, self.truth.u_applied)
        known = np.isfinite(act_truth)
        out = fr.faults.copy()
        out[known] = act_truth[known]
        return out

    def advance(self, u_cmd: np.ndarray) -> None:
        """Step the truth over [t_k, t_k+1) with u_cmd (2,) and the actuator faults at t_k (the
        frame's `faults` get their command-dependent entries first)."""
        fr = self.frame()
        u_cmd = np.asarray(u_cmd, dtype=float)
        if self.typed:
            fr.faults[:] = self.fault_truth(u_cmd)
        self.truth.step(u_cmd, fr.faults if fr.profile is None else fr.profile, fr.active)
        self.u_prev = u_cmd.copy()
        self.k += 1
        self._frame = None


def run(scenario: Scenario, seed: int, seconds: float | None = None, nav: NavFn | None = None,
        airframe: AirframeParams | None = None, autopilot: Autopilot | None = None) -> Trajectory:
    """Fly the scenario in closed loop for `seconds` (default scenario.duration_s) at scenario.dt_s.

    nav(t, y, mask, u_prev) returns an object with `.state` (5,) or a (5,) array; None flies on
    the truth. Under scenario.navigation = "onboard" or "truth" the autopilot flies on its own
    navigation (`onboard_nav`) whatever nav returns; nav still runs on every frame and is recorded.
    `autopilot` overrides the default design (tests use it for custom commands).
    """
    stepper = SimStepper(scenario, seed, airframe)
    ap = autopilot if autopilot is not None else default_autopilot(scenario, stepper.airframe)
    ap.reset()
    duration = scenario.duration_s if seconds is None else seconds
    K = int(round(duration / scenario.dt_s))
    m, nf = len(scenario.sensors.measurements), len(scenario.faults)
    t = np.empty(K)
    z = np.empty((K, 5))
    y = np.empty((K, m))
    mask = np.empty((K, m), dtype=bool)
    u = np.empty((K, 2))
    faults = np.empty((K, nf))
    active = np.empty((K, nf), dtype=bool)
    navs = np.empty((K, 5))
    gamma = np.empty(K)
    ps = np.empty(K)
    outputs: list = []
    onboard = autopilot_navigation(scenario.navigation, scenario.faults)
    for k in range(K):
        fr = stepper.frame()
        if nav is None:
            z_nav = fr.z_true
        else:
            out = nav(fr.t, fr.y, fr.mask, fr.u_applied)
            outputs.append(out)
            z_nav = np.asarray(out.state if hasattr(out, "state") else out, dtype=float)
        view = fr.autopilot_view(z_nav) if onboard is None else onboard.view(fr)
        u_k = ap.update(fr.t, view)
        t[k], z[k], y[k], mask[k], faults[k] = fr.t, fr.z_true, fr.y, fr.mask, stepper.fault_truth(u_k)
        u[k], navs[k], gamma[k], ps[k] = u_k, z_nav, ap.gamma_command, fr.static_pressure_pa
        active[k] = fr.active
        stepper.advance(u_k)
    return Trajectory(t, z, y, mask, u, faults, navs, gamma, ps, seed, outputs, active)
