"""Translating an autopilot's own log (PX4 ULog, ArduPilot DataFlash) into MAVLink messages.

The autopilot profiles (config/autopilots/*.toml) read MAVLink messages. An onboard log holds the
same quantities in the autopilot's internal topics, so `fdir import` rebuilds, per logged sample,
the MAVLink message the autopilot would have streamed (same fields, same units), packs it with the
service's dialect as the autopilot's system 1 / component 1, and feeds it through the tlog import
path (`log_import`): the recording then holds `/mavlink/raw/in` bytes, and `fdir replay` needs no
new input kind.

`MessageLog` collects (time us since boot, message) pairs from any number of topics and yields
them time-ordered as `TlogMessage`s (t_ns = the boot time in ns), with a 1 Hz HEARTBEAT and the
parameters as PARAM_VALUE at the log's start.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.tlog import ReadStats, TlogMessage

HEARTBEAT_PERIOD_US = 1_000_000
"""The translated log's HEARTBEAT period (us): 1 Hz, as an autopilot sends it."""


def px4_bytewise(value: int) -> float:
    """PX4's PARAM_VALUE encoding of an integer parameter: the int32's four bytes read as a float32."""
    return struct.unpack("<f", struct.pack("<i", int(value)))[0]


def latest_index(times_us: np.ndarray, at_us: np.ndarray) -> np.ndarray:
    """Per time in `at_us`: the index of the latest sample of `times_us` (sorted) at or before it,
    or -1 where there is none yet."""
    return np.searchsorted(times_us, at_us, side="right") - 1


def value_at(times_us: np.ndarray, values: np.ndarray, at_us: np.ndarray) -> np.ndarray:
    """The latest `values` sample at or before each time of `at_us`; NaN before the first sample."""
    idx = latest_index(times_us, at_us)
    out = np.full(len(at_us), np.nan)
    ok = idx >= 0
    out[ok] = np.asarray(values, dtype=float)[idx[ok]]
    return out


@dataclass
class MessageLog:
    """The translated messages of one log, sent as (system 1, component 1) with HEARTBEAT.autopilot
    `autopilot` and HEARTBEAT.type `mav_type`. `add` takes (time us since boot, message)."""

    autopilot: int
    mav_type: int = dialect.MAV_TYPE_FIXED_WING
    kind: str = "log"
    file_bytes: int = 0
    items: list[tuple[int, int, Any]] = field(default_factory=list)

    def add(self, t_us: int, msg: Any) -> None:
        """One message at `t_us` (us since boot); equal times keep the order they were added in."""
        self.items.append((int(t_us), len(self.items), msg))

    def add_heartbeats(self, t0_us: int, t1_us: int) -> None:
        """A HEARTBEAT every HEARTBEAT_PERIOD_US from t0_us to t1_us (us since boot)."""
        for t in range(int(t0_us), int(t1_us) + 1, HEARTBEAT_PERIOD_US):
            self.add(t, dialect.MAVLink_heartbeat_message(
                self.mav_type, self.autopilot, dialect.MAV_MODE_FLAG_SAFETY_ARMED, 0,
                dialect.MAV_STATE_ACTIVE, 3))

    def add_param(self, t_us: int, name: str, value: float, integer: bool, bytewise: bool) -> None:
        """PARAM_VALUE `name` = `value` at t_us: an integer as MAV_PARAM_TYPE_INT32, its value
        bytewise (PX4) or cast to float (ArduPilot); else REAL32."""
        ptype = dialect.MAV_PARAM_TYPE_INT32 if integer else dialect.MAV_PARAM_TYPE_REAL32
        sent = px4_bytewise(int(value)) if integer and bytewise else float(value)
        self.add(t_us, dialect.MAVLink_param_value_message(name.encode()[:16], sent, ptype, 0xFFFF, 0xFFFF))

    def messages(self, stats: ReadStats, progress: Callable[[int], None] | None = None,
                 every: int = 2000) -> Iterator[TlogMessage]:
        """The messages in time order as packed MAVLink 2 `TlogMessage`s (t_ns = boot time ns);
        counted in `stats`. progress(approximate bytes of the log done) every `every` messages."""
        mav = new_mavlink(1, 1)
        self.items.sort(key=lambda item: (item[0], item[1]))
        n = max(len(self.items), 1)
        for i, (t_us, _, msg) in enumerate(self.items):
            data = bytes(msg.pack(mav))
            mav.seq = (mav.seq + 1) % 256   # as MAVLink.send does
            stats.messages += 1
            stats.by_type[msg.get_type()] += 1
            if progress is not None and i % every == 0:
                progress(self.file_bytes * i // n)
            yield TlogMessage(t_us * 1000, data, msg)
        if progress is not None:
            progress(self.file_bytes)


class TranslatedReader:
    """A reader with the `TlogReader` interface (`stats`, iteration) over a translated log."""

    def __init__(self, log: MessageLog, stats: ReadStats,
                 progress: Callable[[int], None] | None = None) -> None:
        self.log = log
        self.stats = stats
        self.progress = progress

    def __iter__(self) -> Iterator[TlogMessage]:
        return self.log.messages(self.stats, self.progress)


__all__ = ["HEARTBEAT_PERIOD_US", "MessageLog", "TranslatedReader", "latest_index", "px4_bytewise",
           "value_at"]
