"""The simulated Aerosonde on the wire: what an autopilot would send, and the estimates coming back.

Sent per frame k (all stamped with the simulation time t_k; `time_boot_ms` = round(t_k * 1000),
`time_usec` = round(t_k * 1e6)), only for the measurements the scenario has:
  GPS_RAW_INT      alt (mm above MSL) = GNSS altitude measurement
  SCALED_PRESSURE  press_abs (hPa) = the barometer's static pressure (barometric formula)
  ATTITUDE         pitch (rad), pitchspeed (rad/s) = measured pitch and pitch rate
  ODOMETRY         child_frame_id MAV_FRAME_BODY_FRD; vx, vz (m/s) = measured body velocities u, w;
                   pose unknown (NaN) - the truth never goes on the wire
and, once the autopilot has computed u_k, the actuator outputs stamped t_k:
  SERVO_OUTPUT_RAW servo2_raw = elevator: 1500 + 500 * delta_e / 30 deg us (1000..2000),
                   servo3_raw = throttle: 1000 + 1000 * delta_t us (ArduPlane channel order)
  ACTUATOR_OUTPUT_STATUS actuator[0] = delta_e (rad), actuator[1] = delta_t (0..1), float32:
                   the unquantised copy (1 us of PWM is 0.06 deg of elevator).
HEARTBEAT (MAV_TYPE_FIXED_WING, system 1, component 1) once per second of simulation time.
"""

from __future__ import annotations

import math

import numpy as np

from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.mavlink import pack as fast_pack
from fdir_service.service_config import RHO_SEA_LEVEL
from sim_bridge.scenario import Scenario

ELEVATOR_PWM_RANGE_RAD = math.radians(30.0)
"""Elevator deflection at PWM 1000 / 2000 us (-/+), 1500 us = 0."""


def elevator_to_pwm(delta_e: float) -> int:
    """Elevator angle (rad) -> PWM (us), 1 us resolution, clipped to 1000..2000."""
    return int(min(max(round(1500.0 + 500.0 * delta_e / ELEVATOR_PWM_RANGE_RAD), 1000), 2000))


def throttle_to_pwm(delta_t: float) -> int:
    """Throttle (0..1) -> PWM (us), clipped to 1000..2000."""
    return int(min(max(round(1000.0 + 1000.0 * delta_t), 1000), 2000))


class AutopilotLink:
    """Encodes the simulator's frames as an autopilot's MAVLink 2 stream and decodes replies.

    system/component: the autopilot's ids; key: optional 32-byte signing key.
    """

    def __init__(self, scenario: Scenario, system: int = 1, component: int = 1,
                 key: bytes | None = None, signing_timestamp: int = 0) -> None:
        self.scenario = scenario
        self.rows = {name: j for j, name in enumerate(scenario.sensors.measurements)}
        self.tx = new_mavlink(system, component, key=key, initial_timestamp=signing_timestamp)
        self.rx = new_mavlink(255, 0, key=key)
        self._last_hb_s: int | None = None

    def _pack(self, msg) -> bytes:
        return fast_pack(msg, self.tx)   # = bytes(msg.pack(self.tx)), cheaper

    def heartbeat(self) -> bytes:
        mode = (dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | dialect.MAV_MODE_FLAG_STABILIZE_ENABLED
                | dialect.MAV_MODE_FLAG_GUIDED_ENABLED | dialect.MAV_MODE_FLAG_AUTO_ENABLED
                | dialect.MAV_MODE_FLAG_SAFETY_ARMED)
        return self._pack(dialect.MAVLink_heartbeat_message(
            dialect.MAV_TYPE_FIXED_WING, dialect.MAV_AUTOPILOT_GENERIC, mode, 0,
            dialect.MAV_STATE_ACTIVE, 3))

    def sensor_messages(self, t: float, y: np.ndarray, mask: np.ndarray,
                        static_pressure_pa: float) -> list[bytes]:
        """The sensor messages of one frame (HEARTBEAT first on each new second), in send order:
        GPS_RAW_INT (a GNSS fix), SCALED_PRESSURE, ATTITUDE, ODOMETRY (u, w), VFR_HUD (airspeed),
        SCALED_IMU (accelerometer); a message only when one of its rows was measured."""
        t_ms = int(round(t * 1000.0))
        out: list[bytes] = []
        if self._last_hb_s != t_ms // 1000:
            self._last_hb_s = t_ms // 1000
            out.append(self.heartbeat())

        def val(name: str) -> float | None:
            j = self.rows.get(name)
            return None if j is None or not mask[j] else float(y[j])

        values = {name: val(name) for name in self.rows}
        for make in (self._gnss, self._baro, self._attitude, self._odometry, self._vfr_hud, self._imu):
            msg = make(t, values, static_pressure_pa)
            if msg is not None:
                out.append(self._pack(msg))
        return out

    @staticmethod
    def _gnss(t: float, v: dict, static_pressure_pa: float):
        gnss = v.get("gnss_alt")
        if gnss is None:
            return None
        return dialect.MAVLink_gps_raw_int_message(int(round(t * 1e6)), dialect.GPS_FIX_TYPE_3D_FIX, 0, 0,
                                                   int(round(gnss * 1000.0)), 100, 150, 65535, 65535, 12)

    @staticmethod
    def _baro(t: float, v: dict, static_pressure_pa: float):
        if v.get("baro_alt") is None:
            return None
        airspeed = v.get("airspeed")     # the pitot's differential pressure, read back with rho_0
        diff_hpa = 0.0 if airspeed is None else 0.5 * RHO_SEA_LEVEL * float(airspeed) ** 2 / 100.0
        return dialect.MAVLink_scaled_pressure_message(int(round(t * 1000.0)),
                                                       float(static_pressure_pa) / 100.0, diff_hpa, 1500)

    @staticmethod
    def _attitude(t: float, v: dict, static_pressure_pa: float):
        theta, q = v.get("theta"), v.get("q")
        if theta is None and q is None:
            return None
        nan = float("nan")
        return dialect.MAVLink_attitude_message(int(round(t * 1000.0)), 0.0, nan if theta is None else theta,
                                                0.0, 0.0, nan if q is None else q, 0.0)

    @staticmethod
    def _odometry(t: float, v: dict, static_pressure_pa: float):
        u, w, theta = v.get("u"), v.get("w"), v.get("theta")
        if u is None and w is None:
            return None
        nan = float("nan")
        quat = [nan] * 4 if theta is None else [math.cos(theta / 2), 0.0, math.sin(theta / 2), 0.0]
        return dialect.MAVLink_odometry_message(
            int(round(t * 1e6)), dialect.MAV_FRAME_LOCAL_NED, dialect.MAV_FRAME_BODY_FRD, nan, nan, nan, quat,
            nan if u is None else u, nan, nan if w is None else w, nan, nan, nan,
            [nan] * 21, [nan] * 21, 0, dialect.MAV_ESTIMATOR_TYPE_NAIVE, 0)

    @staticmethod
    def _vfr_hud(t: float, v: dict, static_pressure_pa: float):
        airspeed = v.get("airspeed")
        if airspeed is None:
            return None
        nan = float("nan")
        return dialect.MAVLink_vfr_hud_message(airspeed, nan, 0, 0, nan, nan)

    @staticmethod
    def _imu(t: float, v: dict, static_pressure_pa: float):
        ax, az = v.get("ax"), v.get("az")
        if ax is None and az is None:
            return None

        def mg(a: float | None) -> int:
            return 0 if a is None else int(max(min(round(a / 9.80665 * 1000.0), 32767), -32768))
        return dialect.MAVLink_scaled_imu_message(int(round(t * 1000.0)), mg(ax), 0, mg(az), 0, 0, 0, 0, 0, 0)

    def actuator_messages(self, t: float, u_cmd: np.ndarray) -> list[bytes]:
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
        return [
            self._pack(dialect.MAVLink_servo_output_raw_message(t_us & 0xFFFFFFFF, 0, *servo)),
            self._pack(dialect.MAVLink_actuator_output_status_message(t_us, 0b11, act)),
        ]

    def parse(self, data: bytes) -> list:
        """Decode bytes coming back from the service (robust; signature checked when keyed)."""
        return [m for m in (self.rx.parse_buffer(data) or []) if m.get_type() != "BAD_DATA"]


class LossyLink:
    """Deterministic random packet loss: each MAVLink packet (one encoded message) is dropped with
    probability `loss`, drawn from its own seeded stream (independent of the simulation's)."""

    def __init__(self, loss: float, seed: int = 0) -> None:
        if not 0.0 <= loss < 1.0:
            raise ValueError(f"packet loss must be in [0, 1), got {loss}")
        self.loss = float(loss)
        self.rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x1055]))
        self.sent = 0
        self.dropped = 0

    def filter(self, packets: list[bytes]) -> list[bytes]:
        """The packets that survive (order kept)."""
        if not self.loss:
            self.sent += len(packets)
            return list(packets)
        keep = self.rng.random(len(packets)) >= self.loss
        out = [b for b, k in zip(packets, keep, strict=True) if k]
        self.sent += len(out)
        self.dropped += len(packets) - len(out)
        return out


