"""`fdir identify`'s propulsion: the throttle's thrust and the engine's response, fitted to a flight.

The catalogue's thrust check (`estimation/thrust.py`) reads the throttle the propeller delivers
from the accelerometer through the airframe's axial force balance (SPEC section 2):

    a_x - f_x(alpha, V, delta_e) = k_T (k_m^2 d^2 - V^2) = A d^2 - B V^2

with d the throttle delivered, k_T = rho S_prop C_prop / (2 m), and f_x the aerodynamic force per
unit mass (the file's polar). On an aircraft the file does not describe, the propeller's k_m and
C_prop are off (its thrust falls with the airspeed more or less steeply), and its speed, hence its
thrust, follows the command with a lag: JSBSim's Aerosonde (a speed-controlled propeller) gives a third of
the file's thrust per unit of throttle and follows it in 0.2-0.3 s, and read against the file's
the quick throttle moves of an autopilot in turbulence looked like a dead engine
(docs/faults.md, "The catalogue on other aircraft").

`fit_propulsion` fits A and B by least squares (scipy.linalg.lstsq) with d the command through a
first-order lag (`inputs.EngineLag`), for each lag of `TAU_GRID_S`, and keeps the lag whose fit
leaves the least residual in throttle terms. k_m = sqrt(A / B) and C_prop = 2 m B / (rho S_prop)
go into the identified airframe file (the drag stays the file's), the lag into the estimator's
`[parts] engine_tau_s`. The airspeed varies little in cruise, so B is mostly the level of the
thrust the flight needed, not its slope with the airspeed: the fit is the throttle check's local
balance, not a propeller map. Frames are used near level flight only (`pitot.near_level_flight`),
where the check reads them. Units SI; throttle 0..1.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lstsq
from scipy.signal import lfilter

from fdir_service.airframe.params import AirframeParams
from fdir_service.estimation.pitot import near_level_flight
from fdir_service.estimation.thrust import ThrustCheck

TAU_GRID_S = (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.7, 1.0, 1.5)
"""The engine lags (s) tried: from at once to a slow piston engine's spool."""
MIN_FRAMES = 200
"""At least 10 s of level frames at 20 Hz."""
MIN_THROTTLE_SPREAD = 0.02
"""The throttle command's least standard deviation over the level frames for a fit: a flight whose
throttle hardly moved (calm air) cannot tell the propeller's gain from its drag."""
WANDER_S = 5.0
"""s: the span over which the residual's wander is measured (`PropulsionFit.wander`)."""


@dataclass(frozen=True)
class PropulsionFit:
    """The fitted propulsion: k_motor and C_prop for the airframe file, the engine's lag (s), and
    the throttle check's residual (throttle units, RMS) with the file's propulsion and the fit's."""

    k_motor: float
    C_prop: float
    engine_tau_s: float
    residual: float
    residual_before: float
    frames_used: int
    wander: float = float("nan")
    """Per sqrt(s): how fast the residual's one-second mean wanders over WANDER_S (the slow part no
    lag or gain explains: the throttle's mode-0 drift, its bias entry's `drift_sigma`)."""

    def apply(self, params: AirframeParams) -> AirframeParams:
        """`params` with the fitted k_motor and C_prop."""
        return dataclasses.replace(params, k_motor=self.k_motor, C_prop=self.C_prop)

    def report(self) -> str:
        """Two lines for the terminal."""
        return (f"throttle:  k_motor {self.k_motor:.2f}, C_prop {self.C_prop:.3f}, the engine's response "
                f"{self.engine_tau_s:.2f} s ([parts] engine_tau_s) over {self.frames_used} level frames\n"
                f"           the thrust check's residual {self.residual:.3f} of throttle RMS "
                f"(the file's propulsion at once: {self.residual_before:.3f}; [parts] thrust_sigma), "
                f"wandering {self.wander:.3f} per sqrt(s) (the throttle's drift_sigma)")


def lagged(command: np.ndarray, tau_s: float, dt: float) -> np.ndarray:
    """The command (K,) through a first-order lag of tau_s (s) stepped every dt (s), from its first
    value (0: the command itself)."""
    if tau_s <= 0.0:
        return np.asarray(command, dtype=float)
    a = math.exp(-dt / tau_s)
    c = np.asarray(command, dtype=float)
    return lfilter([1.0 - a], [1.0, -a], c, zi=[a * c[0]])[0]


def _thrust_per_mass(s: dict[str, np.ndarray], params: AirframeParams) -> tuple[np.ndarray, np.ndarray]:
    """(y, V) (K,): y = a_x - f_x (m/s^2), the thrust per unit mass of each frame, and its airspeed."""
    check = ThrustCheck(params)
    V = np.maximum(s["airspeed"], 1.0)
    fx = np.array([check.aero_axial(az, v, de) for az, v, de in zip(s["az"], V, s["de"], strict=True)])
    return s["ax"] - fx, V


def _level(s: dict[str, np.ndarray]) -> np.ndarray:
    """(K,) bool: frames with every row the fit needs, read near level flight."""
    ok = np.isfinite(s["ax"]) & np.isfinite(s["az"]) & (s["airspeed"] > 5.0) & np.isfinite(s["dt"])
    level = [near_level_flight(th, q, math.atan2(w, u)) for th, q, u, w in
             zip(s["theta"], s["q"], s["u"], s["w"], strict=True)]
    return ok & np.array(level, dtype=bool)


def _throttle_residual(y: np.ndarray, V: np.ndarray, A: float, B: float, d: np.ndarray) -> np.ndarray:
    """(K,) the throttle the thrust y implies under (A, B) less the delivered d (throttle units)."""
    return np.sqrt(np.maximum(y + B * V * V, 0.0) / A) - d


def _throttle_rms(y: np.ndarray, V: np.ndarray, A: float, B: float, d: np.ndarray) -> float:
    """RMS (throttle units) of `_throttle_residual`."""
    return float(np.sqrt(np.mean(_throttle_residual(y, V, A, B, d) ** 2)))


def _wander(r: np.ndarray, dt: float) -> float:
    """Per sqrt(s): the RMS change of r's one-second mean over WANDER_S, over sqrt(WANDER_S)."""
    second, span = max(int(round(1.0 / dt)), 1), max(int(round(WANDER_S / dt)), 1)
    if r.size < second + span + 1:
        return float("nan")
    m = np.convolve(r, np.ones(second) / second, mode="valid")
    return float(np.sqrt(np.mean((m[span:] - m[:-span]) ** 2) / WANDER_S))


def fit_propulsion(s: dict[str, np.ndarray], params: AirframeParams, dt: float) -> PropulsionFit | None:
    """The propulsion of a flight's frames s (K,) each: ax, az, airspeed, de (rad), dt (throttle
    command), theta, q, u, w (NaN where missing), on the airframe `params` (its lift already
    fitted); dt (s) the frame step. None with fewer than MIN_FRAMES level frames or a throttle that
    hardly moved (MIN_THROTTLE_SPREAD)."""
    use = _level(s)
    if np.count_nonzero(use) < MIN_FRAMES or not np.nanstd(s["dt"][use]) >= MIN_THROTTLE_SPREAD:
        return None
    y, V = (v[use] for v in _thrust_per_mass(s, params))
    check = ThrustCheck(params)
    before = _throttle_rms(y, V, check.k_thrust * check.k_motor2, check.k_thrust, s["dt"][use])
    command = np.nan_to_num(s["dt"], nan=float(np.nanmean(s["dt"])))
    best = None
    for tau in TAU_GRID_S:
        d = lagged(command, tau, dt)[use]
        (A, B), *_ = lstsq(np.column_stack([d * d, -V * V]), y)
        if A > 0 and B > 0:
            rms = _throttle_rms(y, V, A, B, d)
            best = (rms, tau, A, B) if best is None or rms < best[0] else best
    if best is None:
        return None
    rms, tau, A, B = best
    C_prop = 2.0 * params.m * B / (params.rho * params.S_prop)
    wander = _wander(_throttle_residual(y, V, A, B, lagged(command, tau, dt)[use]), dt)
    return PropulsionFit(math.sqrt(A / B), float(C_prop), float(tau), rms, before, int(np.count_nonzero(use)),
                         wander)
