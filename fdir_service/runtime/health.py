"""Estimator and link health, and the re-initialisation decisions (config `[health]`).

After each filter step `EstimatorHealth.check` names a `HealthProblem` or None: a non-finite
estimate, a non-physical jump of the airframe estimate (`max_state_jump`, per frame), the filter's
own re-initialisation counter moving, or a particle filter's N_eff below `min_n_eff` on
`degenerate_frames` frames in a row. `must_reinitialise` says whether to act now: acute problems
(non-finite, jump, the filter raising) always, the others only outside `reinit_holdoff_s` of frame
time after the last re-initialisation. The new filter starts from `state_from_measurements`.
The HEARTBEAT says CRITICAL (`heartbeat_state`) while a row is stale, within the holdoff, or while
the link is lost.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.measurement import MEASURED_STATE, measured_state
from fdir_service.mavlink import dialect
from fdir_service.runtime.events import Cause, HealthProblem

if TYPE_CHECKING:
    from fdir_service.estimator_config import EstimatorConfig
    from fdir_service.runtime.frames import AssembledFrame
    from fdir_service.service_config import HealthConfig

STATE_LABELS = ("p_d", "u", "w", "theta", "q")
NON_FINITE = HealthProblem(Cause.NON_FINITE, "non-finite estimate")
FILTER_RESET = HealthProblem(Cause.FILTER_RESET, "filter lost every particle")
INPUT_RESUMED = HealthProblem(Cause.INPUT_RESUMED, "input resumed after a gap")


def filter_raised(error: BaseException) -> HealthProblem:
    """The problem of a filter.step that raised `error`."""
    return HealthProblem(Cause.FILTER_RAISED, f"filter raised {type(error).__name__}")


def is_finite(out: StepOutput) -> bool:
    """Whether every estimate in the step output is finite (state, faults, P(fault), N_eff)."""
    return bool(np.isfinite(out.x_mean).all() and np.isfinite(out.fault_probability).all()
                and np.isfinite(out.fault_estimate).all() and np.isfinite(out.n_eff))


class EstimatorHealth:
    """The estimator's health state between frames (see the module doc). `config`: `[health]`;
    `estimator`: gives the rows (measurement names) and their filter sigmas."""

    def __init__(self, config: HealthConfig, estimator: EstimatorConfig, filter_reinits: int = 0) -> None:
        self.config = config
        self.estimator = estimator
        self.sigma = np.asarray(estimator.filter_sigma(), dtype=float)
        self.rows = [MEASURED_STATE.get(name) for name in estimator.measurements]
        jump = tuple(getattr(config, "max_state_jump", ()) or ())
        self.max_jump = np.asarray(jump, dtype=float) if len(jump) == 5 else None
        self.filter_reinits = filter_reinits          # the filter's own counter, last seen
        self.low_neff = 0                             # frames in a row with N_eff < min_n_eff
        self.last_reinit_us: int | None = None
        self.last_good_state: np.ndarray | None = None   # (5,) of the last frame without a problem
        self.prev_state: np.ndarray | None = None        # (5,) last published airframe estimate

    # ------------------------------------------------------------------ checks
    def check(self, out: StepOutput, filt, frame: AssembledFrame) -> HealthProblem | None:
        """The problem after this frame's step, or None; the jump check is skipped across a
        restart or a synthetic frame."""
        prev = None if (frame.restart or frame.synthetic) else self.prev_state
        return self.problem(out, filt, prev)

    def problem(self, out: StepOutput, filt, prev: np.ndarray | None = None) -> HealthProblem | None:
        """Why the filter `filt` needs re-initialising after its step output `out`, or None. prev:
        the previous frame's airframe estimate (5,), for the state-jump check."""
        if not is_finite(out):
            return NON_FINITE
        jump = self.state_jump(out, prev)
        if jump is not None:
            return jump
        n = int(getattr(filt, "reinitialisations", 0))
        if n != self.filter_reinits:
            self.filter_reinits = n
            return FILTER_RESET
        return self._degenerate(out, filt)

    def state_jump(self, out: StepOutput, prev: np.ndarray | None) -> HealthProblem | None:
        """A jump of an airframe state beyond max_state_jump since prev (5,), e.g. "p_d jump +2e+04/frame"."""
        if prev is None or self.max_jump is None:
            return None
        jump = np.abs(np.asarray(out.x_mean[:5], dtype=float) - prev) > self.max_jump
        if not jump.any():
            return None
        j = int(np.argmax(jump))
        return HealthProblem(Cause.STATE_JUMP, f"{STATE_LABELS[j]} jump {out.x_mean[j] - prev[j]:+.3g}/frame")

    def _degenerate(self, out: StepOutput, filt) -> HealthProblem | None:
        """A particle filter with N_eff < min_n_eff for degenerate_frames frames in a row."""
        if hasattr(filt, "N") and out.n_eff < self.config.min_n_eff:
            self.low_neff += 1
            if self.low_neff >= self.config.degenerate_frames:
                return HealthProblem(Cause.DEGENERATE,
                                     f"N_eff < {self.config.min_n_eff:g} for {self.low_neff} frames")
        else:
            self.low_neff = 0
        return None

    def in_holdoff(self, time_us: int) -> bool:
        """Whether frame time time_us (us) is within reinit_holdoff_s after the last re-initialisation."""
        return (self.last_reinit_us is not None
                and time_us - self.last_reinit_us < self.config.reinit_holdoff_s * 1e6)

    def must_reinitialise(self, problem: HealthProblem, time_us: int) -> bool:
        """Act on `problem` now: always when acute, else only outside the holdoff."""
        return problem.acute or not self.in_holdoff(time_us)

    # ------------------------------------------------------------------ bookkeeping
    def started(self, filt) -> None:
        """A filter `filt` started on the first frame (operating_point.init = "first_frame"): not a
        re-initialisation (no holdoff), only its counters are taken."""
        self.filter_reinits = int(getattr(filt, "reinitialisations", 0))
        self.low_neff = 0

    def reinitialised(self, filt, time_us: int) -> None:
        """A new filter `filt` was built at frame time time_us (us)."""
        self.filter_reinits = int(getattr(filt, "reinitialisations", 0))
        self.low_neff = 0
        self.last_reinit_us = time_us

    def healthy(self, out: StepOutput) -> None:
        """A step without a problem: its airframe estimate is the reference for the next rebuild."""
        if np.isfinite(out.x_mean[:5]).all():
            self.last_good_state = np.asarray(out.x_mean[:5], dtype=float).copy()

    def published(self, out: StepOutput) -> None:
        """The step output being published: the reference of the next frame's jump check."""
        x5 = np.asarray(out.x_mean[:5], dtype=float)
        self.prev_state = x5.copy() if np.isfinite(x5).all() else None

    def heartbeat_state(self, frame: AssembledFrame, link_lost: bool) -> int:
        """MAV_STATE for the HEARTBEAT: CRITICAL while a row is stale, within the re-initialisation
        holdoff or with the link lost, else ACTIVE."""
        critical = frame.stale or self.in_holdoff(frame.time_us) or link_lost
        return dialect.MAV_STATE_CRITICAL if critical else dialect.MAV_STATE_ACTIVE

    # ------------------------------------------------------------------ re-initialisation
    def state_from_measurements(self, y: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """An airframe state (5,) made from one frame's measurements y (m,) where mask (m,), and the
        rows (m,) bool that agree with it within `reinit_gate_sigmas` sigma.

        Each state is the measurement of a row that measures it (altitudes: -p_d); where several
        rows measure one state, the one nearest the last healthy estimate (or the trim state) wins,
        so a glitching altitude sensor does not pick the state. States no row measures keep the
        last healthy estimate.
        """
        from fdir_service.estimation.factory import trim_state

        ref = self.last_good_state if self.last_good_state is not None else trim_state(self.estimator)
        x0 = measured_state(self.estimator.measurements, y, mask, ref)
        keep = mask.copy()
        for j, row in enumerate(self.rows):
            if row is not None and keep[j]:
                col, coef = row
                keep[j] = abs(y[j] / coef - x0[col]) <= self.config.reinit_gate_sigmas * self.sigma[j]
        return x0, keep
