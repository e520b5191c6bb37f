"""What the simulated autopilot puts on the wire: one message set per `sim-bridge fly --profile`.

A message set turns one frame of the simulator (the measured rows, SI, and the barometer's static
pressure) and the autopilot's command into MAVLink message objects; `AutopilotLink`
(mavlink_bridge.py) packs them, adds the HEARTBEAT once per second and answers requests.

- `native` (the default): the simulator's own set, read by the service file's `[measurements]`
  (`fdir run --autopilot none`): ODOMETRY body velocities, SCALED_IMU, ACTUATOR_OUTPUT_STATUS, ...
- `ardupilot`: ArduPlane's stock set, read by config/autopilots/ardupilot.toml (`fdir run
  --autopilot ardupilot|auto`): HEARTBEAT autopilot 3, ATTITUDE, GLOBAL_POSITION_INT (NED cm/s),
  GPS_RAW_INT (UNIX-epoch GPS time), SCALED_PRESSURE, RAW_IMU (mG), VFR_HUD (no timestamp),
  SERVO_OUTPUT_RAW (PWM through ArduPlane's default SERVOn_* parameters), PARAM_VALUE answers.

Clocks: the simulation time t (s) is the boot time (time_boot_ms = round(t * 1000), time_usec
since boot = round(t * 1e6)), so the service's frames and FDIR_ESTIMATEs keep the simulator's
frame times. The longitudinal simulation flies wings level, heading north (roll = yaw = 0).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from fdir_service.mavlink import dialect
from fdir_service.service_config import RHO_SEA_LEVEL
from sim_bridge.scenario import Scenario

Values = dict[str, float | None]
"""Row name -> the measured value this frame (SI), None when the row has no sample."""

PROFILES = ("native", "ardupilot")
"""The `sim-bridge fly --profile` choices."""

ELEVATOR_PWM_RANGE_RAD = math.radians(30.0)
"""Native: elevator deflection at PWM 1000 / 2000 us (-/+), 1500 us = 0."""


class MessageSet(Protocol):
    """One autopilot's message set (message objects, not yet packed)."""

    def heartbeat(self): ...

    def sensors(self, t: float, v: Values, static_pressure_pa: float) -> list: ...

    def actuators(self, t: float, u_cmd: np.ndarray) -> list: ...

    def answer(self, msg) -> list: ...


def make_message_set(profile: str, scenario: Scenario, system: int = 1) -> MessageSet:
    """The message set of `profile` ("native" | "ardupilot") for a scenario; ValueError otherwise."""
    if profile == "native":
        return NativeMessages()
    if profile == "ardupilot":
        return ArduPlaneMessages(scenario, system)
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
        return dialect.MAVLink_attitude_message(int(round(t * 1000.0)), 0.0, _nan_if_none(theta),
                                                0.0, 0.0, _nan_if_none(q), 0.0)

    @staticmethod
    def _odometry(t: float, v: Values, static_pressure_pa: float):
        u, w, theta = v.get("u"), v.get("w"), v.get("theta")
        if u is None and w is None:
            return None
        nan = float("nan")
        quat = [nan] * 4 if theta is None else [math.cos(theta / 2), 0.0, math.sin(theta / 2), 0.0]
        return dialect.MAVLink_odometry_message(
            int(round(t * 1e6)), dialect.MAV_FRAME_LOCAL_NED, dialect.MAV_FRAME_BODY_FRD, nan, nan, nan, quat,
            _nan_if_none(u), nan, _nan_if_none(w), nan, nan, nan,
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


# ------------------------------------------------------------------------------ ArduPlane

ARDUPLANE_SERVO_PARAMS: dict[str, tuple[int, int]] = {
    # name: (value, MAV_PARAM_TYPE): ArduPlane's defaults (SRV_Channel: FUNCTION AP_Int16, MIN / TRIM /
    # MAX AP_Int16, REVERSED AP_Int8); ArduPilot sends integers as their float value
    "SERVO1_FUNCTION": (4, dialect.MAV_PARAM_TYPE_INT16),     # aileron
    "SERVO2_FUNCTION": (19, dialect.MAV_PARAM_TYPE_INT16),    # elevator
    "SERVO3_FUNCTION": (70, dialect.MAV_PARAM_TYPE_INT16),    # throttle
    "SERVO4_FUNCTION": (21, dialect.MAV_PARAM_TYPE_INT16),    # rudder
    "SERVO2_MIN": (1100, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO2_TRIM": (1500, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO2_MAX": (1900, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO2_REVERSED": (0, dialect.MAV_PARAM_TYPE_INT8),
    "SERVO3_MIN": (1100, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO3_TRIM": (1500, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO3_MAX": (1900, dialect.MAV_PARAM_TYPE_INT16),
    "SERVO3_REVERSED": (0, dialect.MAV_PARAM_TYPE_INT8),
}
"""The SERVOn_* parameters the simulated ArduPlane uses and answers PARAM_REQUEST_* with."""

ELEVATOR_TRAVEL_RAD = math.radians(25.0)
"""The simulated Aerosonde's elevator deflection at SERVO2_MIN / SERVO2_MAX (rad)."""
GPS_EPOCH_US = 1_750_000_000_000_000
"""GPS_RAW_INT.time_usec at simulation time 0: UNIX time (us) of 2025-06-15 15:06:40 UTC."""
HOME_LAT_DEG, HOME_LON_DEG = -35.363262, 149.165237
"""Where the flight starts (ArduPilot SITL's default home, CMAC)."""
EARTH_RADIUS_M = 6_371_000.0
ARDUPLANE_AUTO_MODE = 10
"""ArduPlane's custom_mode AUTO."""


def elevator_pwm_ardupilot(delta_e: float) -> int:
    """delta_e (rad, + = trailing edge down) -> SERVO2 PWM (us) with ArduPlane's defaults.

    ArduPilot's positive elevator output is nose-up (trailing edge up, = -delta_e), a fraction of
    the travel (ELEVATOR_TRAVEL_RAD, 25 deg) mapped as `SRV_Channel::pwm_from_angle`: TRIM + frac *
    (MAX - TRIM) above trim, TRIM + frac * (TRIM - MIN) below; clipped to MIN..MAX, 1 us steps.
    """
    p = ARDUPLANE_SERVO_PARAMS
    lo, trim, hi = p["SERVO2_MIN"][0], p["SERVO2_TRIM"][0], p["SERVO2_MAX"][0]
    frac = min(max(-delta_e / ELEVATOR_TRAVEL_RAD, -1.0), 1.0)
    pwm = trim + frac * ((hi - trim) if frac >= 0 else (trim - lo))
    return int(round(pwm))


def throttle_pwm_ardupilot(delta_t: float) -> int:
    """Throttle (0..1) -> SERVO3 PWM (us): MIN + delta_t * (MAX - MIN), clipped, 1 us steps."""
    p = ARDUPLANE_SERVO_PARAMS
    lo, hi = p["SERVO3_MIN"][0], p["SERVO3_MAX"][0]
    return int(round(lo + min(max(delta_t, 0.0), 1.0) * (hi - lo)))


def _int16(x: float) -> int:
    return int(max(min(round(x), 32767), -32768))


class ArduPlaneMessages:
    """ArduPlane's stock streams for the rows the ArduPilot profile reads.

    The ground velocity on GLOBAL_POSITION_INT is the measured body velocity (u, w rows: the
    truth's ground velocity, wind included, plus the scenario's noise and faults, standing for the
    EKF's) rotated to NED with the attitude sent on ATTITUDE, so the service's derivation gives the
    measured u, w back (to 1 cm/s). Position: north of the home by the integrated velocity; altitude
    the barometer's (ArduPilot's default EKF height source).
    """

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
        """HEARTBEAT: MAV_TYPE_FIXED_WING, MAV_AUTOPILOT_ARDUPILOTMEGA, armed, AUTO."""
        return _heartbeat(dialect.MAV_AUTOPILOT_ARDUPILOTMEGA, ARDUPLANE_AUTO_MODE)

    def sensors(self, t: float, v: Values, static_pressure_pa: float) -> list:
        """ATTITUDE, GLOBAL_POSITION_INT, RAW_IMU, SCALED_PRESSURE, VFR_HUD, GPS_RAW_INT (on a fix);
        each only when one of its rows was measured."""
        self._navigate(v)
        makers = (self._attitude, self._position, self._imu, self._baro, self._vfr_hud, self._gnss)
        return [m for m in (make(t, v, static_pressure_pa) for make in makers) if m is not None]

    def _navigate(self, v: Values) -> None:
        """NED velocity (m/s) from u, w and theta; the north position and altitude (m) updated."""
        u, w, theta = v.get("u"), v.get("w"), v.get("theta")
        if u is not None and w is not None:
            th = 0.0 if theta is None else theta
            self.ned = (u * math.cos(th) + w * math.sin(th), 0.0, -u * math.sin(th) + w * math.cos(th))
        self.north_m += self.ned[0] * self.dt
        alt = v.get("baro_alt")
        if alt is not None:
            self.alt_m = float(alt)
            if self.home_alt_m is None:
                self.home_alt_m = self.alt_m

    def _lat_lon_e7(self) -> tuple[int, int]:
        lat = HOME_LAT_DEG + math.degrees(self.north_m / EARTH_RADIUS_M)
        return int(round(lat * 1e7)), int(round(HOME_LON_DEG * 1e7))

    @staticmethod
    def _attitude(t: float, v: Values, static_pressure_pa: float):
        theta, q = v.get("theta"), v.get("q")
        if theta is None and q is None:
            return None
        return dialect.MAVLink_attitude_message(int(round(t * 1000.0)), 0.0, _nan_if_none(theta), 0.0,
                                                0.0, _nan_if_none(q), 0.0)

    def _position(self, t: float, v: Values, static_pressure_pa: float):
        """GLOBAL_POSITION_INT: lat/lon degE7, alt / relative_alt mm, vx/vy/vz cm/s NED, hdg 0 cdeg."""
        if v.get("u") is None or v.get("w") is None:
            return None
        lat, lon = self._lat_lon_e7()
        rel = self.alt_m - (self.home_alt_m or self.alt_m)
        vn, ve, vd = self.ned
        return dialect.MAVLink_global_position_int_message(
            int(round(t * 1000.0)), lat, lon, int(round(self.alt_m * 1000.0)), int(round(rel * 1000.0)),
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

    def _vfr_hud(self, t: float, v: Values, static_pressure_pa: float):
        """VFR_HUD: airspeed, groundspeed m/s, heading deg, throttle %, alt m, climb m/s; no time."""
        airspeed = v.get("airspeed")
        if airspeed is None:
            return None
        vn, ve, vd = self.ned
        return dialect.MAVLink_vfr_hud_message(float(airspeed), math.hypot(vn, ve), 0,
                                               int(round(100.0 * self.throttle)), self.alt_m, -vd)

    def _gnss(self, t: float, v: Values, static_pressure_pa: float):
        """GPS_RAW_INT on a new fix: time_usec the fix's UNIX-epoch time (the reported altitude's,
        gnss_latency_s before t), alt mm MSL, vel cm/s, cog 0 cdeg."""
        gnss = v.get("gnss_alt")
        if gnss is None:
            return None
        lat, lon = self._lat_lon_e7()
        t_fix_us = GPS_EPOCH_US + int(round((t - self.gnss_latency_s) * 1e6))
        vel = int(min(round(math.hypot(self.ned[0], self.ned[1]) * 100.0), 65534))
        return dialect.MAVLink_gps_raw_int_message(t_fix_us, dialect.GPS_FIX_TYPE_3D_FIX, lat, lon,
                                                   int(round(gnss * 1000.0)), 100, 150, vel, 0, 12)

    def actuators(self, t: float, u_cmd: np.ndarray) -> list:
        """SERVO_OUTPUT_RAW (time_usec uint32 since boot, port 0): SERVO1 aileron and SERVO4 rudder
        at trim, SERVO2 elevator and SERVO3 throttle PWM (us) from u_cmd (2,) [delta_e rad, delta_t]."""
        de, dt_ = float(u_cmd[0]), float(u_cmd[1])
        self.throttle = min(max(dt_, 0.0), 1.0)
        servo = [1500, elevator_pwm_ardupilot(de), throttle_pwm_ardupilot(dt_), 1500] + [0] * 12
        return [dialect.MAVLink_servo_output_raw_message(int(round(t * 1e6)) & 0xFFFFFFFF, 0, *servo)]

    def answer(self, msg) -> list:
        """PARAM_VALUE(s) for a PARAM_REQUEST_LIST / PARAM_REQUEST_READ addressed to this system
        (or broadcast); a name or index not in ARDUPLANE_SERVO_PARAMS gets no answer, as ArduPilot.
        A stream request gets its COMMAND_ACK (`interval_ack`)."""
        kind = msg.get_type()
        if kind not in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ"):
            return interval_ack(msg)
        if msg.target_system not in (0, self.system):
            return []
        names = list(ARDUPLANE_SERVO_PARAMS)
        if kind == "PARAM_REQUEST_LIST":
            return [self._param_value(i) for i in range(len(names))]
        if msg.param_index >= 0:
            return [self._param_value(msg.param_index)] if msg.param_index < len(names) else []
        pid = msg.param_id.decode("ascii", "replace") if isinstance(msg.param_id, bytes) else msg.param_id
        pid = pid.rstrip("\x00")
        return [self._param_value(names.index(pid))] if pid in names else []

    @staticmethod
    def _param_value(index: int):
        name = list(ARDUPLANE_SERVO_PARAMS)[index]
        value, ptype = ARDUPLANE_SERVO_PARAMS[name]
        return dialect.MAVLink_param_value_message(name.encode("ascii"), float(value), ptype,
                                                   len(ARDUPLANE_SERVO_PARAMS), index)
