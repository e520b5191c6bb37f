"""What a world fault does to its target: typed faults (issue 17, the world's side).

A fault channel's profile value a(t) (SI, `faults.channel_value`) and its profile activity
(`faults.channel_active`: a component inside [start_s, end_s), an intermittent one in an on phase)
act on the target according to the channel's `fault_type` (`[[world.faults]] type`):

sensor rows (`SensorFaults`, used by `sensors.SensorSuite`):
- bias     y_r += a (always; the only type before issue 17, same bits);
- drift    y_r += a, as a bias (its profile a ramp), but typed: scored per item and type;
- stuck    while active y_r = held + a (+ the row's usual noise, unless `noise = "none"`), held = the
           noise-free reading of the last fault-free frame (a = 0: stuck where it was);
- noisy    while active the row's noise draw is multiplied by k = max(a, 1) (the same draw, so the
           other rows' random streams do not change);
- blocked  the pitot (airspeed row) blocked, ram and drain: the total pressure trapped at onset, so
           the indicated airspeed follows the static pressure,
           V_ind = sqrt(max(0, V_0^2 + 2 (p_s(h_0) - p_s(h)) / rho_0)) + noise, with V_0, h_0,
           rho_0 the true airspeed, altitude and standard-atmosphere density at onset (a climb
           reads fast by about g dh / V_0); the profile value a is ignored (only its activity counts).
A stuck or blocked row replaces the row's reading after every other error (other faults on the row,
GNSS latency, baro / gyro bias); the barometer row is then converted through the pressure as usual.

actuators (`ActuatorFaults`, used by `world.Truth` and `jsbsim_truth.JSBSimTruth`):
- bias           u_i += a;
- jammed         while active u_i = (the input applied over the frame before onset) + a;
- effectiveness  while active u_i = g u_i with g = min(max(a, 0), 1);
- engine         (delta_t only) while active the propeller gives g = min(max(a, 0), 1) of its thrust:
                 an engine that quits is g = 0, thrust ~0 while the command stays up. The internal
                 aircraft's thrust k_T (k_m^2 delta_t^2 - V^2) (SPEC section 2) is scaled through the
                 throttle that gives it, delta_t' = sqrt(g delta_t^2 + (1 - g) (V / k_m)^2), V the
                 airspeed at the frame's start (an effectiveness g = 0 there is the model's windmill
                 drag, k_T V^2: 1.5 g at 40 m/s); JSBSim's electric motor gets g delta_t, its
                 propeller windmilling as JSBSim models it (`engine_out`).

Truth (`Frame.faults`, `Trajectory.faults`, `/sim/truth`): per channel the additive-equivalent
value that the estimator's fault entry estimates, 0 while inactive: bias a; stuck and blocked the
noise-free reading minus the true noise-free reading; jammed and effectiveness the applied minus the
commanded input (for effectiveness (g - 1) u_cmd, for engine delta_t' - u_cmd); noisy k - 1.

Activity (`activity`): a bias channel is active where its value is non-zero (as before: a ramp's
first frame, 0, is fault-free); a typed channel wherever its profile is active, whatever its value
(a noisy with k = 1 or an effectiveness with g = 1 is an active fault of value 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fdir_service.atmosphere import L0_K_PER_M, M_AIR, R_GAS, T0_K, pressure_from_altitude
from sim_bridge.faults import channel_active
from sim_bridge.scenario import ACTUATORS, FaultChannel


def air_density(h_m: float) -> float:
    """Standard-atmosphere density (kg/m^3) at altitude h_m (m): p M / (R T), T = T0 + L0 h."""
    return pressure_from_altitude(float(h_m)) * M_AIR / (R_GAS * (T0_K + L0_K_PER_M * float(h_m)))


def blocked_pitot_airspeed(v0_mps: float, h0_m: float, h_m: float) -> float:
    """Indicated airspeed (m/s) of a pitot blocked at airspeed v0_mps and altitude h0_m (m), now at
    altitude h_m (m): sqrt(max(0, V_0^2 + 2 (p_s(h_0) - p_s(h)) / rho_0))."""
    dp = pressure_from_altitude(float(h0_m)) - pressure_from_altitude(float(h_m))
    return math.sqrt(max(0.0, v0_mps * v0_mps + 2.0 * dp / air_density(h0_m)))


def is_typed(channels: Sequence[FaultChannel]) -> bool:
    """Whether any channel is of a type other than bias."""
    return any(ch.fault_type != "bias" for ch in channels)


def activity(channels: Sequence[FaultChannel], values: np.ndarray, t: float) -> np.ndarray:
    """(nf,) bool: each channel active at t (s) (module docstring); values (nf,) its profile values."""
    act = np.asarray(values) != 0.0
    for j, ch in enumerate(channels):
        if ch.fault_type != "bias":
            act[j] = channel_active(ch, t)
    return act


def _default_active(values: np.ndarray, active: np.ndarray | None) -> np.ndarray:
    """active, or (bias-only callers) value != 0."""
    return np.asarray(values) != 0.0 if active is None else np.asarray(active, dtype=bool)


class SensorFaults:
    """The typed sensor faults of a world (module docstring) and their state (held readings).

    faults: the scenario's channels (nf); rows: the world's measurement rows (m).
    """

    def __init__(self, faults: Sequence[FaultChannel], rows: Sequence[str]) -> None:
        self.nf = len(faults)
        self.typed = [(j, list(rows).index(ch.target), ch) for j, ch in enumerate(faults)
                      if ch.kind == "sensor" and ch.fault_type not in ("bias", "drift")]
        self.noisy = [(j, r) for j, r, ch in self.typed if ch.fault_type == "noisy"]
        self.reset()

    def reset(self) -> None:
        """Forget the held readings (a new run)."""
        self._held: dict[int, float] = {}
        self._blocked: dict[int, tuple[float, float]] = {}

    def scale_noise(self, noise: np.ndarray, values: np.ndarray, active: np.ndarray) -> None:
        """noise (m,) in place: each active noisy row's draw times k = max(a, 1)."""
        for j, r in self.noisy:
            if active[j]:
                noise[r] *= max(float(values[j]), 1.0)

    def apply(self, y: np.ndarray, clean: np.ndarray, noise: np.ndarray, values: np.ndarray,
              active: np.ndarray, altitude_m: float) -> np.ndarray:
        """Stuck and blocked rows of y (m,) in place; returns the truth (nf,) of the typed channels
        (NaN elsewhere). clean (m,): the noise-free fault-free reading; noise (m,) this frame's
        (already scaled); values, active (nf,); altitude_m the true altitude (m)."""
        truth = np.full(self.nf, np.nan)
        for j, r, ch in self.typed:
            truth[j] = self._row(y, r, j, ch, clean[r], noise[r], float(values[j]), bool(active[j]),
                                 altitude_m)
        return truth

    def _row(self, y: np.ndarray, r: int, j: int, ch: FaultChannel, clean: float, noise: float,
             a: float, on: bool, altitude_m: float) -> float:
        """One typed channel on row r: sets y[r] if it holds it; returns its truth."""
        if not on:
            self._held[j] = clean
            self._blocked.pop(j, None)
            return 0.0
        if ch.fault_type == "noisy":
            return max(a, 1.0) - 1.0
        if ch.fault_type == "stuck":
            reading = self._held.setdefault(j, clean) + a
            y[r] = reading + (noise if ch.noise == "kept" else 0.0)
            return reading - clean
        v0, h0 = self._blocked.setdefault(j, (clean, altitude_m))
        reading = blocked_pitot_airspeed(v0, h0, altitude_m)
        y[r] = reading + noise
        return reading - clean


def unit_gain(g: float) -> float:
    """A remaining gain or share g clipped to [0, 1] (effectiveness, engine)."""
    return min(max(float(g), 0.0), 1.0)


def scaled_command(u: float, g: float) -> float:
    """An input u (SI) that keeps g of its effect, g clipped to [0, 1] (effectiveness)."""
    return u * unit_gain(g)


class ActuatorFaults:
    """The actuator faults of a world (every type, bias included) and their state (jam positions).

    faults: the scenario's channels (nf); inputs [delta_e rad, delta_t 0..1]. engine_out(delta_t, g)
    -> the throttle that gives g (clipped to [0, 1]) of delta_t's thrust (the truth engine's;
    default `scaled_command`).
    """

    def __init__(self, faults: Sequence[FaultChannel], engine_out=scaled_command) -> None:
        self.nf = len(faults)
        self.engine_out = engine_out
        self.channels = [(ACTUATORS.index(ch.target), j, ch.fault_type) for j, ch in enumerate(faults)
                         if ch.kind == "actuator"]
        self.reset()

    def reset(self) -> None:
        """Forget the jam positions (a new run)."""
        self._onset: dict[int, float] = {}

    def _jam(self, i: int, j: int, u_prev: np.ndarray) -> float:
        """The position (SI) jammed channel j holds input i at, before its profile value."""
        return self._onset.get(j, float(u_prev[i]))

    def applied(self, u_cmd: np.ndarray, values: np.ndarray, active: np.ndarray | None,
                u_prev: np.ndarray) -> np.ndarray:
        """The input (2,) the airframe feels: u_cmd (2,) with the channels' values (nf,) and
        activity (nf,) (None: value != 0), channel by channel in order; u_prev (2,) the input
        applied over the previous frame (a jam's position at onset). Changes no state."""
        u = np.array(u_cmd, dtype=float)
        active = _default_active(values, active)
        for i, j, kind in self.channels:
            if kind == "bias":
                u[i] += values[j]
            elif not active[j]:
                continue
            else:
                u[i] = self._typed(i, j, kind, u[i], values, u_prev)
        return u

    def _typed(self, i: int, j: int, kind: str, u_i: float, values: np.ndarray,
               u_prev: np.ndarray) -> float:
        """Input i (SI) under active typed channel j of `kind`, before it u_i."""
        if kind == "jammed":
            return self._jam(i, j, u_prev) + float(values[j])
        return (self.engine_out if kind == "engine" else scaled_command)(u_i, float(values[j]))

    def commit(self, values: np.ndarray, active: np.ndarray | None, u_prev: np.ndarray) -> None:
        """After a frame flown with `applied`: remember each newly active jam's onset position."""
        active = _default_active(values, active)
        for i, j, kind in self.channels:
            if kind == "jammed" and active[j]:
                self._onset[j] = self._jam(i, j, u_prev)
            elif kind == "jammed":
                self._onset.pop(j, None)

    def truth(self, u_cmd: np.ndarray, values: np.ndarray, active: np.ndarray,
              u_prev: np.ndarray) -> np.ndarray:
        """(nf,) the additive-equivalent truth of the typed actuator channels (NaN elsewhere):
        jammed, effectiveness and engine applied - commanded ((g - 1) u_cmd for effectiveness);
        0 while inactive."""
        out = np.full(self.nf, np.nan)
        for i, j, kind in self.channels:
            if kind == "bias":
                continue
            if not active[j]:
                out[j] = 0.0
            elif kind == "effectiveness":          # (g - 1) u, the recorded truth's own rounding
                out[j] = (unit_gain(values[j]) - 1.0) * float(u_cmd[i])
            else:
                out[j] = self._typed(i, j, kind, float(u_cmd[i]), values, u_prev) - float(u_cmd[i])
        return out
