"""Reading an ArduPilot DataFlash log (`.bin`) for `fdir import`: its messages -> the MAVLink
messages ardupilot.toml reads.

pymavlink's DFReader parses the file; each logged sample becomes the message ArduPilot's MAVLink
streams would have sent from it (`MessageLog`, log_translate.py), times = TimeUS (us since boot):

- ATT Roll, Pitch, Yaw (deg) -> ATTITUDE roll, pitch, yaw (rad); the rates (rad/s) from the latest
  IMU GyrX, GyrY, GyrZ at or before it (NaN when the log has no IMU);
- IMU AccX, AccY, AccZ (m/s^2) -> RAW_IMU xacc, yacc, zacc (mG, m/s^2 / 9.80665 * 1000);
- BARO Press (Pa) -> SCALED_PRESSURE press_abs (hPa);
- GPS Lat, Lng (deg), Alt (m MSL) -> GPS_RAW_INT lat, lon (degE7), alt (mm);
- XKF1 (else NKF1) VN, VE, VD (m/s) -> GLOBAL_POSITION_INT vx, vy, vz (cm/s), with the latest GPS
  position; without either, GPS Spd, GCrs, VZ;
- ARSP Airspeed (else CTUN As) (m/s) -> VFR_HUD.airspeed;
- RCOU C1..C14 (PWM us) -> SERVO_OUTPUT_RAW port 0;
- PARM Name, Value -> PARAM_VALUE (REAL32, as ArduPilot sends them);

plus a HEARTBEAT (autopilot 3 = ArduPilot, fixed wing) at 1 Hz.
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.log_translate import MessageLog, value_at
from fdir_service.mavlink import dialect
from fdir_service.tlog import ReadStats

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
G0 = 9.80665
"""Standard gravity (m/s^2): RAW_IMU's mG = m/s^2 / G0 * 1000."""
TYPES = ("ATT", "IMU", "BARO", "GPS", "XKF1", "NKF1", "ARSP", "CTUN", "RCOU", "PARM")
"""The DataFlash messages read (instance 0 of IMU / BARO / GPS / XKF1 / NKF1 / ARSP)."""

Samples = dict[str, list[Any]]


def _instance0(msg: Any) -> bool:
    """Whether `msg` is of the first sensor / EKF core (I, C or Instance 0, or none logged)."""
    for key in ("I", "C", "Instance"):
        value = getattr(msg, key, None)
        if value is not None:
            return int(value) == 0
    return True


def read_samples(path: Path) -> tuple[Samples, int]:
    """The messages of TYPES in the log at `path`, by type (instance 0), and the file's bytes read."""
    from pymavlink import mavutil

    reader = mavutil.mavlink_connection(str(path))
    samples: Samples = defaultdict(list)
    while (msg := reader.recv_match(type=list(TYPES))) is not None:
        if msg.get_type() == "PARM" or _instance0(msg):
            samples[msg.get_type()].append(msg)
    return samples, int(getattr(reader, "offset", 0))


def _series(msgs: list[Any], *fields: str) -> tuple[np.ndarray, np.ndarray]:
    """(TimeUS array, (n, len(fields)) float array) of `msgs`."""
    t = np.array([m.TimeUS for m in msgs], dtype=np.int64)
    return t, np.array([[float(getattr(m, f)) for f in fields] for m in msgs]).reshape(len(msgs), len(fields))


class DataflashTranslator:
    """Fills a `MessageLog` from the DataFlash samples (`samples`: type -> messages)."""

    def __init__(self, samples: Samples, log: MessageLog) -> None:
        self.s = samples
        self.log = log

    def translate(self) -> None:
        """Every message of the module table."""
        self.attitude()
        self.raw_imu()
        self.pressure()
        self.gps()
        self.global_position()
        self.airspeed()
        self.servo_outputs()

    def _rates(self, t: np.ndarray) -> np.ndarray:
        """(n, 3) body rates rad/s at times t: the latest IMU GyrX, GyrY, GyrZ; NaN without IMU."""
        if not self.s.get("IMU"):
            return np.full((len(t), 3), np.nan)
        ti, gyr = _series(self.s["IMU"], "GyrX", "GyrY", "GyrZ")
        return np.column_stack([value_at(ti, gyr[:, k], t) for k in range(3)])

    def attitude(self) -> None:
        """ATTITUDE (rad, rad/s; time_boot_ms = TimeUS / 1000) per ATT sample."""
        if not self.s.get("ATT"):
            return
        t, deg = _series(self.s["ATT"], "Roll", "Pitch", "Yaw")
        rad, rates = np.radians(deg), self._rates(t)
        for i, ti in enumerate(t):
            self.log.add(ti, dialect.MAVLink_attitude_message(
                int(ti // 1000) & 0xFFFFFFFF, *rad[i], *rates[i]))

    def raw_imu(self) -> None:
        """RAW_IMU xacc, yacc, zacc (mG) per IMU sample (gyro, mag 0: the profile reads acc only)."""
        if not self.s.get("IMU"):
            return
        t, acc = _series(self.s["IMU"], "AccX", "AccY", "AccZ")
        mg = np.round(acc / G0 * 1000.0).clip(-32768, 32767).astype(int)
        for ti, row in zip(t, mg, strict=True):
            self.log.add(ti, dialect.MAVLink_raw_imu_message(
                int(ti), *(int(v) for v in row), 0, 0, 0, 0, 0, 0))

    def pressure(self) -> None:
        """SCALED_PRESSURE press_abs (hPa = Pa * 0.01) per BARO sample."""
        for m in self.s.get("BARO", []):
            self.log.add(m.TimeUS, dialect.MAVLink_scaled_pressure_message(
                int(m.TimeUS // 1000) & 0xFFFFFFFF, float(m.Press) * 0.01, 0.0, 0))

    def gps(self) -> None:
        """GPS_RAW_INT (lat / lon degE7, alt mm MSL, fix = Status) per GPS sample."""
        for m in self.s.get("GPS", []):
            self.log.add(m.TimeUS, dialect.MAVLink_gps_raw_int_message(
                int(m.TimeUS), int(m.Status), int(round(m.Lat * 1e7)), int(round(m.Lng * 1e7)),
                int(round(m.Alt * 1000.0)), 65535, 65535, 65535, 65535, 255))

    def _velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """(TimeUS, (n, 3) VN, VE, VD m/s): XKF1, else NKF1, else GPS Spd / GCrs / VZ."""
        for name in ("XKF1", "NKF1"):
            if self.s.get(name):
                return _series(self.s[name], "VN", "VE", "VD")
        t, g = _series(self.s.get("GPS", []), "Spd", "GCrs", "VZ")
        crs = np.radians(g[:, 1])
        return t, np.column_stack([g[:, 0] * np.cos(crs), g[:, 0] * np.sin(crs), g[:, 2]])

    def global_position(self) -> None:
        """GLOBAL_POSITION_INT vx, vy, vz (cm/s NED) with the latest GPS lat, lon (degE7), alt (mm)."""
        t, v = self._velocity()
        gt, pos = _series(self.s.get("GPS", []), "Lat", "Lng", "Alt")
        where = np.nan_to_num(np.column_stack([value_at(gt, pos[:, k], t) for k in range(3)]))
        cms = np.round(v * 100.0).clip(-32768, 32767).astype(int)
        for i, ti in enumerate(t):
            self.log.add(ti, dialect.MAVLink_global_position_int_message(
                int(ti // 1000) & 0xFFFFFFFF, int(round(where[i, 0] * 1e7)), int(round(where[i, 1] * 1e7)),
                int(round(where[i, 2] * 1000.0)), 0, *(int(c) for c in cms[i]), 65535))

    def airspeed(self) -> None:
        """VFR_HUD.airspeed m/s per ARSP Airspeed (else CTUN As) sample."""
        msgs, key = (self.s["ARSP"], "Airspeed") if self.s.get("ARSP") else (self.s.get("CTUN", []), "As")
        for m in msgs:
            value = getattr(m, key, None)
            if value is not None:
                self.log.add(m.TimeUS, dialect.MAVLink_vfr_hud_message(float(value), 0.0, 0, 0, 0.0, 0.0))

    def servo_outputs(self) -> None:
        """SERVO_OUTPUT_RAW port 0 (PWM us; C15, C16 0) per RCOU sample."""
        for m in self.s.get("RCOU", []):
            pwm = [int(getattr(m, f"C{k}", 0) or 0) for k in range(1, 17)]
            self.log.add(m.TimeUS, dialect.MAVLink_servo_output_raw_message(
                int(m.TimeUS) & 0xFFFFFFFF, 0, *(min(max(p, 0), 65535) for p in pwm)))


def _span_us(samples: Samples) -> tuple[int, int]:
    """(first, last) TimeUS of the samples read (PARM included); (0, 0) if none."""
    times = [m.TimeUS for msgs in samples.values() for m in (msgs[0], msgs[-1]) if msgs]
    return (int(min(times)), int(max(times))) if times else (0, 0)


def _add_parameters(samples: Samples, log: MessageLog, t0_us: int) -> None:
    """PARAM_VALUE (REAL32, as ArduPilot sends them) per PARM, at its time (not before t0_us)."""
    for m in samples.get("PARM", []):
        if math.isfinite(float(m.Value)):
            log.add_param(max(int(m.TimeUS), t0_us), str(m.Name), float(m.Value), False, bytewise=False)


def read_dataflash(path: str | os.PathLike[str]) -> tuple[MessageLog, ReadStats]:
    """The translated messages of the DataFlash log at `path` and its read statistics (damage: the
    reader stopped before the end of the file)."""
    path = Path(path)
    stats = ReadStats(file_bytes=path.stat().st_size, kind="DataFlash")
    samples, read_bytes = read_samples(path)
    stats.good_bytes = min(read_bytes, stats.file_bytes) or stats.file_bytes
    if stats.good_bytes < stats.file_bytes:
        stats.stopped = f"the DataFlash log could not be read past byte {stats.good_bytes}"
    log = MessageLog(MAV_AUTOPILOT_ARDUPILOTMEGA, kind="DataFlash", file_bytes=stats.file_bytes)
    t0, t1 = _span_us(samples)
    log.add_heartbeats(t0, t1)
    _add_parameters(samples, log, t0)
    DataflashTranslator(samples, log).translate()
    return log, stats


__all__ = ["MAV_AUTOPILOT_ARDUPILOTMEGA", "TYPES", "DataflashTranslator",
           "read_dataflash"]
