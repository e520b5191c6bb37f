"""`sim-bridge experiment SCENARIO|all`: the thesis's Monte Carlo campaigns, with results.json,
report.md and figures side by side with the thesis's tables."""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

from fdir_service.errors import ConfigError
from sim_bridge.onboard_nav import NAVIGATION
from sim_bridge.scenario import FAMILIES, load_scenario


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "experiment", help="run a thesis Monte Carlo campaign and write its report",
        description="Run every filter of a scenario (plus the EKF-GATE baseline) over RUNS closed-loop "
        "Monte Carlo runs, in parallel processes or on a dask.distributed cluster, and write "
        "results.json, report.md and PNG figures beside the thesis's table.")
    p.add_argument("scenario", help="experiment id (ch4, ch5a, ch5b, ch5c, ch6, real-calm, ...), a .toml "
                   "path, or a family: 'all' / 'thesis' (the five thesis tables), 'real' (the real-sky "
                   "worlds, each faulty and fault-free: docs/real-world.md)")
    p.add_argument("--runs", type=int, default=100, help="Monte Carlo runs per filter (default 100)")
    p.add_argument("--particles", type=int, default=None,
                   help="particles per filter (default: the scenario's, 1000)")
    p.add_argument("--seed", type=int, default=0, help="campaign seed (default 0)")
    p.add_argument("--out", default=None,
                   help="output folder (default results/SCENARIO; with a family, OUT/SCENARIO)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: cores)")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="send the runs to this dask.distributed scheduler instead of local processes")
    p.add_argument("--filters", default=None,
                   help="comma-separated subset of filters (default: the scenario's plus EKF-GATE)")
    p.add_argument("--navigation", choices=NAVIGATION, default=None,
                   help="what the autopilot flies on, overriding the world's [world.autopilot] navigation: "
                   "'monitor' (the filter's own estimate, the thesis's closed loop), 'onboard' (its own "
                   "navigation through its faulty sensors) or 'truth' (a navigation the faulty sensor "
                   "does not reach): docs/real-world.md")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--publish", metavar="DOCS", default=None,
                   help="also publish the results into the docs: copy each scenario folder to "
                   "DOCS/results/<id>/ and regenerate DOCS/results.md (e.g. --publish docs)")
    p.set_defaults(func=main)


def _check(args: argparse.Namespace) -> None:
    if args.runs < 1:
        raise ConfigError(f"--runs: expected a positive integer, got {args.runs}")
    if args.particles is not None and args.particles < 1:
        raise ConfigError(f"--particles: expected a positive integer, got {args.particles}")


def _out_dir(args: argparse.Namespace, sid: str) -> Path:
    """results/<id>, --out (one scenario) or --out/<id> (all)."""
    if args.out is None:
        return Path("results") / sid
    return Path(args.out) / sid if args.scenario in FAMILIES else Path(args.out)


def _run_one(args: argparse.Namespace, sid: str, filters: list[str] | None) -> tuple[str, dict, Path]:
    """One scenario's campaign and report; prints its summary lines. (id, results doc, folder)."""
    from sim_bridge.campaign import run_campaign
    from sim_bridge.report import by_type_lines, write_report, yardstick_lines

    sc = load_scenario(sid)
    if args.navigation is not None:
        sc = dataclasses.replace(sc, navigation=args.navigation)
    out = _out_dir(args, sc.id)
    ts = time.perf_counter()
    camp = run_campaign(sc, args.runs, args.particles, args.seed, workers=args.workers,
                        dask=args.dask, progress=not args.quiet, filters=filters)
    doc = write_report(camp, out, make_figures=not args.no_figures)
    print(f"{sc.id}: {args.runs} runs x {len(camp.filters)} filters "
          f"({', '.join(camp.filters)}), N = {camp.particles}: {time.perf_counter() - ts:.1f} s "
          f"-> {out}/report.md")
    for name, fd in doc["filters"].items():
        means = ", ".join(f"{q} {v['mean']:.4g}" for q, v in fd["rmse"].items()
                          if q.startswith("f_") and v["mean"] is not None)
        print(f"  {name:8s} {fd['step_ms']:.3f} ms/step  mean RMSE {means}")
        for line in yardstick_lines(fd.get("yardstick")) + by_type_lines(fd.get("yardstick")):
            print(f"    {line}")
    return sc.id, doc, out


def _print_orderings(results: dict[str, dict]) -> None:
    from sim_bridge.report import REFERENCE_ORDERINGS, check_orderings

    for o in check_orderings(results):
        rel = " < " if o["strict"] else " <= "
        print(f"ordering {o['scenario']} {o['quantity']}: {rel.join(o['chain'])}: "
              f"{'holds' if o['holds'] else 'FAILS'} ({json.dumps(o['values'])})")
    for o in check_orderings(results, REFERENCE_ORDERINGS):
        print(f"reference {o['scenario']} {o['quantity']}: {' < '.join(o['chain'])}: "
              f"{'holds' if o['holds'] else 'does not hold'} ({json.dumps(o['values'])})")


def _family_report(args: argparse.Namespace, ids: list[str]) -> None:
    """OUT/report.md: the thesis's combined page, or a family's own (e.g. the real sky)."""
    from sim_bridge.family_report import family_markdown
    from sim_bridge.report import combined_markdown

    root = Path(args.out) if args.out is not None else Path("results")
    thesis = args.scenario in ("all", "thesis")
    text = combined_markdown(root, ids) if thesis else family_markdown(
        root, ids, f"The {args.scenario} family: campaigns")
    (root / "report.md").write_text(text)
    print(f"all of {args.scenario}: {root}/report.md")


def _publish(outs: dict[str, Path], docs: str) -> None:
    from sim_bridge.report import publish

    page = None
    for sid, out in outs.items():
        page = publish(out.parent, docs, [sid]) if out.name == sid else _publish_renamed(out, sid, docs)
    print(f"published: {page} and {Path(docs) / 'results'}/<id>/")


def main(args: argparse.Namespace) -> int:
    _check(args)
    ids = list(FAMILIES.get(args.scenario, (args.scenario,)))
    filters = args.filters.split(",") if args.filters else None
    t0 = time.perf_counter()
    results, outs = {}, {}
    for sid in ids:
        key, doc, out = _run_one(args, sid, filters)
        results[key], outs[key] = doc, out
    if args.scenario in FAMILIES:
        _family_report(args, ids)
    _print_orderings(results)
    if args.publish:
        _publish(outs, args.publish)
    print(f"wall time {time.perf_counter() - t0:.1f} s")
    return 0


def _publish_renamed(out: Path, sid: str, docs: str) -> Path:
    """publish() for an --out folder not named after its scenario: stage it as <tmp>/<sid>/."""
    import tempfile

    from sim_bridge.report import publish

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / sid).symlink_to(out.resolve(), target_is_directory=True)
        return publish(tmp, docs, [sid])
