"""What the simulated autopilot puts on the wire: one message set per `sim-bridge fly --profile`.

A message set turns one frame of the simulator (the measured rows, SI, and the barometer's static
pressure) and the autopilot's command into MAVLink message objects; `AutopilotLink`
(mavlink_bridge.py) packs them, adds the HEARTBEAT once per second and answers requests.

- `native` (the default): the simulator's own set, read by the service file's `[measurements]`
  (`fdir run --autopilot none`): ODOMETRY body velocities, SCALED_IMU, ACTUATOR_OUTPUT_STATUS, ...
- `ardupilot`: ArduPlane's stock set, read by config/autopilots/ardupilot.toml (`fdir run
  --autopilot ardupilot|auto`): HEARTBEAT autopilot 3, ATTITUDE, GLOBAL_POSITION_INT (NED cm/s),
  GPS_RAW_INT (UNIX-epoch GPS time), SYSTEM_TIME (1 Hz, SRn_EXTRA3), SCALED_PRESSURE, RAW_IMU (mG),
  VFR_HUD (no timestamp), SERVO_OUTPUT_RAW (PWM through its SERVOn_* parameters: ArduPlane's
  defaults, or `--param` overrides), PARAM_VALUE answers (only when asked, as a stock ArduPlane).
- `px4`: PX4's Onboard-mode set (MAV_n_MODE = 2), read by config/autopilots/px4.toml (`fdir run
  --autopilot px4|auto`): HEARTBEAT autopilot 12, ATTITUDE, LOCAL_POSITION_NED (NED m/s),
  HIGHRES_IMU (m/s^2, hPa), GPS_RAW_INT (fix time since boot), VFR_HUD, SERVO_OUTPUT_RAW port 0
  (PWM on the MAIN channels of the profile's example [parameters]), PARAM_VALUE answers (integers
  bytewise, as PX4).

Clocks: the simulation time t (s) is the boot time (time_boot_ms = round(t * 1000), time_usec
since boot = round(t * 1e6)), so the service's frames and FDIR_ESTIMATEs keep the simulator's
frame times. The internal simulation flies wings level, heading north (roll = yaw = 0); a world that
measures the roll, the body-y velocity v and the roll and yaw rates p, r (JSBSim's) sends them on
ATTITUDE (roll, rollspeed, yawspeed) and in the NED velocity.
"""

from __future__ import annotations

import math
import struct
from typing import Protocol

import numpy as np

from fdir_service.mavlink import dialect
from fdir_service.runtime.derived import PX4_SERVO_FUNCTION_0, PX4_SURFACES
from fdir_service.service_config import RHO_SEA_LEVEL
from sim_bridge.scenario import Scenario

Values = dict[str, float | None]
"""Row name -> the measured value this frame (SI), None when the row has no sample."""

PROFILES = ("native", "ardupilot", "px4")
"""The `sim-bridge fly --profile` choices."""

ELEVATOR_PWM_RANGE_RAD = math.radians(30.0)
"""Native: elevator deflection at PWM 1000 / 2000 us (-/+), 1500 us = 0."""


class MessageSet(Protocol):
    """One autopilot's message set (message objects, not yet packed)."""

    def heartbeat(self): ...

    def sensors(self, t: float, v: Values, static_pressure_pa: float) -> list: ...

    def actuators(self, t: float, u_cmd: np.ndarray) -> list: ...

    def answer(self, msg) -> list: ...


def make_message_set(profile: str, scenario: Scenario, system: int = 1,
                     params: dict[str, float] | None = None) -> MessageSet:
    """The message set of `profile` ("native" | "ardupilot" | "px4") for a scenario; ValueError
    otherwise. `params`: parameter values that differ from the autopilot's defaults (ardupilot only)."""
    if params and profile != "ardupilot":
        raise ValueError(f"--param: only the ardupilot profile takes parameters, not {profile!r}")
    if profile == "native":
        return NativeMessages()
    if profile == "ardupilot":
        return ArduPlaneMessages(scenario, system, params)
    if profile == "px4":
        return PX4Messages(scenario, system)
    raise ValueError(f"--profile: expected one of {', '.join(PROFILES)}, got {profile!r}")


def elevator_to_pwm(delta_e: float) -> int:
    """Native: elevator angle (rad) -> PWM (us), 1 us resolution, clipped to 1000..2000."""
    return int(min(max(round(1500.0 + 500.0 * delta_e / ELEVATOR_PWM_RANGE_RAD), 1000), 2000))


def throttle_to_pwm(delta_t: float) -> int:
    """Native: throttle (0..1) -> PWM (us), clipped to 1000..2000."""
    return int(min(max(round(1000.0 + 1000.0 * delta_t), 1000), 2000))


def _mg(a: float | None) -> int:
    """Specific force (m/s^2) -> milli-g, int16 (None: 0)."""
    return 0 if a is None else int(max(min(round(a / 9.80665 * 1000.0), 32767), -32768))


def _nan_if_none(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def _diff_pressure_hpa(airspeed: float | None) -> float:
    """The pitot's differential pressure (hPa) of an EAS airspeed (m/s), read back with rho_0."""
    return 0.0 if airspeed is None else 0.5 * RHO_SEA_LEVEL * float(airspeed) ** 2 / 100.0


# ------------------------------------------------------------------------------ native

def _heartbeat(autopilot: int, custom_mode: int = 0):
    """An armed fixed-wing HEARTBEAT in an auto mode, of MAV_AUTOPILOT `autopilot`."""
    mode = (dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | dialect.MAV_MODE_FLAG_STABILIZE_ENABLED
            | dialect.MAV_MODE_FLAG_GUIDED_ENABLED | dialect.MAV_MODE_FLAG_AUTO_ENABLED
            | dialect.MAV_MODE_FLAG_SAFETY_ARMED)
    return dialect.MAVLink_heartbeat_message(dialect.MAV_TYPE_FIXED_WING, autopilot, mode, custom_mode,
                                             dialect.MAV_STATE_ACTIVE, 3)


def interval_ack(msg) -> list:
    """COMMAND_ACK ACCEPTED for a MAV_CMD_SET_MESSAGE_INTERVAL (a COMMAND_LONG): the simulated
    autopilot takes the service's stream requests (its rates are the scenario's all the same)."""
    if msg.get_type() != "COMMAND_LONG" or msg.command != dialect.MAV_CMD_SET_MESSAGE_INTERVAL:
        return []
    return [dialect.MAVLink_command_ack_message(msg.command, dialect.MAV_RESULT_ACCEPTED)]


class NativeMessages:
    """The simulator's own message set (see mavlink_bridge.py's docstring for the fields)."""

    def heartbeat(self):
        """HEARTBEAT, MAV_AUTOPILOT_GENERIC."""
        return _heartbeat(dialect.MAV_AUTOPILOT_GENERIC)

    def sensors(self, t: float, v: Values, static_pressure_pa: float) -> list:
        """GPS_RAW_INT, SCALED_PRESSURE, ATTITUDE, ODOMETRY, VFR_HUD, SCALED_IMU: each only when one
        of its rows was measured."""
        makers = (self._gnss, self._baro, self._attitude, self._odometry, self._vfr_hud, self._imu)
        return [m for m in (make(t, v, static_pressure_pa) for make in makers) if m is not None]

    @staticmethod
    def _gnss(t: float, v: Values, static_pressure_pa: float):
        gnss = v.get("gnss_alt")
        if gnss is None:
            return None
        return dialect.MAVLink_gps_raw_int_message(int(round(t * 1e6)), dialect.GPS_FIX_TYPE_3D_FIX, 0, 0,
                                                   int(round(gnss * 1000.0)), 100, 150, 65535, 65535, 12)

    @staticmethod
    def _baro(t: float, v: Values, static_pressure_pa: float):
        if v.get("baro_alt") is None:
            return None
        return dialect.MAVLink_scaled_pressure_message(int(round(t * 1000.0)),
                                                       float(static_pressure_pa) / 100.0,
                                                       _diff_pressure_hpa(v.get("airspeed")), 1500)

    @staticmethod
    def _attitude(t: float, v: Values, static_pressure_pa: float):
        theta, q = v.get("theta"), v.get("q")
        if theta is None and q is None:
            return None
        roll, p, r = (v.get(k) or 0.0 for k in ("roll", "p", "r"))   # 0 unless measured (wings level)
        return dialect.MAVLink_attitude_message(int(round(t * 1000.0)), roll, _nan_if_none(theta),
                                                0.0, p, _nan_if_none(q), r)

    @staticmethod
    def _odometry(t: float, v: Values, static_pressure_pa: float):
        u, w, theta = v.get("u"), v.get("w"), v.get("theta")
        if u is None and w is None:
            return None
        nan = float("nan")
        quat = [nan] * 4 if theta is None else [math.cos(theta / 2), 0.0, math.sin(theta / 2), 0.0]
        return dialect.MAVLink_odometry_message(
            int(round(t * 1e6)), dialect.MAV_FRAME_LOCAL_NED, dialect.MAV_FRAME_BODY_FRD, nan, nan, nan, quat,
            _nan_if_none(u), (v.get("v") or 0.0), _nan_if_none(w), nan, nan, nan,
            [nan] * 21, [nan] * 21, 0, dialect.MAV_ESTIMATOR_TYPE_NAIVE, 0)

    @staticmethod
    def _vfr_hud(t: float, v: Values, static_pressure_pa: float):
        airspeed = v.get("airspeed")
        if airspeed is None:
            return None
        nan = float("nan")
        return dialect.MAVLink_vfr_hud_message(airspeed, nan, 0, 0, nan, nan)

    @staticmethod
    def _imu(t: float, v: Values, static_pressure_pa: float):
        ax, az = v.get("ax"), v.get("az")
        if ax is None and az is None:
            return None
        return dialect.MAVLink_scaled_imu_message(int(round(t * 1000.0)), _mg(ax), 0, _mg(az),
                                                  0, 0, 0, 0, 0, 0)

    def actuators(self, t: float, u_cmd: np.ndarray) -> list:
        """SERVO_OUTPUT_RAW (PWM) and ACTUATOR_OUTPUT_STATUS (float SI) for the command u_cmd (2,)."""
        t_us = int(round(t * 1e6))
        de, dt_ = float(u_cmd[0]), float(u_cmd[1])
        servo = [0] * 16
        servo[0] = 1500                      # aileron (lateral not simulated)
        servo[1] = elevator_to_pwm(de)
        servo[2] = throttle_to_pwm(dt_)
        servo[3] = 1500                      # rudder
        act = [0.0] * 32
        act[0], act[1] = de, dt_
        return [dialect.MAVLink_servo_output_raw_message(t_us & 0xFFFFFFFF, 0, *servo),
                dialect.MAVLink_actuator_output_status_message(t_us, 0b11, act)]

    def answer(self, msg) -> list:
        """The native autopilot answers stream requests only (`interval_ack`)."""
        return interval_ack(msg)


# ------------------------------------------------------------------------------ stock autopilots

ELEVATOR_TRAVEL_RAD = math.radians(25.0)
"""The simulated Aerosonde's elevator deflection at the servo's MIN / MAX PWM (rad)."""
HOME_LAT_DEG, HOME_LON_DEG = -35.363262, 149.165237
"""Where the flight starts (ArduPilot SITL's default home, CMAC)."""
EARTH_RADIUS_M = 6_371_000.0
SERVO_OUTPUTS = 16
"""SERVO_OUTPUT_RAW's channels (servo9..16_raw: the MAVLink 2 extension)."""

Params = dict[str, tuple[int, int]]
"""Parameter name -> (value, MAV_PARAM_TYPE)."""


def angle_pwm(frac: float, lo: float, trim: float, hi: float) -> int:
    """An angle-type servo output, a fraction of its travel (clipped to [-1, 1]), -> PWM (us) as
    `SRV_Channel::pwm_from_angle`: trim + frac * (hi - trim) above trim, trim + frac * (trim - lo)
    below; 1 us steps. The inverse of fdir_service's `pwm_to_angle_fraction`."""
    frac = min(max(frac, -1.0), 1.0)
    return int(round(trim + frac * ((hi - trim) if frac >= 0 else (trim - lo))))


def range_pwm(x: float, lo: float, hi: float) -> int:
    """A range-type servo output (throttle, clipped to 0..1) -> PWM (us): lo + x * (hi - lo), 1 us steps."""
    return int(round(lo + min(max(x, 0.0), 1.0) * (hi - lo)))


def _int16(x: float) -> int:
    return int(max(min(round(x), 32767), -32768))


def _param_id(msg) -> str:
    """A PARAM_REQUEST_READ's param_id as text (NUL padding removed)."""
    pid = msg.param_id.decode("ascii", "replace") if isinstance(msg.param_id, bytes) else msg.param_id
    return pid.rstrip("\x00")


class _StockAutopilot:
    """What the simulated stock autopilots share: the navigation state from the measured rows, the
    ATTITUDE / VFR_HUD / GPS_RAW_INT messages, SERVO_OUTPUT_RAW and the parameter protocol.

    The ground velocity `ned` (m/s) is the measured body velocity (u, w rows: the truth's ground
    velocity, wind included, plus the scenario's noise and faults, standing for the EKF's) rotated
    to NED with the pitch sent on ATTITUDE, so the service's derivation gives the measured u, w back.
    Position: north of the home by the integrated velocity; altitude the barometer's.
    A subclass sets AUTOPILOT, CUSTOM_MODE, PARAMS, GPS_TIME0_US and the message makers.
    """

    AUTOPILOT = dialect.MAV_AUTOPILOT_GENERIC
    CUSTOM_MODE = 0
    PARAMS: Params = {}
    GPS_TIME0_US = 0
    """GPS_RAW_INT.time_usec (us) at simulation time 0."""

    def __init__(self, scenario: Scenario, system: int = 1) -> None:
        self.system = system
        self.dt = scenario.dt_s
        self.gnss_latency_s = float(scenario.sensors.gnss_latency_s or 0.0)
        self.north_m = 0.0
        self.home_alt_m: float | None = None
        self.alt_m = 0.0
        self.throttle = 0.0
        self.ned = (0.0, 0.0, 0.0)

    def heartbeat(self):
        """HEARTBEAT: MAV_TYPE_FIXED_WING, the class's MAV_AUTOPILOT, armed, its auto custom_mode."""
        return _heartbeat(self.AUTOPILOT, self.CUSTOM_MODE)

    def sensors(self, t: float, v: Values, static_pressure_pa: float) -> list:
        """The `_makers` messages in order, each only when one of its rows was measured."""
        self._navigate(v)
        return [m for m in (make(t, v, static_pressure_pa) for make in self._makers()) if m is not None]

    def _makers(self) -> tuple:
        return ()

    def _navigate(self, v: Values) -> None:
        """NED velocity (m/s) from u, v, w, the roll and theta (heading north; v and the roll 0 when
        not measured: wings level); the north position and altitude (m) updated."""
        u, w, theta = v.get("u"), v.get("w"), v.get("theta")
        if u is not None and w is not None:
            th, phi, vy = 0.0 if theta is None else theta, (v.get("roll") or 0.0), (v.get("v") or 0.0)
            tilted = vy * math.sin(phi) + w * math.cos(phi)          # along body z rolled back to level
            self.ned = (u * math.cos(th) + tilted * math.sin(th), vy * math.cos(phi) - w * math.sin(phi),
                        -u * math.sin(th) + tilted * math.cos(th))
        self.north_m += self.ned[0] * self.dt
        alt = v.get("baro_alt")
        if alt is not None:
            self.alt_m = float(alt)
            if self.home_alt_m is None:
                self.home_alt_m = self.alt_m

    def _relative_alt_m(self) -> float:
        """Altitude above the first barometer reading (m)."""
        return self.alt_m - (self.home_alt_m or self.alt_m)

    def _lat_lon_e7(self) -> tuple[int, int]:
        lat = HOME_LAT_DEG + math.degrees(self.north_m / EARTH_RADIUS_M)
        return int(round(lat * 1e7)), int(round(HOME_LON_DEG * 1e7))

    @staticmethod
    def _attitude(t: float, v: Values, static_pressure_pa: float):
        """ATTITUDE: time_boot_ms; roll (0 unless measured) and pitch rad; rollspeed, pitchspeed,
        yawspeed rad/s (roll and yaw rates 0 unless measured); yaw 0."""
        return NativeMessages._attitude(t, v, static_pressure_pa)

    def _vfr_hud(self, t: float, v: Values, static_pressure_pa: float):
        """VFR_HUD: airspeed, groundspeed m/s, heading deg, throttle %, alt m, climb m/s; no time."""
        airspeed = v.get("airspeed")
        if airspeed is None:
            return None
        vn, ve, vd = self.ned
        return dialect.MAVLink_vfr_hud_message(float(airspeed), math.hypot(vn, ve), 0,
                                               int(round(100.0 * self.throttle)), self.alt_m, -vd)

    def _gnss(self, t: float, v: Values, static_pressure_pa: float):
        """GPS_RAW_INT on a new fix: time_usec the fix's time (the reported altitude's, gnss_latency_s
        before t; GPS_TIME0_US at t = 0; not before 0), alt mm MSL, vel cm/s, cog 0 cdeg."""
        gnss = v.get("gnss_alt")
        if gnss is None:
            return None
        lat, lon = self._lat_lon_e7()
        t_fix_us = max(self.GPS_TIME0_US + int(round((t - self.gnss_latency_s) * 1e6)), 0)
        vel = int(min(round(math.hypot(self.ned[0], self.ned[1]) * 100.0), 65534))
        return dialect.MAVLink_gps_raw_int_message(t_fix_us, dialect.GPS_FIX_TYPE_3D_FIX, lat, lon,
                                                   int(round(gnss * 1000.0)), 100, 150, vel, 0, 12)

    def actuators(self, t: float, u_cmd: np.ndarray) -> list:
        """SERVO_OUTPUT_RAW (time_usec uint32 since boot, port 0): `_servos` PWM (us) of u_cmd (2,)
        [delta_e rad, delta_t 0..1]."""
        de, dt_ = float(u_cmd[0]), float(u_cmd[1])
        self.throttle = min(max(dt_, 0.0), 1.0)
        servo = self._servos(de, dt_)
        return [dialect.MAVLink_servo_output_raw_message(int(round(t * 1e6)) & 0xFFFFFFFF, 0, *servo)]

    def _servos(self, delta_e: float, delta_t: float) -> list[int]:
        """The SERVO_OUTPUT_RAW channels 1..16 (PWM us, 0 = not output)."""
        return [0] * SERVO_OUTPUTS

    def answer(self, msg) -> list:
        """PARAM_VALUE(s) for a PARAM_REQUEST_LIST / PARAM_REQUEST_READ addressed to this system
        (or broadcast); a name or index not in PARAMS gets no answer. A stream request gets its
        COMMAND_ACK (`interval_ack`)."""
        kind = msg.get_type()
        if kind not in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ"):
            return interval_ack(msg)
        if msg.target_system not in (0, self.system):
            return []
        names = list(self.PARAMS)
        if kind == "PARAM_REQUEST_LIST":
            return [self._param_value(i) for i in range(len(names))]
        if msg.param_index >= 0:
            return [self._param_value(msg.param_index)] if msg.param_index < len(names) else []
        pid = _param_id(msg)
        return [self._param_value(names.index(pid))] if pid in names else []

    def _param_value(self, index: int):
        name = list(self.PARAMS)[index]
        value, ptype = self.PARAMS[name]
        return dialect.MAVLink_param_value_message(name.encode("ascii"), self._encode(value, ptype), ptype,
                                                   len(self.PARAMS), index)

    @staticmethod
    def _encode(value: int, param_type: int) -> float:
        """PARAM_VALUE.param_value of a parameter: the value cast to float (ArduPilot's encoding)."""
        return float(value)


# ------------------------------------------------------------------------------ ArduPlane

_INT16, _INT8 = dialect.MAV_PARAM_TYPE_INT16, dialect.MAV_PARAM_TYPE_INT8
ARDUPLANE_FUNCTIONS = {1: 4, 2: 19, 3: 70, 4: 21}
"""ArduPlane's default SERVOn_FUNCTION: aileron, elevator, throttle, rudder (other outputs 0: disabled)."""
ARDUPLANE_SERVO_PARAMS: Params = {
    # name: (value, MAV_PARAM_TYPE): ArduPlane's defaults for all 16 outputs (SRV_Channel: FUNCTION,
    # MIN / TRIM / MAX AP_Int16, REVERSED AP_Int8); ArduPilot sends integers as their float value
    **{f"SERVO{n}_FUNCTION": (ARDUPLANE_FUNCTIONS.get(n, 0), _INT16) for n in range(1, SERVO_OUTPUTS + 1)},
    **{f"SERVO{n}_{kind}": (value, ptype) for n in range(1, SERVO_OUTPUTS + 1) for kind, value, ptype in (
        ("MIN", 1100, _INT16), ("TRIM", 1500, _INT16), ("MAX", 1900, _INT16), ("REVERSED", 0, _INT8))},
}
"""The SERVOn_* parameters the simulated ArduPlane uses and answers PARAM_REQUEST_* with (its
defaults; `sim-bridge fly --param NAME=VALUE` overrides them)."""
ARDUPLANE_ELEVATOR, ARDUPLANE_THROTTLE = 19, 70
"""SERVOn_FUNCTION of the elevator and the throttle."""


def with_overrides(params: Params, overrides: dict[str, float] | None) -> Params:
    """`params` with some values replaced (their MAV_PARAM_TYPE kept); ValueError for an unknown name."""
    out = dict(params)
    for name, value in (overrides or {}).items():
        if name not in out:
            raise ValueError(f"--param {name}: not a parameter of this autopilot "
                             f"(e.g. {', '.join(list(out)[:3])}, ...)")
        out[name] = (int(value), out[name][1])
    return out


GPS_EPOCH_US = 1_750_000_000_000_000
"""ArduPlane's GPS_RAW_INT.time_usec at simulation time 0: UNIX time (us) of 2025-06-15 15:06:40 UTC."""
ARDUPLANE_AUTO_MODE = 10
"""ArduPlane's custom_mode AUTO."""
SYSTEM_TIME_PERIOD_S = 1.0
"""ArduPlane sends SYSTEM_TIME in its SRn_EXTRA3 stream group, at 1 Hz (SRn_EXTRA3 = 1)."""


def ardupilot_output_pwm(function: int, value: float, p: Params, n: int) -> int:
    """Output n's PWM (us) with its SERVOn_* parameters `p`: the elevator (function 19) from
    value = delta_e (rad, + = trailing edge down), the throttle (70) from value = delta_t (0..1),
    another function at TRIM, a disabled output (0) 0.

    ArduPilot's positive elevator output is nose-up (trailing edge up, = -delta_e), a fraction of
    the travel (ELEVATOR_TRAVEL_RAD, 25 deg), negated when REVERSED, mapped with MIN / TRIM / MAX
    (`angle_pwm`, SRV_Channel::pwm_from_angle); the throttle MIN .. MAX (MAX .. MIN reversed)."""
    lo, trim, hi, rev = (p[f"SERVO{n}_{k}"][0] for k in ("MIN", "TRIM", "MAX", "REVERSED"))
    if function == ARDUPLANE_ELEVATOR:
        frac = -value / ELEVATOR_TRAVEL_RAD
        return angle_pwm(-frac if rev else frac, lo, trim, hi)
    if function == ARDUPLANE_THROTTLE:
        return range_pwm(1.0 - value if rev else value, lo, hi)
    return 0 if function == 0 else int(trim)


class ArduPlaneMessages(_StockAutopilot):
    """ArduPlane's stock streams for the rows the ArduPilot profile reads: ATTITUDE,
    GLOBAL_POSITION_INT (NED cm/s; the measured u, w back to 1 cm/s), RAW_IMU, SCALED_PRESSURE,
    VFR_HUD, GPS_RAW_INT (UNIX-epoch fix time), SYSTEM_TIME (1 Hz); SERVO_OUTPUT_RAW through its
    SERVOn_* parameters (ArduPlane's defaults with `params` overriding some)."""

    AUTOPILOT = dialect.MAV_AUTOPILOT_ARDUPILOTMEGA
    CUSTOM_MODE = ARDUPLANE_AUTO_MODE
    PARAMS = ARDUPLANE_SERVO_PARAMS
    GPS_TIME0_US = GPS_EPOCH_US

    def __init__(self, scenario: Scenario, system: int = 1, params: dict[str, float] | None = None) -> None:
        super().__init__(scenario, system)
        self.system_time_due_s = 0.0
        self.PARAMS = with_overrides(ARDUPLANE_SERVO_PARAMS, params)

    def _makers(self) -> tuple:
        return (self._attitude, self._position, self._imu, self._baro, self._vfr_hud, self._system_time,
                self._gnss)

    def _system_time(self, t: float, v: Values, static_pressure_pa: float):
        """SYSTEM_TIME every SYSTEM_TIME_PERIOD_S (s): time_unix_usec on the GPS clock (GPS_TIME0_US
        at t = 0), time_boot_ms = t in ms."""
        if t < self.system_time_due_s - 1e-9:
            return None
        periods = 1 + (t - self.system_time_due_s) // SYSTEM_TIME_PERIOD_S
        self.system_time_due_s += SYSTEM_TIME_PERIOD_S * periods
        return dialect.MAVLink_system_time_message(self.GPS_TIME0_US + int(round(t * 1e6)),
                                                   int(round(t * 1000.0)))

    def _position(self, t: float, v: Values, static_pressure_pa: float):
        """GLOBAL_POSITION_INT: lat/lon degE7, alt / relative_alt mm, vx/vy/vz cm/s NED, hdg 0 cdeg."""
        if v.get("u") is None or v.get("w") is None:
            return None
        lat, lon = self._lat_lon_e7()
        vn, ve, vd = self.ned
        return dialect.MAVLink_global_position_int_message(
            int(round(t * 1000.0)), lat, lon, int(round(self.alt_m * 1000.0)),
            int(round(self._relative_alt_m() * 1000.0)),
            _int16(vn * 100.0), _int16(ve * 100.0), _int16(vd * 100.0), 0)

    @staticmethod
    def _imu(t: float, v: Values, static_pressure_pa: float):
        """RAW_IMU: time_usec since boot; xacc / zacc mG (FRD specific force), ygyro mrad/s."""
        ax, az, q = v.get("ax"), v.get("az"), v.get("q")
        if ax is None and az is None:
            return None
        gy = 0 if q is None else _int16(q * 1000.0)
        return dialect.MAVLink_raw_imu_message(int(round(t * 1e6)), _mg(ax), 0, _mg(az), 0, gy, 0, 0, 0, 0)

    @staticmethod
    def _baro(t: float, v: Values, static_pressure_pa: float):
        """SCALED_PRESSURE: press_abs hPa (static), press_diff hPa (pitot), 15 degC."""
        return NativeMessages._baro(t, v, static_pressure_pa)

    def _servos(self, delta_e: float, delta_t: float) -> list[int]:
        """Each output by its SERVOn_FUNCTION (`ardupilot_output_pwm`; defaults: SERVO1 aileron and
        SERVO4 rudder at trim, SERVO2 elevator, SERVO3 throttle, 5..16 disabled: 0), PWM us."""
        value = {ARDUPLANE_ELEVATOR: delta_e, ARDUPLANE_THROTTLE: delta_t}
        p = self.PARAMS
        out = []
        for n in range(1, SERVO_OUTPUTS + 1):
            function = p[f"SERVO{n}_FUNCTION"][0]
            out.append(ardupilot_output_pwm(function, value.get(function, 0.0), p, n))
        return out


# ------------------------------------------------------------------------------ PX4

_INT32 = dialect.MAV_PARAM_TYPE_INT32
PX4_PARAMS: Params = {
    # name: (value, MAV_PARAM_TYPE): config/autopilots/px4.toml's [parameters], an example standard
    # plane (PX4 has no default layout); PX4's parameters are int32 or float, integers sent bytewise
    "CA_SV_CS0_TYPE": (1, _INT32),        # left aileron  -> function 201
    "CA_SV_CS1_TYPE": (2, _INT32),        # right aileron -> 202
    "CA_SV_CS2_TYPE": (3, _INT32),        # elevator      -> 203
    "CA_SV_CS3_TYPE": (4, _INT32),        # rudder        -> 204
    "PWM_MAIN_FUNC1": (201, _INT32),
    "PWM_MAIN_FUNC2": (202, _INT32),
    "PWM_MAIN_FUNC3": (203, _INT32),      # the elevator on MAIN 3
    "PWM_MAIN_FUNC4": (204, _INT32),
    "PWM_MAIN_FUNC5": (101, _INT32),      # motor 1 on MAIN 5
    "PWM_MAIN_MIN3": (1000, _INT32),
    "PWM_MAIN_MAX3": (2000, _INT32),
    "PWM_MAIN_MIN5": (1000, _INT32),
    "PWM_MAIN_MAX5": (2000, _INT32),
    "PWM_MAIN_REV": (0, _INT32),          # bit n-1 reverses MAIN n
}
"""The parameters the simulated PX4 uses and answers PARAM_REQUEST_* with."""

PX4_ELEVATOR_SURFACE_TYPE = 3
"""CA_SV_CSi_TYPE of an elevator; surface i drives output function 201 + i."""
PX4_MOTOR1_FUNCTION = 101
PX4_PWM_DEFAULTS = (1000.0, 2000.0)
"""PWM_MAIN_MINn / MAXn when not set (us); PWM_MAIN_CENTn unset (-1): (MIN + MAX) / 2."""
PX4_MAIN_CHANNELS = 8
PX4_AUTO_MISSION_MODE = (4 << 16) | (4 << 24)
"""PX4's custom_mode: main mode AUTO (4) << 16, sub mode MISSION (4) << 24."""


def _px4(name: str, default: float | None = None) -> float | None:
    entry = PX4_PARAMS.get(name)
    return default if entry is None else float(entry[0])


def px4_channel(function: int) -> int | None:
    """The lowest MAIN channel n (1-based) with PWM_MAIN_FUNCn == function, or None."""
    for n in range(1, PX4_MAIN_CHANNELS + 1):
        if _px4(f"PWM_MAIN_FUNC{n}") == function:
            return n
    return None


def px4_elevator_function() -> int | None:
    """201 + the lowest control surface i with CA_SV_CSi_TYPE = 3 (elevator), or None."""
    for i in range(PX4_SURFACES):
        if _px4(f"CA_SV_CS{i}_TYPE") == PX4_ELEVATOR_SURFACE_TYPE:
            return PX4_SERVO_FUNCTION_0 + i
    return None


def px4_limits(n: int) -> tuple[float, float, float, bool]:
    """MAIN channel n's (MIN, centre, MAX) PWM (us) and whether bit n-1 of PWM_MAIN_REV reverses it."""
    lo = _px4(f"PWM_MAIN_MIN{n}", PX4_PWM_DEFAULTS[0])
    hi = _px4(f"PWM_MAIN_MAX{n}", PX4_PWM_DEFAULTS[1])
    cent = _px4(f"PWM_MAIN_CENT{n}", -1.0)
    centre = cent if cent >= 0 else 0.5 * (lo + hi)
    return lo, centre, hi, bool(int(_px4("PWM_MAIN_REV", 0.0)) >> (n - 1) & 1)


def elevator_pwm_px4(delta_e: float, n: int) -> int:
    """delta_e (rad, + = trailing edge down) -> the elevator's MAIN n PWM (us): PX4's positive
    elevator output is a nose-up torque (CA_SV_CSi_TRQ_P = 1: trailing edge up, = -delta_e), a
    fraction of ELEVATOR_TRAVEL_RAD, negated on a reversed channel, mapped with MIN / centre / MAX."""
    lo, centre, hi, rev = px4_limits(n)
    frac = -delta_e / ELEVATOR_TRAVEL_RAD
    return angle_pwm(-frac if rev else frac, lo, centre, hi)


def throttle_pwm_px4(delta_t: float, n: int) -> int:
    """Throttle (0..1) -> the motor's MAIN n PWM (us): MIN .. MAX (MAX .. MIN reversed)."""
    lo, _, hi, rev = px4_limits(n)
    x = min(max(delta_t, 0.0), 1.0)
    return range_pwm(1.0 - x if rev else x, lo, hi)


def _px4_bytewise(value: int) -> float:
    """An int32 parameter as PX4 sends it: the float whose four bytes are the integer's."""
    return struct.unpack("<f", struct.pack("<i", int(value)))[0]


class PX4Messages(_StockAutopilot):
    """PX4's Onboard-mode streams (MAV_n_MODE = 2) for the rows the PX4 profile reads: ATTITUDE,
    LOCAL_POSITION_NED (m, m/s NED; the measured u, w back), HIGHRES_IMU (m/s^2, hPa), VFR_HUD,
    GPS_RAW_INT (fix time since boot); SERVO_OUTPUT_RAW port 0 on the MAIN channels of PX4_PARAMS."""

    AUTOPILOT = dialect.MAV_AUTOPILOT_PX4
    CUSTOM_MODE = PX4_AUTO_MISSION_MODE
    PARAMS = PX4_PARAMS

    def _makers(self) -> tuple:
        return (self._attitude, self._position, self._imu, self._vfr_hud, self._gnss)

    def _position(self, t: float, v: Values, static_pressure_pa: float):
        """LOCAL_POSITION_NED: time_boot_ms; x north, y east, z down of the home (m); vx, vy, vz m/s NED."""
        if v.get("u") is None or v.get("w") is None:
            return None
        vn, ve, vd = self.ned
        return dialect.MAVLink_local_position_ned_message(int(round(t * 1000.0)), self.north_m, 0.0,
                                                          -self._relative_alt_m(), vn, ve, vd)

    @staticmethod
    def _imu(t: float, v: Values, static_pressure_pa: float):
        """HIGHRES_IMU: time_usec since boot; xacc / zacc m/s^2 (FRD specific force), ygyro rad/s,
        abs_pressure / diff_pressure hPa, pressure_alt m, 15 degC; NaN and its fields_updated bit
        clear where the row was not measured."""
        ax, az, q, alt = v.get("ax"), v.get("az"), v.get("q"), v.get("baro_alt")
        if ax is None and az is None and alt is None:
            return None
        updated = sum(bit for bit, x in ((1, ax), (4, az), (16, q)) if x is not None)
        updated |= 0 if alt is None else 0x1E00       # abs, diff pressure, pressure_alt, temperature
        abs_hpa = math.nan if alt is None else float(static_pressure_pa) / 100.0
        return dialect.MAVLink_highres_imu_message(
            int(round(t * 1e6)), _nan_if_none(ax), 0.0, _nan_if_none(az), 0.0, _nan_if_none(q), 0.0,
            0.0, 0.0, 0.0, abs_hpa, _diff_pressure_hpa(v.get("airspeed")), _nan_if_none(alt), 15.0,
            updated, 0)

    def _servos(self, delta_e: float, delta_t: float) -> list[int]:
        """MAIN 1..8: the elevator surface's and motor 1's channel from u, the other assigned
        channels at their centre, unassigned ones 0 (not output)."""
        servo = [int(round(px4_limits(n)[1])) if _px4(f"PWM_MAIN_FUNC{n}", 0.0) else 0
                 for n in range(1, PX4_MAIN_CHANNELS + 1)]
        elevator = px4_channel(px4_elevator_function() or 0)
        motor = px4_channel(PX4_MOTOR1_FUNCTION)
        if elevator is not None:
            servo[elevator - 1] = elevator_pwm_px4(delta_e, elevator)
        if motor is not None:
            servo[motor - 1] = throttle_pwm_px4(delta_t, motor)
        return servo + [0] * (SERVO_OUTPUTS - PX4_MAIN_CHANNELS)

    @staticmethod
    def _encode(value: int, param_type: int) -> float:
        """PX4's encoding: an integer type bytewise (`_px4_bytewise`), a float as is."""
        return float(value) if param_type == dialect.MAV_PARAM_TYPE_REAL32 else _px4_bytewise(value)
