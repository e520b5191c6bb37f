"""Derived rows: a measurement or input computed from more than one MAVLink message.

An autopilot profile (`config/autopilots/<name>.toml`) declares a derived row with
`derive = "<name>"`, the message that carries its sample (`message`, whose timestamp places the
value in a frame) and `sources`, every message type the derivation reads (checked against
`DERIVATIONS`). The derivation returns the raw value in the sample message's units; the row's
`scale`, `offset`, `transform` and valid range then apply as for any mapped field.

Derivations:

- `body_velocity_u`, `body_velocity_v`, `body_velocity_w`: the body-axis velocity (x forward, y
  right, z down; same unit as the sample, e.g. cm/s) of a NED velocity sample (`vx`, `vy`, `vz`
  of GLOBAL_POSITION_INT: north, east, down) rotated into the body axes with the attitude
  (`roll`, `pitch`, `yaw` rad of ATTITUDE, Z-Y-X Euler angles) of the latest attitude message
  stamped at or before the sample, and at most `max_attitude_age_s` older.
- `servo_angle`: an angle-type servo output (elevator, ArduPilot SERVOn_FUNCTION 19) as a fraction
  of its travel in [-1, 1] from its PWM (us) with the channel's MIN / TRIM / MAX / REVERSED, times
  `max_deflection_deg` (in rad) and `sign` (+1: the autopilot's positive output is the
  estimator's positive deflection).
- `servo_range`: a range-type servo output (throttle, function 70) in [0, 1] from MIN .. MAX.

Servo channels are found by their function parameter (`SERVOn_FUNCTION` = `function`, the lowest
such n); the parameter values are the profile's `[parameters]`, replaced by PARAM_VALUE messages
from the autopilot as they arrive (`SourceCache.observe`). A value that cannot be derived (no
attitude yet, an attitude too old, no channel with that function, a NaN) is NaN: the caller drops
the row for that frame, it never reaches the filter.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

ATTITUDE_HISTORY = 16
"""Attitude samples kept (at 50 Hz: 0.3 s) to find the one at or before a velocity sample."""
SERVO_CHANNELS = 16
"""SERVO_OUTPUT_RAW carries servo1_raw .. servo16_raw (9-16 in the MAVLink 2 extension)."""


# ----------------------------------------------------------------------------- the maths (vectorised)

def ned_to_body(v_ned: np.ndarray, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Body-axis velocity (..., 3) [u forward, v right, w down] of NED velocities v_ned (..., 3)
    [north, east, down] for Z-Y-X Euler angles roll, pitch, yaw (rad, shape (...)); same unit in and
    out. v_body = C(roll, pitch, yaw)^T v_ned with C the body-to-NED direction cosine matrix."""
    v = np.asarray(v_ned, dtype=float)
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    vn, ve, vd = v[..., 0], v[..., 1], v[..., 2]
    u = cp * cy * vn + cp * sy * ve - sp * vd
    vv = (sr * sp * cy - cr * sy) * vn + (sr * sp * sy + cr * cy) * ve + sr * cp * vd
    w = (cr * sp * cy + sr * sy) * vn + (cr * sp * sy - sr * cy) * ve + cr * cp * vd
    return np.stack([u, vv, w], axis=-1)


def pwm_to_angle_fraction(pwm: np.ndarray, pwm_min: float, trim: float, pwm_max: float,
                          reversed_: bool = False) -> np.ndarray:
    """An angle-type servo's output as a fraction of its travel in [-1, 1] from PWM (us): (pwm - trim)
    over (max - trim) above trim, over (trim - min) below (ArduPilot's SRV_Channel::pwm_from_angle
    inverted), clipped; negated when the channel is reversed. NaN where min < trim < max fails."""
    p = np.asarray(pwm, dtype=float)
    if not pwm_min < trim < pwm_max:
        return np.full(p.shape, np.nan)
    frac = np.where(p >= trim, (p - trim) / (pwm_max - trim), (p - trim) / (trim - pwm_min))
    frac = np.clip(frac, -1.0, 1.0)
    return -frac if reversed_ else frac


def pwm_to_range_fraction(pwm: np.ndarray, pwm_min: float, pwm_max: float,
                          reversed_: bool = False) -> np.ndarray:
    """A range-type servo's output (throttle) in [0, 1] from PWM (us): (pwm - min) / (max - min),
    clipped; 1 - that when reversed. NaN unless min < max."""
    p = np.asarray(pwm, dtype=float)
    if not pwm_min < pwm_max:
        return np.full(p.shape, np.nan)
    frac = np.clip((p - pwm_min) / (pwm_max - pwm_min), 0.0, 1.0)
    return 1.0 - frac if reversed_ else frac


# ----------------------------------------------------------------------------- the sources

class SourceCache:
    """What the derivations read besides their sample message: the latest attitudes (time us,
    roll, pitch, yaw rad) and the autopilot's parameters (name -> value)."""

    def __init__(self, parameters: dict[str, float] | None = None,
                 attitude_message: str = "ATTITUDE") -> None:
        self.defaults = dict(parameters or {})
        self.params = dict(self.defaults)
        self.attitude_message = attitude_message
        self.attitudes: deque[tuple[int, float, float, float]] = deque(maxlen=ATTITUDE_HISTORY)

    def observe(self, msg, t_us: int | None) -> None:
        """Remember an attitude (stamped t_us) or a PARAM_VALUE; other messages are ignored."""
        mtype = msg.get_type()
        if mtype == self.attitude_message and t_us is not None:
            self.attitudes.append((t_us, float(msg.roll), float(msg.pitch), float(msg.yaw)))
        elif mtype == "PARAM_VALUE":
            self._param(msg)

    def _param(self, msg) -> None:
        name = msg.param_id
        if isinstance(name, bytes):
            name = name.decode("ascii", "replace")
        name = str(name).rstrip("\x00")
        value = float(msg.param_value)
        if math.isfinite(value):
            self.params[name] = value

    def attitude_at(self, t_us: int, max_age_us: int) -> tuple[float, float, float] | None:
        """(roll, pitch, yaw) rad of the latest attitude stamped at or before t_us and at most
        max_age_us older; None if there is none."""
        for ts, roll, pitch, yaw in reversed(self.attitudes):
            if ts <= t_us:
                return (roll, pitch, yaw) if t_us - ts <= max_age_us else None
        return None

    def servo_channel(self, function: int) -> int | None:
        """The lowest n with SERVOn_FUNCTION == function, or None."""
        for n in range(1, SERVO_CHANNELS + 1):
            if self.params.get(f"SERVO{n}_FUNCTION") == function:
                return n
        return None

    def forget_time(self) -> None:
        """The frame clock restarted: attitudes of the old time base no longer apply."""
        self.attitudes.clear()


# ----------------------------------------------------------------------------- the derivations

Options = dict[str, float]
DeriveFn = Callable[[object, int, SourceCache, Options], float]


def _body_velocity(axis: int) -> DeriveFn:
    def derive(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
        att = cache.attitude_at(t_us, int(opt["max_attitude_age_s"] * 1e6))
        if att is None:
            return math.nan
        v = (float(msg.vx), float(msg.vy), float(msg.vz))
        return float(ned_to_body(np.array(v), *att)[axis])
    return derive


def _servo_pwm(msg, cache: SourceCache, function: int) -> tuple[float, int] | None:
    """(PWM us, channel n) of the channel with that function; None if none or not sent."""
    n = cache.servo_channel(function)
    raw = None if n is None else getattr(msg, f"servo{n}_raw", None)
    if raw is None or raw == 0:   # 0: the channel is not output
        return None
    return float(raw), n


def _servo_angle(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    found = _servo_pwm(msg, cache, int(opt["function"]))
    if found is None:
        return math.nan
    pwm, n = found
    p = cache.params
    frac = pwm_to_angle_fraction(pwm, p.get(f"SERVO{n}_MIN", math.nan), p.get(f"SERVO{n}_TRIM", math.nan),
                                 p.get(f"SERVO{n}_MAX", math.nan), bool(p.get(f"SERVO{n}_REVERSED", 0.0)))
    return float(frac) * math.radians(opt["max_deflection_deg"]) * opt["sign"]


def _servo_range(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    found = _servo_pwm(msg, cache, int(opt["function"]))
    if found is None:
        return math.nan
    pwm, n = found
    p = cache.params
    lo, hi = p.get(f"SERVO{n}_MIN", math.nan), p.get(f"SERVO{n}_MAX", math.nan)
    return float(pwm_to_range_fraction(pwm, lo, hi, bool(p.get(f"SERVO{n}_REVERSED", 0.0))))


@dataclass(frozen=True)
class Derivation:
    """A derivation: `sources` (sample message first, then what it reads besides), its options
    (name -> (default or None = required, what a valid value is, test)) and the function."""

    name: str
    sources: tuple[str, ...]
    options: dict[str, tuple[float | None, str, Callable[[float], bool]]]
    fn: DeriveFn


_AGE = {"max_attitude_age_s": (0.2, "a positive time (s)", lambda v: v > 0)}
_FUNCTION = ("a servo function number 1..255 (ArduPilot SERVOn_FUNCTION: 19 elevator, 70 throttle)",
             lambda v: v == int(v) and 1 <= v <= 255)
DERIVATIONS: dict[str, Derivation] = {
    d.name: d for d in (
        Derivation("body_velocity_u", ("GLOBAL_POSITION_INT", "ATTITUDE"), _AGE, _body_velocity(0)),
        Derivation("body_velocity_v", ("GLOBAL_POSITION_INT", "ATTITUDE"), _AGE, _body_velocity(1)),
        Derivation("body_velocity_w", ("GLOBAL_POSITION_INT", "ATTITUDE"), _AGE, _body_velocity(2)),
        Derivation("servo_angle", ("SERVO_OUTPUT_RAW", "PARAM_VALUE"), {
            "function": (None, *_FUNCTION),
            "max_deflection_deg": (None, "a positive angle (deg) below 90", lambda v: 0 < v < 90),
            "sign": (1.0, "+1 or -1", lambda v: v in (1.0, -1.0)),
        }, _servo_angle),
        Derivation("servo_range", ("SERVO_OUTPUT_RAW", "PARAM_VALUE"), {"function": (None, *_FUNCTION)},
                   _servo_range),
    )
}
"""Every derivation a profile may name."""


def derive_value(name: str, msg, t_us: int, cache: SourceCache, options: Options) -> float:
    """The raw derived value (sample message units) of derivation `name`; NaN if not derivable."""
    try:
        return DERIVATIONS[name].fn(msg, t_us, cache, options)
    except (TypeError, ValueError, OverflowError, AttributeError):
        return math.nan
