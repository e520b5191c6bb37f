"""`fdir bench`: median microseconds per filter step, for every filter of the family.

Every filter runs the estimator's own configuration (default: the service's default estimator,
`--estimator NAME|FILE`) on frames drawn from that estimator's own model
(`fdir_service.estimation.model_frames`: trim, its assumed noise, a 5-sigma step on its first
sensor fault 2.5 s into the timed steps), after a warm-up. Particle filters at N = 100, 1000,
10000; Kalman filters once (N is reported as 1000 for them).
The filters of one N run interleaved, step by step, so that load changes hit them alike.
`--json` prints {"cores": C, "filters": {NAME: {"N": us_per_step}}}.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

ORDER = ("KF", "IMM-KF", "bootstrap", "RPF", "RRPF", "JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF")
SIZES = (100, 1000, 10000)


def _clock(name: str):
    return time.perf_counter if name == "wall" else time.thread_time


FrameSource = Callable[[tuple[str, ...], int, int, int], dict[str, tuple[Any, Any]]]
"""(names, N, steps, seed) -> {name: (filter built at N particles, frames with t, y, mask, u (K, ...))}."""


RATIO_GOALS = {"aerosonde-robust": 1.5, "aerosonde": 1.3}
"""Estimator id -> the goal for RJMRPF's median step over the bootstrap filter's at N = 1000: the
robust monitor's (the robust-monitor issue), the thesis estimator's (the first speed work)."""


def bench_estimator(estimator: str | None = None):
    """The estimator `fdir bench` runs: NAME|FILE, or the one `fdir run` monitors with by default
    (config/service/default.toml's [service] estimator)."""
    from fdir_service.estimator_config import load_estimator
    from fdir_service.service_config import load_service_config

    return load_estimator(estimator) if estimator else load_service_config().estimator


def estimator_source(estimator: str | None = None, seed: int = 0) -> FrameSource:
    """Every filter on one estimator (`bench_estimator`) and frames from its own model, with a
    5-sigma step on its first sensor fault 2.5 s into the timed steps."""
    from fdir_service.estimation.factory import build_filter
    from fdir_service.estimation.model_frames import model_frames

    est = bench_estimator(estimator)

    def source(names: tuple[str, ...], N: int, steps: int, warmup: int) -> dict[str, tuple[Any, Any]]:
        onset = (warmup + 50) * est.dt_s
        frames = model_frames(est, warmup + steps, np.random.default_rng(seed), onset_s=onset)
        return {name: (build_filter(name, est, np.random.default_rng(seed + 1), particles=N), frames)
                for name in names}
    return source


def time_steps(setups: dict[str, tuple[Any, Any]], steps: int, warmup: int = 20,
               clock: str = "wall") -> dict[str, tuple[float, float]]:
    """(median, mean) microseconds per `step` call of each (filter, frames) after `warmup` frames.

    A particle filter's step times are bimodal (steps with and without resampling), so the
    median can jump between the two when the resampling rate is near 50 %: the mean is given too.
    The filters run interleaved (step k of every filter, then step k + 1), so that a change of
    machine load affects them alike: their ratios are meaningful on a shared machine.
    clock: "wall" (perf_counter) or "cpu" (this thread's CPU time).
    """
    tick = _clock(clock)
    times = {name: np.empty(steps) for name in setups}
    for k in range(warmup + steps):
        for name, (f, fr) in setups.items():
            t0 = tick()
            f.step(fr.t[k], fr.y[k], fr.mask[k], fr.u[k])
            dt = tick() - t0
            if k >= warmup:
                times[name][k - warmup] = dt
    return {name: (float(np.median(v) * 1e6), float(np.mean(v) * 1e6)) for name, v in times.items()}


def run_bench(source: FrameSource, filters: tuple[str, ...] = ORDER, sizes: tuple[int, ...] = SIZES,
              steps: int = 200, clock: str = "wall", warmup: int = 20) -> dict:
    """{"cores": C, "filters": {NAME: {"N": median us}}, "mean": {NAME: {"N": mean us}}}."""
    out: dict = {"cores": os.cpu_count(), "filters": {name: {} for name in filters},
                 "mean": {name: {} for name in filters}}
    kalman = tuple(f for f in filters if f in ("KF", "IMM-KF"))
    particle = tuple(f for f in filters if f not in kalman)
    runs = [(kalman, 1000, steps)] if kalman else []
    runs += [(particle, N, steps if N <= 1000 else max(steps // 4, 20)) for N in (sizes if particle else ())]
    for names, N, n_steps in runs:
        timed = time_steps(source(names, N, n_steps, warmup), n_steps, warmup, clock)
        for name, (med, mean) in timed.items():
            out["filters"][name][str(N)] = round(med, 1)
            out["mean"][name][str(N)] = round(mean, 1)
    return out


def print_bench(res: dict, title: str, goal: float | None = None) -> None:
    """The table of `run_bench` and the RJMRPF / bootstrap ratio at N = 1000 (goal: the estimator's
    goal for the median ratio, `RATIO_GOALS`, if it has one)."""
    print(title)
    print("median (mean) us per step")
    print(f"{'filter':10s} " + " ".join(f"{'N=' + str(n):>17s}" for n in SIZES))
    for name, r in res["filters"].items():
        m = res["mean"][name]
        cells = " ".join(f"{r[str(n)]:8.1f} ({m[str(n)]:6.1f})" if str(n) in r else f"{'-':>17s}"
                         for n in SIZES)
        print(f"{name:10s} {cells}")
    fl, mean = res["filters"], res["mean"]
    if "1000" in fl.get("RJMRPF", {}) and "1000" in fl.get("bootstrap", {}):
        ratio = fl["RJMRPF"]["1000"] / fl["bootstrap"]["1000"]
        mr = mean["RJMRPF"]["1000"] / mean["bootstrap"]["1000"]
        wanted = f" (goal <= {goal:g})" if goal is not None else ""
        print(f"RJMRPF / bootstrap at N=1000: median {ratio:.2f}, mean {mr:.2f}{wanted}; "
              f"RJMRPF median {fl['RJMRPF']['1000']:.0f} us, mean {mean['RJMRPF']['1000']:.0f} us "
              "(goal < 500 us)")


def parse_filters(text: str, prog: str) -> tuple[str, ...] | None:
    """A comma-separated subset of ORDER (empty: all), or None after printing what is unknown."""
    filters = tuple(text.split(",")) if text else ORDER
    unknown = [f for f in filters if f not in ORDER]
    if unknown:
        print(f"{prog}: unknown filter(s) {', '.join(unknown)}; expected {', '.join(ORDER)}")
        return None
    return filters


def _run(args: argparse.Namespace) -> int:
    filters = parse_filters(args.filters, "fdir bench")
    if filters is None:
        return 2
    if args.parts:
        return _run_parts(args, tuple(f for f in filters if f not in ("KF", "IMM-KF")))
    res = run_bench(estimator_source(args.estimator), filters, SIZES, args.steps, args.clock)
    if args.json:
        print(json.dumps({"cores": res["cores"], "filters": res["filters"]}))
        return 0
    est = bench_estimator(args.estimator).id
    print_bench(res, f"fdir bench: median us per filter step ({res['cores']} cores; {args.clock} clock; "
                f"estimator {est} on frames from its own model; filters interleaved)", RATIO_GOALS.get(est))
    return 0


def _run_parts(args: argparse.Namespace, filters: tuple[str, ...]) -> int:
    """`fdir bench --parts`: `bench_parts.time_parts` of each particle filter at N = 1000."""
    from fdir_service.commands.bench_parts import print_parts, time_parts

    warmup = 50
    setups = estimator_source(args.estimator)(filters, 1000, args.steps, warmup)
    rows = {name: time_parts(f, frames, args.steps, warmup, args.clock)
            for name, (f, frames) in setups.items()}
    est = bench_estimator(args.estimator).id
    print_parts(rows, f"fdir bench --parts: mean us per step at N = 1000 by slot ({args.clock} clock, "
                f"{args.steps} steps after {warmup}; estimator {est} on frames from its own model)")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("bench", help="benchmark every estimator: median us per step",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--steps", type=int, default=200, help="timed steps per filter and N (default 200)")
    p.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                   help="wall time (default) or this thread's CPU time, steadier on a busy machine")
    p.add_argument("--filters", default="", help="comma-separated subset, e.g. RJMRPF,bootstrap")
    p.add_argument("--parts", action="store_true",
                   help="where each particle filter's step goes at N = 1000: predict, jump, sentinels, "
                   "correction, resampling and the rest (mean us per step)")
    p.add_argument("--estimator", metavar="NAME|FILE", default=None,
                   help="estimator to benchmark (config/estimators/NAME.toml or a file; default: the "
                   "one `fdir run` uses, config/service/default.toml's)")
    p.set_defaults(func=_run)
