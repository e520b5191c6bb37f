"""`sim-bridge compare A B`: two campaigns of the same flights, their false alarms flight by flight."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "compare", help="compare two campaigns of the same flights, false alarms flight by flight",
        description="Pair run r of campaign A (before) with run r of campaign B (after), flown on the "
        "same seed, runs and navigation, and say per filter whether B's false alarms changed or only "
        "moved to other flights: flights with fewer and with more, the sign test, and a 95 % interval "
        "on the change of the total from flights resampled (sim_bridge/paired.py).",
        epilog="example:\n"
        "  sim-bridge experiment real-drift --runs 100 --out before/\n"
        "  sim-bridge experiment my-real-drift.toml --runs 100 --out after/\n"
        "  sim-bridge compare before/ after/",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("before", help="a campaign's output folder (or its results.json)")
    p.add_argument("after", help="the other campaign, flown on the same flights")
    p.add_argument("--filters", default="", help="comma-separated filters (default: those both flew)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from sim_bridge.paired import compare, load_results, paired_lines

    try:
        a, b = load_results(args.before), load_results(args.after)
        both = [n for n in a["filters"] if n in b["filters"] and a["filters"][n].get("yardstick")
                and b["filters"][n].get("yardstick")]
        names = args.filters.split(",") if args.filters else both
        unknown = [n for n in names if n not in both]
        if unknown:
            raise ValueError(f"filter(s) {', '.join(unknown)} not in both campaigns "
                             f"(both: {', '.join(both)})")
        print(f"{a.get('scenario')} -> {b.get('scenario')}: {a['runs']} flights, seed {a.get('seed')}")
        for name in names:
            print("\n".join(paired_lines(compare(a, b, name))))
    except (ValueError, KeyError) as exc:
        print(f"sim-bridge compare: {exc}", file=sys.stderr)
        return 2
    return 0
