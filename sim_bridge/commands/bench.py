"""`sim-bridge bench`: time per simulated closed-loop step (linear and nonlinear truth). No asserts."""

from __future__ import annotations

import argparse
import time

from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("bench", help="time per simulated closed-loop step",
                              description="Fly closed-loop runs on truth navigation and print the "
                              "wall-clock time per simulated step (faults, sensors, autopilot, truth).")
    p.add_argument("--seconds", type=float, default=50.0, help="simulated seconds per run (default 50)")
    p.add_argument("--repeat", type=int, default=3, help="runs per case; the best is reported (default 3)")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
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
