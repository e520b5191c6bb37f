"""Offline replay of a recorded flight through the same processing core as `fdir run`.

The recorded raw input bytes (`/mavlink/raw/in`, exactly as read from the autopilot link) are fed,
with their recorded log times, into a fresh `fdir_service.pipeline.Pipeline` rebuilt from the
recorded "config" metadata. With the recorded filter, particle count and seed the estimates are
bit-identical to the flight's on every `/fdir/estimate` field except the wall-clock `latency_s`;
with another filter the replay is a comparison. With the simulator's truth (`/sim/truth`) both
runs are scored (SPEC section 8): RMSE of the fault and state estimates, detection delay (first
step after onset with P(fault) > 0.5 held 0.25 s), false-alarm and missed-detection time fractions.
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
from fdir_service.metrics import (
    HOLD_S,
    P_THRESHOLD,
    episode_delays,
    false_alarm_fraction,
    hold_steps_of,
    missed_fraction,
    rmse,
)
from fdir_service.metrics import TABLE_TIMES as REPORT_TIMES
from fdir_service.metrics import finite_or_none as _num
from fdir_service.recording import schemas as S
from fdir_service.recording.logtools import McapLog
from fdir_service.recording.recorder import ESTIMATE_TOPIC, RAW_IN_TOPIC, Recorder
from fdir_service.recording.truth import TRUTH_TOPIC

NON_DETERMINISTIC_FIELDS = ("latency_s",)
"""`/fdir/estimate` fields excluded from the bit-identity check (wall-clock processing time)."""

# HOLD_S, P_THRESHOLD, REPORT_TIMES and the metric functions: fdir_service.metrics (SPEC section 8)

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


def truth_records(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The `/sim/truth` records of a truth MCAP, in order."""
    return [obj for _, obj in McapLog(path).iter_json(TRUTH_TOPIC)]


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


def align_to_truth(t_est: np.ndarray, t_truth: np.ndarray, tol_s: float) -> tuple[np.ndarray, np.ndarray]:
    """For each estimate time the index of the nearest truth record, and whether it is within tol_s."""
    order = np.argsort(t_truth, kind="stable")
    ts = t_truth[order]
    j = np.clip(np.searchsorted(ts, t_est), 1, max(len(ts) - 1, 1))
    lo = np.clip(j - 1, 0, len(ts) - 1)
    hi = np.clip(j, 0, len(ts) - 1)
    pick = np.where(np.abs(ts[lo] - t_est) <= np.abs(ts[hi] - t_est), lo, hi)
    ok = np.abs(ts[pick] - t_est) <= tol_s
    return order[pick], ok


def score(est: Sequence[dict[str, Any]], truth: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """SPEC section 8 metrics of one run against the simulator truth.

    Per fault j: `rmse` = sqrt(time-mean of (f_hat - f)^2) (SI units of the fault), |error| at the
    thesis's report times, `delay_s` per fault episode (onset -> first step inside the episode with
    P(fault) > 0.5 held 0.25 s; None if never), `false_alarm_fraction` (fault-free steps with
    P > 0.5) and `missed_fraction` (faulty steps with P <= 0.5). Per airframe state: RMSE (SI; theta
    and q also in deg, deg/s). Frames are matched to truth by time (nearest, within half a frame).
    """
    e = as_arrays(est)
    tr = as_arrays(truth)
    if not e or not tr:
        raise ReplayError("score: no estimates or no truth records")
    t = e["frame_time_s"]
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.05
    idx, ok = align_to_truth(t, tr["t"], tol_s=0.5 * dt + 1e-9)
    t = t[ok]
    hold_steps = hold_steps_of(dt, HOLD_S)
    out: dict[str, Any] = {"frames": int(ok.sum()), "frames_unmatched": int((~ok).sum()), "faults": {},
                           "states": {}}
    for fid in fault_ids_of(est[0]):
        if f"f_{fid}" not in tr:
            continue
        f_true = tr[f"f_{fid}"][idx][ok]
        active = (tr[f"active_{fid}"][idx][ok] > 0.5) if f"active_{fid}" in tr else f_true != 0.0
        f_hat = e[f"f_{fid}"][ok]
        p = e[f"pf_{fid}"][ok]
        err = f_hat - f_true
        episodes = [{"onset_s": float(t[s]), "end_s": float(t[end - 1]), "delay_s": d}
                    for s, end, d in episode_delays(t, p, active, hold_steps, P_THRESHOLD)]
        at = {f"{x:.2f}": _num(abs(err[int(np.argmin(np.abs(t - x)))])) for x in REPORT_TIMES
              if t.size and t[0] - dt <= x <= t[-1] + dt}
        out["faults"][fid] = {
            "rmse": _num(rmse(f_hat, f_true)),
            "abs_error_at": at,
            "episodes": episodes,
            "delay_s": episodes[0]["delay_s"] if episodes else None,
            "false_alarm_fraction": false_alarm_fraction(p, active, P_THRESHOLD),
            "missed_fraction": missed_fraction(p, active, P_THRESHOLD),
        }
    for s in S.STATE_NAMES:
        if f"x_{s}" in e and s in tr:
            r = _num(rmse(e[f"x_{s}"][ok], tr[s][idx][ok]))
            out["states"][s] = {"rmse": r}
            if s in ("theta", "q") and r is not None:
                out["states"][s]["rmse_deg"] = math.degrees(r)
    return out


def estimate_differences(a: Sequence[dict[str, Any]], b: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Recorded vs replayed (another filter): RMS and max |difference| of the shared numeric fields."""
    ea, eb = as_arrays(a), as_arrays(b)
    n = min(len(a), len(b))
    out: dict[str, Any] = {}
    for k in ea:
        if k in eb and k not in ("frame_time_s", *NON_DETERMINISTIC_FIELDS) and k != "resampled":
            d = ea[k][:n] - eb[k][:n]
            out[k] = {"rms": _num(np.sqrt(np.nanmean(d ** 2))) if n else None,
                      "max_abs": _num(np.nanmax(np.abs(d))) if n and np.isfinite(d).any() else None}
    return out


# ------------------------------------------------------------------------------ replay

class _EstimateCollector:
    """A PipelineObserver that keeps the flattened estimates of a replay."""

    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []

    def on_metadata(self, name: str, data: dict[str, str]) -> None:
        pass

    def on_raw(self, direction: str, data: bytes, t_ns: int) -> None:
        pass

    def on_message(self, msg: Any, t_ns: int) -> None:
        pass

    def on_estimate(self, frame_time_s: float, out: StepOutput, latency_s: float, t_ns: int) -> None:
        self.records.append(S.estimate_json(frame_time_s, out, latency_s))

    def on_event(self, level: str, text: str, t_ns: int) -> None:
        pass

    def on_particles(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray, t_ns: int) -> None:
        pass


@dataclass
class ReplayResult:
    """What `replay` did. identity: against the recorded estimates (meaningful when same_setup);
    differences: recorded vs replayed when the setup differs; metrics: {"recorded": ..., "replayed":
    ...} with truth; speed: log duration / wall time of the replay."""

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
    metrics: dict[str, Any] | None = None
    out_paths: list[Path] = field(default_factory=list)
    report_files: list[Path] = field(default_factory=list)
    truth: list[dict[str, Any]] | None = None

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
    kw = {} if filter_factory is None else {"filter_factory": filter_factory}
    return Pipeline(config, filter_name=filter_name, particles=particles, seed=seed, observers=observers,
                    **kw)


def replay(log_path: str | os.PathLike[str], *, filter_name: str | None = None, particles: int | None = None,
           seed: int | None = None, truth: str | os.PathLike[str] | None = None,
           out: str | os.PathLike[str] | None = None, report_dir: str | os.PathLike[str] | None = None,
           observers: Sequence[Any] = (), filter_factory: Any = None) -> ReplayResult:
    """Feed a log's recorded input through a fresh pipeline; compare, score and report.

    filter_name / particles / seed: override the recorded ones (None: as recorded); truth: a
    `/sim/truth` MCAP from `sim-bridge fly --record`; out: record the replay (same topics as a
    flight); report_dir: write summary.json, report.md and figures there; observers: extra
    PipelineObservers; filter_factory: passed to the Pipeline (tests).
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
        out_paths=list(recorder.paths) if recorder is not None else [])
    if not same:
        result.differences = estimate_differences(recorded, replayed)
    if truth is not None:
        tr = truth_records(truth)
        result.metrics = {"replayed": score(replayed, tr)}
        if recorded:
            result.metrics["recorded"] = score(recorded, tr)
        result.truth = tr
    if report_dir is not None:
        result.report_files = write_report(result, Path(report_dir))
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
        "metrics": result.metrics,
        "out": [str(p) for p in result.out_paths],
    }


def summary_json(result: ReplayResult) -> str:
    return json.dumps(summary(result), indent=2)


# ------------------------------------------------------------------------------ report

_STATE_LABELS = {"p_d": ("altitude h", "m", -1.0), "u": ("u", "m/s", 1.0), "w": ("w", "m/s", 1.0),
                 "theta": ("pitch theta", "deg", math.degrees(1.0)), "q": ("pitch rate q", "deg/s",
                                                                         math.degrees(1.0))}


def write_report(result: ReplayResult, report_dir: Path) -> list[Path]:
    """summary.json, report.md and the figures (faults.png: estimates and P(fault) against the
    truth; states.png: airframe states) of a replay. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report_dir.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    rec, rep = as_arrays(result.recorded), as_arrays(result.replayed)
    tr = as_arrays(result.truth) if result.truth else {}
    rec_label = f"recorded ({result.recorded_setup.get('filter')})"
    rep_label = f"replayed ({result.filter}, N={result.particles}, seed {result.seed})"
    faults = fault_ids_of(result.replayed[0]) if result.replayed else []

    if faults:
        fig, axes = plt.subplots(2, len(faults), figsize=(5.5 * len(faults), 6), squeeze=False, sharex=True)
        for j, fid in enumerate(faults):
            ax, axp = axes[0, j], axes[1, j]
            if tr and f"f_{fid}" in tr:
                ax.plot(tr["t"], tr[f"f_{fid}"], "k-", lw=2, label="truth")
            if rec:
                ax.plot(rec["frame_time_s"], rec[f"f_{fid}"], "C0-", lw=1, label=rec_label)
                axp.plot(rec["frame_time_s"], rec[f"pf_{fid}"], "C0-", lw=1, label=rec_label)
            if not result.same_setup or not rec:
                ax.plot(rep["frame_time_s"], rep[f"f_{fid}"], "C3--", lw=1, label=rep_label)
                axp.plot(rep["frame_time_s"], rep[f"pf_{fid}"], "C3--", lw=1, label=rep_label)
            axp.axhline(P_THRESHOLD, color="0.6", lw=0.8, ls=":")
            ax.set_title(f"fault {fid}")
            ax.set_ylabel("estimate (SI)")
            axp.set_ylabel("P(fault)")
            axp.set_ylim(-0.05, 1.05)
            axp.set_xlabel("frame time (s)")
            ax.grid(alpha=0.3)
            axp.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=8)
        fig.tight_layout()
        p = report_dir / "faults.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        files.append(p)

    fig, axes = plt.subplots(len(_STATE_LABELS), 1, figsize=(9, 10), sharex=True)
    for ax, (s, (label, unit, k)) in zip(axes, _STATE_LABELS.items(), strict=True):
        if tr and s in tr:
            ax.plot(tr["t"], k * tr[s], "k-", lw=1.5, label="truth")
        if rec:
            ax.plot(rec["frame_time_s"], k * rec[f"x_{s}"], "C0-", lw=1, label=rec_label)
        if not result.same_setup or not rec:
            ax.plot(rep["frame_time_s"], k * rep[f"x_{s}"], "C3--", lw=1, label=rep_label)
        ax.set_ylabel(f"{label} ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("frame time (s)")
    fig.tight_layout()
    p = report_dir / "states.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    files.append(p)

    p = report_dir / "summary.json"
    p.write_text(summary_json(result))
    files.append(p)
    p = report_dir / "report.md"
    p.write_text(report_markdown(result))
    files.append(p)
    return files


def _fmt(v: Any, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)


def report_markdown(result: ReplayResult) -> str:
    """A short human-readable replay report."""
    lines = [f"# Replay of {result.log.name}", ""]
    lines.append(f"- recorded: filter {result.recorded_setup.get('filter')}, N = "
                 f"{result.recorded_setup.get('particles')}, seed {result.recorded_setup.get('seed')}")
    lines.append(f"- replayed: filter {result.filter}, N = {result.particles}, seed {result.seed}")
    lines.append(f"- {result.frames} frames, {result.log_duration_s:.2f} s of log in {result.wall_s:.2f} s "
                 f"({result.speed:.0f}x real time)")
    if result.same_setup:
        lines.append(f"- same setup as the flight: {result.identity.describe()}")
    lines.append("")
    if result.metrics:
        lines += ["## Fault metrics (SPEC section 8)", "",
                  "| run | fault | RMSE | delay (s) | false-alarm fraction | missed fraction |",
                  "|---|---|---|---|---|---|"]
        for run, m in result.metrics.items():
            for fid, fm in m["faults"].items():
                delays = ", ".join(_fmt(e["delay_s"], ".2f") for e in fm["episodes"]) or "-"
                lines.append(f"| {run} | {fid} | {_fmt(fm['rmse'])} | {delays} | "
                             f"{_fmt(fm['false_alarm_fraction'])} | {_fmt(fm['missed_fraction'])} |")
        lines += ["", "## State RMSE", "", "| run | " + " | ".join(S.STATE_NAMES) + " |",
                  "|---|" + "---|" * len(S.STATE_NAMES)]
        for run, m in result.metrics.items():
            cells = []
            for s in S.STATE_NAMES:
                st = m["states"].get(s, {})
                unit = " deg" if "rmse_deg" in st else ""
                cells.append(_fmt(st.get("rmse_deg", st.get("rmse")), ".4f") + unit)
            lines.append(f"| {run} | " + " | ".join(cells) + " |")
        lines.append("")
    if result.differences:
        lines += ["## Recorded vs replayed estimates", "",
                  "| field | RMS diff | max abs diff |", "|---|---|---|"]
        for k, d in result.differences.items():
            if k.startswith(("f_", "pf_", "pfa_", "pmd_")):
                lines.append(f"| {k} | {_fmt(d['rms'], '.4g')} | {_fmt(d['max_abs'], '.4g')} |")
        lines.append("")
    lines += ["Figures: faults.png (fault estimates and P(fault) vs truth), "
              "states.png (airframe states).", ""]
    return "\n".join(lines)
