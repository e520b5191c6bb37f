"""Monte Carlo metrics of SPEC section 8: RMSE over runs, the thesis's table columns, the median
run, and detection delay / false-alarm / missed-detection fractions.

Array conventions: R runs, K steps, nf fault channels. Times in s. The functions are unit-agnostic
(convert to table units, e.g. degrees, before calling them).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

TABLE_TIMES = (10.05, 20.05, 30.05, 40.05)
"""The instants (s) at which the thesis's tables report RMSE_k."""


def rmse_over_runs(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """RMSE_k = sqrt(mean over runs of (estimate - truth)^2): (R, K, ...) -> (K, ...).

    Runs whose estimate is NaN at a step are left out of that step's mean; all-NaN gives NaN.
    """
    err2 = (np.asarray(estimate, float) - np.asarray(truth, float)) ** 2
    with np.errstate(invalid="ignore"):
        n = np.sum(np.isfinite(err2), axis=0)
        s = np.nansum(err2, axis=0)
        return np.where(n > 0, np.sqrt(s / np.maximum(n, 1)), np.nan)


def time_index(t: np.ndarray, at: float) -> int:
    """Index of the step whose time is nearest to `at` (s)."""
    return int(np.argmin(np.abs(np.asarray(t, float) - at)))


def table_columns(rmse_k: np.ndarray, t: np.ndarray, times: tuple[float, ...] = TABLE_TIMES) -> dict:
    """The thesis's columns of one quantity: RMSE_k at each of `times` (keys "10.05", ...) and
    "mean" = time-average of RMSE_k over the run. rmse_k (K,), t (K,) s. NaN becomes None."""
    out: dict[str, float | None] = {}
    for at in times:
        out[f"{at:.2f}"] = _num(rmse_k[time_index(t, at)])
    out["mean"] = _num(np.mean(rmse_k)) if np.all(np.isfinite(rmse_k)) else None
    return out


def _num(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def median_run(abs_errors: np.ndarray) -> int:
    """The median run of SPEC section 8.

    abs_errors (R, K, nf) = |f - f_hat| per run, step and fault. Per fault, the run's score is the
    time-mean error; scores are standardised across runs (minus mean, over std; a fault whose
    scores do not vary contributes 0), averaged over faults, sorted, and the run of (1-based) rank
    floor(R/2 + 1/2) is returned (as a 0-based run index). Runs with a NaN score (failed) are left out.
    """
    e = np.asarray(abs_errors, float)
    if e.ndim == 2:
        e = e[:, :, None]
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)    # all-NaN runs (failed) are skipped
        score = np.nanmean(e, axis=1)                       # (R, nf)
    runs = np.flatnonzero(np.all(np.isfinite(score), axis=1))
    if runs.size == 0:
        return 0
    score = score[runs]
    mu = score.mean(axis=0)
    sd = score.std(axis=0)
    z = np.where(sd > 0, (score - mu) / np.where(sd > 0, sd, 1.0), 0.0)
    avg = z.mean(axis=1)
    order = np.argsort(avg, kind="stable")
    rank = int(math.floor(len(avg) / 2 + 0.5))          # 1-based
    return int(runs[order[max(rank, 1) - 1]])


def fault_episodes(active: np.ndarray) -> list[tuple[int, int]]:
    """[(start, end)) step ranges where the boolean (K,) `active` is True."""
    a = np.concatenate([[False], np.asarray(active, bool), [False]])
    d = np.diff(a.astype(np.int8))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def held_above(prob: np.ndarray, hold_steps: int, threshold: float = 0.5) -> np.ndarray:
    """held[k] = prob > threshold on every step k .. k + hold_steps - 1 (steps past the end count as
    not held). prob (..., K) -> bool (..., K)."""
    above = np.asarray(prob, float) > threshold
    if hold_steps <= 1:
        return above
    K = above.shape[-1]
    c = np.concatenate([np.zeros(above.shape[:-1] + (1,), int), np.cumsum(above, axis=-1)], axis=-1)
    held = np.zeros_like(above)
    n = K - hold_steps + 1
    if n > 0:
        held[..., :n] = (c[..., hold_steps:] - c[..., :n]) == hold_steps
    return held


def detection_metrics(t: np.ndarray, prob: np.ndarray, truth: np.ndarray, hold_s: float = 0.25,
                      threshold: float = 0.5) -> dict:
    """Detection figures of one fault channel over R runs (SPEC section 8).

    t (K,) s; prob (R, K) = P(fault); truth (R, K) true fault value (0 where fault-free).
    Returns delay_s (mean over detected episodes of: time from onset to the first step inside the
    episode at which P > threshold then holds for hold_s), delay_median_s, detected_fraction (of
    episodes), false_alarm_fraction (of fault-free steps with P > threshold) and missed_fraction (of
    faulty steps with P <= threshold). Fractions pool all runs; None where undefined.
    """
    t = np.asarray(t, float)
    prob = np.atleast_2d(np.asarray(prob, float))
    truth = np.atleast_2d(np.asarray(truth, float))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    hold_steps = max(1, int(round(hold_s / dt)))
    active = truth != 0.0
    above = prob > threshold
    held = held_above(prob, hold_steps, threshold)
    delays: list[float] = []
    episodes = 0
    for r in range(prob.shape[0]):
        for start, end in fault_episodes(active[r]):
            episodes += 1
            hits = np.flatnonzero(held[r, start:end])
            if hits.size:
                delays.append(float(t[start + hits[0]] - t[start]))
    free = ~active
    return {
        "delay_s": _num(np.mean(delays)) if delays else None,
        "delay_median_s": _num(np.median(delays)) if delays else None,
        "detected_fraction": (len(delays) / episodes) if episodes else None,
        "false_alarm_fraction": _num(np.mean(above[free])) if free.any() else None,
        "missed_fraction": _num(np.mean(~above[active])) if active.any() else None,
    }
