"""A stock PX4-like stream in MAVLink "Onboard" mode (HEARTBEAT autopilot 12, ATTITUDE,
LOCAL_POSITION_NED, HIGHRES_IMU, GPS_RAW_INT at 5 Hz, VFR_HUD without a timestamp,
SERVO_OUTPUT_RAW PWM at 10 Hz, PARAM_VALUEs with PX4's bytewise integer encoding) fed as bytes
through `fdir run --autopilot auto`'s pipeline picks the PX4 profile and gives frames whose rows
are all there and finite: u, w derived from the NED velocity (m/s) and the attitude, the elevator
in radians from the PWM of the channel the control allocation parameters name."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import AutopilotSelected
from tests.helpers.autopilot_streams import body_to_ned, run, settled_rows

ROLL, PITCH, YAW = 0.1, 0.05, 1.0
U, W = 40.0, 2.0
DELTA_E, DELTA_T = -0.05, 0.6     # rad (trailing edge up), throttle fraction


def int_param(mav, name: str, value: int):
    """A PARAM_VALUE as PX4 sends an INT32 parameter: the integer's bytes in the float field."""
    as_float = struct.unpack("<f", struct.pack("<i", value))[0]
    return dialect.MAVLink_param_value_message(name.encode(), as_float, dialect.MAV_PARAM_TYPE_INT32,
                                               900, 0).pack(mav)


def px4_bytes(seconds: float = 3.0) -> bytes:
    """The stream of a PX4 fixed-wing at boot time 1 s: the elevator moved (by PARAM_VALUE) to MAIN 6
    with MIN 1100 / MAX 1900, the motor on MAIN 5 (the profile's example layout)."""
    mav = new_mavlink(1, 1)
    vn, ve, vd = body_to_ned(ROLL, PITCH, YAW) @ np.array([U, 0.0, W])   # m/s
    pwm_e = round(1500 + 400 * (-DELTA_E) / math.radians(25.0))   # PX4: + = nose-up torque
    pwm_t = round(1000 + 1000 * DELTA_T)
    press = pressure_from_altitude(500.0) / 100.0   # hPa
    out = []
    for i in range(int(seconds * 20)):
        t = 1000 + 50 * i
        wob = 1e-3 * math.sin(0.7 * i)
        msgs = []
        if i % 20 == 0:
            msgs.append(mav.heartbeat_encode(dialect.MAV_TYPE_FIXED_WING, dialect.MAV_AUTOPILOT_PX4,
                                             0, 0, dialect.MAV_STATE_ACTIVE))
        msgs += [
            mav.attitude_encode(t, ROLL, PITCH + wob, YAW, 0.0, 0.01 + wob, 0.0),
            mav.local_position_ned_encode(t, 10.0, 20.0, -500.0, vn, ve, vd + 0.01 * (i % 2)),
            mav.highres_imu_encode(t * 1000, 0.1, 0.0, -9.80665, 0.0, 0.01, 0.0, 0.2, 0.0, 0.4,
                                   press + wob, 0.98, 500.0, 25.0, 0x1FFF),
            mav.vfr_hud_encode(U + 0.01 * i, U, 57, 60, 500.0, 0.0),
        ]
        if i % 2 == 0:
            msgs.append(mav.servo_output_raw_encode(t * 1000, 0, 1500, 1500, 1500, 1500, pwm_t, pwm_e, 0, 0))
        if i % 4 == 0:
            msgs.append(mav.gps_raw_int_encode((t - 10) * 1000, 3, 0, 0, 500_100 + i, 100, 150, 4000,
                                               5730, 12))
        for m in msgs:
            out.append(m.pack(mav))
        if i == 0:   # after the HEARTBEAT (before it, nothing of the autopilot is followed yet)
            moved = (("PWM_MAIN_FUNC3", 0), ("PWM_MAIN_FUNC6", 203), ("PWM_MAIN_MIN6", 1100),
                     ("PWM_MAIN_MAX6", 1900))
            out += [int_param(mav, name, v) for name, v in moved]
    return b"".join(out)


def test_a_px4_stream_gives_frames_with_every_row_finite():
    p, row, u_in = settled_rows(px4_bytes(), "px4")
    assert np.nanmax(np.abs(row["u"] - U)) < 0.02 and np.nanmax(np.abs(row["w"] - W)) < 0.06
    assert row["az"] == pytest.approx(-9.80665, abs=1e-5) and row["ax"] == pytest.approx(0.1, abs=1e-6)
    assert row["theta"] == pytest.approx(PITCH, abs=1.1e-3)
    assert row["baro_alt"] == pytest.approx(500.0, abs=0.1)
    assert np.nanmax(np.abs(row["gnss_alt"] - 500.1)) < 0.1
    assert np.all((row["airspeed"] >= U) & (row["airspeed"] < U + 1.0))
    assert u_in[:, 0] == pytest.approx(DELTA_E, abs=1.1e-3) and u_in[:, 1] == pytest.approx(DELTA_T)
    assert "u not derivable" not in p.rejected_counts and "delta_e not derivable" not in p.rejected_counts


def test_px4_profile_by_name_reads_the_same_stream():
    p, calls, events = run(px4_bytes(1.5), autopilot="px4")
    assert not list(events.of(AutopilotSelected)) and len(calls) >= 25
    for _, y, mask, u in calls[5:]:
        assert mask.all() or not mask[p.assembler.names.index("gnss_alt")]
        assert np.all(np.isfinite(y[mask])) and np.all(np.isfinite(u))
