"""`fdir import FILE.ulg --out OUT.mcap` on a real PX4 log (tests/data/README.md: pyulog's
`sample_log_small.ulg`, PX4 v1.11.2 on a CubeOrange, MAV_TYPE 22 = a standard VTOL, 6.5 s of data
on the ground), translated to the MAVLink messages px4.toml reads, then `fdir replay` on the
result; a ULog cut short imports up to the cut with a message. The same for `fdir import FILE.bin`
on a real ArduPlane DataFlash log (ArduPlane V4.2.3 on an omnibusf4pro, on the ground)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fdir_service.log_import import import_tlog, summary_lines
from fdir_service.recording.logtools import McapLog
from fdir_service.replay import replay
from fdir_service.ulog import quaternion_to_euler, read_ulog
from tests.e2e.test_tlog_import import estimates_are_finite

ROOT = Path(__file__).resolve().parents[2]
ULOG = ROOT / "tests" / "data" / "px4-vtol-cubeorange-real.ulg"
PARTICLES = 200
MIN_ROW_FRACTION = {"gnss_alt": 0.20, "baro_alt": 0.95, "u": 0.95, "w": 0.95, "theta": 0.95, "q": 0.95,
                    "ax": 0.95, "az": 0.95}
"""Measured on this log (frames with the row / 20 Hz frames over the stretch the log had it):
gnss_alt 32 / 127 = 25.2 % (the GPS logs at 5 Hz), baro_alt, u, w, q 100 %, theta, ax, az 98.5 %
(128 / 130). The floors asserted are the measured ones less margin. airspeed: 0 frames: the
log's 595 airspeed samples are all negative (-2.4 .. -1.1 m/s, on the ground: the pitot's zero
offset) and dropped as out of range (valid_min 0); asserted as such."""


def import_into(tmp_path_factory, log: Path, autopilot: str) -> tuple[Path, object]:
    """`log` imported with the profile `autopilot` into a fresh directory: (recording, result)."""
    out = tmp_path_factory.mktemp(log.suffix[1:]) / f"{autopilot}.mcap"
    return out, import_tlog(log, out, autopilot=autopilot, particles=PARTICLES)


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> tuple[Path, object]:
    """The real ULog imported with the px4 profile (the command's default for a .ulg)."""
    return import_into(tmp_path_factory, ULOG, "px4")


def test_the_real_ulog_imports_with_the_rows_the_px4_profile_promises(imported):
    out, r = imported
    assert r.autopilot == (1, 1) and r.autopilot_type == 12 and r.read.damage() is None
    assert r.fed["PARAM_VALUE"] == 980 and r.fed["HEARTBEAT"] == 7
    assert 6.0 < r.duration_s < 7.0 and r.estimates_finite
    rows = {row.name: row for row in r.rows}
    for name, floor in MIN_ROW_FRACTION.items():
        row = rows[name]
        assert row.fraction >= floor, f"{name}: {row.frames_with} / {row.expected} = " \
            f"{100 * row.fraction:.1f} % of the 20 Hz frames (measured floor {100 * floor:.0f} %)"
    assert rows["airspeed"].frames_with == 0 and r.rejected["airspeed out of range"] == 223
    log = McapLog(out)
    assert log.metadata["config"]["autopilot"] == "px4"
    assert "/mavlink/1/1/HIGHRES_IMU" in set(log.topics())


def test_integer_parameters_arrive_bytewise_and_are_decoded(imported):
    _, r = imported
    # PX4 v1.11's PWM_MAIN_MIN3 = 950 (int32), sent as the float whose bytes are 950's, read back as 950
    assert r.parameters_set["PWM_MAIN_MIN3"] == 950.0
    assert any("PWM_MAIN_MIN3=950" in line for line in summary_lines(r))


def test_the_attitude_is_the_logged_quaternion(imported):
    out, _ = imported
    log, _ = read_ulog(ULOG)
    att = [m for _, _, m in log.items if m.get_type() == "ATTITUDE"]
    recorded = [rec for _, rec in McapLog(out).iter_json("/mavlink/1/1/ATTITUDE")]
    assert len(recorded) == len(att) == 1298
    level_and_pitched = np.array([[1.0, 0.0, 0.0, 0.0], [math.cos(0.25), 0.0, math.sin(0.25), 0.0]])
    roll, pitch, _ = quaternion_to_euler(level_and_pitched)
    assert roll.tolist() == [0.0, 0.0] and pitch == pytest.approx([0.0, 0.5])
    assert recorded[100]["pitch"] == pytest.approx(att[100].pitch, abs=1e-6)


def test_replay_of_the_import_is_identical_and_finite(imported):
    out, r = imported
    same = replay(out)
    assert same.identity.identical, same.identity.describe()
    assert same.frames == r.frames and estimates_are_finite(same.replayed)


def test_a_cut_ulog_imports_up_to_the_cut_with_a_message(tmp_path):
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(ULOG.read_bytes()[:500_000])
    r = import_tlog(cut, tmp_path / "cut.mcap", autopilot="px4", particles=100)
    assert "damaged ULog" in r.read.damage() and "cut off inside a message" in r.read.damage()
    assert r.autopilot == (1, 1) and 60 <= r.frames < 131 and r.estimates_finite
    assert replay(tmp_path / "cut.mcap").identity.identical
    stub = tmp_path / "stub.ulg"
    stub.write_bytes(ULOG.read_bytes()[:3000])   # inside the format definitions
    s = import_tlog(stub, tmp_path / "stub.mcap", autopilot="px4", particles=100)
    assert "damaged ULog" in s.read.damage() and s.frames == 0


def test_the_import_command_picks_the_px4_profile_for_a_ulog(tmp_path, capsys):
    from fdir_service.cli import main

    assert main(["import", str(ULOG), "--out", str(tmp_path / "cli.mcap"), "--particles", "100",
                 "--no-progress"]) == 0
    summary = capsys.readouterr().out
    assert "HEARTBEAT autopilot 12" in summary and "damaged" not in summary
    assert McapLog(tmp_path / "cli.mcap").metadata["config"]["autopilot"] == "px4"


BIN = ROOT / "tests" / "data" / "arduplane-omnibusf4pro-real-ground.bin"
BIN_MIN_ROW_FRACTION = {"gnss_alt": 0.20, "u": 0.80, "w": 0.80, "theta": 0.90}
"""Measured on the real ArduPlane DataFlash log (tests/data/README.md: ArduPlane V4.2.3 on an
omnibusf4pro, 48.9 s on the ground): gnss_alt 209 / 851 = 24.6 % (GPS at 5 Hz), u, w 831 / 946 =
87.8 % (XKF1 at ~21 Hz; 115 frames "frozen"), theta 928 / 978 = 94.9 %. The log holds no IMU,
BARO, ARSP, CTUN or RCOU (its LOG_BITMASK): baro_alt, ax, az, airspeed have no samples and q
(pitch rate from IMU GyrY) is NaN in every ATTITUDE and dropped; asserted as such."""


@pytest.fixture(scope="module")
def imported_bin(tmp_path_factory) -> tuple[Path, object]:
    """The real DataFlash log imported with the ardupilot profile (the command's default)."""
    return import_into(tmp_path_factory, BIN, "ardupilot")


def test_the_real_dataflash_log_imports_with_the_rows_it_holds(imported_bin):
    out, r = imported_bin
    assert r.autopilot == (1, 1) and r.autopilot_type == 3 and r.read.damage() is None
    assert r.fed["PARAM_VALUE"] == 1083 and r.fed["HEARTBEAT"] == 49 and r.fed["ATTITUDE"] == 1037
    assert 48.0 < r.duration_s < 50.0 and r.estimates_finite
    rows = {row.name: row for row in r.rows}
    for name, floor in BIN_MIN_ROW_FRACTION.items():
        assert rows[name].fraction >= floor, f"{name}: {rows[name].frames_with} / {rows[name].expected}"
    for name in ("baro_alt", "q", "ax", "az", "airspeed"):
        assert rows[name].frames_with == 0
    assert r.rejected["q out of range"] == 1037
    assert r.parameters_set["SERVO3_TRIM"] == 1100.0
    assert McapLog(out).metadata["config"]["autopilot"] == "ardupilot"


def test_the_dataflash_attitude_is_the_logged_one_in_radians(imported_bin):
    out, _ = imported_bin
    from pymavlink import mavutil

    first = mavutil.mavlink_connection(str(BIN)).recv_match(type="ATT")
    recorded = next(rec for _, rec in McapLog(out).iter_json("/mavlink/1/1/ATTITUDE"))
    assert recorded["pitch"] == pytest.approx(math.radians(first.Pitch), abs=1e-6)
    assert recorded["roll"] == pytest.approx(math.radians(first.Roll), abs=1e-6)


def test_replay_of_the_dataflash_import_is_identical_and_finite(imported_bin):
    out, r = imported_bin
    same = replay(out)
    assert same.identity.identical, same.identity.describe()
    assert same.frames == r.frames and estimates_are_finite(same.replayed)
