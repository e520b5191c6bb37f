"""The yardstick per fault type (issue 17, "fault catalogue"): for a world whose injected faults
have types (stuck, noisy, jammed, ...), how each type is detected, isolated and estimated.

An injected fault is an (item, type): its channel's target (a measurement row or an input) and its
`fault_type` (sensor "bias" | "stuck" | "noisy" | "blocked", actuator "bias" | "jammed" |
"effectiveness" | "engine"). A monitored entry is the same pair (`FaultSpec.target`, `FaultSpec.fault_type`).
Per episode (a stretch of the channel's active frames; activity from the profile's intervals,
`channel_active`, since a noisy k or an effectiveness g can leave the additive-equivalent value ~0
while active), with the service's declarations (`sim_bridge.yardstick.declarations`) and the
window from onset to GRACE_S after the end (`sim_bridge.yardstick`):
- the **right** entries have the same item and a matching type (`type_matches`: equal, a
  "blocked" pitot answered by a "stuck" entry; an "engine" loss by the throttle's "effectiveness"
  where the estimator has no "engine" entry);
- declarations are by item, as the service makes them (`fdir_service.runtime.items`): P(item
  faulty) combines its entries' P (exclusive additive types add up, a noisy one is independent),
  through the service's hysteresis; the type declared is the one the service names
  (`named_entry`: the most probable entry once it holds p_type of P(item), else "unclear"), beside
  the most probable at the first declared frame and SETTLE_S later (`item_view`);
- **detected**: the item is declared in the window; **delay** from the onset to its first declared
  frame (0 if it stood declared already); **declared while active** (`during`): that frame comes
  before the episode's end (`sim_bridge.yardstick`);
- **delay past 3 sigma**: the delay counted instead from the first frame at which the fault's
  additive-equivalent size reaches 3 sigma of its sensor's noise in the world (`three_sigma_frame`;
  0 if declared before): a ramp, a blockage or a stuck reading starts at 0 and needs seconds to
  stand out, which the delay from the onset counts; actuators and noisy sensors from the onset;
- **declared as**: the first item declared in the window (`yardstick.first_declared`: the fault's
  own item may stand declared already, any other must start its declaration inside the window),
  as (its item, its type then), else "missed";
- **magnitude error**: RMSE over the episode's active frames of the right entry's estimate (the one
  declared, else the first right entry) against the world's additive-equivalent truth, in the
  fault's unit (noisy and effectiveness: unitless).
Pooled per world fault type (`pool_by_type`) with a confusion table (true item:type -> declared
item:type or "missed"). Times in s; R runs, K frames, nf monitored entries, nw world faults.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from fdir_service.runtime.publishing import UNCLEAR
from sim_bridge.faults import EDGE_TOL_S
from sim_bridge.scenario import ProfileComponent
from sim_bridge.yardstick import (
    EPS_S,
    Hysteresis,
    declarations,
    declared_during,
    delay_stats,
    episode_window,
    episodes,
    first_declared,
    first_standing,
)

UNITLESS_TYPES = ("noisy", "effectiveness", "engine")
"""Types whose additive-equivalent value is a factor minus 1 (k - 1, g - 1): no unit."""
ANSWERS: dict[str, tuple[str, ...]] = {"blocked": ("blocked", "stuck")}
"""World type -> the estimator types that answer it rightly (default: the same type only)."""
FALLBACK_ANSWERS: dict[str, tuple[str, ...]] = {"engine": ("effectiveness",)}
"""World type -> the types that answer it where the item has no entry of the right type: an engine
loss is the throttle's lost effectiveness for an estimator without an engine entry."""
MISSED = "missed"
SETTLE_S = 2.0
"""The most probable type this long after the declaration: the `right_settled` figure beside the
type named (`named_entry`) and the most probable at the declaration."""
GOALS = {"detection_fraction": 0.95, "delay_median_s": 2.0, "right_fraction": 0.90,
         "false_alarms_per_hour": 0.1}
"""The issue's acceptance: >= 95 % detected, median delay <= 2 s, right item and type >= 90 %,
<= 0.1 false alarms per flight hour with every type enabled."""


class Kind(NamedTuple):
    """A fault's item (target: measurement row or input) and its type."""

    target: str
    type: str

    def label(self) -> str:
        """"target:type", the confusion table's key."""
        return f"{self.target}:{self.type}"


class WorldFault(NamedTuple):
    """An injected fault as this yardstick sees it: its kind, unit label and SI -> unit divisor,
    and the additive-equivalent size (SI) at which it stands out of its sensor's noise (3 sigma of
    the world's row; 0 for actuators and noisy sensors: from the onset)."""

    kind: Kind
    unit: str
    scale: float
    three_sigma: float = 0.0


def fault_type(fault: Any) -> str:
    """A world channel's or monitored entry's type ("bias" when it has none)."""
    return getattr(fault, "fault_type", "bias")


def kind_of(fault: Any) -> Kind:
    """(target, type) of a FaultChannel or FaultSpec."""
    return Kind(fault.target, fault_type(fault))


def world_fault(channel: Any, sigma: dict[str, float] | None = None) -> WorldFault:
    """A FaultChannel's kind and the unit its magnitude error is reported in; with the world's
    sensor noise sigma (row -> SI), its 3-sigma size on a sensor row."""
    ty = fault_type(channel)
    if ty in UNITLESS_TYPES:
        return WorldFault(Kind(channel.target, ty), "-", 1.0)
    three = 3.0 * (sigma or {}).get(channel.target, 0.0)
    return WorldFault(Kind(channel.target, ty), channel.unit, channel.unit_scale, three)


def three_sigma_frame(truth: np.ndarray, s: int, e: int, three_sigma: float) -> int | None:
    """The first frame of the episode [s, e) at which the additive-equivalent truth (K,) SI reaches
    three_sigma in size (s for 0: from the onset), None if it never does: where a ramp, a blockage
    or a stuck reading, which start at 0, first stand out of the sensor's noise."""
    if three_sigma <= 0.0:
        return s
    k = np.flatnonzero(np.abs(truth[s:e]) >= three_sigma)
    return s + int(k[0]) if k.size else None


def is_typed(channels: Sequence[Any]) -> bool:
    """Whether a world injects any fault that is not a bias (then it is scored by item and type)."""
    return any(fault_type(c) != "bias" for c in channels)


def type_matches(world_type: str, entry_type: str) -> bool:
    """Whether an entry of entry_type is the right answer to a world fault of world_type."""
    return entry_type in ANSWERS.get(world_type, (world_type,))


def item_type_matches(entries: Sequence[Kind], world: Sequence[Kind]) -> list[list[int]]:
    """Per world fault (nw,), the indices of the entries (nf,) of the same item and matching type
    (`type_matches`; else, where the item has none, of a `FALLBACK_ANSWERS` type)."""
    def right(w: Kind) -> list[int]:
        own = [j for j, e in enumerate(entries) if e.target == w.target and type_matches(w.type, e.type)]
        fallback = FALLBACK_ANSWERS.get(w.type, ())
        return own or [j for j, e in enumerate(entries) if e.target == w.target and e.type in fallback]
    return [right(w) for w in world]


def truth_columns(entries: Sequence[Any], channels: Sequence[Any]) -> list[int | None]:
    """Per monitored entry (FaultSpec, nf), the world channel (FaultChannel, index into nw) whose
    value is its truth: the channel of the same id in a bias-only world, else the first channel it
    rightly answers (same item, matching type); None: the world injects none."""
    if not is_typed(channels):
        ids = [c.id for c in channels]
        return [ids.index(e.id) if e.id in ids else None for e in entries]
    right = item_type_matches([kind_of(e) for e in entries], [kind_of(c) for c in channels])
    return [next((w for w, r in enumerate(right) if j in r), None) for j in range(len(entries))]


def component_active(comp: ProfileComponent, t: np.ndarray) -> np.ndarray:
    """(K,) bool: where one profile component acts at times t (K,) s: [start_s, end_s), and for an
    intermittent one only its on phases (edges as `sim_bridge.faults.component_value`)."""
    t = np.asarray(t, float)
    on = (t >= comp.start_s - EDGE_TOL_S) & (t < comp.end_s - EDGE_TOL_S)
    if comp.shape == "intermittent":
        on &= np.mod(t - comp.start_s + EDGE_TOL_S, comp.on_s + comp.off_s) < comp.on_s
    return on


def channel_active(channel: Any, t: np.ndarray) -> np.ndarray:
    """(K,) bool: where any of a channel's profile components acts."""
    out = np.zeros(np.shape(t), bool)
    for comp in channel.profile:
        out |= component_active(comp, t)
    return out


def world_active(channels: Sequence[Any], t: np.ndarray) -> np.ndarray:
    """(K, nw) bool: each channel's activity at times t (K,) s."""
    return np.stack([channel_active(c, t) for c in channels], axis=1) if channels else \
        np.zeros((np.size(t), 0), bool)


def magnitude_sq(estimate: np.ndarray, truth: np.ndarray, active: np.ndarray,
                 scale: float) -> tuple[float, int]:
    """(sum of squared errors, frames) of estimate vs truth (K,) SI over the active frames (K,)
    bool, in the fault's unit (SI / scale); NaN frames left out."""
    err = (np.asarray(estimate, float)[active] - np.asarray(truth, float)[active]) / scale
    ok = np.isfinite(err)
    return float(np.sum(err[ok] ** 2)), int(ok.sum())


class ItemView(NamedTuple):
    """The service's view by item (`fdir_service.runtime.items`): names (ni,), targets (ni,);
    prob (K, ni) P(item faulty); best (K, ni) the index of each item's most probable entry; share
    (K, ni) its share of P(item) (`items.type_share`)."""

    names: list[str]
    targets: list[str]
    prob: np.ndarray
    best: np.ndarray
    share: np.ndarray


def item_view(prob: np.ndarray, entries: Sequence[Kind], names: list[str]) -> ItemView:
    """The items of entries (nf,) and their P (`items.item_probability`) from the entries' P
    prob (..., K, nf); best: the most probable entry of each item per frame."""
    from types import SimpleNamespace

    from fdir_service.runtime.items import item_layout, item_probability, type_share

    layout = item_layout([SimpleNamespace(id=n, target=en.target)
                          for n, en in zip(names, entries, strict=True)])
    p_item = item_probability(prob, layout, [en.type for en in entries])
    filled = np.where(np.isnan(prob), -np.inf, prob)
    best = np.stack([np.asarray(g)[np.argmax(filled[..., g], axis=-1)] for g in layout.entries], axis=-1)
    p_best = np.take_along_axis(prob, best, axis=-1)
    return ItemView(list(layout.names), list(layout.targets), p_item, best, type_share(p_best, p_item))


def sure_since(t: np.ndarray, sure: np.ndarray, best: np.ndarray) -> np.ndarray:
    """(K,) s: the first frame time of each frame's run in which the same entry `best` (K,) has been
    clear enough to name (`sure` (K,) bool), NaN where it is not (`publishing.Publisher._track_type`)."""
    new = sure.copy()
    new[1:] &= ~(sure[:-1] & (best[1:] == best[:-1]))
    first = np.maximum.accumulate(np.where(new, np.arange(sure.size), 0))
    return np.where(sure, t[first], np.nan)


def named_entry(t: np.ndarray, dec: np.ndarray, view: ItemView, i: int, k0: int,
                rule: Hysteresis) -> tuple[int, int] | None:
    """(frame, entry) where the service names the type of item i declared at frame k0
    (`publishing.Publisher`): the first frame from k0 on, while the declaration stands, where the
    most probable entry has held a share >= p_type of P(item) >= p_declare for type_hold_s (after
    k0: and at least declare_hold_s); None if never. dec (K,): the item's declaration."""
    best = view.best[:, i]
    sure = (view.share[:, i] >= rule.p_type) & (np.nan_to_num(view.prob[:, i]) >= rule.p_declare)
    rest = dec[k0 + 1:]
    end = k0 + 1 + (int(np.argmin(rest)) if not rest.all() else rest.size)   # the declaration's end
    held = t[:end] - sure_since(t[:end], sure[:end], best[:end])          # NaN where not sure
    if held[k0] >= rule.type_hold_s - EPS_S:
        return k0, int(best[k0])
    later = k0 + 1 + np.flatnonzero(held[k0 + 1:] >= max(rule.type_hold_s, rule.declare_hold_s) - EPS_S)
    return (int(later[0]), int(best[later[0]])) if later.size else None


def typed_episode(t: np.ndarray, dec: np.ndarray, view: ItemView, entries: Sequence[Kind],
                  fault: WorldFault, right: list[int], s: int, e: int, rule: Hysteresis) -> dict:
    """Detection and isolation of one episode [s, e) of a world fault, against the item
    declarations dec (K, ni) (`ItemView`: item names break ties); right: indices of its right
    entries. The type declared is the one the service names (`named_entry`; "unclear" if none
    before the declaration ends), beside the most probable at the first declared frame
    (`right_probable`) and SETTLE_S later (`right_settled`). Magnitude fields: `typed_run`."""
    win = episode_window(t, s, e)
    item = [i for i, tg in enumerate(view.targets) if tg == fault.kind.target]
    hit = first_standing(dec, win, item)
    first = first_declared(dec, win, item, view.names)
    out = {"item": fault.kind.target, "type": fault.kind.type, "detected": hit is not None,
           "delay_s": float(t[s + hit[0]] - t[s]) if hit else None,
           "during": hit is not None and s + hit[0] < e, "declared": MISSED,
           "right": False, "right_probable": False, "right_settled": False, "right_item": False,
           "named_s": None, "entry": right[0] if right else None}
    if not first:
        return out
    k0, i = win.start + first[0], first[1]
    entry = int(view.best[k0, i])
    settled = int(view.best[min(int(np.searchsorted(t, t[k0] + SETTLE_S)), t.size - 1), i])
    back = dec[k0::-1, i]
    start = 0 if back.all() else k0 - int(np.argmin(back)) + 1          # the declaration's first frame
    named = named_entry(t, dec[:, i], view, i, start, rule)
    target = entries[entry].target
    out.update(declared=Kind(target, entries[named[1]].type if named else UNCLEAR).label(),
               right=named is not None and named[1] in right, right_probable=entry in right,
               right_settled=settled in right, right_item=target == fault.kind.target,
               named_s=max(0.0, float(t[named[0]] - t[k0])) if named else None,
               entry=entry if entry in right else out["entry"])
    return out


def typed_run(t: np.ndarray, prob: np.ndarray, f_hat: np.ndarray, entries: Sequence[Kind],
              names: list[str], faults: Sequence[WorldFault], truth: np.ndarray, active: np.ndarray,
              rule: Hysteresis) -> list[dict]:
    """One run's episodes (`typed_episode`, plus sq_err and n: the magnitude error's sum of squares
    and frames): prob, f_hat (K, nf) P(fault) and estimates (SI) of the entries; truth (K, nw) the
    world's additive-equivalent values (SI), active (K, nw) bool its activity."""
    view = item_view(prob, entries, names)
    dec = declarations(t, view.prob, rule)
    right = item_type_matches(entries, [f.kind for f in faults])
    out = []
    for w, fault in enumerate(faults):
        for s, e in episodes(active[:, w]):
            ep = typed_episode(t, dec, view, entries, fault, right[w], s, e, rule)
            ep["delay_3sigma_s"] = _delay_past(t, ep["delay_s"], s, three_sigma_frame(truth[:, w], s, e,
                                                                                       fault.three_sigma))
            j = ep.pop("entry")
            sq, n = magnitude_sq(f_hat[s:e, j], truth[s:e, w], active[s:e, w], fault.scale) \
                if j is not None else (0.0, 0)
            out.append({**ep, "unit": fault.unit, "sq_err": sq, "n": n})
    return out


def _delay_past(t: np.ndarray, delay_s: float | None, s: int, c: int | None) -> float | None:
    """The detection delay (s) from frame c, where the fault reached 3 sigma, instead of the onset
    s (0 if declared before; None if missed or it never did)."""
    if delay_s is None or c is None:
        return None
    return max(0.0, delay_s - float(t[c] - t[s]))


def _fraction(eps: list[dict], key: str) -> float | None:
    """Share of episodes whose key is true; None without episodes."""
    return sum(1 for ep in eps if ep[key]) / len(eps) if eps else None


def magnitude_rmse(eps: list[dict]) -> dict[str, float]:
    """unit -> RMSE of the magnitude over every active frame of the episodes (units not pooled)."""
    out = {}
    for unit in dict.fromkeys(ep["unit"] for ep in eps):
        sq = sum(ep["sq_err"] for ep in eps if ep["unit"] == unit)
        n = sum(ep["n"] for ep in eps if ep["unit"] == unit)
        if n:
            out[unit] = float(np.sqrt(sq / n))
    return out


def type_row(eps: list[dict]) -> dict:
    """The pooled figures of one fault type's episodes."""
    delays = [ep["delay_s"] for ep in eps if ep["delay_s"] is not None]
    named = [ep["named_s"] for ep in eps if ep["named_s"] is not None]
    past = [ep["delay_3sigma_s"] for ep in eps if ep.get("delay_3sigma_s") is not None]
    return {"episodes": len(eps), "detected": len(delays),
            "detection_fraction": _fraction(eps, "detected"), "delay_s": delay_stats(delays),
            "delay_3sigma_s": delay_stats(past),
            "detected_during": declared_during(eps),
            "right_fraction": _fraction(eps, "right"), "right_item_fraction": _fraction(eps, "right_item"),
            "right_probable_fraction": _fraction(eps, "right_probable"),
            "right_settled_fraction": _fraction(eps, "right_settled"),
            "named": len(named), "named_s": delay_stats(named), "magnitude_rmse": magnitude_rmse(eps)}


def confusion(eps: list[dict]) -> dict[str, dict[str, int]]:
    """True "item:type" -> {declared "item:type" or "missed": episodes}."""
    out: dict[str, dict[str, int]] = {}
    for ep in eps:
        row = out.setdefault(Kind(ep["item"], ep["type"]).label(), {})
        row[ep["declared"]] = row.get(ep["declared"], 0) + 1
    return out


def pool_by_type(eps: list[dict]) -> dict:
    """The episodes of all runs pooled: {"types": type -> `type_row`, "confusion": `confusion`}."""
    types = dict.fromkeys(ep["type"] for ep in eps)
    return {"types": {ty: type_row([ep for ep in eps if ep["type"] == ty]) for ty in types},
            "confusion": confusion(eps)}


def typed_yardstick(t: np.ndarray, prob: np.ndarray, f_hat: np.ndarray, entries: Sequence[Kind],
                    names: list[str], faults: Sequence[WorldFault], truth: np.ndarray,
                    active: np.ndarray, rule: Hysteresis | None = None) -> dict:
    """`pool_by_type` of one filter over R runs: prob, f_hat (R, K, nf); truth (R, K, nw) SI,
    active (R, K, nw) bool. A run with NaN P everywhere (failed) is left out."""
    rule = rule or Hysteresis.of_service()
    eps = [ep for r in range(prob.shape[0]) if np.isfinite(prob[r]).any()
           for ep in typed_run(t, prob[r], f_hat[r], entries, names, faults, truth[r], active[r], rule)]
    return pool_by_type(eps)


def run_activity(scenario: Any, sim_seeds: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(R, K, nw) bool: each run's world fault activity at times t (K,) s, from the profiles that
    run flew (`sim_bridge.simulate.run_faults` of its simulator seed, sim_seeds (R,))."""
    from sim_bridge.simulate import run_faults

    return np.stack([world_active(run_faults(scenario, int(seed)).faults, t) for seed in sim_seeds])


def scenario_yardsticks(scenario: Any, t: np.ndarray, prob: np.ndarray, f_hat: np.ndarray,
                        world_faults: np.ndarray, sim_seeds: np.ndarray,
                        rule: Hysteresis | None = None) -> tuple[dict, dict]:
    """A typed world's inputs to the strict yardstick, by item as the service declares
    ({"prob": (R, K, ni) P(item faulty), "fault_ids": item names, "right": per world fault its
    item, "world_active": (R, K, nw)}), and the per-type pool (`typed_yardstick`).
    prob, f_hat (R, K, nf); world_faults (R, K, nw) additive-equivalent truth (SI); rule: the
    per-type pool's hysteresis (default: the service's)."""
    entries = [kind_of(f) for f in scenario.estimator.faults]
    names = [f.id for f in scenario.estimator.faults]
    active = run_activity(scenario, sim_seeds, t)
    sigma = getattr(getattr(scenario, "sensors", None), "sigma", None)     # the world's sensor noise
    faults = [world_fault(c, sigma) for c in scenario.faults]
    view = item_view(prob, entries, names)
    right = [[i for i, tg in enumerate(view.targets) if tg == f.kind.target] for f in faults]
    strict = {"prob": view.prob, "fault_ids": view.names, "right": right, "world_active": active}
    return strict, typed_yardstick(t, prob, f_hat, entries, names, faults, world_faults, active, rule)
