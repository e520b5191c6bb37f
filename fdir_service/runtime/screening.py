"""Per-message screening: every check a decoded message or one of its values must pass before it
can reach the filter. What fails is dropped and counted by a typed reason (`events.Rejected`),
never handed on, and never as a NaN.

Message checks (`MessageScreen`, before the source filter): pymavlink's BAD_DATA (bad CRC,
unsigned or badly signed, malformed), MAVLink 1 frames, unknown message ids, commands (the service
acts on none), duplicates (same bytes from the same sender). `SourceFilter` then keeps one
autopilot system. Value checks (used by frame assembly): timestamp present, `where` filter,
finite and within [valid_min, valid_max] (`field_value`), not frozen (`FrozenRows`).

`Rejections` counts by key; `RejectionReport` turns the counts into events (first of each kind,
a summary at most once per second of frame time) and rate-limited STATUSTEXT for the reasons an
operator should know about.
"""

from __future__ import annotations

import math
import operator
from collections import Counter, deque
from collections.abc import Callable, Sequence
from functools import reduce

from fdir_service.mavlink import dialect
from fdir_service.runtime.events import (
    Event,
    OtherSystemIgnored,
    Rejected,
    RejectionSummary,
    SensorFrozen,
    SensorUnfrozen,
)
from fdir_service.runtime.publishing import RateLimit
from fdir_service.service_config import FieldMap

COMMAND_MESSAGES = frozenset({
    "COMMAND_LONG", "COMMAND_INT", "COMMAND_CANCEL", "SET_MODE", "PARAM_SET", "PARAM_EXT_SET",
    "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "PARAM_EXT_REQUEST_READ", "PARAM_EXT_REQUEST_LIST",
    "MISSION_ITEM", "MISSION_ITEM_INT", "MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "SETUP_SIGNING", "FILE_TRANSFER_PROTOCOL", "SET_POSITION_TARGET_LOCAL_NED", "SERIAL_CONTROL",
})
"""Messages that ask a MAVLink node to change its behaviour. The service acts on none of them
(there is no option to enable any): each is dropped and counted ("command ignored")."""

DUPLICATE_MEMORY = 32
"""Packets remembered per sender to recognise a duplicate (same bytes, same sequence number)."""
DUPLICATE_SENDERS = 64
"""Senders remembered; beyond that the oldest half is forgotten (a flood of forged sender ids)."""

MAVLINK1 = Rejected("mavlink1")
UNKNOWN_ID = Rejected("unknown message id")
DUPLICATE = Rejected("duplicate")
OTHER_SYSTEM = Rejected("other system")
NO_TIMESTAMP = Rejected("no timestamp")
TIME_JUMP = Rejected("time jump")
LATE_MEASUREMENT = Rejected("late measurement")
SURPLUS = Rejected("surplus (above frame rate)")


class Rejections(Counter[str]):
    """Dropped input by key (a `Counter`: "gnss_alt out of range" -> n), remembering the typed
    `Rejected` behind each key (`kind(key)`); `added`: everything counted so far by `add`."""

    def __init__(self) -> None:
        super().__init__()
        self.kinds: dict[str, Rejected] = {}
        self.added = 0

    def add(self, rejected: Rejected, n: int = 1) -> None:
        """Count n drops of this kind."""
        key = rejected.key
        self[key] += n
        self.added += n
        if key not in self.kinds:
            self.kinds[key] = rejected

    def kind(self, key: str) -> Rejected:
        """The typed rejection counted under `key`."""
        return self.kinds[key]


def bad_data_reason(msg) -> Rejected:
    """Why pymavlink could not decode a frame (a BAD_DATA message): unsigned, bad signature,
    bad crc or malformed."""
    reason = str(getattr(msg, "reason", "")).lower()
    data = bytes(getattr(msg, "data", b"") or b"")
    if "signature" in reason:
        signed = len(data) > 2 and data[0] == 0xFD and (data[2] & dialect.MAVLINK_IFLAG_SIGNED)
        return Rejected("bad signature" if signed else "unsigned")
    if "crc" in reason:
        return Rejected("bad crc")
    return Rejected("malformed")


class MessageScreen:
    """The checks on each decoded message before the source filter. `check(msg)` returns the
    reason to drop it, or None; it remembers the last DUPLICATE_MEMORY packets per sender."""

    def __init__(self) -> None:
        self.recent: dict[tuple[int, int], deque[bytes]] = {}

    def check(self, msg) -> Rejected | None:
        """None when the message passes; else why it is dropped (not counted here)."""
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            return bad_data_reason(msg)
        buf = msg.get_msgbuf()
        if buf and buf[0] == 0xFE:
            return MAVLINK1
        if mtype.startswith("UNKNOWN"):
            return UNKNOWN_ID
        if mtype in COMMAND_MESSAGES:
            return Rejected("command ignored", mtype)
        return DUPLICATE if self.is_duplicate(msg, bytes(buf)) else None

    def is_duplicate(self, msg, packet: bytes) -> bool:
        """Whether the sender sent these exact bytes among its last DUPLICATE_MEMORY packets
        (remembers them otherwise)."""
        key = (msg.get_srcSystem(), msg.get_srcComponent())
        recent = self.recent.get(key)
        if recent is None:
            recent = self.recent[key] = deque(maxlen=DUPLICATE_MEMORY)
        if packet in recent:
            return True
        recent.append(packet)
        if len(self.recent) > DUPLICATE_SENDERS:  # bounded: a flood of forged sender ids
            for k in list(self.recent)[:DUPLICATE_SENDERS // 2]:
                del self.recent[k]
        return False


class SourceFilter:
    """Keeps the messages of one autopilot system. `system`: the configured one, or None until
    the first autopilot HEARTBEAT or mapped message picks it (then `on_lock(system)` is called).
    Our own output echoed back is dropped silently; other systems are counted ("other system")
    and announced once each (`events`, drained by the caller)."""

    MAX_ANNOUNCED = 256

    def __init__(self, component: int, system: int | None, is_mapped: Callable[[str], bool],
                 on_lock: Callable[[int], None], rejections: Rejections) -> None:
        self.component = component
        self.system = system
        self.is_mapped = is_mapped
        self.on_lock = on_lock
        self.rejections = rejections
        self.others: set[int] = set()
        self.events: list[Event] = []

    def accept(self, msg) -> bool:
        """Whether the message comes from the followed autopilot."""
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if src_comp == self.component and (self.system is None or src_sys == self.system):
            return False  # our own output echoed back
        if self.system is None and not self._lock_on(msg, src_sys):
            return False
        if src_sys != self.system:
            self.rejections.add(OTHER_SYSTEM)
            if src_sys not in self.others and len(self.others) < self.MAX_ANNOUNCED:
                self.others.add(src_sys)
                self.events.append(OtherSystemIgnored(src_sys, self.system))
            return False
        return True

    def _lock_on(self, msg, src_sys: int) -> bool:
        """Follow src_sys if this is an autopilot's HEARTBEAT or a mapped message."""
        mtype = msg.get_type()
        is_autopilot_hb = mtype == "HEARTBEAT" and msg.autopilot != dialect.MAV_AUTOPILOT_INVALID
        if not (is_autopilot_hb or self.is_mapped(mtype)):
            return False
        self.system = src_sys
        self.on_lock(src_sys)
        return True


# ---------------------------------------------------------------------------- values

def message_time_us(msg) -> int | None:
    """The message's autopilot timestamp in us (time_usec, else time_boot_ms * 1000), or None."""
    t = getattr(msg, "time_usec", None)
    if t is not None:
        return int(t)
    t = getattr(msg, "time_boot_ms", None)
    return None if t is None else int(t) * 1000


def matches_where(msg, where: tuple[tuple[str, float], ...]) -> bool:
    """Whether every (field, value) of a mapping's `where` filter holds for the message."""
    if not where:
        return True
    try:
        return all(float(getattr(msg, wk)) == wv for wk, wv in where)
    except (TypeError, ValueError, AttributeError):
        return False


def read_value(msg, fm: FieldMap) -> float:
    """The mapped field converted to SI (fm.convert); NaN when it cannot be converted."""
    raw = getattr(msg, fm.field)
    if fm.index is not None:
        raw = raw[fm.index]
    try:
        return fm.convert(raw)
    except (TypeError, ValueError, OverflowError):
        return math.nan


def field_value(msg, fm: FieldMap) -> float | None:
    """The mapped value (SI) if finite and within [fm.min, fm.max], else None ("out of range")."""
    raw = getattr(msg, fm.field)   # read_value, inlined: once per mapped field of every message
    if fm.index is not None:
        raw = raw[fm.index]
    try:
        v = fm.convert(raw)
    except (TypeError, ValueError, OverflowError):
        return None
    return v if math.isfinite(v) and fm.min <= v <= fm.max else None


def checked_value(fm: FieldMap, raw: float) -> float | None:
    """fm.convert(raw) (SI) if finite and within [fm.min, fm.max], else None ("out of range")."""
    try:
        v = fm.convert(raw)
    except (TypeError, ValueError, OverflowError):
        return None
    return v if math.isfinite(v) and fm.min <= v <= fm.max else None


class FrozenRows:
    """Rows that hold a bit-identical value for their frozen_s (message time) are frozen: their
    values are dropped ("<row> frozen") until it changes. Announces both (`events`)."""

    def __init__(self, measurements: tuple[FieldMap, ...], events: list[Event]) -> None:
        self.names = [fm.name for fm in measurements]
        self.frozen_us = [int(fm.frozen_s * 1e6) for fm in measurements]
        self.value: list[float | None] = [None] * len(measurements)
        self.since_us: list[int] = [0] * len(measurements)
        self.now: set[str] = set()
        self.events = events

    def watched(self, j: int) -> bool:
        """Whether row j is checked at all (frozen_s > 0)."""
        return bool(self.frozen_us[j])

    def check(self, j: int, v: float, t_us: int) -> bool:
        """Whether row j, measuring v at t_us, has held that value for frozen_s."""
        name = self.names[j]
        if v != self.value[j]:
            self.value[j] = v
            self.since_us[j] = t_us
            if name in self.now:
                self.now.discard(name)
                self.events.append(SensorUnfrozen(name))
            return False
        held = t_us - self.since_us[j]
        if held < self.frozen_us[j]:
            return False
        if name not in self.now:
            self.now.add(name)
            self.events.append(SensorFrozen(name, v, held * 1e-6))
        return True


# ---------------------------------------------------------------------------- reporting

SUMMARY_PERIOD_US = 1_000_000
"""At most one RejectionSummary per second of frame time."""


class RejectionReport:
    """Reports dropped input: a `Rejected` event the first time each kind appears, operator
    reasons as STATUSTEXT "FDIR rejected <n> input: <key>" (first time, then at most once per
    `statustext_interval_s` of frame time per key), and a `RejectionSummary` at most once per
    second of frame time while the counts move."""

    def __init__(self, statustext_interval_s: float) -> None:
        self.limit = RateLimit(statustext_interval_s)
        self.seen: set[str] = set()
        self.sent_count: Counter[str] = Counter()
        self.reported = 0
        self.last_summary_us: int | None = None

    def report(self, counters: Sequence[Rejections], now_us: int) -> tuple[list[Event], list[str]]:
        """(events, STATUSTEXT texts) for the counts so far (`counters` summed) at frame time now_us."""
        n = sum(c.added for c in counters)
        if n == self.reported:
            return [], []
        total: Counter[str] = reduce(operator.add, counters, Counter())
        kinds = {k: r for c in counters for k, r in c.kinds.items()}
        events: list[Event] = [kinds[r] for r in total if r not in self.seen]
        self.seen.update(total)
        texts = self._statustexts(total, kinds, now_us)
        if self.last_summary_us is None or now_us - self.last_summary_us >= SUMMARY_PERIOD_US:
            self.last_summary_us = now_us
            self.reported = n
            events.append(RejectionSummary(n, tuple(sorted(total.items()))))
        return events, texts

    def _statustexts(self, total: Counter[str], kinds: dict[str, Rejected], now_us: int) -> list[str]:
        texts = []
        for r, c in total.items():
            if c == self.sent_count[r] or not kinds[r].operator:
                continue
            if self.limit.due(f"reject:{r}", now_us):
                self.sent_count[r] = c
                texts.append(f"FDIR rejected {c} input: {r}"[:50])
        return texts
