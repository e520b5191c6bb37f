"""Which runs of an experiment raise false alarms, and when: the per-run view behind a campaign's
false alarms per flight hour.

    python benchmarks/false_alarm_runs.py real-stuck [--runs 100] [--first 0] [--seed 0] [--workers 2]
                                                     [--navigation monitor|onboard|truth]

Flies each run as `sim-bridge experiment` does (campaign seed --seed, default 0; RJMRPF),
declares items as the service does (P(item) over its types, the declare hysteresis) and prints,
for every run with a false alarm, a missed fault or a lost state: the largest state error
|x_hat - z| (p_d m, u m/s, w m/s, theta rad, q rad/s), each false declaration as
item:type@time (s), the injected faults' onsets, and each injected fault its item never declared
(onset to 3 s after its end) as "missed id:item start-end s, max P(item)".
"""

from __future__ import annotations

import argparse
import dataclasses
from multiprocessing import Pool

import numpy as np

from sim_bridge.campaign import fly
from sim_bridge.onboard_nav import NAVIGATION
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared, episode_window, quiet_mask

LOST_M = 100.0
"""An altitude error above this (m) marks a run whose state was lost."""


def false_declarations(world: str, run: int, seed: int = 0, navigation: str | None = None
                       ) -> tuple[int, np.ndarray, list[str], list[tuple[str, float]], list[str]]:
    """(run, max |state error| (5,), false declarations "item:type@t", [(fault id, onset s)],
    the injected faults never declared); navigation: overrides the world's (`onboard_nav`)."""
    sc = load_scenario(world)
    if navigation is not None:
        sc = dataclasses.replace(sc, navigation=navigation)
    tr = fly(sc, "RJMRPF", run, seed)                      # on one BLAS thread per worker
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
    return run, np.abs(X - tr.z).max(axis=0), found, onsets, missed_faults(sc, tr, view)


def missed_faults(sc, tr, view) -> list[str]:
    """The injected faults whose item was not declared between onset and GRACE_S after the end, as
    "missed id:item start-end, max P(item)" (tr: the flight; view: its `ItemView`)."""
    out = []
    for j, f in enumerate(sc.faults):
        on = np.flatnonzero(tr.active[:, j])
        if not on.size or f.target not in view.targets:
            continue
        i = view.targets.index(f.target)
        window = episode_window(tr.t, on[0], on[-1] + 1)          # onset to GRACE_S after the end
        if not declared(tr.t, view.prob[:, i], Hysteresis())[window].any():
            out.append(f"missed {f.id}:{f.target} {tr.t[on[0]]:.1f}-{tr.t[on[-1]]:.1f} s, "
                       f"max P {view.prob[window, i].max():.2f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0, help="campaign seed (sim-bridge experiment --seed)")
    ap.add_argument("--navigation", choices=NAVIGATION, default=None,
                    help="what the autopilot flies on (sim-bridge experiment --navigation)")
    a = ap.parse_args()
    with Pool(a.workers) as pool:
        jobs = [(a.world, r, a.seed, a.navigation) for r in range(a.first, a.runs)]
        for run, err, found, onsets, missed in pool.starmap(false_declarations, jobs):
            lost = " LOST" if err[0] > LOST_M else ""
            if found or lost or missed:
                print(run, np.round(err, 1), lost, found, onsets, *missed, flush=True)


if __name__ == "__main__":
    main()
