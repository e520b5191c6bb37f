"""The flight recorder: a `PipelineObserver` that writes everything the service sees and says to MCAP.

Topics (all JSON with a named jsonschema, see `fdir_service.recording.schemas`):
  /mavlink/raw/in, /mavlink/raw/out   bytes exactly as read from / written to the autopilot link
  /mavlink/<sys>/<comp>/<MSG>         every decoded, accepted input message
  /fdir/estimate                      one flat record per filter step (fdir.Estimate)
  /fdir/items                         per frame, the monitored items (fdir.Items), only for estimators
                                      with typed faults or several entries per target
  /fdir/particles                     the 20 most weighted particles, once per second of frame time
  /fdir/log                           events (foxglove.Log): fault declared/cleared, stale, rejected
Metadata records: "config", "versions", "dialect" (as the pipeline hands them over), repeated in
every segment. The log time of every message is the pipeline's t_ns (receive time).

Deferred mode (`defer()`, what `fdir run` uses): the observer calls queue cheap references (the
estimate as its flat dict, particle copies) and `drain()` encodes and writes them after the frame's
output has been sent; the file content is the same as in the default eager mode.

Crash safety: chunks are ZSTD-compressed and closed at least once a second of log time, so a
SIGKILL loses at most the last second; SIGTERM/SIGINT must call `close()` (the daemon does) to
write the summary. Rotation: a new segment `<stem>.001.mcap`, `<stem>.002.mcap`, ... starts when
the current one exceeds `rotate_bytes` or spans `rotate_seconds` of log time.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.recording import schemas as S
from fdir_service.recording.sink import DEFAULT_CHUNK_BYTES, JsonMcapFile
from fdir_service.runtime.items import ItemReport

RAW_IN_TOPIC = "/mavlink/raw/in"
RAW_OUT_TOPIC = "/mavlink/raw/out"
ESTIMATE_TOPIC = "/fdir/estimate"
PARTICLES_TOPIC = "/fdir/particles"
ITEMS_TOPIC = "/fdir/items"
LOG_TOPIC = "/fdir/log"


def default_record_path(directory: str | os.PathLike[str], now: datetime | None = None) -> Path:
    """`<directory>/fdir-YYYYmmddTHHMMSSZ.mcap`: a fresh recording name (wall clock, UTC)."""
    now = now or datetime.now(UTC)
    return Path(directory) / f"fdir-{now.strftime('%Y%m%dT%H%M%SZ')}.mcap"


def segment_path(path: str | os.PathLike[str], index: int) -> Path:
    """Segment `index` of a rotated recording: 0 is `path` itself, then `<stem>.001.mcap`, ..."""
    p = Path(path)
    if index == 0:
        return p
    return p.with_name(f"{p.stem}.{index:03d}{p.suffix or '.mcap'}")


class Recorder:
    """Writes the pipeline's raw bytes, decoded messages, estimates, events and particles to MCAP.

    path: the first segment's file; rotate_bytes / rotate_seconds: start a new segment past this
    size (bytes on disk) or log-time span (s), None = never; chunk_bytes: uncompressed chunk size
    cap; flush_interval_s: log-time interval between chunk flushes (<= 1 s for the crash promise).
    Thread-safe; `close()` is idempotent and must be called on SIGTERM / SIGINT.
    """

    def __init__(self, path: str | os.PathLike[str], *, rotate_bytes: int | None = None,
                 rotate_seconds: float | None = None, chunk_bytes: int = DEFAULT_CHUNK_BYTES,
                 flush_interval_s: float = 1.0) -> None:
        if flush_interval_s <= 0:
            raise ValueError("flush_interval_s must be > 0")
        self.path = Path(path)
        self.rotate_bytes = rotate_bytes
        self.rotate_ns = None if rotate_seconds is None else int(rotate_seconds * 1e9)
        self._chunk_bytes = chunk_bytes
        self._flush_interval_s = flush_interval_s
        self._lock = threading.RLock()
        self._metadata: list[tuple[str, dict[str, str]]] = []
        self._estimate_layout: tuple[tuple[str, ...], int, bool, bool] | None = None
        self._state_names: list[str] | None = None
        self.paths: list[Path] = []
        self._segment_start_ns: int | None = None
        self._file: JsonMcapFile | None = None
        self.closed = False
        self.deferred = False
        self._queue: list[tuple[Callable[..., None], tuple[Any, ...]]] = []
        self._open_segment()

    # ------------------------------------------------------------------ deferral
    def defer(self, on: bool = True) -> None:
        """Deferred mode (the daemon's): the PipelineObserver calls only queue cheap references
        (bytes, the StepOutput, the message object) and `drain()` encodes and writes them, in call
        order, after the frame's output has been sent. The file content is the same either way."""
        with self._lock:
            self.deferred = on
            if not on:
                self._drain_locked()

    def drain(self) -> None:
        """Encode and write everything queued in deferred mode (call before the next frame is fed:
        the queued StepOutput is referenced, not copied)."""
        if self._queue:
            with self._lock:
                self._drain_locked()

    @property
    def queued(self) -> int:
        """Observer calls queued in deferred mode and not written yet (0 after `drain()`)."""
        return len(self._queue)

    def _drain_locked(self) -> None:
        q, self._queue = self._queue, []
        for fn, args in q:
            fn(*args)

    # ------------------------------------------------------------------ segments
    def _open_segment(self) -> None:
        path = segment_path(self.path, len(self.paths))
        self._file = JsonMcapFile(path, chunk_bytes=self._chunk_bytes,
                                  flush_interval_s=self._flush_interval_s)
        self.paths.append(path)
        self._segment_start_ns = None
        for name, data in self._metadata:
            self._file.add_metadata(name, data)

    def _before_write(self, t_ns: int) -> JsonMcapFile:
        f = self._file
        assert f is not None
        if self._segment_start_ns is None:
            self._segment_start_ns = t_ns
        rotate = (self.rotate_ns is not None and t_ns - self._segment_start_ns >= self.rotate_ns) or (
            self.rotate_bytes is not None and f.message_count > 0 and f.size_bytes() >= self.rotate_bytes)
        if rotate:
            f.close()
            self._open_segment()
            self._segment_start_ns = t_ns
            f = self._file
            assert f is not None
        return f

    def _write(self, topic: str, schema: dict[str, Any] | Callable[[], dict[str, Any]], obj: dict[str, Any],
               t_ns: int) -> None:
        with self._lock:
            if self.closed:
                return
            f = self._before_write(t_ns)
            if not f.has_topic(topic):
                f.register(topic, schema() if callable(schema) else schema)
            f.write(topic, obj, t_ns)

    # ------------------------------------------------------------------ PipelineObserver
    def on_metadata(self, name: str, data: Mapping[str, Any]) -> None:
        """Store a metadata record ("config", "versions", "dialect"); repeated in every segment."""
        record = {str(k): str(v) for k, v in data.items()}
        with self._lock:
            if self.closed:
                return
            self._metadata.append((name, record))
            assert self._file is not None
            self._file.add_metadata(name, record)

    def on_raw(self, direction: str, data: bytes, t_ns: int) -> None:
        """Bytes exactly as read ("in") from or sent ("out") to the autopilot link."""
        if self.deferred:
            self._queue.append((self._on_raw_now, (direction, data, t_ns)))
            return
        self._on_raw_now(direction, data, t_ns)

    def _on_raw_now(self, direction: str, data: bytes, t_ns: int) -> None:
        if direction not in ("in", "out"):
            raise ValueError(f"raw direction must be 'in' or 'out', got {direction!r}")
        if not data:
            return
        topic = RAW_IN_TOPIC if direction == "in" else RAW_OUT_TOPIC
        self._write(topic, S.RAW_SCHEMA, S.raw_json(direction, bytes(data)), t_ns)

    def on_message(self, msg: Any, t_ns: int) -> None:
        """A decoded, accepted input message on `/mavlink/<sys>/<comp>/<MSG>`."""
        if self.deferred:
            self._queue.append((self._on_message_now, (msg, t_ns)))
            return
        self._on_message_now(msg, t_ns)

    def _on_message_now(self, msg: Any, t_ns: int) -> None:
        cls = type(msg)
        self._write(S.mavlink_topic(msg), lambda: S.mavlink_schema(cls), S.mavlink_message_json(msg), t_ns)

    def on_estimate(self, frame_time_s: float, out: StepOutput, latency_s: float, t_ns: int) -> None:
        """One filter step, flattened (see `schemas.estimate_field_names`)."""
        if self.deferred:   # snapshot the numbers now (~15 us): the filter may reuse its arrays
            obj = S.estimate_json(frame_time_s, out, latency_s)
            self._queue.append((self._on_estimate_now, (frame_time_s, out, latency_s, t_ns, obj)))
            return
        self._on_estimate_now(frame_time_s, out, latency_s, t_ns)

    def _on_estimate_now(self, frame_time_s: float, out: StepOutput, latency_s: float, t_ns: int,
                         obj: dict[str, Any] | None = None) -> None:
        n = int(np.asarray(out.x_mean).size)
        layout = (tuple(out.fault_ids), n, S.is_adaptive(out), S.is_typed(out))
        with self._lock:
            if self._estimate_layout is None:
                self._estimate_layout = layout
                self._state_names = S.state_names(layout[0], n)
            elif layout != self._estimate_layout:
                raise ValueError(f"estimate layout changed mid-recording: {layout} != "
                                 f"{self._estimate_layout}")
        def schema() -> dict[str, Any]:
            return S.estimate_schema(layout[0], n, adaptive=layout[2], typed=layout[3])

        if obj is None:
            obj = S.estimate_json(frame_time_s, out, latency_s)
        self._write(ESTIMATE_TOPIC, schema, obj, t_ns)

    def on_items(self, frame_time_s: float, report: ItemReport, t_ns: int) -> None:
        """One frame's monitored items on `/fdir/items` (see `schemas.items_field_names`)."""
        obj = S.items_json(frame_time_s, report)
        if self.deferred:
            self._queue.append((self._write, (ITEMS_TOPIC, lambda: S.items_schema(report.names), obj, t_ns)))
            return
        self._write(ITEMS_TOPIC, lambda: S.items_schema(report.names), obj, t_ns)

    def on_event(self, level: str, text: str, t_ns: int) -> None:
        """An event on the `foxglove.Log` topic (level "info" | "warning" | "error")."""
        if self.deferred:
            self._queue.append((self._on_event_now, (level, text, t_ns)))
            return
        self._on_event_now(level, text, t_ns)

    def _on_event_now(self, level: str, text: str, t_ns: int) -> None:
        self._write(LOG_TOPIC, S.FOXGLOVE_LOG_SCHEMA, S.log_json(level, text, t_ns), t_ns)

    def on_particles(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray, t_ns: int) -> None:
        """The top particles (k, n) and weights (k,) of one frame."""
        if self.deferred:
            states, weights = np.array(states, dtype=float), np.array(weights, dtype=float)   # copies
            self._queue.append((self._on_particles_now, (frame_time_s, states, weights, t_ns)))
            return
        self._on_particles_now(frame_time_s, states, weights, t_ns)

    def _on_particles_now(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray,
                          t_ns: int) -> None:
        states = np.atleast_2d(np.asarray(states, dtype=float))
        names = self._state_names or [f"s{i}" for i in range(states.shape[1])]
        if len(names) != states.shape[1]:
            names = [f"s{i}" for i in range(states.shape[1])]
        obj = S.particles_json(frame_time_s, states, weights, names)
        self._write(PARTICLES_TOPIC, S.PARTICLES_SCHEMA, obj, t_ns)

    # ------------------------------------------------------------------ lifecycle
    def flush(self) -> None:
        """Close the chunk in progress now (the recorder also does this every second of log time)."""
        with self._lock:
            self._drain_locked()
            if not self.closed and self._file is not None:
                self._file.flush()

    def close(self) -> None:
        """Finalise the current segment (summary and footer). Idempotent."""
        with self._lock:
            if self.closed:
                return
            self._drain_locked()
            self.closed = True
            if self._file is not None:
                self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
