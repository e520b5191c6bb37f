"""Offline replay of a recorded flight through the same processing core as `fdir run`.

The recorded raw input bytes (`/mavlink/raw/in`, exactly as read from the autopilot link) are fed,
with their recorded log times, into a fresh `fdir_service.pipeline.Pipeline` rebuilt from the
recorded "config" metadata. With the recorded filter, particle count and seed the estimates are
bit-identical to the flight's on every `/fdir/estimate` field except the wall-clock `latency_s`;
with another filter the replay is a comparison (`estimate_differences`). An estimator with typed
faults or several entries per target also records its monitored items (`/fdir/items`); the replay
reproduces them (`ReplayResult.items_identity`) and summarises each item's type (`item_summary`).
A log without items (every older one) replays as before. Scoring against a
simulator's truth and the report figures belong to the lab: `sim-bridge replay` (sim_bridge/replay_score.py).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.recording import schemas as S
from fdir_service.recording.logtools import McapLog
from fdir_service.recording.recorder import ESTIMATE_TOPIC, ITEMS_TOPIC, RAW_IN_TOPIC, Recorder
from fdir_service.runtime.items import TYPE_NAMES, ItemReport

NON_DETERMINISTIC_FIELDS = ("latency_s",)
"""`/fdir/estimate` fields excluded from the bit-identity check (wall-clock processing time)."""

# keys of the "config" metadata record written by the pipeline (first match wins)
_SERVICE_KEYS = ("service_toml", "service", "config_toml", "config")
_LEGACY_SCENARIO_KEYS = ("scenario_toml",)
"""Logs before the estimator files: the scenario TOML the estimator was built from."""


class ReplayError(ValueError):
    """The log cannot be replayed (no recorded config or no raw input)."""


# ------------------------------------------------------------------------------ reading a log

def recorded_setup(log: McapLog) -> dict[str, Any]:
    """The flight's setup from the "config" metadata: service TOML text, the estimator document
    (`estimator_json`; from the scenario TOML of a log recorded before estimator files), filter,
    particles, seed."""
    cfg = log.metadata.get("config")
    if not cfg:
        raise ReplayError(f"{log.path}: no 'config' metadata: not a recording of `fdir run`")
    service = next((cfg[k] for k in _SERVICE_KEYS if k in cfg), None)
    if service is None:
        raise ReplayError(f"{log.path}: 'config' metadata holds no service TOML (keys: {sorted(cfg)})")
    legacy = next((cfg[k] for k in _LEGACY_SCENARIO_KEYS if k in cfg), None)
    estimator = json.loads(cfg["estimator_json"]) if cfg.get("estimator_json") else None
    out: dict[str, Any] = {"service_toml": service, "estimator_doc": estimator, "legacy_scenario": legacy}
    out["autopilot"] = cfg.get("autopilot") or "none"
    out["autopilot_profiles"] = json.loads(cfg.get("autopilot_profiles_json") or "{}")
    out["filter"] = cfg.get("filter")
    out["particles"] = int(cfg["particles"]) if cfg.get("particles") not in (None, "") else None
    out["seed"] = int(cfg["seed"]) if cfg.get("seed") not in (None, "") else None
    return out


def raw_input(log: McapLog) -> list[tuple[int, bytes]]:
    """(log time ns, bytes) of every recorded input read, in order."""
    return [(t, S.raw_bytes(obj)) for t, obj in log.iter_json(RAW_IN_TOPIC)]


def estimates(log: McapLog) -> list[dict[str, Any]]:
    """The recorded `/fdir/estimate` records, in order."""
    return [obj for _, obj in log.iter_json(ESTIMATE_TOPIC)]


def item_records(log: McapLog) -> list[dict[str, Any]]:
    """The recorded `/fdir/items` records, in order (none in a log of an all-bias estimator)."""
    return [obj for _, obj in log.iter_json(ITEMS_TOPIC)]


def item_names_of(record: dict[str, Any]) -> list[str]:
    """The item names of one `/fdir/items` record (its `type_<name>` fields)."""
    return [k[5:] for k in record if k.startswith("type_")]


def item_summary(records: Sequence[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per item of an `/fdir/items` sequence: `type`, its most frequent most probable type over the
    declared frames (over all frames when never declared); `declared_fraction` of the frames;
    `p_max`, the highest P(item faulty)."""
    out: dict[str, dict[str, Any]] = {}
    for name in item_names_of(records[0]) if records else []:
        declared = [r for r in records if r.get(f"declared_{name}")]
        codes = [r[f"type_{name}"] for r in (declared or records)]
        code = max(set(codes), key=lambda c: (codes.count(c), -c))
        ps = [r[f"p_{name}"] for r in records if r.get(f"p_{name}") is not None]
        out[name] = {"type": TYPE_NAMES.get(code, str(code)),
                     "declared_fraction": len(declared) / len(records),
                     "p_max": max(ps) if ps else None}
    return out


# ------------------------------------------------------------------------------ comparison

def deterministic(record: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in record.items() if k not in NON_DETERMINISTIC_FIELDS}


@dataclass
class Identity:
    """Bit-identity of two estimate sequences on every field but `latency_s`."""

    identical: bool
    frames_a: int
    frames_b: int
    mismatched_frames: int
    first_mismatch: tuple[int, str] | None   # (frame index, field)
    common_identical: bool = False           # the frames both have agree (a killed log's prefix)

    def describe(self) -> str:
        if self.identical:
            return f"bit-identical: {self.frames_a} estimates, every field but latency_s"
        if self.common_identical:
            return (f"bit-identical on the {min(self.frames_a, self.frames_b)} frames both have "
                    f"({self.frames_a} recorded, {self.frames_b} replayed: the recording was cut short?)")
        where = "" if self.first_mismatch is None else f"; first at frame {self.first_mismatch[0]}, " \
            f"field {self.first_mismatch[1]}"
        return (f"NOT identical: {self.frames_a} recorded vs {self.frames_b} replayed estimates, "
                f"{self.mismatched_frames} frames differ{where}")


def compare_identity(a: Sequence[dict[str, Any]], b: Sequence[dict[str, Any]]) -> Identity:
    """Compare two estimate sequences exactly (JSON floats round-trip, so == is bit equality)."""
    mismatched = 0
    first: tuple[int, str] | None = None
    for k, (ra, rb) in enumerate(zip(a, b, strict=False)):
        da, db = deterministic(ra), deterministic(rb)
        if da != db:
            mismatched += 1
            if first is None:
                diff = [f for f in da if da.get(f) != db.get(f)] or sorted(set(db) - set(da))
                first = (k, diff[0] if diff else "?")
    common = mismatched == 0 and min(len(a), len(b)) > 0
    mismatched += abs(len(a) - len(b))
    if first is None and len(a) != len(b):
        first = (min(len(a), len(b)), "<missing frame>")
    return Identity(mismatched == 0, len(a), len(b), mismatched, first, common)


def as_arrays(records: Sequence[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Field -> (K,) float array (null -> NaN) of an estimate or truth sequence."""
    if not records:
        return {}
    keys = list(records[0])
    return {k: np.array([np.nan if r.get(k) is None else float(r[k]) for r in records]) for k in keys}


def fault_ids_of(record: dict[str, Any]) -> list[str]:
    return [k[3:] for k in record if k.startswith("pf_")]


def estimate_differences(a: Sequence[dict[str, Any]], b: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Recorded vs replayed (another filter): RMS and max |difference| of the shared numeric fields."""
    ea, eb = as_arrays(a), as_arrays(b)
    n = min(len(a), len(b))
    out: dict[str, Any] = {}
    for k in ea:
        if k in eb and k not in ("frame_time_s", *NON_DETERMINISTIC_FIELDS) and k != "resampled":
            d = ea[k][:n] - eb[k][:n]
            finite = n and np.isfinite(d).any()
            out[k] = {"rms": S.finite_or_none(np.sqrt(np.nanmean(d ** 2))) if n else None,
                      "max_abs": S.finite_or_none(np.nanmax(np.abs(d))) if finite else None}
    return out


# ------------------------------------------------------------------------------ replay

class _EstimateCollector:
    """A PipelineObserver that keeps the flattened estimates of a replay."""

    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []
        self.items: list[dict[str, Any]] = []

    def on_metadata(self, name: str, data: dict[str, str]) -> None:
        pass

    def on_raw(self, direction: str, data: bytes, t_ns: int) -> None:
        pass

    def on_message(self, msg: Any, t_ns: int) -> None:
        pass

    def on_estimate(self, frame_time_s: float, out: StepOutput, latency_s: float, t_ns: int) -> None:
        self.records.append(S.estimate_json(frame_time_s, out, latency_s))

    def on_items(self, frame_time_s: float, report: ItemReport, t_ns: int) -> None:
        self.items.append(S.items_json(frame_time_s, report))

    def on_event(self, level: str, text: str, t_ns: int) -> None:
        pass

    def on_particles(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray, t_ns: int) -> None:
        pass


@dataclass
class ReplayResult:
    """What `replay` did. identity: against the recorded estimates (meaningful when same_setup);
    differences: recorded vs replayed when the setup differs; speed: log duration / wall time;
    recorded_items / replayed_items: the `/fdir/items` records (empty for an all-bias estimator)
    and items_identity their comparison."""

    log: Path
    filter: str
    particles: int
    seed: int
    recorded_setup: dict[str, Any]
    same_setup: bool
    recorded: list[dict[str, Any]]
    replayed: list[dict[str, Any]]
    identity: Identity
    frames: int
    log_duration_s: float
    wall_s: float
    differences: dict[str, Any] | None = None
    out_paths: list[Path] = field(default_factory=list)
    recorded_items: list[dict[str, Any]] = field(default_factory=list)
    replayed_items: list[dict[str, Any]] = field(default_factory=list)

    @property
    def items_identity(self) -> Identity:
        """Bit-identity of the recorded and replayed `/fdir/items` records."""
        return compare_identity(self.recorded_items, self.replayed_items)

    @property
    def speed(self) -> float:
        """How many times faster than real time the replay ran."""
        return self.log_duration_s / self.wall_s if self.wall_s > 0 else math.inf


def build_pipeline(setup: dict[str, Any], *, filter_name: str | None, particles: int | None,
                   seed: int | None, observers: Sequence[Any], filter_factory: Any = None) -> Any:
    """A fresh Pipeline from a recorded setup (overrides where given)."""
    from fdir_service.pipeline import Pipeline
    from fdir_service.service_config import ServiceConfig

    if setup.get("estimator_doc") is None and setup.get("legacy_scenario"):
        from fdir_service.recording.legacy import service_from_legacy

        doc, est = service_from_legacy(setup["service_toml"], setup["legacy_scenario"])
        config = ServiceConfig.from_document(doc, setup["service_toml"], estimator_doc=est,
                                             source="<recorded config, before estimator files>")
    else:
        config = ServiceConfig.from_toml_text(setup["service_toml"], estimator_doc=setup.get("estimator_doc"),
                                              source="<recorded config>")
    if setup.get("autopilot", "none") != "none":
        from fdir_service.autopilot_profile import select_autopilot

        config = select_autopilot(config, setup["autopilot"], setup.get("autopilot_profiles") or {})
    kw = {} if filter_factory is None else {"filter_factory": filter_factory}
    return Pipeline(config, filter_name=filter_name, particles=particles, seed=seed, observers=observers,
                    **kw)


def replay(log_path: str | os.PathLike[str], *, filter_name: str | None = None, particles: int | None = None,
           seed: int | None = None, out: str | os.PathLike[str] | None = None,
           observers: Sequence[Any] = (), filter_factory: Any = None) -> ReplayResult:
    """Feed a log's recorded input through a fresh pipeline and compare with the recorded estimates.

    filter_name / particles / seed: override the recorded ones (None: as recorded); out: record the
    replay (same topics as a flight); observers: extra PipelineObservers; filter_factory: passed to
    the Pipeline (tests).
    """
    log = McapLog(log_path)
    setup = recorded_setup(log)
    inputs = raw_input(log)
    if not inputs:
        raise ReplayError(f"{log.path}: no recorded input on {RAW_IN_TOPIC}")
    recorded = estimates(log)
    collector = _EstimateCollector()
    obs: list[Any] = [collector, *observers]
    recorder = Recorder(out) if out is not None else None
    if recorder is not None:
        obs.append(recorder)
    f_name = filter_name or setup["filter"]
    n_part = particles if particles is not None else setup["particles"]
    s = seed if seed is not None else setup["seed"]
    try:
        pipe = build_pipeline(setup, filter_name=f_name, particles=n_part, seed=s, observers=obs,
                              filter_factory=filter_factory)
        t0 = time.perf_counter()
        for t_ns, data in inputs:
            pipe.feed(data, t_ns)
        pipe.close(inputs[-1][0])
        wall = time.perf_counter() - t0
    finally:
        if recorder is not None:
            recorder.close()
    f_name = getattr(pipe, "filter_name", f_name)
    n_part = getattr(pipe, "particles", n_part)
    s = getattr(pipe, "seed", s)
    same = (f_name == (setup["filter"] or f_name) and n_part == (setup["particles"] or n_part)
            and s == (setup["seed"] if setup["seed"] is not None else s))
    replayed = collector.records
    duration = (inputs[-1][0] - inputs[0][0]) / 1e9 if len(inputs) > 1 else 0.0
    if replayed and len(replayed) > 1:
        duration = max(duration, replayed[-1]["frame_time_s"] - replayed[0]["frame_time_s"])
    result = ReplayResult(
        log=log.path, filter=str(f_name), particles=int(n_part or 0), seed=int(s or 0), recorded_setup=setup,
        same_setup=same, recorded=recorded, replayed=replayed, identity=compare_identity(recorded, replayed),
        frames=len(replayed), log_duration_s=duration, wall_s=wall,
        out_paths=list(recorder.paths) if recorder is not None else [],
        recorded_items=item_records(log), replayed_items=collector.items)
    if not same:
        result.differences = estimate_differences(recorded, replayed)
    return result


def summary(result: ReplayResult) -> dict[str, Any]:
    """A JSON-able summary of a replay (what `--report` writes to summary.json)."""
    return {
        "log": str(result.log),
        "recorded": {k: v for k, v in result.recorded_setup.items() if k in ("filter", "particles", "seed")},
        "replayed": {"filter": result.filter, "particles": result.particles, "seed": result.seed},
        "same_setup": result.same_setup,
        "identity": {"identical": result.identity.identical, "recorded_frames": result.identity.frames_a,
                     "replayed_frames": result.identity.frames_b,
                     "mismatched_frames": result.identity.mismatched_frames,
                     "first_mismatch": result.identity.first_mismatch},
        "frames": result.frames,
        "log_duration_s": result.log_duration_s,
        "wall_s": result.wall_s,
        "speed_x_realtime": result.speed,
        "differences": result.differences,
        "items": {"recorded": item_summary(result.recorded_items),
                  "replayed": item_summary(result.replayed_items),
                  "identical": result.items_identity.identical},
        "out": [str(p) for p in result.out_paths],
    }


def summary_json(result: ReplayResult) -> str:
    return json.dumps(summary(result), indent=2)
