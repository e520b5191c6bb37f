"""Two campaigns of the same flights compared flight by flight: did a change remove false alarms, or
only move them to other flights?

A world's false alarms cluster in flights (a flight whose state departs raises several), so two
totals that differ by a handful say little. Flown on the same seed, run r of both campaigns is the
same world, sensors and injected faults; only the estimator differs. Per filter, this pairs run r's
false alarms (count and seconds standing, from results.json's `false_alarm_list`) and gives:
the flights where the change has fewer, more and as many; the sign test's two-sided p on the
flights that differ (binomial, half each way under no effect); and a 95 % interval on the change
of the total, resampling flights with replacement (a paired bootstrap, `BOOTSTRAP_DRAWS` draws of
a fixed seed: the same campaigns, the same interval).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

BOOTSTRAP_DRAWS = 10000


class NotPairedError(ValueError):
    """The two campaigns did not fly the same flights."""


def load_results(path: str | Path) -> dict:
    """results.json of a campaign: the file, or the folder `sim-bridge experiment --out` wrote."""
    p = Path(path)
    p = p / "results.json" if p.is_dir() else p
    try:
        return json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: not a campaign's results.json ({exc})") from None


def per_run(doc: dict, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(false alarms (R,), seconds they stood (R,)) of filter `name` in each of the doc's R runs."""
    fa = doc["filters"][name]["yardstick"]["false_alarm_list"]
    count, seconds = np.zeros(doc["runs"]), np.zeros(doc["runs"])
    for f in fa:
        if not 0 <= f["run"] < doc["runs"]:
            raise ValueError(f"false alarm in run {f['run']} of a campaign of {doc['runs']} runs")
        count[f["run"]] += 1
        seconds[f["run"]] += f["s"]
    return count, seconds


@dataclass(frozen=True)
class PairedFalseAlarms:
    """Run-by-run comparison of filter `name`'s false alarms in campaign A (before) and B (after)."""

    name: str
    runs: int
    total: tuple[int, int]
    runs_with: tuple[int, int]
    seconds: tuple[float, float]
    fewer: int
    more: int
    sign_p: float
    change_95: tuple[float, float]


def _check_paired(a: dict, b: dict) -> None:
    for key in ("runs", "seed", "navigation"):
        if a.get(key) != b.get(key):
            raise NotPairedError(f"the campaigns differ in {key} ({a.get(key)} against {b.get(key)}): "
                                 "not the same flights")


def compare(a: dict, b: dict, name: str) -> PairedFalseAlarms:
    """Filter `name`'s false alarms in campaigns a and b (results.json docs of the same flights)."""
    _check_paired(a, b)
    (ca, sa), (cb, sb) = per_run(a, name), per_run(b, name)
    d = cb - ca
    fewer, more = int(np.count_nonzero(d < 0)), int(np.count_nonzero(d > 0))
    p = binomtest(fewer, fewer + more).pvalue if fewer + more else 1.0
    rng = np.random.default_rng(0)
    draws = d[rng.integers(0, d.size, size=(BOOTSTRAP_DRAWS, d.size))].sum(axis=1)
    lo, hi = np.percentile(draws, [2.5, 97.5])
    return PairedFalseAlarms(name, int(d.size), (int(ca.sum()), int(cb.sum())),
                             (int(np.count_nonzero(ca)), int(np.count_nonzero(cb))),
                             (float(sa.sum()), float(sb.sum())), fewer, more, float(p),
                             (float(lo), float(hi)))


def paired_lines(c: PairedFalseAlarms) -> list[str]:
    """What `sim-bridge compare` prints of one filter."""
    (ta, tb), (ra, rb), (sa, sb) = c.total, c.runs_with, c.seconds
    lo, hi = c.change_95
    verdict = "a change" if lo > 0 or hi < 0 else "within the flights' noise"
    return [f"{c.name}: false alarms {ta} -> {tb} (in {ra} -> {rb} of {c.runs} flights; standing "
            f"{sa:.0f} -> {sb:.0f} s)",
            f"  flights with fewer {c.fewer}, with more {c.more}, as many {c.runs - c.fewer - c.more}; "
            f"sign test p = {c.sign_p:.2f}",
            f"  change of the total, 95 % (flights resampled): {lo:+.0f} to {hi:+.0f}: {verdict}"]
