"""UNIX-epoch time stamps onto the autopilot's boot clock, from SYSTEM_TIME (`stamp = "epoch"`).

The frames run on one clock, the autopilot's time since boot. A few fields count UNIX-epoch time
instead: ArduPilot's GPS_RAW_INT.time_usec once the GNSS has a fix (time since boot before).
SYSTEM_TIME carries both clocks, time_unix_usec (us) and time_boot_ms (ms), so

    offset_us = time_unix_usec - 1000 * time_boot_ms      boot_us = epoch_us - offset_us

The offset held is the latest SYSTEM_TIME's (time_boot_ms is whole milliseconds: a mapped stamp
is up to 1 ms early). A change of more than OFFSET_JUMP_US (a GPS time correction, an RTC set) is
taken at once and reported (`EpochOffsetJumped`). A SYSTEM_TIME whose time_unix_usec is not epoch
time (0: the autopilot's real-time clock is not set yet) is ignored. A value is epoch time when it
is at least EPOCH_MIN_US; anything smaller already counts since boot.
"""

from __future__ import annotations

from fdir_service.runtime.events import EpochOffsetJumped, EpochTimeUnmapped, Event

EPOCH_MIN_US = 10**15
"""A time stamp (us) at least this is UNIX-epoch time (2001-09-09 onwards); a boot time is less
(10^15 us since boot = 31.7 years)."""
OFFSET_JUMP_US = 10_000
"""A change of the epoch - boot offset (us) larger than this is reported as a jump."""
SYSTEM_TIME = "SYSTEM_TIME"
"""The message that carries both clocks."""


def is_epoch_us(t_us: int) -> bool:
    """Whether a time stamp (us) is UNIX-epoch time rather than time since boot."""
    return t_us >= EPOCH_MIN_US


class EpochClock:
    """The UNIX-epoch - boot offset (us) learned from SYSTEM_TIME; maps epoch stamps onto boot
    time. `events` (shared with the frame assembler) receives the offset jumps and, once per
    message type, the notice that its epoch stamps cannot be mapped yet."""

    def __init__(self, events: list[Event]) -> None:
        self.events = events
        self.offset_us: int | None = None
        self._unmapped_told: set[str] = set()

    def observe(self, msg) -> None:
        """A SYSTEM_TIME: take its offset (us); report a jump beyond OFFSET_JUMP_US."""
        unix_us, boot_ms = int(msg.time_unix_usec), int(msg.time_boot_ms)
        if not is_epoch_us(unix_us):
            return
        offset = unix_us - 1000 * boot_ms
        if self.offset_us is not None and abs(offset - self.offset_us) > OFFSET_JUMP_US:
            self.events.append(EpochOffsetJumped((offset - self.offset_us) * 1e-6))
        self.offset_us = offset

    def boot_us(self, t_us: int, mtype: str) -> int | None:
        """Stamp t_us (us) of a `mtype` message on the boot clock: as it is if it already counts
        since boot, epoch time minus the offset, or None (told once per type) before any SYSTEM_TIME."""
        if not is_epoch_us(t_us):
            return t_us
        if self.offset_us is not None:
            return t_us - self.offset_us
        if mtype not in self._unmapped_told:
            self._unmapped_told.add(mtype)
            self.events.append(EpochTimeUnmapped(mtype))
        return None

    def forget(self) -> None:
        """The autopilot rebooted (the boot clock restarted): the offset is unknown again."""
        self.offset_us = None
