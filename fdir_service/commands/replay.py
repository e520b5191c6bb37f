"""`fdir replay`: run a recorded flight's input through the service's processing core again."""

from __future__ import annotations

import argparse
import sys

from mcap.exceptions import McapError

from fdir_service.estimation.recipes import FILTER_NAMES
from fdir_service.replay import ReplayError, ReplayResult, item_summary, replay


def add_replay_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments `fdir replay` and `sim-bridge replay` share."""
    p.add_argument("log", metavar="LOG.mcap", help="a recording of `fdir run` (or of a replay)")
    p.add_argument("--filter", dest="filter_name", metavar="NAME", choices=FILTER_NAMES,
                   help=f"filter to run instead of the recorded one ({', '.join(FILTER_NAMES)})")
    p.add_argument("--particles", type=int, metavar="N", help="particle count (default: as recorded)")
    p.add_argument("--seed", type=int, metavar="N", help="filter seed (default: as recorded)")
    p.add_argument("--out", metavar="NEW.mcap", help="record the replay like a flight")


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "replay", help="replay a recorded flight offline (check bit-identity, compare filters)",
        description="Feed the raw MAVLink input recorded in LOG.mcap through a fresh copy of the "
        "service's processing core (the recorded config). With the recorded filter, particle count and "
        "seed the estimates are bit-identical to the flight's (every /fdir/estimate field but latency_s); "
        "with another filter the run is a comparison. Works on a log whose writer was killed. "
        "To score against a simulator's truth and draw figures: "
        "`sim-bridge replay LOG --truth T --report D`.")
    add_replay_arguments(p)
    p.set_defaults(func=_run)
    return p


def print_replay(r: ReplayResult) -> None:
    """The replay's speed, setups, and identity (same setup) or estimate differences (another one)."""
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
            print(f"  {fid}: estimate RMS difference {fmt(d.get('rms'))}, P(fault) RMS difference "
                  f"{fmt(dp.get('rms'))}")
    print_items(r)
    if r.out_paths:
        print("recorded to " + ", ".join(str(p) for p in r.out_paths))


def print_items(r: ReplayResult) -> None:
    """Per monitored item (estimators with typed faults): its type, declared fraction and max P,
    replayed (and recorded, when the setup differs); nothing for an all-bias estimator."""
    if not r.replayed_items:
        return
    if r.same_setup and r.recorded_items:
        print(f"items: {r.items_identity.describe()}")
    recorded = item_summary(r.recorded_items)
    for name, s in item_summary(r.replayed_items).items():
        was = recorded.get(name) if not r.same_setup else None
        tail = f" (recorded: {was['type']}, declared {was['declared_fraction']:.0%})" if was else ""
        print(f"  {name}: {s['type']}, declared {s['declared_fraction']:.0%} of frames, "
              f"max P {fmt(s['p_max'], '.2f')}{tail}")


def exit_code(r: ReplayResult) -> int:
    """0, or 3 when the same setup did not reproduce the recorded estimates (or items)."""
    if not r.same_setup:
        return 0
    items_ok = not r.recorded_items or r.items_identity.identical or r.items_identity.common_identical
    return 0 if (r.identity.identical or r.identity.common_identical) and items_ok else 3


def _run(args: argparse.Namespace) -> int:
    try:
        r = replay(args.log, filter_name=args.filter_name, particles=args.particles, seed=args.seed,
                   out=args.out)
    except (ReplayError, McapError, OSError) as exc:
        print(f"fdir replay: {exc}", file=sys.stderr)
        return 1
    print_replay(r)
    return exit_code(r)


def fmt(v: float | None, spec: str = ".3f") -> str:
    """v formatted, or "-" for None."""
    return "-" if v is None else format(v, spec)
