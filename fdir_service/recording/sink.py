"""An MCAP file of JSON topics that closes its ZSTD chunk at least once a second of log time.

`JsonMcapFile` is the writing core shared by the flight `Recorder` and the simulator's
`TruthWriter`: it registers one named jsonschema per topic on first use, writes JSON messages, and
calls the mcap Writer's `flush()` (close the chunk in progress, write it and its message index,
flush the OS file) whenever the log time has advanced `flush_interval_s` since the last flush.
After a SIGKILL the file therefore holds every complete chunk, i.e. everything but at most the
last `flush_interval_s` of log time (`fdir log recover` rebuilds a readable file from it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from fdir_service import __version__
from fdir_service.recording.schemas import MESSAGE_ENCODING, SCHEMA_ENCODING, schema_bytes

PROFILE = ""  # plain MCAP (JSON messages with jsonschema schemas)
LIBRARY = f"fdir-service/{__version__}"
DEFAULT_CHUNK_BYTES = 512 * 1024
_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False)
"""= json.dumps(obj, separators=(",", ":"), allow_nan=False), without building an encoder per call."""


class JsonMcapFile:
    """One MCAP file: JSON messages on named-schema channels, ZSTD chunks, time-driven flushing.

    path: output file (parent directories are created); chunk_bytes: a chunk is also closed when
    its uncompressed size exceeds this; flush_interval_s: log-time interval between chunk flushes.
    """

    def __init__(self, path: str | os.PathLike[str], *, chunk_bytes: int = DEFAULT_CHUNK_BYTES,
                 flush_interval_s: float = 1.0) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by close())
        self._writer = Writer(self._file, chunk_size=chunk_bytes, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._file.flush()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._flush_ns = int(flush_interval_s * 1e9)
        self._last_flush_ns: int | None = None
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self.message_count = 0
        self.closed = False

    # -- registration
    def has_topic(self, topic: str) -> bool:
        return topic in self._channels

    def register(self, topic: str, schema: dict[str, Any], metadata: dict[str, str] | None = None) -> int:
        """Register `topic` with its jsonschema (schemas are shared by title); returns the channel id."""
        if topic in self._channels:
            return self._channels[topic]
        name = schema["title"]
        data = schema_bytes(schema)
        key = f"{name}\0{data.decode()}"
        schema_id = self._schemas.get(key)
        if schema_id is None:
            schema_id = self._writer.register_schema(name=name, encoding=SCHEMA_ENCODING, data=data)
            self._schemas[key] = schema_id
        channel_id = self._writer.register_channel(topic=topic, message_encoding=MESSAGE_ENCODING,
                                                   schema_id=schema_id, metadata=metadata or {})
        self._channels[topic] = channel_id
        return channel_id

    # -- writing
    def write(self, topic: str, obj: dict[str, Any], t_ns: int) -> None:
        """Append one JSON message to a registered topic at log time t_ns (ns)."""
        t_ns = max(int(t_ns), 0)
        self.tick(t_ns)  # close the chunk first, so a chunk holds [t_flush, t_flush + 1 s)
        data = _ENCODER.encode(obj).encode()
        self._writer.add_message(channel_id=self._channels[topic], log_time=t_ns, data=data,
                                 publish_time=t_ns, sequence=self.message_count & 0xFFFFFFFF)
        self.message_count += 1
        if self.first_ns is None:
            self.first_ns = t_ns
        self.last_ns = t_ns if self.last_ns is None else max(self.last_ns, t_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})
        self._file.flush()

    def tick(self, t_ns: int) -> None:
        """Advance the flush timer to log time t_ns: flush if `flush_interval_s` has passed."""
        if self._last_flush_ns is None or t_ns < self._last_flush_ns:
            self._last_flush_ns = t_ns
        elif t_ns - self._last_flush_ns >= self._flush_ns:
            self.flush()
            self._last_flush_ns = t_ns

    def flush(self) -> None:
        """Close the chunk in progress and hand everything written to the OS."""
        if not self.closed:
            self._writer.flush()

    def size_bytes(self) -> int:
        return self._file.tell()

    def close(self) -> None:
        """Finalise the file (summary, indexes, footer); idempotent."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()
