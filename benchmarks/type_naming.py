"""What naming a fault's kind only once it is clear would score (docs/faults.md, "What stays
ambiguous"): a study of the service's naming rule, not a change to it.

    python benchmarks/type_naming.py real-stuck [--runs 20] [--workers 2] [--shares 0.5,0.8]

Flies runs 0..RUNS-1 of a typed world as `sim-bridge experiment` does (campaign seed 0, RJMRPF)
and, for each injected episode whose item is declared (P(item) over its types, the service's
hysteresis, `sim_bridge.type_yardstick`), compares two rules:
- today's: the kind named is the item's most probable type at its first declared frame
  (share 0 in the table);
- share c: the kind is named at the first declared frame from which one type has held at least
  c of P(item) for the declare hold (0.2 s), and not before (the episode is "unnamed" if that
  never happens while the item stays declared).
Printed per rule: episodes named, the share named rightly (item and type, as the campaign's
"right" column), and the naming delay after the declaration (median, p90, s).
"""

from __future__ import annotations

import argparse
from multiprocessing import Pool
from types import SimpleNamespace

import numpy as np

from fdir_service.runtime.items import item_layout
from sim_bridge.campaign import fly, sim_seed
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run_faults
from sim_bridge.type_yardstick import item_type_matches, item_view, kind_of, world_active, world_fault
from sim_bridge.yardstick import Hysteresis, declarations, episode_window, episodes, first_declared


def flight(world: str, run: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (K,), P(entry) (K, nf), the world faults' activity (K, nw)) of one run."""
    sc = load_scenario(world)
    tr = fly(sc, "RJMRPF", run)
    P = np.array([o.fault_probability for o in tr.outputs])
    return tr.t, P, world_active(run_faults(sc, sim_seed(0, run)).faults, tr.t)


def named_frame(t: np.ndarray, declared: np.ndarray, best: np.ndarray, share: np.ndarray, start: int,
                c: float, hold_s: float) -> int | None:
    """The first frame from `start` (while declared (K,)) at which one entry (best (K,)) has held a
    share (K,) >= c for hold_s; c = 0: `start` itself (today's rule)."""
    if c <= 0.0:
        return start
    since = None
    for k in range(start, t.size):
        if not declared[k]:
            return None
        if share[k] < c or (since is not None and best[k] != best[since]):
            since = k if share[k] >= c else None
            continue
        since = k if since is None else since
        if t[k] - t[since] + 1e-6 >= hold_s:
            return k
    return None


def episode_names(sc, t: np.ndarray, P: np.ndarray, active: np.ndarray, shares: list[float],
                  rule: Hysteresis) -> list[dict]:
    """Per injected episode: {share c: (right, delay s) or None (unnamed or missed)}."""
    entries = [kind_of(f) for f in sc.estimator.faults]
    names = [f.id for f in sc.estimator.faults]
    faults = [world_fault(c) for c in sc.faults]
    right = item_type_matches(entries, [f.kind for f in faults])
    layout = item_layout([SimpleNamespace(id=n, target=e.target)
                          for n, e in zip(names, entries, strict=True)])
    view = item_view(P, entries, names)
    dec = declarations(t, view.prob, rule)
    out = []
    for w, fault in enumerate(faults):
        for s, e in episodes(active[:, w]):
            win = episode_window(t, s, e)
            own = [i for i, tg in enumerate(view.targets) if tg == fault.kind.target]
            first = first_declared(dec, win, own, view.names)
            if not first:
                out.append(dict.fromkeys(shares))
                continue
            kd, item = win.start + first[0], first[1]
            ent = np.array(layout.entries[item])
            pe = P[:, ent]
            best = np.argmax(pe, axis=1)
            share = pe[np.arange(t.size), best] / np.maximum(pe.sum(axis=1), 1e-12)
            row = {}
            for c in shares:
                k = named_frame(t, dec[:, item], best, share, kd, c, rule.declare_hold_s)
                row[c] = None if k is None else (item in own and int(ent[best[k]]) in right[w],
                                                 float(t[k] - t[kd]))
            out.append(row)
    return out


def print_table(world: str, rows: list[dict], shares: list[float]) -> None:
    print(f"{world}: {len(rows)} episodes")
    print("share c | named | right (of named) | right (of all) | naming delay median / p90 (s)")
    for c in shares:
        named = [r[c] for r in rows if r[c] is not None]
        ok = sum(1 for right, _ in named if right)
        d = [delay for _, delay in named] or [float("nan")]
        print(f"{c:7.2f} | {len(named):5d} | {ok / max(len(named), 1):16.2f} | {ok / len(rows):14.2f} | "
              f"{np.median(d):.2f} / {np.percentile(d, 90):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--shares", default="0.5,0.7,0.8,0.9", help="comma-separated shares c to try")
    a = ap.parse_args()
    shares = [0.0] + [float(x) for x in a.shares.split(",")]
    sc = load_scenario(a.world)
    with Pool(a.workers) as pool:
        flights = pool.starmap(flight, [(a.world, r) for r in range(a.runs)])
    rule = Hysteresis.of_service()
    rows = [row for t, P, act in flights for row in episode_names(sc, t, P, act, shares, rule)]
    print_table(a.world, rows, shares)


if __name__ == "__main__":
    main()
