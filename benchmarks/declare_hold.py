"""What the service's declare hold trades: false alarms per flight hour against detection delay
(docs/service.md, "The declare hold"): a study of `[publish.declare] declare_hold_s`, not a change.

    python benchmarks/declare_hold.py real-drift [--runs 100] [--seed 0] [--holds 0.2,0.5,1.0]
        [--workers 2] [--traces FILE.npz]

Flies runs 0..RUNS-1 of a world as `sim-bridge experiment WORLD --filters RJMRPF` does (the same
flights: the hold decides what the service says, not what the filter or the autopilot does), keeps
every run's P(fault) traces, and scores them with the service's hysteresis at each declare hold
(the other settings as config/service/default.toml). `--traces FILE` keeps the traces in FILE and,
when FILE exists, scores it instead of flying again. Printed per hold: false alarms (count; how
many stand from a declaration made while a fault was active or within the yardstick's grace after
it; per fault-free hour, 95 % upper bound), faults declared, median / p90 delay, the right fault isolated;
in a typed world, per fault type: detected, median delay and the right item and type named.

The declarations of a longer hold are a subset of a shorter one's (a declaration starts later or
not at all, and clears at the same frame), so false alarms can only fall and delays only grow.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from sim_bridge.campaign import run_campaign
from sim_bridge.report import scenario_yardstick
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declarations, rate_upper_bound

FILTER = "RJMRPF"
TRACE_KEYS = ("t", "prob", "f_hat", "world_faults", "sim_seeds", "world_active")


def traces(world: str, runs: int, seed: int, workers: int, path: Path | None) -> dict:
    """{t (K,), prob, f_hat (R, K, nf), world_faults, world_active (R, K, nw), sim_seeds (R,)}: read
    from path if it exists, else flown (and written to path if given)."""
    if path is not None and path.exists():
        with np.load(path) as z:
            return {k: z[k] for k in TRACE_KEYS}
    camp = run_campaign(load_scenario(world), runs, seed=seed, workers=workers, filters=[FILTER])
    fr = camp.filters[FILTER]
    out = {k: getattr(fr, k) for k in TRACE_KEYS}
    if path is not None:
        np.savez_compressed(path, **out)
    return out


def score(sc, tr: dict, rule: Hysteresis) -> dict:
    """The campaign's yardstick (`report.scenario_yardstick`) of the traces under rule, no ROC."""
    return scenario_yardstick(sc, tr["t"], tr["prob"], tr["f_hat"], tr["world_faults"],
                              tr["world_active"], tr["sim_seeds"], rule=rule, thresholds=())


def standing_from_before(sc, tr: dict, rule: Hysteresis, y: dict) -> int:
    """How many of y's false alarms are a declaration already standing on the frame before their
    first fault-free frame: made while a fault was active, or within the yardstick's grace after."""
    entries, names = [kind_of(f) for f in sc.estimator.faults], [f.id for f in sc.estimator.faults]
    t, n = tr["t"], 0
    for fa in y["false_alarm_list"]:
        view = item_view(tr["prob"][fa["run"]], entries, names)
        dec = declarations(t, view.prob, rule)
        k = int(np.searchsorted(t, fa["t_s"] - 1e-6))
        n += bool(k > 0 and dec[k - 1, view.names.index(fa["item"])])
    return n


def _f(x, fmt: str = "{:.2f}") -> str:
    return "-" if x is None else fmt.format(x)


def print_table(world: str, rows: list[tuple[float, dict]]) -> None:
    """One line per hold, then the per-type lines of a typed world."""
    print(f"\n{world}: {FILTER}, the service's hysteresis at each declare hold")
    print("| declare hold (s) | false alarms | standing from a declaration made earlier "
          "| per hour (95 % bound) | declared | median / p90 delay (s) | right fault isolated |")
    print("|---|---|---|---|---|---|---|")
    for hold, y in rows:
        d = y["delay_s"] or {}
        bound = rate_upper_bound(y["false_alarms"], y["fault_free_hours"])
        print(f"| {hold:.2f} | {y['false_alarms']} in {y['fault_free_hours']:.2f} h | {y['standing']} | "
              f"{_f(y['false_alarms_per_hour'])} ({_f(bound)}) | "
              f"{y['detected']} / {y['episodes']} | {_f(d.get('median'))} / {_f(d.get('p90'))} | "
              f"{_f(y['isolation_accuracy'])} |")
    if "by_type" not in rows[0][1]:
        return
    print("\n| declare hold (s) | type | detected | median delay (s) | right item and type named |")
    print("|---|---|---|---|---|")
    for hold, y in rows:
        for ty, r in y["by_type"]["types"].items():
            print(f"| {hold:.2f} | {ty} | {_f(r['detection_fraction'])} | "
                  f"{_f((r['delay_s'] or {}).get('median'))} | {_f(r['right_fraction'])} |")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("world")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--holds", default="0.2,0.5,1.0", help="declare holds, s, comma separated")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--traces", type=Path, default=None, help="keep (or read) the P traces here (.npz)")
    a = ap.parse_args(argv)
    sc = load_scenario(a.world)
    tr = traces(a.world, a.runs, a.seed, a.workers, a.traces)
    base = Hysteresis.of_service()
    holds = [float(h) for h in a.holds.split(",")]
    rows = []
    for h in holds:
        rule = dataclasses.replace(base, declare_hold_s=h)
        y = score(sc, tr, rule)
        rows.append((h, {**y, "standing": standing_from_before(sc, tr, rule, y)}))
    print_table(a.world, rows)


if __name__ == "__main__":
    main()
