"""Scoring a replay against the simulator's truth, and its report (`sim-bridge replay`).

`replay_and_score(log, truth=...)` runs `fdir_service.replay.replay` (the flying package's replay:
same pipeline, bit-identical with the recorded setup) and scores the recorded and the replayed
estimates against a `/sim/truth` MCAP from `sim-bridge fly --record` (SPEC section 8): RMSE of the
fault and state estimates, detection delay (first step after onset with P(fault) > 0.5 held 0.25 s),
false-alarm and missed-detection time fractions. `write_report` draws the estimates against the
truth (faults.png, states.png) and writes summary.json and report.md.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.recording import schemas as S
from fdir_service.recording.schemas import finite_or_none
from fdir_service.replay import ReplayResult, as_arrays, fault_ids_of, item_summary, replay, summary
from fdir_service.runtime.items import TYPE_NAMES
from sim_bridge.metrics import (
    HOLD_S,
    P_THRESHOLD,
    TABLE_TIMES,
    episode_delays,
    false_alarm_fraction,
    hold_steps_of,
    missed_fraction,
    rmse,
)
from sim_bridge.truth_log import truth_records


@dataclass
class ScoredReplay:
    """A replay with its scores: metrics {"replayed": ..., "recorded": ...} (each `score`'s output)
    when a truth was given, the truth records, and the report files written."""

    result: ReplayResult
    metrics: dict[str, Any] | None = None
    truth: list[dict[str, Any]] | None = None
    report_files: list[Path] = field(default_factory=list)


def replay_and_score(log: str | os.PathLike[str], *, truth: str | os.PathLike[str] | None = None,
                     report_dir: str | os.PathLike[str] | None = None, **replay_kw: Any) -> ScoredReplay:
    """`fdir_service.replay.replay(log, **replay_kw)`, scored against `truth` (a `/sim/truth` MCAP)
    when given; report_dir: write summary.json, report.md and the figures there."""
    scored = ScoredReplay(replay(log, **replay_kw))
    if truth is not None:
        tr = truth_records(truth)
        scored.truth = tr
        scored.metrics = {"replayed": score(scored.result.replayed, tr)}
        if scored.result.recorded:
            scored.metrics["recorded"] = score(scored.result.recorded, tr)
    if report_dir is not None:
        scored.report_files = write_report(scored, Path(report_dir))
    return scored


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


def _entry_type(record: dict[str, Any], fid: str) -> str:
    """A fault entry's type from an estimate record (`ft_<id>`; "bias" in a record without it)."""
    return TYPE_NAMES.get(int(record.get(f"ft_{fid}") or 0), "bias")


def score(est: Sequence[dict[str, Any]], truth: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """SPEC section 8 metrics of one run against the simulator truth.

    Per fault j: its `type` (bias, stuck, ...; `ft_<id>`), `rmse` = sqrt(time-mean of (f_hat - f)^2)
    (SI units of the fault), |error| at the thesis's report times, `delay_s` per fault episode
    (onset -> first step inside the episode with P(fault) > 0.5 held 0.25 s; None if never),
    `false_alarm_fraction` (fault-free steps with P > 0.5) and `missed_fraction` (faulty steps
    with P <= 0.5). Per airframe state: RMSE (SI; theta and q also in deg, deg/s). Frames are
    matched to truth by time (nearest, within half a frame).
    """
    e = as_arrays(est)
    tr = as_arrays(truth)
    if not e or not tr:
        raise ValueError("score: no estimates or no truth records")
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
        at = {f"{x:.2f}": finite_or_none(abs(err[int(np.argmin(np.abs(t - x)))])) for x in TABLE_TIMES
              if t.size and t[0] - dt <= x <= t[-1] + dt}
        out["faults"][fid] = {
            "type": _entry_type(est[0], fid),
            "rmse": finite_or_none(rmse(f_hat, f_true)),
            "abs_error_at": at,
            "episodes": episodes,
            "delay_s": episodes[0]["delay_s"] if episodes else None,
            "false_alarm_fraction": false_alarm_fraction(p, active, P_THRESHOLD),
            "missed_fraction": missed_fraction(p, active, P_THRESHOLD),
        }
    for s in S.STATE_NAMES:
        if f"x_{s}" in e and s in tr:
            r = finite_or_none(rmse(e[f"x_{s}"][ok], tr[s][idx][ok]))
            out["states"][s] = {"rmse": r}
            if s in ("theta", "q") and r is not None:
                out["states"][s]["rmse_deg"] = math.degrees(r)
    return out




_STATE_LABELS = {"p_d": ("altitude h", "m", -1.0), "u": ("u", "m/s", 1.0), "w": ("w", "m/s", 1.0),
                 "theta": ("pitch theta", "deg", math.degrees(1.0)), "q": ("pitch rate q", "deg/s",
                                                                         math.degrees(1.0))}


@dataclass
class _Series:
    """What one figure draws: recorded, replayed (or {}) and truth (or {}) field arrays, labels."""

    rec: dict[str, np.ndarray]
    rep: dict[str, np.ndarray]
    truth: dict[str, np.ndarray]
    rec_label: str
    rep_label: str

    @classmethod
    def of(cls, scored: ScoredReplay) -> _Series:
        r = scored.result
        rep = as_arrays(r.replayed) if (not r.same_setup or not r.recorded) else {}
        return cls(as_arrays(r.recorded), rep, as_arrays(scored.truth) if scored.truth else {},
                   f"recorded ({r.recorded_setup.get('filter')})",
                   f"replayed ({r.filter}, N={r.particles}, seed {r.seed})")

    def plot(self, ax, field: str, truth_field: str, k: float = 1.0) -> None:
        """truth (black), recorded (C0) and replayed (C3 dashed) of one field on ax, times k."""
        if truth_field in self.truth:
            ax.plot(self.truth["t"], k * self.truth[truth_field], "k-", lw=1.5, label="truth")
        if field in self.rec:
            ax.plot(self.rec["frame_time_s"], k * self.rec[field], "C0-", lw=1, label=self.rec_label)
        if field in self.rep:
            ax.plot(self.rep["frame_time_s"], k * self.rep[field], "C3--", lw=1, label=self.rep_label)


def _fault_figure(plt, series: _Series, faults: list[str], path: Path) -> Path:
    """faults.png: per fault, its estimate (top) and P(fault) (bottom) against the truth."""
    fig, axes = plt.subplots(2, len(faults), figsize=(5.5 * len(faults), 6), squeeze=False, sharex=True)
    for j, fid in enumerate(faults):
        ax, axp = axes[0, j], axes[1, j]
        series.plot(ax, f"f_{fid}", f"f_{fid}")
        series.plot(axp, f"pf_{fid}", "")
        axp.axhline(P_THRESHOLD, color="0.6", lw=0.8, ls=":")
        ax.set(title=f"fault {fid}", ylabel="estimate (SI)")
        axp.set(ylabel="P(fault)", ylim=(-0.05, 1.05), xlabel="frame time (s)")
        ax.grid(alpha=0.3)
        axp.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    return _save(plt, fig, path)


def _state_figure(plt, series: _Series, path: Path) -> Path:
    """states.png: the airframe states against the truth."""
    fig, axes = plt.subplots(len(_STATE_LABELS), 1, figsize=(9, 10), sharex=True)
    for ax, (s, (label, unit, k)) in zip(axes, _STATE_LABELS.items(), strict=True):
        series.plot(ax, f"x_{s}", s, k)
        ax.set_ylabel(f"{label} ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("frame time (s)")
    return _save(plt, fig, path)


def _save(plt, fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(scored: ScoredReplay, report_dir: Path) -> list[Path]:
    """summary.json, report.md and the figures (faults.png: estimates and P(fault) against the
    truth; states.png: airframe states) of a scored replay. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report_dir.mkdir(parents=True, exist_ok=True)
    r = scored.result
    series = _Series.of(scored)
    faults = fault_ids_of(r.replayed[0]) if r.replayed else []
    files = [_fault_figure(plt, series, faults, report_dir / "faults.png")] if faults else []
    files.append(_state_figure(plt, series, report_dir / "states.png"))
    p = report_dir / "summary.json"
    p.write_text(json.dumps({**summary(r), "metrics": scored.metrics}, indent=2))
    files.append(p)
    p = report_dir / "report.md"
    p.write_text(report_markdown(scored))
    files.append(p)
    return files


def _fmt(v: Any, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)


def _metrics_markdown(metrics: dict[str, Any]) -> list[str]:
    lines = ["## Fault metrics (SPEC section 8)", "",
             "| run | fault | type | RMSE | delay (s) | false-alarm fraction | missed fraction |",
             "|---|---|---|---|---|---|---|"]
    for run, m in metrics.items():
        for fid, fm in m["faults"].items():
            delays = ", ".join(_fmt(e["delay_s"], ".2f") for e in fm["episodes"]) or "-"
            lines.append(f"| {run} | {fid} | {fm.get('type', 'bias')} | {_fmt(fm['rmse'])} | {delays} | "
                         f"{_fmt(fm['false_alarm_fraction'])} | {_fmt(fm['missed_fraction'])} |")
    lines += ["", "## State RMSE", "", "| run | " + " | ".join(S.STATE_NAMES) + " |",
              "|---|" + "---|" * len(S.STATE_NAMES)]
    for run, m in metrics.items():
        cells = []
        for s in S.STATE_NAMES:
            st = m["states"].get(s, {})
            unit = " deg" if "rmse_deg" in st else ""
            cells.append(_fmt(st.get("rmse_deg", st.get("rmse")), ".4f") + unit)
        lines.append(f"| {run} | " + " | ".join(cells) + " |")
    return lines + [""]


def _differences_markdown(differences: dict[str, Any]) -> list[str]:
    lines = ["## Recorded vs replayed estimates", "", "| field | RMS diff | max abs diff |", "|---|---|---|"]
    for k, d in differences.items():
        if k.startswith(("f_", "pf_", "pfa_", "pmd_")):
            lines.append(f"| {k} | {_fmt(d['rms'], '.4g')} | {_fmt(d['max_abs'], '.4g')} |")
    return lines + [""]


def _items_markdown(r: ReplayResult) -> list[str]:
    """The monitored items' types (estimators with typed faults; nothing otherwise)."""
    if not r.replayed_items:
        return []
    lines = ["## Monitored items", "", "| item | type | declared fraction | max P |", "|---|---|---|---|"]
    for name, s in item_summary(r.replayed_items).items():
        lines.append(f"| {name} | {s['type']} | {_fmt(s['declared_fraction'], '.2f')} | "
                     f"{_fmt(s['p_max'], '.2f')} |")
    return lines + [""]


def report_markdown(scored: ScoredReplay) -> str:
    """A short human-readable replay report."""
    r = scored.result
    setup = r.recorded_setup
    lines = [f"# Replay of {r.log.name}", "",
             f"- recorded: filter {setup.get('filter')}, N = {setup.get('particles')}, "
             f"seed {setup.get('seed')}",
             f"- replayed: filter {r.filter}, N = {r.particles}, seed {r.seed}",
             f"- {r.frames} frames, {r.log_duration_s:.2f} s of log in {r.wall_s:.2f} s "
             f"({r.speed:.0f}x real time)"]
    if r.same_setup:
        lines.append(f"- same setup as the flight: {r.identity.describe()}")
    lines.append("")
    if scored.metrics:
        lines += _metrics_markdown(scored.metrics)
    if r.differences:
        lines += _differences_markdown(r.differences)
    lines += _items_markdown(r)
    lines += ["Figures: faults.png (fault estimates and P(fault) vs truth), "
              "states.png (airframe states).", ""]
    return "\n".join(lines)
