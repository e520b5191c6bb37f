"""`fdir bench`: median microseconds per filter step, for every filter of the family.

Each filter runs on open-loop synthetic data of its benchmark scenario (KF, IMM-KF: ch4, linear;
RPF, RRPF, JMRPF, RJMRPF and the plain bootstrap filter: ch5a, nonlinear process model;
AJMRPF, ARJMRPF: ch6, same model) from t = 7.5 s, through a fault onset, after a warm-up.
Particle filters at N = 100, 1000, 10000; Kalman filters once (N is reported as 1000 for them).
The filters of one N run interleaved, step by step, so that load changes hit them alike.
`--json` prints {"cores": C, "filters": {NAME: {"N": us_per_step}}}.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

BENCH_SCENARIO = {"KF": "ch4", "IMM-KF": "ch4", "RPF": "ch5a", "RRPF": "ch5a", "JMRPF": "ch5a",
                  "RJMRPF": "ch5a", "bootstrap": "ch5a", "AJMRPF": "ch6", "ARJMRPF": "ch6"}
ORDER = ("KF", "IMM-KF", "bootstrap", "RPF", "RRPF", "JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF")
SIZES = (100, 1000, 10000)


def _clock(name: str):
    return time.perf_counter if name == "wall" else time.thread_time


def time_filters(names: tuple[str, ...], N: int, steps: int, warmup: int = 20, seed: int = 0,
                 clock: str = "wall") -> dict[str, tuple[float, float]]:
    """(median, mean) microseconds per `step` call of each filter at N particles.

    A particle filter's step times are bimodal (steps with and without resampling), so the
    median can jump between the two when the resampling rate is near 50 %: the mean is given too.

    The filters run interleaved (step k of every filter, then step k + 1), so that a change of
    machine load affects them alike: their ratios are meaningful on a shared machine.
    clock: "wall" (perf_counter) or "cpu" (this thread's CPU time).
    """
    from fdir_service.estimation.factory import build_filter
    from fdir_service.estimation.synthetic import generate
    from sim_bridge.scenario import load_scenario

    tick = _clock(clock)
    runs, filters = {}, {}
    start = 0
    for name in names:
        sid = BENCH_SCENARIO[name]
        sc = load_scenario(sid)
        start = int(round(7.5 / sc.dt_s))
        if sid not in runs:
            runs[sid] = generate(sc, np.random.default_rng(seed), start + warmup + steps)
        filters[name] = build_filter(name, sc.estimator, np.random.default_rng(seed + 1), particles=N)
    times = {name: np.empty(steps) for name in names}
    for k in range(start + warmup + steps):
        for name in names:
            run = runs[BENCH_SCENARIO[name]]
            f = filters[name]
            t0 = tick()
            f.step(run.t[k], run.y[k], run.mask[k], run.u[k])
            dt = tick() - t0
            if k >= start + warmup:
                times[name][k - start - warmup] = dt
    return {name: (float(np.median(v) * 1e6), float(np.mean(v) * 1e6)) for name, v in times.items()}


def run_bench(filters: tuple[str, ...] = ORDER, sizes: tuple[int, ...] = SIZES,
              steps: int = 200, clock: str = "wall") -> dict:
    """{"cores": C, "filters": {NAME: {"N": median us}}, "mean": {NAME: {"N": mean us}}}."""
    out: dict = {"cores": os.cpu_count(), "filters": {name: {} for name in filters},
                 "mean": {name: {} for name in filters}}
    kalman = tuple(f for f in filters if f in ("KF", "IMM-KF"))
    particle = tuple(f for f in filters if f not in kalman)
    if kalman:
        for name, (med, mean) in time_filters(kalman, 1000, steps, clock=clock).items():
            out["filters"][name]["1000"] = round(med, 1)
            out["mean"][name]["1000"] = round(mean, 1)
    for N in sizes if particle else ():
        n_steps = steps if N <= 1000 else max(steps // 4, 20)
        for name, (med, mean) in time_filters(particle, N, n_steps, clock=clock).items():
            out["filters"][name][str(N)] = round(med, 1)
            out["mean"][name][str(N)] = round(mean, 1)
    return out


def _run(args: argparse.Namespace) -> int:
    filters = tuple(args.filters.split(",")) if args.filters else ORDER
    unknown = [f for f in filters if f not in BENCH_SCENARIO]
    if unknown:
        print(f"fdir bench: unknown filter(s) {', '.join(unknown)}; expected {', '.join(ORDER)}")
        return 2
    res = run_bench(filters, SIZES, args.steps, args.clock)
    if args.json:
        print(json.dumps({"cores": res["cores"], "filters": res["filters"]}))
        return 0
    print(f"fdir bench: median us per filter step ({res['cores']} cores; {args.clock} clock; "
          "open-loop synthetic data; filters interleaved)")
    print("median (mean) us per step")
    print(f"{'filter':10s} {'scenario':8s} " + " ".join(f"{'N=' + str(n):>17s}" for n in SIZES))
    for name, r in res["filters"].items():
        m = res["mean"][name]
        cells = " ".join(f"{r[str(n)]:8.1f} ({m[str(n)]:6.1f})" if str(n) in r else f"{'-':>17s}"
                         for n in SIZES)
        print(f"{name:10s} {BENCH_SCENARIO[name]:8s} {cells}")
    fl = res["filters"]
    if "RJMRPF" in fl and "bootstrap" in fl:
        ratio = fl["RJMRPF"]["1000"] / fl["bootstrap"]["1000"]
        mr = res["mean"]["RJMRPF"]["1000"] / res["mean"]["bootstrap"]["1000"]
        print(f"RJMRPF / bootstrap at N=1000: median {ratio:.2f}, mean {mr:.2f} (goal <= 1.3); "
              f"RJMRPF median {fl['RJMRPF']['1000']:.0f} us, mean {res['mean']['RJMRPF']['1000']:.0f} us "
              "(goal < 500 us)")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("bench", help="benchmark every estimator: median us per step",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--steps", type=int, default=200, help="timed steps per filter and N (default 200)")
    p.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                   help="wall time (default) or this thread's CPU time, steadier on a busy machine")
    p.add_argument("--filters", default="", help="comma-separated subset, e.g. RJMRPF,bootstrap")
    p.set_defaults(func=_run)
