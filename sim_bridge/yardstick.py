"""The safety engineer's yardstick: what the service would have declared, judged against the world.

The service declares fault j when P(fault j) >= p_declare on every frame for declare_hold_s, and
clears it when P <= p_clear for clear_hold_s (`[publish.declare]` of the service's default config,
`fdir_service.runtime.publishing`). Applied here to each run's P(fault) series (`declared`):
- the **fault-free flight time** is the time while the world injects no fault (any of its faults,
  monitored or not) and not within GRACE_S after an injected fault ended; a **false alarm** is each
  stretch of fault-free time during which one fault stands declared: a declaration that starts
  there, or one that started during an injected fault (of another item, say) and still stands
  when the fault-free time begins; false alarms per flight hour is their ratio over all runs, and
  the **falsely declared fraction** the share of fault-free time with any fault declared;
- an injected fault episode is **detected** when a monitored fault that answers it is declared at
  some frame from its onset to GRACE_S after its end; its **delay** is from the onset to that
  frame (0 if it was declared already). It is **declared while active** when that frame comes
  before the episode's end: a first declaration in the GRACE_S after it is the fault caught late, or
  only the state error it left (a slow ramp the state followed, declared when the reading snaps
  back), and is counted apart (`detected_during`). The answer is the monitored fault of the same id
  (`id_matches`, bias-only worlds) or, in a world of typed faults, every entry of the same item
  and type (`sim_bridge.type_yardstick.item_type_matches`);
- **isolation**: the answering fault when it was detected, else the first other monitored
  fault whose declaration starts in that window, else "none": a confusion table injected id ->
  declared id (a fault declared already, for another reason, is no answer to this one);
- the **ROC**: false alarms per hour and detection fraction over a grid of p_declare.
Times in s; P(fault) series (R, K) per fault; frames at times t (K,).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2

from fdir_service.recording.schemas import finite_or_none
from fdir_service.service_config import TYPE_HOLD_S

GRACE_S = 3.0
"""After an injected fault ends, declarations are neither false alarms nor fault-free time for
this long (the service's clear hold is 1 s; the estimate needs a little more to settle)."""
ROC_THRESHOLDS = (0.6, 0.7, 0.8, 0.9, 0.95, 0.99)
EPS_S = 1e-6


def rate_upper_bound(count: int, hours: float, confidence: float = 0.95) -> float | None:
    """The one-sided upper confidence bound (per hour) on a Poisson rate of which `count` events
    were seen in `hours`: chi2(confidence, 2 (count + 1)) / (2 hours), the exact (Garwood) bound.
    0 false alarms in 10 h says below 0.30 per hour at 95 %; None without hours."""
    if hours <= 0:
        return None
    return float(chi2.ppf(confidence, 2 * (count + 1)) / (2.0 * hours))


@dataclass(frozen=True)
class Hysteresis:
    """The service's declare / clear rule (probabilities, hold times in s)."""

    p_declare: float = 0.9
    declare_hold_s: float = 0.2
    p_clear: float = 0.5
    clear_hold_s: float = 1.0
    p_type: float = 0.8
    type_hold_s: float = TYPE_HOLD_S

    @classmethod
    def of_service(cls) -> Hysteresis:
        """The rule of the service's default config (`[publish.declare]`)."""
        from fdir_service.service_config import load_service_config

        dc = load_service_config().publish.declare
        return cls(dc.p_declare, dc.declare_hold_s, dc.p_clear, dc.clear_hold_s, dc.p_type,
                   dc.type_hold_s)

    def with_threshold(self, p: float) -> Hysteresis:
        """The same rule declaring at p (clearing below min(p_clear, p - 0.1))."""
        return replace(self, p_declare=p, p_clear=min(self.p_clear, p - 0.1))


def first_held(t: np.ndarray, crossing: np.ndarray, start: int, hold_s: float) -> int | None:
    """The first frame >= start where `crossing` has held for hold_s since its run began (a run
    counted from `start` at the earliest), or None."""
    idx = np.flatnonzero(crossing[start:])
    while idx.size:
        s = start + int(idx[0])
        rest = crossing[s:]
        stop = s + (int(np.argmin(rest)) if not rest.all() else rest.size)      # end of the run
        j = int(np.searchsorted(t, t[s] + hold_s - EPS_S, side="left"))
        if j < stop:
            return j
        idx = np.flatnonzero(crossing[stop:])
        start = stop
    return None


def declared(t: np.ndarray, p: np.ndarray, rule: Hysteresis) -> np.ndarray:
    """(K,) bool: whether the service has the fault declared after each frame (P series p (K,))."""
    p = np.nan_to_num(np.asarray(p, dtype=float), nan=0.0)
    up, down = p >= rule.p_declare, p <= rule.p_clear
    out = np.zeros(p.size, dtype=bool)
    i, state = 0, False
    while i < p.size:
        j = first_held(t, down if state else up, i, rule.clear_hold_s if state else rule.declare_hold_s)
        if j is None:
            out[i:] = state
            break
        out[i:j] = state
        state = not state
        out[j] = state
        i = j + 1
    return out


def _onsets(mask: np.ndarray) -> np.ndarray:
    """Indices where a bool series (K,) turns True."""
    m = mask.astype(np.int8)
    return np.flatnonzero(np.diff(m, prepend=0) == 1)


def episodes(active: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the True stretches of active (K,), end exclusive."""
    d = np.diff(active.astype(np.int8), prepend=0, append=0)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def false_alarm_list(t: np.ndarray, false_dec: np.ndarray, fault_ids: list[str], dt: float) -> list[dict]:
    """Each false alarm of one run, {"item", "t_s": its first frame (s), "s": how long it stood
    (s)}, in time order: false_dec (K, nf) the declarations in fault-free time; dt the frame (s)."""
    out = [{"item": fault_ids[j], "t_s": round(float(t[a]), 2), "s": round((b - a) * dt, 2)}
           for j in range(false_dec.shape[1]) for a, b in episodes(false_dec[:, j])]
    return sorted(out, key=lambda fa: (fa["t_s"], fa["item"]))


def quiet_mask(t: np.ndarray, world_active: np.ndarray) -> np.ndarray:
    """(K,) bool: no world fault active and none ended within GRACE_S."""
    quiet = ~world_active
    for _, e in episodes(world_active):
        quiet[e:np.searchsorted(t, t[e - 1] + GRACE_S, side="right")] = False
    return quiet


def episode_window(t: np.ndarray, s: int, e: int) -> slice:
    """The frames from onset s to GRACE_S after the episode's last frame e - 1."""
    return slice(s, int(np.searchsorted(t, t[e - 1] + GRACE_S, side="right")))


def declarations(t: np.ndarray, prob: np.ndarray, rule: Hysteresis) -> np.ndarray:
    """(K, nf) bool: each monitored fault's declaration (`declared`) from its P series prob (K, nf)."""
    if not prob.shape[1]:
        return np.zeros((t.size, 0), bool)
    return np.stack([declared(t, prob[:, j], rule) for j in range(prob.shape[1])], axis=1)


def world_activity(world_faults: np.ndarray, world_active: np.ndarray | None = None) -> np.ndarray:
    """(K, nw) bool: where each injected fault is active: world_active when given (from the
    profiles' intervals: a typed fault's value may be ~0 while active), else its value non-zero."""
    if world_active is not None:
        return np.asarray(world_active, bool)
    return np.nan_to_num(world_faults) != 0.0


def id_matches(fault_ids: list[str], world_ids: list[str]) -> list[list[int]]:
    """Per world fault, the monitored faults (indices into fault_ids) that are its right answer:
    the one of the same id (bias-only worlds), none if unmonitored."""
    return [[fault_ids.index(w)] if w in fault_ids else [] for w in world_ids]


def run_yardstick(t: np.ndarray, prob: np.ndarray, fault_ids: list[str], world_faults: np.ndarray,
                  world_ids: list[str], rule: Hysteresis, right: list[list[int]] | None = None,
                  world_active: np.ndarray | None = None) -> dict:
    """One run: prob (K, nf) P(fault) of the monitored faults fault_ids; world_faults (K, nw) the
    world's injected faults (0 where inactive); right: per world fault, the indices of the monitored
    faults that answer it (default `id_matches`); world_active (K, nw) bool: activity, default
    world_faults != 0. Returns counts to pool over runs (see `pool`)."""
    dec = declarations(t, prob, rule)
    act = world_activity(world_faults, world_active) if world_faults.size else np.zeros((t.size, 0), bool)
    quiet = quiet_mask(t, act.any(axis=1))
    false_dec = dec & quiet[:, None]
    false_alarms = sum(int(_onsets(false_dec[:, j]).size) for j in range(dec.shape[1]))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    out = {"false_alarms": false_alarms, "fault_free_s": float(quiet.sum() * dt),
           "false_declared_s": float(false_dec.any(axis=1).sum() * dt), "episodes": [],
           "false_alarm_list": false_alarm_list(t, false_dec, fault_ids, dt)}
    right = id_matches(fault_ids, world_ids) if right is None else right
    for w, wid in enumerate(world_ids):
        for s, e in episodes(act[:, w]):
            out["episodes"].append(_episode(t, dec, fault_ids, wid, right[w], s, e))
    return out


def _declarations_in(series: np.ndarray, win: slice) -> np.ndarray:
    """Frames (relative to win.start) where a declaration of one fault (K,) bool starts inside win."""
    on = _onsets(series)
    return on[(on >= win.start) & (on < win.stop)] - win.start


def first_standing(dec: np.ndarray, win: slice, cols: list[int]) -> tuple[int, int] | None:
    """(frame relative to win.start, fault index) of the first frame of window win at which one of
    the faults cols stands declared in dec (K, nf) (ties: the lower index), or None."""
    hits = [(int(h[0]), j) for j in cols for h in (np.flatnonzero(dec[win, j]),) if h.size]
    return min(hits) if hits else None


def first_declared(dec: np.ndarray, win: slice, own: list[int],
                   names: list[str]) -> tuple[int, int] | None:
    """(frame relative to win.start, fault index) of the first answer in window win of dec (K, nf):
    a fault of `own` declared at any frame of the window (one standing already counts), any other
    fault only by a declaration that starts inside it; ties go to `own`, then by the faults'
    names (nf,). None: nothing declared."""
    cands = [(int(h[0]), 0, names[j], j) for j in own for h in (np.flatnonzero(dec[win, j]),) if h.size]
    cands += [(int(k[0]), 1, names[j], j) for j in range(dec.shape[1]) if j not in own
              for k in (_declarations_in(dec[:, j], win),) if k.size]
    if not cands:
        return None
    k, _, _, j = min(cands)
    return k, j


def _episode(t: np.ndarray, dec: np.ndarray, fault_ids: list[str], wid: str, own: list[int],
             s: int, e: int) -> dict:
    """Detection and isolation of one injected episode [s, e) of world fault wid, answered by the
    monitored faults `own` (indices into fault_ids); "during": declared before the episode's end."""
    win = episode_window(t, s, e)
    hit = first_standing(dec, win, own)
    if hit:
        k, j = hit
        return {"id": wid, "detected": True, "delay_s": float(t[s + k] - t[s]),
                "during": s + k < e, "isolated_as": fault_ids[j], "right": True}
    first = first_declared(dec, win, [], fault_ids)
    return {"id": wid, "detected": False, "delay_s": None, "during": False,
            "isolated_as": fault_ids[first[1]] if first else "none", "right": False}


def declared_during(eps: list[dict]) -> int:
    """How many episodes (`_episode`, `type_yardstick.typed_episode`) were declared while active."""
    return sum(1 for ep in eps if ep.get("during"))


def delay_stats(delays: list[float]) -> dict:
    """median, p90, max (s; None without delays) and n of detection delays (s)."""
    def q(x: float) -> float | None:
        return finite_or_none(np.percentile(delays, x)) if delays else None

    return {"median": q(50), "p90": q(90), "max": q(100), "n": len(delays)}


def pool(runs: list[dict], world_ids: list[str], run_ids: list[int] | None = None) -> dict:
    """The yardstick over runs (each `run_yardstick`'s output; run_ids: their run numbers, default
    0, 1, ...) as results.json's `yardstick`; "false_alarm_list" names each false alarm's run, and
    "runs_with_false_alarms" counts the runs that raised any (a run whose state departs raises
    several: the count says how clustered they are)."""
    fa = sum(r["false_alarms"] for r in runs)
    hours = sum(r["fault_free_s"] for r in runs) / 3600.0
    false_h = sum(r.get("false_declared_s", 0.0) for r in runs) / 3600.0
    eps = [ep for r in runs for ep in r["episodes"]]
    delays = [ep["delay_s"] for ep in eps if ep["delay_s"] is not None]
    confusion: dict[str, dict[str, int]] = {wid: {} for wid in world_ids}
    for ep in eps:
        row = confusion.setdefault(ep["id"], {})
        row[ep["isolated_as"]] = row.get(ep["isolated_as"], 0) + 1
    right = sum(1 for ep in eps if ep.get("right", ep["isolated_as"] == ep["id"]))

    return {
        "false_alarms": fa, "fault_free_hours": hours,
        "false_alarms_per_hour": (fa / hours) if hours > 0 else None,
        "runs": len(runs), "runs_with_false_alarms": sum(1 for r in runs if r["false_alarms"] > 0),
        "falsely_declared_fraction": (false_h / hours) if hours > 0 else None,
        "episodes": len(eps), "detected": len(delays),
        "detection_fraction": (len(delays) / len(eps)) if eps else None,
        "detected_during": declared_during(eps),
        "delay_s": delay_stats(delays),
        "isolation": confusion,
        "isolation_accuracy": (right / len(eps)) if eps else None,
        "false_alarm_list": [{"run": rid, **fa} for rid, r in zip(run_ids or range(len(runs)), runs,
                                                                 strict=True)
                             for fa in r.get("false_alarm_list", [])],
    }


def yardstick(t: np.ndarray, prob: np.ndarray, fault_ids: list[str], world_faults: np.ndarray,
              world_ids: list[str], rule: Hysteresis | None = None,
              thresholds: tuple[float, ...] = ROC_THRESHOLDS, right: list[list[int]] | None = None,
              world_active: np.ndarray | None = None) -> dict:
    """The yardstick of one filter over R runs: prob (R, K, nf), world_faults (R, K, nw); a run with
    NaN everywhere (failed) is left out. right, world_active (R, K, nw): as `run_yardstick`. Adds
    the ROC over the declare threshold."""
    rule = rule or Hysteresis.of_service()
    ok = [r for r in range(prob.shape[0]) if np.isfinite(prob[r]).any()]

    def at(rl: Hysteresis) -> dict:
        return pool([run_yardstick(t, prob[r], fault_ids, world_faults[r], world_ids, rl, right,
                                   None if world_active is None else world_active[r]) for r in ok],
                    world_ids, ok)

    out = at(rule)
    out["p_declare"] = rule.p_declare
    out["roc"] = [{"p_declare": p, **{k: v for k, v in at(rule.with_threshold(p)).items()
                                      if k in ("false_alarms_per_hour", "detection_fraction")}}
                  for p in thresholds]
    return out
