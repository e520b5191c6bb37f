"""A stock ArduPlane-like stream (HEARTBEAT autopilot 3, ATTITUDE, GLOBAL_POSITION_INT, RAW_IMU,
SCALED_PRESSURE, GPS_RAW_INT at 5 Hz, VFR_HUD without a timestamp, SERVO_OUTPUT_RAW PWM, a
PARAM_VALUE) fed as bytes through `fdir run --autopilot auto`'s pipeline gives frames whose rows
are all there and finite: u, w derived from the NED velocity and the attitude, the elevator in
radians from PWM. Missing attitude never yields a NaN row."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import EpochTimeUnmapped
from tests.helpers.autopilot_streams import body_to_ned, run, settled_rows

ROLL, PITCH, YAW = 0.1, 0.05, 1.0
U, W = 40.0, 2.0
DELTA_E, DELTA_T = -0.05, 0.6     # rad (trailing edge up), throttle fraction



GPS_EPOCH_US = 1_764_000_000_000_000
"""2025-11-24 in UNIX-epoch microseconds: GPS_RAW_INT.time_usec once the GNSS has a fix."""


def ardupilot_bytes(seconds: float = 3.0, attitude: bool = True, gps_clock_us: int = 0, fix_lag_ms: int = 80,
                    system_time_from_s: float | None = None) -> bytes:
    """The stream of a 20 Hz ArduPlane telemetry loop starting at boot time 1 s; GPS_RAW_INT's
    time_usec (the fix's time, fix_lag_ms before the loop's stamp: negative = after it) on boot time +
    gps_clock_us (GPS_EPOCH_US: UNIX-epoch time, as with a fix); SYSTEM_TIME at 1 Hz from boot time
    system_time_from_s (s) on, taken 0.4 ms after the loop's stamp (time_boot_ms drops the 0.4 ms)."""
    mav = new_mavlink(1, 1)
    vn, ve, vd = body_to_ned(ROLL, PITCH, YAW) @ np.array([U, 0.0, W]) * 100.0   # cm/s
    pwm_e = round(1500 + 400 * (-DELTA_E) / math.radians(25.0))    # ArduPilot: + = nose up
    pwm_t = round(1100 + 800 * DELTA_T)
    press = pressure_from_altitude(500.0) / 100.0
    out = [dialect.MAVLink_param_value_message(b"SERVO2_TRIM", 1500.0, 9, 900, 30).pack(mav)]
    for i in range(int(seconds * 20)):
        t = 1000 + 50 * i
        wob = 1e-3 * math.sin(0.7 * i)     # sensors are never bit-identical (that would be frozen)
        msgs = []
        if i % 20 == 0:
            msgs.append(mav.heartbeat_encode(dialect.MAV_TYPE_FIXED_WING, dialect.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                             0, 0, dialect.MAV_STATE_ACTIVE))
        if attitude:
            msgs.append(mav.attitude_encode(t, ROLL, PITCH + wob, YAW, 0.0, 0.01 + wob, 0.0))
        msgs += [
            mav.global_position_int_encode(t, 0, 0, 500_000, 400_000, round(vn), round(ve), round(vd) + i % 2,
                                           5730),
            mav.raw_imu_encode(t * 1000, 10, 0, -1000, 0, 0, 0, 0, 0, 0),
            mav.scaled_pressure_encode(t, press + wob, 9.8, 2500),
            mav.vfr_hud_encode(U + 0.01 * i, U, 57, 60, 500.0, 0.0),
            mav.servo_output_raw_encode(t * 1000, 0, 1500, pwm_e, pwm_t, 1500, 0, 0, 0, 0),
        ]
        if system_time_from_s is not None and i % 20 == 0 and t >= 1000 * system_time_from_s:
            msgs.append(mav.system_time_encode(GPS_EPOCH_US + t * 1000 + 400, t))
        if i % 4 == 0:
            msgs.append(mav.gps_raw_int_encode(gps_clock_us + (t - fix_lag_ms) * 1000, 3, 0, 0, 500_100 + i,
                                               100, 150, 4000, 5730, 12))
        if i % 4 == 2:   # the same fix sent again (stream faster than the GNSS): dropped
            msgs.append(mav.gps_raw_int_encode(gps_clock_us + (t - 100 - fix_lag_ms) * 1000, 3, 0, 0,
                                               500_100 + i - 2, 100, 150, 4000, 5730, 12))
        for m in msgs:
            out.append(m.pack(mav))
            mav.seq = (mav.seq + 1) % 256   # as mav.send would: a re-sent sample is a new packet
    return b"".join(out)



def test_an_ardupilot_stream_gives_frames_with_every_row_finite():
    p, row, u_in = settled_rows(ardupilot_bytes(), "ardupilot")
    # the pitch wobble (1e-3 rad) is not in the velocity: w reads it as up to 0.04 m/s, plus 1 cm/s steps
    assert np.nanmax(np.abs(row["u"] - U)) < 0.02 and np.nanmax(np.abs(row["w"] - W)) < 0.06
    assert row["az"] == pytest.approx(-9.80665) and row["theta"] == pytest.approx(PITCH, abs=1.1e-3)
    assert row["baro_alt"] == pytest.approx(500.0, abs=0.1)
    assert np.nanmax(np.abs(row["gnss_alt"] - 500.1)) < 0.1
    assert p.rejected_counts["GPS_RAW_INT repeated sample"] > 0
    assert np.all((row["airspeed"] >= U) & (row["airspeed"] < U + 1.0))
    assert u_in[:, 0] == pytest.approx(DELTA_E, abs=1.1e-3) and u_in[:, 1] == pytest.approx(DELTA_T)
    assert "u not derivable" not in p.rejected_counts


def test_without_attitude_u_and_w_are_missing_not_nan():
    p, calls, _ = run(ardupilot_bytes(2.0, attitude=False), autopilot="ardupilot")
    names = p.assembler.names
    assert calls
    for _, y, mask, _ in calls:
        assert not mask[names.index("u")] and not mask[names.index("w")]
        assert np.all(np.isfinite(y[mask]))
    assert p.rejected_counts["u not derivable"] > 0


def test_an_epoch_time_gps_fix_lands_on_the_boot_clock():
    """Mixed clocks: GPS_RAW_INT counts UNIX-epoch microseconds while every other message counts
    time since boot. Without SYSTEM_TIME the GNSS row still lands in the frames (on the latest
    boot-clock stamp, stamp = "epoch"'s fallback), no time jump restarts the clock and nothing is
    dropped as late."""
    p, calls, _ = run(ardupilot_bytes(gps_clock_us=GPS_EPOCH_US))
    names = p.assembler.names
    settled = calls[10:-1]
    j = names.index("gnss_alt")
    assert np.mean([m[j] for _, _, m, _ in settled]) == pytest.approx(0.25, abs=0.05)
    t = np.array([c[0] for c in calls])
    assert np.all(np.diff(t) > 0) and t[-1] < 10.0            # frame time stays on the boot clock
    assert not any("late" in k or "time jump" in k for k in p.rejected_counts), p.rejected_counts


def gnss_frame_offsets_ms(calls, names) -> tuple[np.ndarray, np.ndarray]:
    """(times (ms), ms past the nearest multiple of the 50 ms loop period) of the frames that carry
    the GNSS row."""
    j = names.index("gnss_alt")
    t_ms = np.array([t * 1e3 for t, _, m, _ in calls if m[j]])
    return t_ms, np.remainder(t_ms + 25.0, 50.0) - 25.0


def test_with_system_time_an_epoch_time_fix_is_placed_at_its_boot_time():
    """The fix is taken 10 ms after the other samples of its 50 ms frame and sent with them, stamped in
    UNIX-epoch time. Before SYSTEM_TIME (from boot time 2 s) it is placed at the latest boot-clock
    stamp (said once); after, at its own boot time: the frame it completes is stamped 10 ms after the
    loop's stamp, within 1 ms (time_boot_ms drops SYSTEM_TIME's 0.4 ms)."""
    p, calls, events = run(ardupilot_bytes(4.0, gps_clock_us=GPS_EPOCH_US, fix_lag_ms=-10,
                                           system_time_from_s=2.0))
    t_ms, past_ms = gnss_frame_offsets_ms(calls, p.assembler.names)
    before, after = past_ms[t_ms < 2000.0], past_ms[t_ms > 2000.0]
    assert len(before) >= 3 and len(after) >= 8
    assert np.allclose(before, 0.0, atol=1e-6)                     # the latest stamp
    assert np.all(np.abs(after - 10.0) <= 1.0), after             # its own time
    assert [e.message for e in events.of(EpochTimeUnmapped)] == ["GPS_RAW_INT"]
    assert not any("late" in k or "time jump" in k for k in p.rejected_counts), p.rejected_counts


def test_with_system_time_a_fix_sent_after_its_frame_is_still_taken():
    """A fix 80 ms old when sent belongs to a frame already stepped: it is placed at the latest
    stamp as before (not dropped as late), its repeat dropped. The first fix, with no frame stepped
    yet, is at its own boot time (1000 - 80 ms, less SYSTEM_TIME's 0.4 ms)."""
    p, calls, _ = run(ardupilot_bytes(3.0, gps_clock_us=GPS_EPOCH_US, system_time_from_s=1.0))
    t_ms, past_ms = gnss_frame_offsets_ms(calls, p.assembler.names)
    assert t_ms[0] == pytest.approx(919.6)
    assert len(t_ms) >= 10 and np.allclose(past_ms[1:], 0.0, atol=1e-6)
    assert p.rejected_counts["GPS_RAW_INT repeated sample"] > 0
    assert not any("late" in k or "time jump" in k for k in p.rejected_counts), p.rejected_counts
