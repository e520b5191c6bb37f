"""`fdir import`: a ground station's telemetry log (`.tlog`) -> a recording `fdir replay` accepts.

A PX4 ULog (`.ulg`) or ArduPilot DataFlash log (`.bin`) is first translated into the MAVLink
messages the autopilot would have streamed (ulog.py, dataflash.py) and then imported the same way.

The autopilot's messages (`tlog.AutopilotMessages`), as MAVLink 2 bytes, are fed with their tlog
receive times through the service's own `Pipeline` built exactly as `fdir run --autopilot ...`
builds it, with the flight `Recorder` as observer. The MCAP written is therefore what a live
`fdir run` next to that autopilot would have recorded: `/mavlink/raw/in` (the bytes, log time =
the tlog time), the decoded messages, `/fdir/estimate`, `/fdir/log`, and the "config" metadata
(service TOML, estimator, autopilot profile). `fdir replay OUT.mcap` reproduces the estimates
bit for bit; `--filter` etc. compare filters on the real log.

Besides the recording, `ImportResult` says what the log held: its duration, messages by type,
the autopilot's PARAM_VALUE messages and the servo parameters they set, and for every estimator
row how many frames had it (`RowRate`) over the stretch where the autopilot streamed it.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.log_translate import TranslatedReader
from fdir_service.runtime.events import Event, FaultCleared, FaultDeclared
from fdir_service.tlog import AutopilotMessages, ReadStats, TlogReader


@dataclass
class RowRate:
    """Frames that carried row `name` over the stretch from the first to the last frame that had it:
    `frames_with` of `expected` (frames stepped in that stretch, the filled-in gaps included)."""

    name: str
    frames_with: int
    expected: int
    rate_hz: float

    @property
    def fraction(self) -> float:
        return self.frames_with / self.expected if self.expected else 0.0


@dataclass
class ImportResult:
    """What `import_tlog` read and wrote. Times in s; `declarations`: the FaultDeclared events."""

    tlog: Path
    out_paths: list[Path]
    read: ReadStats
    autopilot: tuple[int, int] | None
    autopilot_type: int | None
    others: Counter[tuple[int, int]]
    fed: Counter[str]
    duration_s: float
    frames: int
    rows: list[RowRate]
    param_values: int
    parameters_set: dict[str, float]
    declarations: list[FaultDeclared]
    clearances: list[FaultCleared]
    rejected: dict[str, int]
    estimates_finite: bool
    inputs: dict[str, str]


class _FrameTap:
    """Wraps the pipeline's filters to see each frame handed to them: (time s, mask (m,)); a frame
    stepped twice (re-initialised) keeps its last mask. The estimates are the filter's own."""

    def __init__(self) -> None:
        self.masks: dict[float, np.ndarray] = {}

    def factory(self, name: str, estimator: Any, rng: np.random.Generator, particles: int | None,
                x0: np.ndarray | None = None) -> Any:
        from fdir_service.estimation.factory import build_filter

        return _TappedFilter(build_filter(name, estimator, rng, particles=particles, x0=x0), self.masks)


class _TappedFilter:
    def __init__(self, inner: Any, masks: dict[float, np.ndarray]) -> None:
        self._inner = inner
        self._masks = masks

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> Any:
        self._masks[float(t)] = np.array(mask, dtype=bool)
        return self._inner.step(t, y, mask, u)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class _Watch:
    """A PipelineObserver keeping the declarations and whether every estimate was finite."""

    def __init__(self) -> None:
        self.events: list[Event] = []
        self.finite = True

    def on_metadata(self, name: str, data: dict[str, str]) -> None: ...
    def on_raw(self, direction: str, data: bytes, t_ns: int) -> None: ...
    def on_message(self, msg: Any, t_ns: int) -> None: ...
    def on_event(self, level: str, text: str, t_ns: int) -> None: ...
    def on_particles(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray,
                     t_ns: int) -> None: ...

    def on_estimate(self, frame_time_s: float, out: Any, latency_s: float, t_ns: int) -> None:
        self.finite = self.finite and bool(np.all(np.isfinite(out.x_mean)))

    def on_runtime_event(self, event: Event, t_ns: int) -> None:
        if isinstance(event, FaultDeclared | FaultCleared):
            self.events.append(event)


def row_rates(names: tuple[str, ...], masks: dict[float, np.ndarray], frame_rate_hz: float) -> list[RowRate]:
    """Per row: frames with it / frames stepped between the first and the last frame with it."""
    if not masks:
        return [RowRate(n, 0, 0, 0.0) for n in names]
    times = np.array(sorted(masks))
    m = np.array([masks[t] for t in times])
    out = []
    for j, name in enumerate(names):
        idx = np.flatnonzero(m[:, j])
        if idx.size == 0:
            out.append(RowRate(name, 0, 0, 0.0))
            continue
        expected = int(idx[-1] - idx[0] + 1)
        out.append(RowRate(name, int(idx.size), expected, frame_rate_hz * idx.size / expected))
    return out


def build_config(autopilot: str, estimator: str | None, service_config: str | os.PathLike[str] | None = None):
    """The service config `fdir run --autopilot autopilot --estimator estimator` would use."""
    from fdir_service.autopilot_profile import select_autopilot
    from fdir_service.service_config import load_service_config

    return select_autopilot(load_service_config(service_config, estimator=estimator), autopilot)


def open_log(path: str | os.PathLike[str], progress: Callable[[int], None] | None = None) -> Any:
    """The reader of `path` by its suffix: .ulg (PX4 ULog, translated to MAVLink: ulog.py), .bin
    (ArduPilot DataFlash, translated: dataflash.py), anything else a tlog (`TlogReader`)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".ulg":
        from fdir_service.ulog import read_ulog

        return TranslatedReader(*read_ulog(path), progress)
    if suffix == ".bin":
        from fdir_service.dataflash import read_dataflash

        return TranslatedReader(*read_dataflash(path), progress)
    return TlogReader(path, progress=progress)


def default_autopilot(path: str | os.PathLike[str]) -> str:
    """The profile a log's format implies: px4 for a ULog, ardupilot otherwise."""
    return "px4" if Path(path).suffix.lower() == ".ulg" else "ardupilot"


def import_tlog(tlog: str | os.PathLike[str], out: str | os.PathLike[str], *, autopilot: str = "ardupilot",
                estimator: str | None = None, service_config: str | os.PathLike[str] | None = None,
                particles: int | None = None, progress: Callable[[int], None] | None = None) -> ImportResult:
    """Import `tlog` into the MCAP recording `out` (see the module doc). autopilot: a profile name,
    "auto" or a file (as `fdir run --autopilot`); estimator: as `fdir run --estimator`; particles:
    override the estimator's count; progress(bytes read) drives a progress bar."""
    from fdir_service.pipeline import Pipeline
    from fdir_service.recording.recorder import Recorder

    config = build_config(autopilot, estimator, service_config)
    tap, watch = _FrameTap(), _Watch()
    reader = open_log(tlog, progress)
    keep = AutopilotMessages()
    recorder = Recorder(out)
    fed: Counter[str] = Counter()
    span = [None, None]
    try:
        pipe = Pipeline(config, particles=particles, observers=[recorder, watch], filter_factory=tap.factory)
        for item in reader:
            for m in keep.take(item):
                pipe.feed(m.data, m.t_ns)
                fed[m.mtype] += 1
                span = [m.t_ns if span[0] is None else span[0], m.t_ns]
        keep.finish()
        pipe.close(span[1] or 0)
    finally:
        recorder.close()
    return _result(Path(tlog), recorder.paths, reader, keep, fed, span, pipe, tap, watch)


def _result(tlog: Path, paths: list[Path], reader: Any, keep: AutopilotMessages, fed: Counter[str],
            span: list[int | None], pipe: Any, tap: _FrameTap, watch: _Watch) -> ImportResult:
    cache = pipe.assembler.sources
    set_by_log = {k: v for k, v in cache.params.items() if k in cache.defaults and v != cache.defaults[k]}
    duration = (span[1] - span[0]) * 1e-9 if span[0] is not None else 0.0
    return ImportResult(
        tlog=tlog, out_paths=list(paths), read=reader.stats, autopilot=keep.sender,
        autopilot_type=keep.autopilot_type, others=keep.others, fed=fed, duration_s=duration,
        frames=pipe.frames, rows=row_rates(pipe.assembler.names, tap.masks, pipe.config.frame_rate_hz),
        param_values=fed["PARAM_VALUE"], parameters_set=set_by_log,
        declarations=[e for e in watch.events if isinstance(e, FaultDeclared)],
        clearances=[e for e in watch.events if isinstance(e, FaultCleared)],
        rejected=pipe.rejected_counts, estimates_finite=watch.finite, inputs=input_sources(pipe))


def input_sources(pipe: Any) -> dict[str, str]:
    """Per input channel (delta_e, delta_t): where it came from at the end of the log: the servo
    channel of its SERVOn_FUNCTION, or why not (then the trim input is held)."""
    cache = pipe.assembler.sources
    out = {}
    for fm in pipe.config.inputs:
        function = dict(fm.options).get("function")
        if function is None:
            out[fm.name] = f"{fm.message}.{fm.field}" if fm.field else f"{fm.message} ({fm.derive})"
            continue
        n = cache.servo_channel(int(function))
        out[fm.name] = (f"SERVO{n} (SERVO{n}_FUNCTION = {function:g})" if n is not None else
                        f"no channel with SERVOn_FUNCTION = {function:g}: trim input held")
    return out


# ------------------------------------------------------------------------------ the summary

def summary_lines(r: ImportResult, top: int = 10) -> list[str]:
    """The command's summary: what was read, the autopilot, messages, parameters, rows, declarations."""
    lines = [f"read {r.read.messages} packets from {r.tlog} ({r.read.file_bytes} bytes)"]
    if r.read.mavlink1:
        lines.append(f"  {r.read.mavlink1} MAVLink 1 packets re-framed as MAVLink 2 "
                     "(the service reads MAVLink 2)")
    if r.read.unknown:
        lines.append(f"  {r.read.unknown} packets of message ids pymavlink does not know skipped")
    damage = r.read.damage()
    if damage:
        lines.append(damage)
    lines += _autopilot_lines(r)
    if r.autopilot is None:
        return lines
    lines.append(f"duration {r.duration_s:.1f} s (tlog time); {r.frames} frames stepped")
    lines.append(f"messages from the autopilot (top {top}): "
                 + ", ".join(f"{k} {v}" for k, v in r.fed.most_common(top)))
    lines += _parameter_lines(r)
    lines.append("estimator rows (frames with the row / frames stepped over the stretch the autopilot "
                 "sent it):")
    lines += [f"  {row.name:10s} {row.frames_with:6d} / {row.expected:6d} = {100 * row.fraction:5.1f} % "
              f"({row.rate_hz:.1f} Hz)" for row in r.rows]
    lines.append("inputs: " + "; ".join(f"{k} from {v}" for k, v in r.inputs.items()))
    lines += _declaration_lines(r)
    lines.append("written: " + ", ".join(str(p) for p in r.out_paths))
    return lines


def _autopilot_lines(r: ImportResult) -> list[str]:
    if r.autopilot is None:
        return ["no autopilot HEARTBEAT (autopilot != MAV_AUTOPILOT_INVALID from component 1) in the "
                "log: nothing was imported"]
    others = ", ".join(f"{s}/{c}: {n}" for (s, c), n in r.others.most_common(5)) or "none"
    return [f"autopilot: system {r.autopilot[0]} component {r.autopilot[1]} (HEARTBEAT autopilot "
            f"{r.autopilot_type}); other senders' messages ignored: {others}"]


def _parameter_lines(r: ImportResult) -> list[str]:
    if r.param_values == 0:
        return ["no PARAM_VALUE in the log: the profile's [parameters] (its defaults) were used "
                "for the servo channels"]
    changed = ", ".join(f"{k}={v:g}" for k, v in sorted(r.parameters_set.items())) or "none differ"
    return [f"{r.param_values} PARAM_VALUE from the autopilot; profile [parameters] they changed: {changed}"]


def _declaration_lines(r: ImportResult) -> list[str]:
    if not r.declarations:
        return ["no fault declared"]
    by_fault = Counter(e.fault_id for e in r.declarations)
    lines = ["fault declarations: " + ", ".join(f"{k} x{v}" for k, v in by_fault.most_common())]
    lines += [f"  {e.text}" for e in r.declarations[:10]]
    return lines


def result_json(r: ImportResult) -> dict[str, Any]:
    """The summary as JSON-able data (`fdir import --json`)."""
    return {
        "tlog": str(r.tlog), "out": [str(p) for p in r.out_paths],
        "read": {"packets": r.read.messages, "file_bytes": r.read.file_bytes, "bad_bytes": r.read.bad_bytes,
                 "bad_packets": r.read.bad_packets, "bad_timestamps": r.read.bad_timestamps,
                 "mavlink1": r.read.mavlink1, "stopped": r.read.stopped},
        "autopilot": r.autopilot, "others": {f"{s}/{c}": n for (s, c), n in r.others.items()},
        "duration_s": r.duration_s, "frames": r.frames, "messages": dict(r.fed),
        "param_values": r.param_values, "parameters_set": r.parameters_set,
        "rows": {row.name: {"frames_with": row.frames_with, "expected": row.expected,
                            "fraction": row.fraction, "rate_hz": row.rate_hz} for row in r.rows},
        "declarations": [{"fault": e.fault_id, "time_s": e.time_s, "p": e.p, "estimate": e.estimate}
                         for e in r.declarations],
        "inputs": r.inputs, "rejected": r.rejected, "estimates_finite": r.estimates_finite,
    }


__all__ = ["ImportResult", "RowRate", "default_autopilot", "import_tlog", "open_log", "result_json",
           "row_rates", "summary_lines"]
