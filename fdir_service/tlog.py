"""Reading a ground station's MAVLink telemetry log (`.tlog`) for `fdir import`.

A tlog is a sequence of records [8-byte big-endian receive time, us since the Unix epoch][one
MAVLink 1 or 2 packet], written by Mission Planner, MAVProxy or QGroundControl. It holds what the
ground station received from the vehicle *and* what it sent itself (its HEARTBEAT, parameter
requests, commands), so `AutopilotMessages` keeps only the autopilot's own messages.

`TlogReader` frames each record itself and has pymavlink decode the packet (CRC and fields,
ardupilotmega dialect); it counts what could not be used: bytes in no decoded record, bad
records (no packet start, a bad CRC, cut off), packets of unknown message ids, and times more
than `MAX_TIME_JUMP_S` off. Nothing is raised for a damaged file: reading resumes at the next
record that decodes.

The service reads MAVLink 2 only (it drops MAVLink 1 as a downgrade on its own link), and many
tlogs (ArduPilot before 4.0, any link set to MAVLink 1) are MAVLink 1: `as_mavlink2` re-frames
such a packet as MAVLink 2 with the same sender, sequence number and payload.
"""

from __future__ import annotations

import os
import struct
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink.generator.mavcrc import x25crc

MAV_AUTOPILOT_INVALID = 8
"""HEARTBEAT.autopilot of a node that is not an autopilot (a ground station, a gimbal)."""
AUTOPILOT_COMPONENT = 1
"""MAV_COMP_ID_AUTOPILOT1: the autopilot's component id."""
MAX_TIME_JUMP_S = 3 * 24 * 3600.0
"""A tlog time further than this (s) from the last good one is corrupt (pymavlink's own bound)."""
PLAUSIBLE_UNIX_S = (946684800.0, 4102444800.0)
"""The first tlog time must lie in 2000..2100 (s since the Unix epoch); else it is corrupt."""
TIMESTAMP_BYTES = 8
_V2_HEADER = struct.Struct("<BBBBBBBHB")   # STX, len, incompat, compat, seq, sys, comp, msgid (24 bit)


@dataclass
class TlogMessage:
    """One decoded packet: `t_ns` the tlog receive time (ns since the Unix epoch), `data` the
    packet's bytes as MAVLink 2, `msg` the pymavlink message (its own dialect's class)."""

    t_ns: int
    data: bytes
    msg: object
    mavlink1: bool = False

    @property
    def mtype(self) -> str:
        return self.msg.get_type()

    @property
    def sender(self) -> tuple[int, int]:
        """(system, component) of the sender."""
        return self.msg.get_srcSystem(), self.msg.get_srcComponent()


@dataclass
class ReadStats:
    """What `TlogReader` read: file size and bytes in decoded packets (with their timestamps),
    packets decoded, MAVLink 1 packets re-framed, BAD_DATA packets, timestamps replaced by the last
    good one, and the error that stopped the read early (None: read to the end); `kind` names the
    file's format in the damage line."""

    file_bytes: int = 0
    good_bytes: int = 0
    messages: int = 0
    mavlink1: int = 0
    bad_packets: int = 0
    bad_timestamps: int = 0
    unknown: int = 0
    stopped: str | None = None
    kind: str = "tlog"
    by_type: Counter[str] = field(default_factory=Counter)

    @property
    def bad_bytes(self) -> int:
        """Bytes of the file in no decoded record (garbage, a cut-off packet, a bad CRC)."""
        return max(self.file_bytes - self.good_bytes, 0)

    def damage(self) -> str | None:
        """One line on what was damaged, or None for a clean file."""
        if not (self.bad_bytes or self.bad_packets or self.bad_timestamps or self.stopped):
            return None
        parts = [f"{self.bad_bytes} bytes in no readable record", f"{self.bad_packets} bad packets",
                 f"{self.bad_timestamps} bad timestamps"]
        if self.stopped:
            parts.append(f"reading stopped early: {self.stopped}")
        return f"damaged {self.kind}: " + ", ".join(parts) + "; everything readable was imported"


def as_mavlink2(packet: bytes, crc_extra: int) -> bytes:
    """A MAVLink 1 packet (0xFE ...) re-framed as MAVLink 2 (same sequence number, sender, message
    id and payload, trailing zeros truncated as MAVLink 2 does); a MAVLink 2 packet as it is."""
    if not packet or packet[0] != 0xFE:
        return bytes(packet)
    length, seq, sys_id, comp, msg_id = packet[1], packet[2], packet[3], packet[4], packet[5]
    payload = bytes(packet[6:6 + length])
    payload = payload.rstrip(b"\0") or payload[:1]
    header = _V2_HEADER.pack(0xFD, len(payload), 0, 0, seq, sys_id, comp, msg_id & 0xFFFF, msg_id >> 16)
    crc = x25crc(header[1:] + payload)
    crc.accumulate(bytes([crc_extra]))
    return header + payload + struct.pack("<H", crc.crc)


def _codec():
    """pymavlink's ardupilotmega dialect, MAVLink 2 module (it decodes MAVLink 1 packets too)."""
    from pymavlink.dialects.v20 import ardupilotmega

    return ardupilotmega, ardupilotmega.MAVLink(None)


def packet_length(data: bytes | memoryview, at: int) -> int | None:
    """The length (bytes) of the MAVLink packet starting at `at` from its header (MAVLink 1: 0xFE,
    len; MAVLink 2: 0xFD, len, incompat flags: signed adds 13), or None when no packet starts there."""
    if at + 3 > len(data):
        return None
    stx, length = data[at], data[at + 1]
    if stx == 0xFE:
        return length + 8
    if stx == 0xFD:
        return length + 12 + (13 if data[at + 2] & 0x01 else 0)
    return None


class TlogReader:
    """Iterate a tlog's decoded packets (`TlogMessage`), counting what is damaged (`stats`).

    Each record is framed exactly: 8 bytes of time, then one packet whose length its header gives;
    pymavlink decodes it (`MAVLink.decode`: the CRC with the message's crc_extra, then the fields).
    Where no packet decodes (no packet start, a bad CRC, a cut-off packet) the bytes are counted
    and the reader moves on one byte at a time to the next record that decodes. (pymavlink's own
    tlog reader, `mavutil.mavlink_connection(FILE.tlog)`, asks for as many bytes as its parser
    state wants and reads past a short MAVLink 1 packet that follows a MAVLink 2 one, as in a tlog
    of a MAVLink 2 autopilot next to a MAVLink 1 ground station; hence the framing here.)

    progress(bytes_read) is called every `progress_every` packets (a progress bar)."""

    def __init__(self, path: str | os.PathLike[str],
                 progress: Callable[[int], None] | None = None, progress_every: int = 2000) -> None:
        self.path = Path(path)
        self.stats = ReadStats(file_bytes=self.path.stat().st_size)
        self.progress = progress
        self.progress_every = progress_every
        self._last_ns: int | None = None
        self._dialect, self._mav = _codec()

    def __iter__(self) -> Iterator[TlogMessage]:
        data = self.path.read_bytes()
        at, bad_run = 0, False
        while at + TIMESTAMP_BYTES < len(data):
            item, size = self._record(data, at, bad_run)
            if item is None and size:
                self.stats.unknown += 1
            elif item is None:
                self.stats.bad_packets += not bad_run   # a run of bad bytes counts as one bad record
                bad_run, size = True, 1
            else:
                bad_run = False
                self._count(item, size)
                yield item
            at += size
            if self.progress is not None and self.stats.messages % self.progress_every == 0:
                self.progress(at)
        if self.progress is not None:
            self.progress(len(data))

    def _record(self, data: bytes, at: int, resync: bool) -> tuple[TlogMessage | None, int]:
        """The record at `at` and its size in bytes; (None, 0) if no packet decodes there, or
        (None, size) for a packet of a message id the dialect does not know (its CRC cannot be
        checked: skipped and counted, and never a place to resync on)."""
        n = packet_length(data, at + TIMESTAMP_BYTES)
        if n is None or at + TIMESTAMP_BYTES + n > len(data):
            return None, 0
        packet = data[at + TIMESTAMP_BYTES:at + TIMESTAMP_BYTES + n]
        try:
            msg = self._mav.decode(bytearray(packet))
        except (self._dialect.MAVError, struct.error, ValueError, IndexError):
            return None, 0
        crc_extra = getattr(msg, "crc_extra", None)
        if crc_extra is None:
            return None, (0 if resync else TIMESTAMP_BYTES + n)
        t_ns = self._time_ns(struct.unpack_from(">Q", data, at)[0] * 1000)
        if t_ns is None:
            return None, 0
        return TlogMessage(t_ns, as_mavlink2(packet, crc_extra), msg, packet[0] == 0xFE), TIMESTAMP_BYTES + n

    def _count(self, item: TlogMessage, size: int) -> None:
        self.stats.messages += 1
        self.stats.good_bytes += size
        self.stats.by_type[item.mtype] += 1
        self.stats.mavlink1 += item.mavlink1

    def _time_ns(self, t_ns: int) -> int | None:
        """The record's time (ns) for a packet that decoded. Before any good time it must lie in
        PLAUSIBLE_UNIX_S (else None: the record is not used); after, a time more than
        MAX_TIME_JUMP_S from the last good one is counted and replaced by that one (a little
        backwards is fine: ground stations stamp packets from several links)."""
        last = self._last_ns
        if last is None:
            lo, hi = PLAUSIBLE_UNIX_S
            if not lo * 1e9 <= t_ns <= hi * 1e9:
                return None
        elif abs(t_ns - last) > int(MAX_TIME_JUMP_S * 1e9):
            self.stats.bad_timestamps += 1
            return last
        self._last_ns = t_ns
        return t_ns


@dataclass
class AutopilotMessages:
    """Keeps the messages of the autopilot: the (system, component 1) that sends a HEARTBEAT with
    autopilot != MAV_AUTOPILOT_INVALID first. Messages before that HEARTBEAT are held and released
    once it is known (`hold_limit` at most, the oldest dropped and counted beyond); everything
    else is counted by sender in `others`."""

    hold_limit: int = 100_000
    sender: tuple[int, int] | None = None
    autopilot_type: int | None = None
    others: Counter[tuple[int, int]] = field(default_factory=Counter)
    dropped_before_heartbeat: int = 0
    _held: list[TlogMessage] = field(default_factory=list)

    def take(self, item: TlogMessage) -> list[TlogMessage]:
        """The autopilot messages this one releases (itself, and the held ones once it is known)."""
        if self.sender is None and self._is_autopilot_heartbeat(item):
            self.sender = item.sender
            self.autopilot_type = int(item.msg.autopilot)
            held, self._held = self._held, []
            return [m for m in held if self._keep(m)] + [item]
        if self.sender is None:
            self._hold(item)
            return []
        return [item] if self._keep(item) else []

    def finish(self) -> None:
        """End of the log: what is still held had no autopilot; counted as other senders."""
        for m in self._held:
            self.others[m.sender] += 1
        self._held = []

    @staticmethod
    def _is_autopilot_heartbeat(item: TlogMessage) -> bool:
        return (item.mtype == "HEARTBEAT" and item.sender[1] == AUTOPILOT_COMPONENT
                and int(item.msg.autopilot) != MAV_AUTOPILOT_INVALID)

    def _hold(self, item: TlogMessage) -> None:
        self._held.append(item)
        if len(self._held) > self.hold_limit:
            self._held.pop(0)
            self.dropped_before_heartbeat += 1

    def _keep(self, item: TlogMessage) -> bool:
        if item.sender == self.sender:
            return True
        self.others[item.sender] += 1
        return False
