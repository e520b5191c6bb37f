"""The combined report of a family of experiments that are not the thesis's (e.g. `real`): how they
were run, the safety yardstick of every world side by side, then each experiment's own report."""

from __future__ import annotations

import json
import re
from pathlib import Path

from sim_bridge.report import _fmt, while_active
from sim_bridge.yardstick import rate_upper_bound

FAULT_COLUMNS = ("f_theta", "f_q")
"""Fault RMSE columns of the summary (the faults the real family injects and the monitor watches)."""


def _docs(root: Path, ids: list[str] | tuple[str, ...]) -> dict[str, dict]:
    return {sid: json.loads((root / sid / "results.json").read_text()) for sid in ids
            if (root / sid / "results.json").exists()}


def _status(docs: dict[str, dict]) -> list[str]:
    L = ["| experiment | runs | particles | seed | wall time (s) |", "|---|---|---|---|---|"]
    for sid, d in docs.items():
        L.append(f"| {sid} | {d['runs']} | {d['particles']} | {d['seed']} | "
                 f"{_fmt(d.get('wall_s'), 1)} |")
    return L + [""]


def _world(sid: str) -> str:
    return sid.removesuffix("-faultfree")


def yardstick_rows(docs: dict[str, dict]) -> list[dict]:
    """Per world and filter, the faulty and fault-free experiments pooled: false alarms over all
    fault-free hours, detection and isolation of the faulty runs, their fault RMSE."""
    rows: dict[tuple[str, str], dict] = {}
    for sid, d in docs.items():
        for name, fd in d["filters"].items():
            y = fd.get("yardstick")
            if not y:
                continue
            r = rows.setdefault((_world(sid), name), {"world": _world(sid), "filter": name,
                                                      "false_alarms": 0, "hours": 0.0, "faulty": None})
            r["false_alarms"] += y["false_alarms"]
            r["hours"] += y["fault_free_hours"]
            if y["episodes"]:
                r["faulty"] = (y, fd["rmse"])
    return list(rows.values())


def yardstick_table(docs: dict[str, dict]) -> list[str]:
    head = ("| world | filter | false alarms / flight hour | 95 % upper bound | false alarms "
            "| fault-free hours | faults declared | median delay (s) | p90 delay (s) "
            "| right fault isolated | ")
    L = [head + " | ".join(f"{c} RMSE" for c in FAULT_COLUMNS) + " |",
         "|---|---|---|---|---|---|---|---|---|---|" + "---|" * len(FAULT_COLUMNS)]
    for r in yardstick_rows(docs):
        fa_h = r["false_alarms"] / r["hours"] if r["hours"] > 0 else None
        bound = rate_upper_bound(r["false_alarms"], r["hours"])
        y, rmse = r["faulty"] if r["faulty"] else ({}, {})
        det = f"{y['detected']} / {y['episodes']}{while_active(y)}" if y else "-"
        delay = y.get("delay_s", {}) if y else {}
        L.append(f"| {r['world']} | {r['filter']} | {_fmt(fa_h, 2)} | {_fmt(bound, 2)} | "
                 f"{r['false_alarms']} | {r['hours']:.2f} | {det} | "
                 f"{_fmt(delay.get('median'), 2)} | {_fmt(delay.get('p90'), 2)} | "
                 f"{_fmt(y.get('isolation_accuracy') if y else None, 2)} | "
                 + " | ".join(_fmt(rmse.get(c, {}).get("mean")) for c in FAULT_COLUMNS) + " |")
    return L + [""]


def _embedded(root: Path, sid: str) -> list[str]:
    """One experiment's report.md, its headings one level down and its figures linked from root."""
    text = (root / sid / "report.md").read_text()
    text = re.sub(r"^(#+) ", r"#\1 ", text, flags=re.M)
    text = re.sub(r"!\[([^]]*)\]\(([^)/]+)\)", rf"![\1]({sid}/\2)", text)
    return [text, ""]


def family_markdown(root: str | Path, ids: list[str] | tuple[str, ...], title: str) -> str:
    """The family's page (root/report.md): status, the yardstick side by side, every report."""
    root = Path(root)
    docs = _docs(root, ids)
    L = [f"# {title}", "", *_status(docs), "## Safety yardstick, world by world", "",
         "Each world's faulty and fault-free experiments pooled: false alarms per fault-free flight "
         "hour by the service's own declare / clear hysteresis, the injected faults declared, their "
         "delay, the right fault isolated, the fault RMSE (deg, deg/s) of the faulty runs. Definitions: "
         "sim_bridge/yardstick.py and docs/real-world.md.", "", *yardstick_table(docs)]
    for sid in docs:
        L += _embedded(root, sid)
    return "\n".join(L)


PUBLISHED_FIGURES = ("roc.png", "fault_estimates_median.png")
"""The figures a family publishes into the docs (the others stay in the campaign folder)."""


def publish_family(root: str | Path, docs_dir: str | Path, ids: list[str] | tuple[str, ...],
                   title: str) -> Path:
    """Copy each experiment's results.json, report.md and PUBLISHED_FIGURES to docs_dir/<id>/ and
    write docs_dir/report.md (the family page, links to figures not published dropped)."""
    import shutil

    root, docs_dir = Path(root), Path(docs_dir)
    for sid in _docs(root, ids):
        dest = docs_dir / sid
        dest.mkdir(parents=True, exist_ok=True)
        for name in ("results.json", "report.md", *PUBLISHED_FIGURES):
            if (root / sid / name).exists():
                shutil.copy2(root / sid / name, dest / name)
    text = family_markdown(root, ids, title)
    kept = [line for line in text.splitlines()
            if not (m := re.match(r"!\[[^]]*\]\(([^)]+)\)", line)) or (docs_dir / m.group(1)).exists()]
    page = docs_dir / "report.md"
    page.write_text("\n".join(kept) + "\n")
    return page
