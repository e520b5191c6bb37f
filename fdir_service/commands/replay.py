"""`fdir replay LOG.mcap`: feed a recorded flight's input through the service's processing core again."""

from __future__ import annotations

import argparse
import sys

from mcap.exceptions import McapError

from fdir_service.replay import ReplayError, replay


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "replay", help="replay a recorded flight offline (check, compare filters, score against truth)",
        description="Feed the raw MAVLink input recorded in LOG.mcap through a fresh copy of the "
        "service's processing core (the recorded config). With the recorded filter, particle count and "
        "seed the estimates are bit-identical to the flight's (every /fdir/estimate field but latency_s); "
        "with another filter the run is a comparison; with the simulator's truth both are scored "
        "(RMSE, detection delay, false-alarm fraction). Works on a log whose writer was killed.")
    p.add_argument("log", metavar="LOG.mcap", help="a recording of `fdir run` (or of a replay)")
    p.add_argument("--filter", dest="filter_name", metavar="NAME",
                   help="filter to run instead of the recorded one (KF, IMM-KF, RPF, RRPF, JMRPF, RJMRPF, "
                   "AJMRPF, ARJMRPF, EKF-GATE)")
    p.add_argument("--particles", type=int, metavar="N", help="particle count (default: as recorded)")
    p.add_argument("--seed", type=int, metavar="N", help="filter seed (default: as recorded)")
    p.add_argument("--truth", metavar="TRUTH.mcap", help="simulator truth from `sim-bridge fly --record`")
    p.add_argument("--out", metavar="NEW.mcap", help="record the replay like a flight")
    p.add_argument("--report", metavar="DIR", help="write summary.json, report.md and figures to DIR")
    p.set_defaults(func=_run)
    return p


def _run(args: argparse.Namespace) -> int:
    try:
        r = replay(args.log, filter_name=args.filter_name, particles=args.particles, seed=args.seed,
                   truth=args.truth, out=args.out, report_dir=args.report)
    except (ReplayError, McapError, OSError) as exc:
        print(f"fdir replay: {exc}", file=sys.stderr)
        return 1
    rec = r.recorded_setup
    print(f"replayed {r.frames} frames ({r.log_duration_s:.2f} s of log) in {r.wall_s:.2f} s: "
          f"{r.speed:.0f}x real time")
    print(f"recorded: {rec.get('filter')} N={rec.get('particles')} seed={rec.get('seed')}; "
          f"replayed: {r.filter} N={r.particles} seed={r.seed}")
    if r.same_setup:
        print(r.identity.describe())
    elif r.differences:
        for fid in [k[3:] for k in r.differences if k.startswith("pf_")]:
            d, dp = r.differences.get(f"f_{fid}", {}), r.differences[f"pf_{fid}"]
            print(f"  {fid}: estimate RMS difference {_f(d.get('rms'))}, P(fault) RMS difference "
                  f"{_f(dp.get('rms'))}")
    if r.metrics:
        for run, m in r.metrics.items():
            for fid, fm in m["faults"].items():
                delays = ", ".join(_f(e["delay_s"], ".2f") for e in fm["episodes"]) or "-"
                print(f"  {run:>8} {fid}: RMSE {_f(fm['rmse'])}, detection delay {delays} s, "
                      f"false alarms {_f(fm['false_alarm_fraction'])}, missed {_f(fm['missed_fraction'])}")
    if r.out_paths:
        print("recorded to " + ", ".join(str(p) for p in r.out_paths))
    if r.report_files:
        print("report: " + ", ".join(str(p) for p in r.report_files))
    return 0 if (r.identity.identical or r.identity.common_identical or not r.same_setup) else 3


def _f(v: float | None, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)
