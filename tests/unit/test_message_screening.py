"""Per-message screening: each check on real MAVLink bytes, the source filter, value checks,
frozen rows, the rejection counter and its report (events, rate-limited STATUSTEXT)."""

from __future__ import annotations

import math
from collections import Counter

import pytest

from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import (
    OtherSystemIgnored,
    Rejected,
    RejectionSummary,
    SensorFrozen,
    SensorUnfrozen,
)
from fdir_service.runtime.screening import (
    DUPLICATE_MEMORY,
    FrozenRows,
    MessageScreen,
    RejectionReport,
    Rejections,
    SourceFilter,
    field_value,
    matches_where,
    message_time_us,
)
from tests.helpers.experiments import ch4_service
from tests.helpers.streams import v1_frame

CFG = ch4_service()
GNSS, BARO, U, W, THETA, Q = CFG.measurements
KEY = bytes(range(32))


def attitude(t_ms: int = 1000, pitch: float = 0.05, system: int = 1, component: int = 1) -> bytes:
    return bytes(dialect.MAVLink_attitude_message(t_ms, 0.0, pitch, 0.0, 0.0, 0.01, 0.0).pack(
        new_mavlink(system, component)))


def decode(data: bytes, key: bytes | None = None) -> list:
    return new_mavlink(255, 0, key=key).parse_buffer(data) or []


def test_message_checks_name_the_reason():
    screen = MessageScreen()
    (ok,) = decode(attitude())
    assert screen.check(ok) is None
    (v1,) = decode(v1_frame(attitude(1050)))
    assert screen.check(v1) == Rejected("mavlink1")
    cmd = bytes(dialect.MAVLink_command_long_message(1, 191, dialect.MAV_CMD_DO_SET_MODE, 0, 1, 0, 0, 0, 0, 0,
                                                     0).pack(new_mavlink(255, 190)))
    (c,) = decode(cmd)
    assert screen.check(c) == Rejected("command ignored", "COMMAND_LONG")
    unknown = bytearray(attitude(1100))
    unknown[7:10] = (50_001).to_bytes(3, "little")
    (u,) = decode(bytes(unknown))
    assert screen.check(u) == Rejected("unknown message id")
    bad = bytearray(attitude(1150))
    bad[12] ^= 0xFF                                   # a payload byte: the CRC no longer matches
    assert [screen.check(m) for m in decode(bytes(bad))] == [Rejected("bad crc")]
    (unsigned,) = decode(attitude(1200), key=KEY)     # a signing link receiving an unsigned frame
    assert screen.check(unsigned) == Rejected("unsigned")


def test_duplicates_are_the_same_bytes_from_the_same_sender():
    screen = MessageScreen()
    (a,) = decode(attitude(1000))
    (a_again,) = decode(attitude(1000))
    (other_sender,) = decode(attitude(1000, component=2))
    assert screen.check(a) is None and screen.check(a_again) == Rejected("duplicate")
    assert screen.check(other_sender) is None
    # only the last DUPLICATE_MEMORY packets per sender are remembered
    for k in range(DUPLICATE_MEMORY):
        (m,) = decode(attitude(2000 + 50 * k))
        assert screen.check(m) is None
    (old,) = decode(attitude(1000))
    assert screen.check(old) is None


def test_source_filter_follows_the_first_autopilot_and_announces_others():
    rej = Rejections()
    locked: list[int] = []
    src = SourceFilter(191, None, lambda t: t == "ATTITUDE", locked.append, rej)
    (own_echo,) = decode(attitude(system=7, component=191))
    assert not src.accept(own_echo) and src.system is None and not rej
    gcs_hb = bytes(dialect.MAVLink_heartbeat_message(6, dialect.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3).pack(
        new_mavlink(255, 190)))
    (hb,) = decode(gcs_hb)
    assert not src.accept(hb) and src.system is None          # a ground station: not followed
    (mine,) = decode(attitude(system=3))
    assert src.accept(mine) and src.system == 3 and locked == [3]
    for t in (1000, 1050):
        (intruder,) = decode(attitude(t, system=4))
        assert not src.accept(intruder)
    assert rej == Counter({"other system": 2}) and src.events == [OtherSystemIgnored(4, 3)]


def test_value_checks():
    (m,) = decode(attitude(1234, pitch=0.25))
    assert message_time_us(m) == 1_234_000
    assert field_value(m, THETA) == pytest.approx(0.25)
    (steep,) = decode(attitude(pitch=3.5))                     # beyond theta's valid_max 3.1416
    (nan,) = decode(attitude(pitch=math.nan))
    assert field_value(steep, THETA) is None and field_value(nan, THETA) is None
    odo = dialect.MAVLink_odometry_message(5_000_000, 1, 12, 0, 0, 0, [1, 0, 0, 0], 25.0, 0, 1.5, 0, 0, 0,
                                           [0.0] * 21, [0.0] * 21, 0, 1, 0)
    assert matches_where(odo, U.where) and field_value(odo, U) == 25.0 and field_value(odo, W) == 1.5
    odo.child_frame_id = 8
    assert not matches_where(odo, U.where) and matches_where(odo, ())
    assert message_time_us(dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)) is None


def test_frozen_rows_after_frozen_s_of_message_time():
    events: list = []
    frozen = FrozenRows(CFG.measurements, events)
    assert frozen.watched(0) and GNSS.frozen_s == 1.0
    held = [frozen.check(0, 501.234, t) for t in range(0, 1_100_000, 50_000)]   # 0 .. 1.05 s
    assert held == [False] * 20 + [True, True]                  # frozen from 1.00 s on
    assert events == [SensorFrozen("gnss_alt", 501.234, 1.0)]
    assert not frozen.check(0, 501.3, 1_150_000) and frozen.now == set()
    assert events[-1] == SensorUnfrozen("gnss_alt")


def test_rejection_report_events_statustext_rate_and_summary():
    a, b = Rejections(), Rejections()
    report = RejectionReport(statustext_interval_s=10.0)
    a.add(Rejected("duplicate"), 3)
    b.add(Rejected("out of range", "theta"))
    events, texts = report.report((a, b), now_us=1_000_000)
    assert events == [Rejected("duplicate"), Rejected("out of range", "theta"),
                      RejectionSummary(4, (("duplicate", 3), ("theta out of range", 1)))]
    assert texts == ["FDIR rejected 1 input: theta out of range"]          # operators only
    assert report.report((a, b), now_us=1_050_000) == ([], [])            # nothing new
    b.add(Rejected("out of range", "theta"), 4)
    events, texts = report.report((a, b), now_us=1_500_000)
    assert events == [] and texts == []           # within 1 s: no summary; within 10 s: no STATUSTEXT
    events, texts = report.report((a, b), now_us=11_000_000)
    assert texts == ["FDIR rejected 5 input: theta out of range"]
    assert events == [RejectionSummary(8, (("duplicate", 3), ("theta out of range", 5)))]
    assert a.kind("duplicate") == Rejected("duplicate") and b["theta out of range"] == 5
