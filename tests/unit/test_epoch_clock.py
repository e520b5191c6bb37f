"""UNIX-epoch stamps onto the boot clock (`runtime.clock.EpochClock`, `stamp = "epoch"`): the offset
from SYSTEM_TIME, epoch vs boot detection, offset jumps, the fallback before any SYSTEM_TIME, and
the frame assembler's placement of an epoch-stamped GPS_RAW_INT."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.autopilot_profile import select_autopilot
from fdir_service.mavlink import dialect
from fdir_service.runtime.clock import EPOCH_MIN_US, OFFSET_JUMP_US, EpochClock, is_epoch_us
from fdir_service.runtime.events import EpochOffsetJumped, EpochTimeUnmapped
from fdir_service.runtime.frames import FrameAssembler
from fdir_service.service_config import load_service_config

EPOCH_US = 1_750_000_000_000_000
"""UNIX time (us) at boot in these tests."""


def system_time(boot_us: int, offset_us: int = EPOCH_US):
    """SYSTEM_TIME taken at boot time boot_us (us): time_unix_usec = offset + boot, whole ms boot."""
    return dialect.MAVLink_system_time_message(offset_us + boot_us, boot_us // 1000)


def gps(time_usec: int, alt_mm: int = 500_000):
    return dialect.MAVLink_gps_raw_int_message(time_usec, 3, 0, 0, alt_mm, 100, 150, 0, 0, 12)


def test_epoch_and_boot_stamps_are_told_apart():
    assert is_epoch_us(EPOCH_US) and is_epoch_us(EPOCH_MIN_US)
    assert not is_epoch_us(0) and not is_epoch_us(EPOCH_MIN_US - 1)
    assert not is_epoch_us(100 * 365 * 86400 * 10**6 // 4)   # 25 years since boot


def test_the_offset_maps_epoch_stamps_and_leaves_boot_stamps():
    events: list = []
    clock = EpochClock(events)
    clock.observe(system_time(12_345_678))          # time_boot_ms 12345: the 678 us are lost
    assert clock.offset_us == EPOCH_US + 678
    assert clock.boot_us(EPOCH_US + 20_000_000, "GPS_RAW_INT") == 20_000_000 - 678   # within 1 ms
    assert clock.boot_us(3_000_000, "GPS_RAW_INT") == 3_000_000   # no fix: already boot time
    assert events == []


def test_before_any_system_time_an_epoch_stamp_is_unmapped_and_said_once_per_type():
    events: list = []
    clock = EpochClock(events)
    assert clock.boot_us(EPOCH_US + 1, "GPS_RAW_INT") is None
    assert clock.boot_us(EPOCH_US + 2, "GPS_RAW_INT") is None
    assert clock.boot_us(EPOCH_US + 3, "GPS2_RAW") is None
    assert clock.boot_us(5_000, "GPS_RAW_INT") == 5_000
    assert events == [EpochTimeUnmapped("GPS_RAW_INT"), EpochTimeUnmapped("GPS2_RAW")]
    clock.observe(dialect.MAVLink_system_time_message(0, 1_000))   # RTC not set: ignored
    assert clock.offset_us is None


def test_an_offset_jump_is_taken_and_reported_small_changes_quietly():
    events: list = []
    clock = EpochClock(events)
    clock.observe(system_time(1_000_000))
    clock.observe(system_time(2_000_000, EPOCH_US + OFFSET_JUMP_US))   # at the threshold: quiet
    assert clock.offset_us == EPOCH_US + OFFSET_JUMP_US and events == []
    clock.observe(system_time(3_000_000, EPOCH_US - 2_000_000))      # GPS time corrected by -2 s
    assert clock.offset_us == EPOCH_US - 2_000_000
    (jump,) = events
    assert isinstance(jump, EpochOffsetJumped) and jump.jump_s == pytest.approx(-2.01)
    assert jump.level == "warning" and "-2.010 s" in jump.text
    clock.forget()
    assert clock.offset_us is None


def ardupilot_assembler() -> FrameAssembler:
    config = select_autopilot(load_service_config(estimator="aerosonde-robust"), "ardupilot")
    return FrameAssembler(config, np.zeros(2))


def test_the_ardupilot_profile_stamps_gps_raw_int_by_epoch_and_reads_system_time():
    asm = ardupilot_assembler()
    assert asm.stamps["GPS_RAW_INT"] == "epoch"
    assert asm.is_mapped("SYSTEM_TIME")
    px4 = FrameAssembler(select_autopilot(load_service_config(estimator="aerosonde-robust"), "px4"),
                         np.zeros(2))
    assert not px4.is_mapped("SYSTEM_TIME")     # PX4 stamps GPS_RAW_INT on its boot clock


def test_gps_raw_int_switching_from_boot_to_epoch_time_lands_on_the_boot_clock():
    asm = ardupilot_assembler()
    asm.latest_us = 900_000
    assert asm._time_us(gps(960_000), "GPS_RAW_INT") == (960_000, False)      # no fix: boot time
    assert asm._time_us(gps(EPOCH_US + 1_010_000), "GPS_RAW_INT") == (900_000, True)   # no SYSTEM_TIME
    asm.accept(system_time(1_000_400))
    assert asm._time_us(gps(EPOCH_US + 1_060_000), "GPS_RAW_INT") == (1_060_000 - 400, False)
    assert asm._time_us(gps(EPOCH_US + 1_060_000), "GPS_RAW_INT") is None   # the same fix again
    assert asm.rejected["GPS_RAW_INT repeated sample"] == 1
    assert asm._time_us(gps(EPOCH_US - 500_000), "GPS_RAW_INT") == (900_000, True)   # before boot
    asm.last_index = 30                                                       # frames to 1.5 s stepped
    assert asm._time_us(gps(EPOCH_US + 1_400_000), "GPS_RAW_INT") == (900_000, True)  # late: latest
    assert asm._time_us(gps(EPOCH_US + 1_600_000), "GPS_RAW_INT") == (1_600_000 - 400, False)
