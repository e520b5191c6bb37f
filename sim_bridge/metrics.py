"""The metrics of SPEC section 8, in one place: RMSE (over runs and over time), the thesis's table
columns, the median run, and detection delay / false-alarm / missed-detection fractions.

Used by the Monte Carlo campaigns (`sim_bridge.report`) and the replay scorer
(`sim_bridge.replay_score`).

Definitions:
- RMSE_k = sqrt(mean over runs of (estimate - truth)^2) at step k; a single run's RMSE is
  sqrt(time-mean of (estimate - truth)^2). NaN (failed run, missing frame) is left out.
- A fault *episode* is a maximal stretch of steps where the true fault is active (non-zero, or
  the world's recorded activity when given: a typed fault can be active at value 0).
  *Detection delay*: time from the episode's first step to the first step inside it at which
  P(fault) > 0.5 and stays above 0.5 for `HOLD_S` = 0.25 s (5 steps at 20 Hz).
  *False-alarm time fraction*: share of fault-free steps with P(fault) > 0.5.
  *Missed-detection time fraction*: share of faulty steps with P(fault) <= 0.5.
- Median run: per fault, each run's time-mean |f - f_hat|, standardised across runs, averaged over
  faults; the run of (1-based) rank floor(R/2 + 1/2) in ascending order.

Array conventions: R runs, K steps, nf fault channels. Times in s. The functions are unit-agnostic
(convert to table units, e.g. degrees, before calling them).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from fdir_service.recording.schemas import finite_or_none

TABLE_TIMES = (10.05, 20.05, 30.05, 40.05)
"""The instants (s) at which the thesis's tables report RMSE_k."""

HOLD_S = 0.25
"""Detection: P(fault) must stay above the threshold this long (s)."""

P_THRESHOLD = 0.5
"""Detection threshold on P(fault)."""


def rmse(estimate: np.ndarray, truth: np.ndarray) -> float:
    """RMSE of one run: sqrt(time-mean of (estimate - truth)^2), NaN steps left out (NaN if none)."""
    err2 = (np.asarray(estimate, float) - np.asarray(truth, float)) ** 2
    ok = np.isfinite(err2)
    return float(np.sqrt(np.mean(err2[ok]))) if ok.any() else float("nan")


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
        out[f"{at:.2f}"] = finite_or_none(rmse_k[time_index(t, at)])
    out["mean"] = finite_or_none(np.mean(rmse_k)) if np.all(np.isfinite(rmse_k)) else None
    return out


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


def held_above(prob: np.ndarray, hold_steps: int, threshold: float = P_THRESHOLD) -> np.ndarray:
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


def hold_steps_of(dt: float, hold_s: float = HOLD_S) -> int:
    """The hold time hold_s (s) in steps of dt (s), at least 1."""
    return max(1, int(round(hold_s / dt)))


def episode_delays(t: np.ndarray, prob: np.ndarray, active: np.ndarray, hold_steps: int,
                   threshold: float = P_THRESHOLD) -> list[tuple[int, int, float | None]]:
    """One run's fault episodes as (start, end, delay_s): steps [start, end) where `active` (K,)
    is True, and the detection delay (s) of each, None if never detected. t, prob (K,)."""
    t = np.asarray(t, float)
    held = held_above(prob, hold_steps, threshold)
    out: list[tuple[int, int, float | None]] = []
    for start, end in fault_episodes(active):
        hits = np.flatnonzero(held[start:end])
        out.append((start, end, float(t[start + hits[0]] - t[start]) if hits.size else None))
    return out


def false_alarm_fraction(prob: np.ndarray, active: np.ndarray,
                         threshold: float = P_THRESHOLD) -> float | None:
    """Share of fault-free steps (active False) with P(fault) > threshold; None if none is free.
    Any shape; all steps are pooled."""
    free = ~np.asarray(active, bool)
    return finite_or_none(np.mean(np.asarray(prob, float)[free] > threshold)) if free.any() else None


def missed_fraction(prob: np.ndarray, active: np.ndarray, threshold: float = P_THRESHOLD) -> float | None:
    """Share of faulty steps (active True) with P(fault) <= threshold; None if none is faulty."""
    act = np.asarray(active, bool)
    return finite_or_none(np.mean(~(np.asarray(prob, float)[act] > threshold))) if act.any() else None


def detection_metrics(t: np.ndarray, prob: np.ndarray, truth: np.ndarray, hold_s: float = HOLD_S,
                      threshold: float = P_THRESHOLD, active: np.ndarray | None = None) -> dict:
    """Detection figures of one fault channel over R runs (SPEC section 8).

    t (K,) s; prob (R, K) = P(fault); truth (R, K) true fault value (0 where fault-free); active
    (R, K) bool where the fault is active (None: truth != 0).
    Returns delay_s (mean over detected episodes of: time from onset to the first step inside the
    episode at which P > threshold then holds for hold_s), delay_median_s, detected_fraction (of
    episodes), false_alarm_fraction (of fault-free steps with P > threshold) and missed_fraction (of
    faulty steps with P <= threshold). Fractions pool all runs; None where undefined.
    """
    t = np.asarray(t, float)
    prob = np.atleast_2d(np.asarray(prob, float))
    truth = np.atleast_2d(np.asarray(truth, float))
    hold_steps = hold_steps_of(float(np.median(np.diff(t))) if t.size > 1 else 1.0, hold_s)
    active = truth != 0.0 if active is None else np.atleast_2d(np.asarray(active, bool))
    delays: list[float] = []
    episodes = 0
    for r in range(prob.shape[0]):
        for _, _, d in episode_delays(t, prob[r], active[r], hold_steps, threshold):
            episodes += 1
            if d is not None:
                delays.append(d)
    return {
        "delay_s": finite_or_none(np.mean(delays)) if delays else None,
        "delay_median_s": finite_or_none(np.median(delays)) if delays else None,
        "detected_fraction": (len(delays) / episodes) if episodes else None,
        "false_alarm_fraction": false_alarm_fraction(prob, active, threshold),
        "missed_fraction": missed_fraction(prob, active, threshold),
    }
