"""Which runs of an experiment raise false alarms, and when: the per-run view behind a campaign's
false alarms per flight hour.

    python benchmarks/false_alarm_runs.py real-stuck [--runs 100] [--first 0] [--workers 2]

Flies each run as `sim-bridge experiment` does (campaign seed 0, RJMRPF), declares items as the
service does (P(item) over its types, the declare hysteresis) and prints, for every run with a
false alarm or a lost state: the largest state error |x_hat - z| (p_d m, u m/s, w m/s, theta rad,
q rad/s), each false declaration as item:type@time (s), and the injected faults' onsets.
"""

from __future__ import annotations

import argparse
from multiprocessing import Pool

import numpy as np

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared, quiet_mask

LOST_M = 100.0
"""An altitude error above this (m) marks a run whose state was lost."""


def false_declarations(world: str, run: int) -> tuple[int, np.ndarray, list[str], list[tuple[str, float]]]:
    """(run, max |state error| (5,), false declarations "item:type@t", [(fault id, onset s)])."""
    sc = load_scenario(world)
    tr = fly(sc, "RJMRPF", run)                            # on one BLAS thread per worker
    P = np.array([o.fault_probability for o in tr.outputs])
    X = np.array([o.x_mean[:5] for o in tr.outputs])
    names = [f.id for f in sc.estimator.faults]
    view = item_view(P, [kind_of(f) for f in sc.estimator.faults], names)
    active = tr.active.any(axis=1) if tr.active.size else np.zeros(len(tr.t), bool)
    quiet = quiet_mask(tr.t, active)
    found = []
    for i, item in enumerate(view.names):
        k = np.flatnonzero(declared(tr.t, view.prob[:, i], Hysteresis()) & quiet)
        found += [f"{item}:{names[view.best[a, i]]}@{tr.t[a]:.1f}" for a in k[np.r_[True, np.diff(k) > 1]]] \
            if k.size else []
    onsets = [(f.id, round(float(tr.t[np.flatnonzero(tr.active[:, j])[0]]), 1))
              for j, f in enumerate(sc.faults) if tr.active[:, j].any()]
    return run, np.abs(X - tr.z).max(axis=0), found, onsets


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    with Pool(a.workers) as pool:
        jobs = [(a.world, r) for r in range(a.first, a.runs)]
        for run, err, found, onsets in pool.starmap(false_declarations, jobs):
            lost = " LOST" if err[0] > LOST_M else ""
            if found or lost:
                print(run, np.round(err, 1), lost, found, onsets, flush=True)


if __name__ == "__main__":
    main()
