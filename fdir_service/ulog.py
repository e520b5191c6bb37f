"""Reading a PX4 ULog (`.ulg`) for `fdir import`: its topics -> the MAVLink messages px4.toml reads.

pyulog (PX4's own ULog reader) parses the file; each logged sample becomes the message PX4's
MAVLink streams would have sent from it (`MessageLog`, log_translate.py), times in us since boot:

- vehicle_attitude q (w, x, y, z) -> ATTITUDE roll, pitch, yaw (rad); the rates (rad/s) from the
  latest vehicle_angular_velocity xyz at or before it (older PX4: the attitude's own rollspeed..);
- vehicle_local_position x, y, z (m), vx, vy, vz (m/s, NED) -> LOCAL_POSITION_NED;
- sensor_combined accelerometer_m_s2 (m/s^2), gyro_rad (rad/s) and the latest
  vehicle_air_data.baro_pressure_pa (Pa) * 0.01 -> HIGHRES_IMU xacc..zgyro, abs_pressure (hPa);
- vehicle_gps_position / sensor_gps alt (mm MSL; newer: altitude_msl_m), lat, lon -> GPS_RAW_INT;
- airspeed_validated calibrated (or indicated) airspeed, or airspeed indicated_airspeed_m_s
  (whichever topic has more samples; m/s) -> VFR_HUD.airspeed;
- actuator_outputs output[0..15] (PWM us) -> SERVO_OUTPUT_RAW port 0 (time_usec mod 2^32);
- the initial and the changed parameters -> PARAM_VALUE (int32 bytewise, as PX4 sends them);

plus a HEARTBEAT (autopilot 12 = PX4, type = the MAV_TYPE parameter) at 1 Hz. A sample with no
rate / pressure yet carries NaN there (the service drops it and counts it). A corrupt or cut-off
file is read by pyulog up to the damage; the damage line says so.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.log_translate import MessageLog, value_at
from fdir_service.mavlink import dialect
from fdir_service.tlog import ReadStats

MAV_AUTOPILOT_PX4 = 12
TOPICS = ("vehicle_attitude", "vehicle_angular_velocity", "vehicle_local_position", "sensor_combined",
          "vehicle_air_data", "vehicle_gps_position", "sensor_gps", "airspeed_validated", "airspeed",
          "actuator_outputs")
"""The topics read (instance 0 of each)."""


def quaternion_to_euler(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(roll, pitch, yaw) rad (ZYX Tait-Bryan, as PX4's Eulerf) of quaternions q (n, 4) = w, x, y, z."""
    w, x, y, z = q.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def _columns(data: dict[str, np.ndarray], name: str, n: int) -> np.ndarray:
    """The array field `name[0..n-1]` of a topic as an (samples, n) float array."""
    return np.column_stack([np.asarray(data[f"{name}[{i}]"], dtype=float) for i in range(n)])


class UlogTranslator:
    """Fills a `MessageLog` from a parsed `pyulog.ULog` (`topics`: name -> field arrays)."""

    def __init__(self, topics: dict[str, dict[str, np.ndarray]], log: MessageLog) -> None:
        self.topics = topics
        self.log = log

    def translate(self) -> None:
        """Every message of the module table."""
        self.attitude()
        self.local_position()
        self.highres_imu()
        self.gps()
        self.airspeed()
        self.servo_outputs()

    def _rate_columns(self, t: np.ndarray, att: dict[str, np.ndarray]) -> np.ndarray:
        """(n, 3) body rates rad/s at the attitude times: vehicle_angular_velocity (latest), or the
        attitude's own rollspeed.. (PX4 before 1.11), else NaN."""
        av = self.topics.get("vehicle_angular_velocity")
        if av is not None:
            return np.column_stack([value_at(av["timestamp"], av[f"xyz[{i}]"], t) for i in range(3)])
        if "pitchspeed" in att:
            return np.column_stack([att[k] for k in ("rollspeed", "pitchspeed", "yawspeed")]).astype(float)
        return np.full((len(t), 3), np.nan)

    def attitude(self) -> None:
        """ATTITUDE per vehicle_attitude sample (time_boot_ms = its timestamp / 1000)."""
        att = self.topics.get("vehicle_attitude")
        if att is None:
            return
        t = att["timestamp"]
        roll, pitch, yaw = quaternion_to_euler(_columns(att, "q", 4))
        rates = self._rate_columns(t, att)
        for i, ti in enumerate(t):
            self.log.add(ti, dialect.MAVLink_attitude_message(
                int(ti // 1000) & 0xFFFFFFFF, roll[i], pitch[i], yaw[i], *rates[i]))

    def local_position(self) -> None:
        """LOCAL_POSITION_NED (x, y, z m, vx, vy, vz m/s NED) per vehicle_local_position sample."""
        lp = self.topics.get("vehicle_local_position")
        if lp is None:
            return
        cols = np.column_stack([lp[k] for k in ("x", "y", "z", "vx", "vy", "vz")]).astype(float)
        for ti, row in zip(lp["timestamp"], cols, strict=True):
            self.log.add(ti, dialect.MAVLink_local_position_ned_message(int(ti // 1000) & 0xFFFFFFFF, *row))

    def highres_imu(self) -> None:
        """HIGHRES_IMU per sensor_combined sample: acc m/s^2, gyro rad/s, abs_pressure hPa from the
        latest vehicle_air_data.baro_pressure_pa (NaN before the first)."""
        sc = self.topics.get("sensor_combined")
        if sc is None:
            return
        t = sc["timestamp"]
        acc, gyro = _columns(sc, "accelerometer_m_s2", 3), _columns(sc, "gyro_rad", 3)
        air = self.topics.get("vehicle_air_data")
        hpa = (value_at(air["timestamp"], air["baro_pressure_pa"], t) * 0.01 if air is not None
               and "baro_pressure_pa" in air else np.full(len(t), np.nan))
        for i, ti in enumerate(t):
            self.log.add(ti, dialect.MAVLink_highres_imu_message(
                int(ti), *acc[i], *gyro[i], 0.0, 0.0, 0.0, hpa[i], 0.0, np.nan, 0.0, 0x3F | 0x200))

    def gps(self) -> None:
        """GPS_RAW_INT (alt mm MSL, lat / lon degE7) per vehicle_gps_position (or sensor_gps) sample."""
        g = self.topics.get("vehicle_gps_position") or self.topics.get("sensor_gps")
        if g is None:
            return
        alt_mm = g["alt"] if "alt" in g else np.asarray(g["altitude_msl_m"]) * 1000.0
        lat = g["lat"] if "lat" in g else np.asarray(g["latitude_deg"]) * 1e7
        lon = g["lon"] if "lon" in g else np.asarray(g["longitude_deg"]) * 1e7
        fix = g.get("fix_type", np.full(len(alt_mm), 3))
        for i, ti in enumerate(g["timestamp"]):
            self.log.add(ti, dialect.MAVLink_gps_raw_int_message(
                int(ti), int(fix[i]), int(lat[i]), int(lon[i]), int(round(float(alt_mm[i]))),
                65535, 65535, 65535, 65535, 255))

    def _airspeed_series(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(times us, airspeed m/s): the topic of airspeed_validated / airspeed with more samples."""
        found = []
        for name, key in (("airspeed_validated", "calibrated_airspeed_m_s"),
                          ("airspeed_validated", "indicated_airspeed_m_s"),
                          ("airspeed", "indicated_airspeed_m_s")):
            d = self.topics.get(name)
            if d is not None and key in d:
                found.append((d["timestamp"], np.asarray(d[key], dtype=float)))
        return max(found, key=lambda s: len(s[0])) if found else None

    def airspeed(self) -> None:
        """VFR_HUD.airspeed m/s per airspeed sample (the other fields 0: the profile reads airspeed only)."""
        series = self._airspeed_series()
        if series is None:
            return
        for ti, v in zip(*series, strict=True):
            self.log.add(ti, dialect.MAVLink_vfr_hud_message(float(v), 0.0, 0, 0, 0.0, 0.0))

    def servo_outputs(self) -> None:
        """SERVO_OUTPUT_RAW port 0 (PWM us, time_usec = timestamp mod 2^32) per actuator_outputs sample."""
        ao = self.topics.get("actuator_outputs")
        if ao is None:
            return
        pwm = np.clip(np.nan_to_num(_columns(ao, "output", 16)), 0, 65535).astype(int)
        for ti, row in zip(ao["timestamp"], pwm, strict=True):
            self.log.add(ti, dialect.MAVLink_servo_output_raw_message(
                int(ti) & 0xFFFFFFFF, 0, *(int(v) for v in row)))


def _topics(ulog: Any) -> dict[str, dict[str, np.ndarray]]:
    """Instance 0 of each of TOPICS present: name -> {field: array}."""
    return {d.name: d.data for d in ulog.data_list if d.name in TOPICS and d.multi_id == 0}


def _span_us(topics: dict[str, dict[str, np.ndarray]], start_us: int) -> tuple[int, int]:
    """(first, last) sample time (us since boot) of the topics read; (start_us, start_us) if none.
    (ULog's own last timestamp can be a late mission or log message, far after the data.)"""
    times = [d["timestamp"] for d in topics.values() if len(d["timestamp"])]
    if not times:
        return start_us, start_us
    return int(min(t[0] for t in times)), int(max(t[-1] for t in times))


def _add_parameters(ulog: Any, log: MessageLog, t0_us: int) -> None:
    """PARAM_VALUE for every initial parameter at t0_us, and each logged change at its time."""
    for name, value in sorted(ulog.initial_parameters.items()):
        log.add_param(t0_us, name, value, isinstance(value, int), bytewise=True)
    for t_us, name, value in ulog.changed_parameters:
        log.add_param(max(int(t_us), t0_us), name, value, isinstance(value, int), bytewise=True)


ULOG_HEADER_BYTES = 16
"""The ULog file header: magic (7 bytes), version (1), timestamp (8, us)."""


def whole_messages_end(data: bytes) -> int:
    """The byte offset where the last whole ULog message ends: the messages after the header are
    [uint16 size][uint8 type][size bytes]; a file cut inside a message ends before len(data)."""
    at = ULOG_HEADER_BYTES
    while at + 3 <= len(data):
        end = at + 3 + int.from_bytes(data[at:at + 2], "little")
        if end > len(data):
            break
        at = end
    return min(at, len(data))


def _parse(path: Path) -> Any:
    """pyulog's parse of the topics read (its corruption notices go to stderr, not stdout)."""
    from pyulog import ULog

    with contextlib.redirect_stdout(sys.stderr):
        return ULog(str(path), message_name_filter_list=list(TOPICS), disable_str_exceptions=True)


def _damage(path: Path, ulog: Any, stats: ReadStats) -> None:
    """Fill stats' good bytes and damage note: pyulog's corruption flag, or a cut-off last message."""
    stats.good_bytes = whole_messages_end(path.read_bytes())
    if ulog.file_corruption:
        stats.stopped = "the ULog is corrupt: pyulog read it up to the damage"
    elif stats.good_bytes < stats.file_bytes:
        stats.stopped = f"the ULog is cut off inside a message at byte {stats.good_bytes}"


def read_ulog(path: str | os.PathLike[str]) -> tuple[MessageLog, ReadStats]:
    """The translated messages of the ULog at `path` and its read statistics (damage: pyulog's
    file-corruption flag)."""
    path = Path(path)
    stats = ReadStats(file_bytes=path.stat().st_size, kind="ULog")
    ulog = _parse(path)
    _damage(path, ulog, stats)
    mav_type = int(ulog.initial_parameters.get("MAV_TYPE", dialect.MAV_TYPE_FIXED_WING))
    log = MessageLog(MAV_AUTOPILOT_PX4, mav_type=mav_type, kind="ULog", file_bytes=stats.file_bytes)
    topics = _topics(ulog)
    t0, t1 = _span_us(topics, int(ulog.start_timestamp))
    log.add_heartbeats(t0, t1)
    _add_parameters(ulog, log, t0)
    UlogTranslator(topics, log).translate()
    return log, stats


__all__ = ["MAV_AUTOPILOT_PX4", "TOPICS", "UlogTranslator", "quaternion_to_euler", "read_ulog"]
