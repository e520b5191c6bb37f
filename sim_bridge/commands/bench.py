"""`sim-bridge bench`: time per simulated closed-loop step (linear and nonlinear truth), and with
`--filters` the filter-step cost on the thesis experiments' estimators and open-loop data. No asserts."""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run

BENCH_EXPERIMENT = {"KF": "ch4", "IMM-KF": "ch4", "RPF": "ch5a", "RRPF": "ch5a", "JMRPF": "ch5a",
                    "RJMRPF": "ch5a", "bootstrap": "ch5a", "AJMRPF": "ch6", "ARJMRPF": "ch6"}
"""The experiment whose estimator each filter is timed on (the thesis's own settings)."""


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("bench", help="time per simulated closed-loop step (or per filter step)",
                              description="Fly closed-loop runs on truth navigation and print the "
                              "wall-clock time per simulated step (faults, sensors, autopilot, truth). "
                              "--filters: instead, time every filter on its thesis experiment's estimator "
                              "(KF, IMM-KF: ch4; RPF ... RJMRPF and bootstrap: ch5a; AJMRPF, ARJMRPF: ch6) "
                              "with open-loop synthetic data from t = 7.5 s, through a fault onset.")
    p.add_argument("--seconds", type=float, default=50.0, help="simulated seconds per run (default 50)")
    p.add_argument("--repeat", type=int, default=3, help="runs per case; the best is reported (default 3)")
    p.add_argument("--filters", nargs="?", const="all", default=None, metavar="LIST",
                   help="time filters instead (comma-separated subset, default all)")
    p.add_argument("--steps", type=int, default=200, help="timed steps per filter and N (default 200)")
    p.set_defaults(func=main)


def thesis_source(seed: int = 0):
    """`fdir bench` frame source: each filter on its BENCH_EXPERIMENT's estimator and synthetic data
    (`sim_bridge.synthetic`), starting 7.5 s in so that the timed steps cross the fault onsets."""
    from fdir_service.estimation.factory import build_filter
    from sim_bridge.synthetic import generate

    def source(names: tuple[str, ...], N: int, steps: int, warmup: int) -> dict[str, tuple[Any, Any]]:
        out = {}
        for name in names:
            sc = load_scenario(BENCH_EXPERIMENT[name])
            start = int(round(7.5 / sc.dt_s))
            frames = generate(sc, np.random.default_rng(seed), start + warmup + steps)
            for key in ("t", "y", "mask", "u"):
                setattr(frames, key, getattr(frames, key)[start:])
            filt = build_filter(name, sc.estimator, np.random.default_rng(seed + 1), particles=N)
            out[name] = (filt, frames)
        return out
    return source


def bench_filters(args: argparse.Namespace) -> int:
    from fdir_service.commands.bench import SIZES, parse_filters, print_bench, run_bench

    filters = parse_filters("" if args.filters == "all" else args.filters, "sim-bridge bench")
    if filters is None:
        return 2
    res = run_bench(thesis_source(), filters, SIZES, args.steps)
    print_bench(res, f"sim-bridge bench --filters: median us per filter step ({res['cores']} cores; thesis "
                "experiments' estimators on open-loop synthetic data; filters interleaved)")
    return 0


def main(args: argparse.Namespace) -> int:
    if args.filters is not None:
        return bench_filters(args)
    print(f"{'case':34s} {'steps':>6s} {'best run (s)':>13s} {'per step (us)':>14s} {'x real time':>12s}")
    for sid, label in (("ch4", "ch4, linear truth (printed F, B)"), ("ch5a", "ch5a, nonlinear truth (RK4)")):
        sc = load_scenario(sid)
        best = float("inf")
        steps = 0
        for seed in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            traj = run(sc, seed, seconds=args.seconds)
            best = min(best, time.perf_counter() - t0)
            steps = traj.t.size
        per = best / steps
        print(f"{label:34s} {steps:6d} {best:13.3f} {per * 1e6:14.1f} {sc.dt_s / per:12.0f}")
    return 0
