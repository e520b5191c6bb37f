"""`sim-bridge replay`: replay a recorded flight (as `fdir replay`) and score it against the truth."""

from __future__ import annotations

import argparse
import sys

from mcap.exceptions import McapError

from fdir_service.commands.replay import add_replay_arguments, exit_code, fmt, print_replay
from fdir_service.replay import ReplayError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "replay", help="replay a recorded flight and score it against the simulator's truth",
        description="`fdir replay` (bit-identical with the recorded setup, a comparison with another "
        "filter), then, with --truth, the recorded and the replayed estimates scored against the "
        "simulator's truth (RMSE, detection delay, false-alarm and missed fractions; SPEC section 8); "
        "--report writes summary.json, report.md and figures.",
        epilog="example:\n"
        "  sim-bridge fly ch4 --speed 0 --nav fdir --record truth.mcap   # beside `fdir run`\n"
        "  sim-bridge replay fdir-*.mcap --filter IMM-KF --truth truth.mcap --report out/",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_replay_arguments(p)
    p.add_argument("--truth", metavar="TRUTH.mcap", help="simulator truth from `sim-bridge fly --record`")
    p.add_argument("--report", metavar="DIR", help="write summary.json, report.md and figures to DIR")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from sim_bridge.replay_score import replay_and_score

    try:
        scored = replay_and_score(args.log, truth=args.truth, report_dir=args.report,
                                  filter_name=args.filter_name, particles=args.particles, seed=args.seed,
                                  out=args.out)
    except (ReplayError, McapError, OSError, ValueError) as exc:
        print(f"sim-bridge replay: {exc}", file=sys.stderr)
        return 1
    print_replay(scored.result)
    for name, m in (scored.metrics or {}).items():
        for fid, fm in m["faults"].items():
            delays = ", ".join(fmt(e["delay_s"], ".2f") for e in fm["episodes"]) or "-"
            print(f"  {name:>8} {fid}: RMSE {fmt(fm['rmse'])}, detection delay {delays} s, "
                  f"false alarms {fmt(fm['false_alarm_fraction'])}, missed {fmt(fm['missed_fraction'])}")
    if scored.report_files:
        print("report: " + ", ".join(str(p) for p in scored.report_files))
    return exit_code(scored.result)
