"""Derived rows: a measurement or input computed from more than one MAVLink message.

An autopilot profile (`config/autopilots/<name>.toml`) declares a derived row with
`derive = "<name>"`, the message that carries its sample (`message`, whose timestamp places the
value in a frame) and `sources`, every message type the derivation reads (checked against
`DERIVATIONS`). The derivation returns the raw value in the sample message's units; the row's
`scale`, `offset`, `transform` and valid range then apply as for any mapped field.

Derivations:

- `body_velocity_u`, `body_velocity_v`, `body_velocity_w`: the body-axis velocity (x forward, y
  right, z down; same unit as the sample: cm/s for GLOBAL_POSITION_INT, m/s for
  LOCAL_POSITION_NED) of a NED velocity sample (`vx`, `vy`, `vz`: north, east, down; either
  message may be the sample, `Derivation.samples`) rotated into the body axes with the attitude
  (`roll`, `pitch`, `yaw` rad of ATTITUDE, Z-Y-X Euler angles) of the latest attitude message
  stamped at or before the sample, and at most `max_attitude_age_s` older.
- `servo_angle`: an angle-type servo output (elevator, ArduPilot SERVOn_FUNCTION 19) as a fraction
  of its travel in [-1, 1] from its PWM (us) with the channel's MIN / TRIM / MAX / REVERSED, times
  `max_deflection_deg` (in rad) and `sign` (+1: the autopilot's positive output is the
  estimator's positive deflection).
- `servo_range`: a range-type servo output (throttle, function 70) in [0, 1] from MIN .. MAX.
- `px4_servo_angle`, `px4_servo_range`: the same maths with PX4's (1.14+, control allocation)
  parameter names (`PX4_MAIN`): the channel n with PWM_MAIN_FUNCn = the function, PWM_MAIN_MINn /
  MAXn, the centre PWM_MAIN_CENTn (missing or < 0: (MIN + MAX) / 2) as the trim, reversed when bit
  n-1 of the PWM_MAIN_REV bitmask is set. The elevator's function is found from its control
  surface: `surface_type` (CA_SV_CSi_TYPE, 3 = elevator) -> the lowest i with that type -> servo
  function 201 + i; the throttle's `function` is given (101 = motor 1).

Servo channels are found by their function parameter (`SERVOn_FUNCTION` = `function`, the lowest
such n; `ServoScheme` names the parameters); the parameter values are the profile's
`[parameters]`, replaced by PARAM_VALUE messages from the autopilot as they arrive
(`SourceCache.observe`; an integer parameter sent bytewise, as PX4 does, is decoded). A value
that cannot be derived (no attitude yet, an attitude too old, no channel with that function, a
NaN) is NaN: the caller drops the row for that frame, it never reaches the filter.
"""

from __future__ import annotations

import math
import struct
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


# ----------------------------------------------------------------------------- the parameters

@dataclass(frozen=True)
class ServoScheme:
    """An autopilot's servo-output parameter names; `{n}` is the output channel (1-based).
    `trim` None: the centre is (MIN + MAX) / 2 unless `centre` names a parameter >= 0.
    `reversed_` with `reversed_bitmask`: one parameter whose bit n-1 reverses channel n."""

    function: str
    minimum: str
    maximum: str
    trim: str | None
    centre: str | None
    reversed_: str
    reversed_bitmask: bool


ARDUPILOT_SERVOS = ServoScheme("SERVO{n}_FUNCTION", "SERVO{n}_MIN", "SERVO{n}_MAX", "SERVO{n}_TRIM",
                               None, "SERVO{n}_REVERSED", False)
"""ArduPilot: SERVOn_FUNCTION / MIN / TRIM / MAX / REVERSED."""
PX4_MAIN = ServoScheme("PWM_MAIN_FUNC{n}", "PWM_MAIN_MIN{n}", "PWM_MAIN_MAX{n}", None,
                       "PWM_MAIN_CENT{n}", "PWM_MAIN_REV", True)
"""PX4 1.14+ (control allocation), the PWM MAIN outputs: PWM_MAIN_FUNCn / MINn / MAXn / CENTn, REV bitmask."""
PX4_SURFACE_TYPE = "CA_SV_CS{i}_TYPE"
"""PX4: control surface i's role (3 = elevator); it drives servo output function 201 + i."""
PX4_SERVO_FUNCTION_0 = 201
PX4_SURFACES = 8

_INT_TYPES = {1: ("<B", 0xFF), 2: ("<b", 0xFF), 3: ("<H", 0xFFFF), 4: ("<h", 0xFFFF),
              5: ("<I", None), 6: ("<i", None)}
"""MAV_PARAM_TYPE UINT8 .. INT32: (struct format, mask of the low bytes or None for 32 bits)."""


def param_number(value: float, param_type: int) -> float:
    """A PARAM_VALUE's value: as sent (a float, or an integer cast to float as ArduPilot does) or,
    for an integer type whose float is not an integer (PX4's bytewise encoding: the float's four
    bytes are the integer's; small integers read as denormals, -1 as NaN), the integer in its bytes."""
    spec = _INT_TYPES.get(int(param_type))
    if spec is None or (math.isfinite(value) and value == int(value)):
        return value
    bits = struct.unpack("<I", struct.pack("<f", value))[0]
    fmt, mask = spec
    raw = bits if mask is None else bits & mask
    return float(struct.unpack(fmt, struct.pack("<I" if mask is None else fmt.upper(), raw))[0])


def param_name(msg) -> str:
    """A PARAM_VALUE's (or PARAM_REQUEST_READ's) param_id as text, NUL padding removed."""
    name = msg.param_id
    if isinstance(name, bytes):
        name = name.decode("ascii", "replace")
    return str(name).rstrip("\x00")


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
        name = param_name(msg)
        value = param_number(float(msg.param_value), int(getattr(msg, "param_type", 9)))
        if math.isfinite(value):
            self.params[name] = value

    def attitude_at(self, t_us: int, max_age_us: int) -> tuple[float, float, float] | None:
        """(roll, pitch, yaw) rad of the latest attitude stamped at or before t_us and at most
        max_age_us older; None if there is none."""
        for ts, roll, pitch, yaw in reversed(self.attitudes):
            if ts <= t_us:
                return (roll, pitch, yaw) if t_us - ts <= max_age_us else None
        return None

    def servo_channel(self, function: int, scheme: ServoScheme = ARDUPILOT_SERVOS) -> int | None:
        """The lowest n whose function parameter (SERVOn_FUNCTION, PWM_MAIN_FUNCn) == function, or None."""
        for n in range(1, SERVO_CHANNELS + 1):
            if self.params.get(scheme.function.format(n=n)) == function:
                return n
        return None

    def surface_function(self, surface_type: int) -> int | None:
        """PX4: the servo output function (201 + i) of the lowest control surface i with
        CA_SV_CSi_TYPE == surface_type, or None."""
        for i in range(PX4_SURFACES):
            if self.params.get(PX4_SURFACE_TYPE.format(i=i)) == surface_type:
                return PX4_SERVO_FUNCTION_0 + i
        return None

    def servo_limits(self, n: int, scheme: ServoScheme) -> tuple[float, float, float, bool]:
        """Channel n's (MIN, TRIM, MAX) PWM (us, NaN where unknown) and whether it is reversed."""
        p = self.params
        lo = p.get(scheme.minimum.format(n=n), math.nan)
        hi = p.get(scheme.maximum.format(n=n), math.nan)
        if scheme.trim is not None:
            trim = p.get(scheme.trim.format(n=n), math.nan)
        else:
            cent = p.get(scheme.centre.format(n=n), -1.0) if scheme.centre else -1.0
            trim = cent if cent >= 0 else 0.5 * (lo + hi)
        rev = p.get(scheme.reversed_.format(n=n), 0.0)
        reversed_ = bool(int(rev) >> (n - 1) & 1) if scheme.reversed_bitmask else bool(rev)
        return lo, trim, hi, reversed_

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


def _servo_pwm(msg, cache: SourceCache, function: int | None,
               scheme: ServoScheme) -> tuple[float, int] | None:
    """(PWM us, channel n) of the channel with that function; None if none or not sent."""
    n = None if function is None else cache.servo_channel(function, scheme)
    raw = None if n is None else getattr(msg, f"servo{n}_raw", None)
    if raw is None or raw == 0:   # 0: the channel is not output
        return None
    return float(raw), n


def _angle(msg, cache: SourceCache, function: int | None, scheme: ServoScheme, opt: Options) -> float:
    """The angle-type output (rad) of the channel with that function."""
    found = _servo_pwm(msg, cache, function, scheme)
    if found is None:
        return math.nan
    pwm, n = found
    lo, trim, hi, rev = cache.servo_limits(n, scheme)
    frac = pwm_to_angle_fraction(pwm, lo, trim, hi, rev)
    return float(frac) * math.radians(opt["max_deflection_deg"]) * opt["sign"]


def _range(msg, cache: SourceCache, function: int | None, scheme: ServoScheme) -> float:
    """The range-type output (0..1) of the channel with that function."""
    found = _servo_pwm(msg, cache, function, scheme)
    if found is None:
        return math.nan
    pwm, n = found
    lo, _, hi, rev = cache.servo_limits(n, scheme)
    return float(pwm_to_range_fraction(pwm, lo, hi, rev))


def _servo_angle(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    return _angle(msg, cache, int(opt["function"]), ARDUPILOT_SERVOS, opt)


def _servo_range(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    return _range(msg, cache, int(opt["function"]), ARDUPILOT_SERVOS)


def _px4_servo_angle(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    return _angle(msg, cache, cache.surface_function(int(opt["surface_type"])), PX4_MAIN, opt)


def _px4_servo_range(msg, t_us: int, cache: SourceCache, opt: Options) -> float:
    return _range(msg, cache, int(opt["function"]), PX4_MAIN)


@dataclass(frozen=True)
class Derivation:
    """A derivation: `sources` (sample message first, then what it reads besides), its options
    (name -> (default or None = required, what a valid value is, test)), the function, and the
    other messages that may be the sample instead of sources[0] (`samples`, same fields)."""

    name: str
    sources: tuple[str, ...]
    options: dict[str, tuple[float | None, str, Callable[[float], bool]]]
    fn: DeriveFn
    samples: tuple[str, ...] = ()

    def sources_for(self, sample: str) -> tuple[str, ...] | None:
        """The `sources` a row sampling `sample` must declare; None if it cannot be the sample."""
        if sample != self.sources[0] and sample not in self.samples:
            return None
        return (sample, *self.sources[1:])


_AGE = {"max_attitude_age_s": (0.2, "a positive time (s)", lambda v: v > 0)}
_FUNCTION = ("a servo function number 1..255 (ArduPilot SERVOn_FUNCTION: 19 elevator, 70 throttle)",
             lambda v: v == int(v) and 1 <= v <= 255)
_PX4_FUNCTION = ("a PX4 output function number 1..9999 (PWM_MAIN_FUNCn: 101 motor 1, 201 servo 1)",
                 lambda v: v == int(v) and 1 <= v <= 9999)
_SURFACE = ("a PX4 control surface type 1..18 (CA_SV_CSi_TYPE: 3 elevator)",
            lambda v: v == int(v) and 1 <= v <= 18)
_DEFLECTION = {
    "max_deflection_deg": (None, "a positive angle (deg) below 90", lambda v: 0 < v < 90),
    "sign": (1.0, "+1 or -1", lambda v: v in (1.0, -1.0)),
}
_NED = ("GLOBAL_POSITION_INT", "ATTITUDE")
_SERVO = ("SERVO_OUTPUT_RAW", "PARAM_VALUE")
DERIVATIONS: dict[str, Derivation] = {
    d.name: d for d in (
        Derivation("body_velocity_u", _NED, _AGE, _body_velocity(0), ("LOCAL_POSITION_NED",)),
        Derivation("body_velocity_v", _NED, _AGE, _body_velocity(1), ("LOCAL_POSITION_NED",)),
        Derivation("body_velocity_w", _NED, _AGE, _body_velocity(2), ("LOCAL_POSITION_NED",)),
        Derivation("servo_angle", _SERVO, {"function": (None, *_FUNCTION), **_DEFLECTION}, _servo_angle),
        Derivation("servo_range", _SERVO, {"function": (None, *_FUNCTION)}, _servo_range),
        Derivation("px4_servo_angle", _SERVO, {"surface_type": (None, *_SURFACE), **_DEFLECTION},
                   _px4_servo_angle),
        Derivation("px4_servo_range", _SERVO, {"function": (None, *_PX4_FUNCTION)}, _px4_servo_range),
    )
}
"""Every derivation a profile may name."""
SERVO_SCHEMES: dict[str, ServoScheme] = {
    "servo_angle": ARDUPILOT_SERVOS, "servo_range": ARDUPILOT_SERVOS,
    "px4_servo_angle": PX4_MAIN, "px4_servo_range": PX4_MAIN,
}
"""The servo derivations and the parameter names each reads."""


def output_channel(derive: str, options: tuple[tuple[str, float], ...], cache: SourceCache) -> int | None:
    """The servo output channel n (1-based) a servo derivation with these options reads, under the
    parameters in `cache`; None for another derivation or when no channel has the function."""
    scheme = SERVO_SCHEMES.get(derive)
    if scheme is None:
        return None
    opt = dict(options)
    if "surface_type" in opt:
        function = cache.surface_function(int(opt["surface_type"]))
    else:
        function = int(opt["function"]) if "function" in opt else None
    return None if function is None else cache.servo_channel(function, scheme)


def derive_value(name: str, msg, t_us: int, cache: SourceCache, options: Options) -> float:
    """The raw derived value (sample message units) of derivation `name`; NaN if not derivable."""
    try:
        return DERIVATIONS[name].fn(msg, t_us, cache, options)
    except (TypeError, ValueError, OverflowError, AttributeError):
        return math.nan
