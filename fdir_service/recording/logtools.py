"""Reading recorded MCAP logs, including ones whose writer was killed, and repairing them.

`McapLog(path)` reads a finalised file through its summary (the mcap library's indexed reader)
and falls back to a linear scan of the data section when the summary or footer is missing or
unreadable: every complete record is read, and the scan stops at the first truncated or corrupt
one (for a killed recorder: the chunk that was being written, i.e. at most the last second).
`log_info` summarises a log; `recover` rewrites what a linear scan finds into a finalised file.
"""

from __future__ import annotations

import io
import json
import os
import struct
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from fdir_service.recording.sink import LIBRARY, PROFILE

MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = struct.Struct("<BQ")


@dataclass
class LinearScan:
    """What a linear read found: schemas, channels, messages in file order, metadata."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    metadata: list[Metadata] = field(default_factory=list)
    finalised: bool = False          # the data section ended properly (DataEnd found)
    truncated_at: int | None = None  # byte offset of the first incomplete or corrupt record
    dropped_bytes: int = 0           # bytes from there to the end of the file


def linear_scan(path: str | os.PathLike[str]) -> LinearScan:
    """Read every complete record of the data section in order, stopping at the first truncated or
    corrupt one (chunk CRCs are checked). Works on files whose writer was killed."""
    out = LinearScan()
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        if f.read(len(MAGIC)) != MAGIC:
            raise McapError(f"{path}: not an MCAP file (bad magic)")
        while True:
            start = f.tell()
            try:
                record, records = _next_record(f, size)
            except _Truncated:
                out.truncated_at = start
                break
            if record is None:
                continue  # unknown record type: skipped by the spec
            _collect(out, records)
            if isinstance(record, (DataEnd, Footer)):
                out.finalised = True
                break
        if out.truncated_at is not None:
            out.dropped_bytes = size - out.truncated_at
    return out


class _Truncated(Exception):
    """The record at the file position is incomplete or corrupt (or the file ended without DataEnd)."""


def _next_record(f: BinaryIO, size: int) -> tuple[Any, list[Any]]:
    """The next record at f's position (size: the file's length in bytes) and the records it holds
    (a chunk's messages, CRC-checked; else itself); (None, []) for an unknown record type.
    Raises _Truncated."""
    start = f.tell()
    head = f.read(_RECORD_HEADER.size)
    if len(head) < _RECORD_HEADER.size:
        raise _Truncated   # ended without DataEnd: truncated (maybe at a record boundary)
    _opcode, length = _RECORD_HEADER.unpack(head)
    if start + _RECORD_HEADER.size + length > size:
        raise _Truncated
    body = f.read(length)
    try:
        reader = StreamReader(io.BytesIO(head + body), skip_magic=True, emit_chunks=True)
        record = next(reader.records)
        records = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
    except StopIteration:
        return None, []
    except Exception as exc:  # noqa: BLE001 (any decoding failure means a corrupt tail)
        raise _Truncated from exc
    return record, records


def _collect(out: LinearScan, records: Iterable[Any]) -> None:
    """File schemas, channels, messages (of known channels) and metadata into the scan."""
    for r in records:
        if isinstance(r, Schema):
            out.schemas[r.id] = r
        elif isinstance(r, Channel):
            out.channels[r.id] = r
        elif isinstance(r, Message):
            if r.channel_id in out.channels:
                out.messages.append(r)
        elif isinstance(r, Metadata):
            out.metadata.append(r)


class McapLog:
    """A recorded log, opened by the indexed reader or, failing that, by a linear scan.

    `mode` is "indexed" (finalised file) or "linear" (summary missing: writer killed).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._scan: LinearScan | None = None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        try:
            with open(self.path, "rb") as f:
                reader = SeekingReader(f)
                summary = reader.get_summary()
                if summary is None or not summary.chunk_indexes and summary.statistics is None:
                    raise McapError("no summary")
                self.schemas = dict(summary.schemas)
                self.channels = dict(summary.channels)
                for m in reader.iter_metadata():
                    self.metadata.setdefault(m.name, dict(m.metadata))
                self._stats = summary.statistics
            self.mode = "indexed"
        except (McapError, struct.error, OSError, ValueError, StopIteration):
            if not self.path.exists():
                raise
            self._scan = linear_scan(self.path)
            self.schemas, self.channels = self._scan.schemas, self._scan.channels
            for m in self._scan.metadata:
                self.metadata.setdefault(m.name, dict(m.metadata))
            self.mode = "linear"

    @property
    def scan(self) -> LinearScan | None:
        """The linear scan, when the file had to be read that way."""
        return self._scan

    def topics(self) -> dict[str, Channel]:
        return {c.topic: c for c in self.channels.values()}

    def iter_messages(self, topics: str | Iterable[str] | None = None
                      ) -> Iterator[tuple[Schema | None, Channel, Message]]:
        """(schema, channel, message) in file (write) order, optionally for some topics only."""
        wanted = {topics} if isinstance(topics, str) else (None if topics is None else set(topics))
        if self._scan is not None:
            for m in self._scan.messages:
                ch = self.channels[m.channel_id]
                if wanted is None or ch.topic in wanted:
                    yield self.schemas.get(ch.schema_id), ch, m
            return
        with open(self.path, "rb") as f:
            yield from SeekingReader(f).iter_messages(topics=None if wanted is None else list(wanted),
                                                      log_time_order=False)

    def iter_json(self, topic: str) -> Iterator[tuple[int, dict[str, Any]]]:
        """(log_time ns, decoded JSON object) of one topic, in write order."""
        for _, _, m in self.iter_messages(topic):
            yield m.log_time, json.loads(m.data)

    def message_counts(self) -> Counter[str]:
        counts: Counter[str] = Counter()
        for _, ch, _ in self.iter_messages():
            counts[ch.topic] += 1
        return counts


def log_info(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Topics with schema names and message counts, time span, metadata and how the file was read."""
    log = McapLog(path)
    counts: Counter[str] = Counter()
    t0: int | None = None
    t1: int | None = None
    for _, ch, m in log.iter_messages():
        counts[ch.topic] += 1
        t0 = m.log_time if t0 is None else min(t0, m.log_time)
        t1 = m.log_time if t1 is None else max(t1, m.log_time)
    topics = {}
    for topic, ch in sorted(log.topics().items()):
        schema = log.schemas.get(ch.schema_id)
        topics[topic] = {"schema": schema.name if schema else None, "encoding": ch.message_encoding,
                         "count": counts.get(topic, 0)}
    info: dict[str, Any] = {
        "path": str(log.path),
        "mode": log.mode,
        "finalised": log.mode == "indexed",
        "size_bytes": log.path.stat().st_size,
        "messages": sum(counts.values()),
        "start_ns": t0,
        "end_ns": t1,
        "duration_s": 0.0 if t0 is None or t1 is None else (t1 - t0) / 1e9,
        "topics": topics,
        "metadata": log.metadata,
    }
    if log.scan is not None:
        info["truncated_at"] = log.scan.truncated_at
        info["dropped_bytes"] = log.scan.dropped_bytes
    return info


def format_info(info: dict[str, Any], *, show_config: bool = True) -> str:
    """`fdir log info` text."""
    lines = [
        f"file:      {info['path']} ({info['size_bytes']} bytes)",
        f"state:     {'finalised' if info['finalised'] else 'not finalised (writer killed?): read linearly'}",
    ]
    if info.get("dropped_bytes"):
        lines.append(f"           {info['dropped_bytes']} trailing bytes unreadable "
                     f"(from offset {info['truncated_at']})")
    lines += [f"messages:  {info['messages']}", f"duration:  {info['duration_s']:.3f} s"]
    lines.append("topics:")
    width = max((len(t) for t in info["topics"]), default=10)
    for topic, t in info["topics"].items():
        lines.append(f"  {topic:<{width}}  {t['count']:>8}  {t['schema']}")
    if info["metadata"]:
        lines.append("metadata:")
        for name, data in info["metadata"].items():
            lines.append(f"  {name}: {', '.join(sorted(data))}")
            if show_config and name == "config":
                for k, v in data.items():
                    if "\n" not in v:
                        lines.append(f"    {k} = {v}")
    return "\n".join(lines)


@dataclass
class RecoverReport:
    messages: int
    channels: int
    schemas: int
    metadata: int
    dropped_bytes: int
    was_finalised: bool


def recover(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> RecoverReport:
    """Rewrite every complete record of `src` (linear scan) into a finalised, indexed `dst`."""
    if Path(src).resolve() == Path(dst).resolve():
        raise ValueError("recover: source and destination must differ")
    scan = linear_scan(src)
    with open(dst, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile=PROFILE, library=LIBRARY)
        schema_ids: dict[int, int] = {}
        for sid, s in scan.schemas.items():
            schema_ids[sid] = w.register_schema(name=s.name, encoding=s.encoding, data=s.data)
        channel_ids: dict[int, int] = {}
        for cid, c in scan.channels.items():
            channel_ids[cid] = w.register_channel(topic=c.topic, message_encoding=c.message_encoding,
                                                  schema_id=schema_ids.get(c.schema_id, 0),
                                                  metadata=dict(c.metadata))
        for m in scan.metadata:
            w.add_metadata(m.name, dict(m.metadata))
        for m in scan.messages:
            w.add_message(channel_id=channel_ids[m.channel_id], log_time=m.log_time, data=m.data,
                          publish_time=m.publish_time, sequence=m.sequence)
        w.finish()
    return RecoverReport(messages=len(scan.messages), channels=len(scan.channels), schemas=len(scan.schemas),
                         metadata=len(scan.metadata), dropped_bytes=scan.dropped_bytes,
                         was_finalised=scan.finalised)
