"""Build any filter of the family from its recipe and an estimator (SPEC sections 5-7).

`build_filter(name, estimator, rng, particles=None, x0=None)` looks the name up in
`recipes.RECIPES` and turns the recipe's slots into part objects with the numbers of the
estimator's `[parts]` table and fault list. Kalman-type filters are built whole (`build_kalman`,
`build_imm`, `build_gating_filter`); particle filters from their parts (`particle_parts`).
KF and IMM-KF always use the linearised model (parts.linear_matrices); the particle filters use
parts.process_model. The filters assume the estimator's own measurement noise.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from fdir_service.airframe.linearize import LinearModel, linear_model
from fdir_service.airframe.params import AirframeParams, load_airframe
from fdir_service.errors import ConfigError
from fdir_service.estimation.adaptive import AdaptiveTransition
from fdir_service.estimation.amplitude import NO_ONSET_STEP, AmplitudePredictor
from fdir_service.estimation.correction import FaultyRowCut, KalmanCorrection, Likelihood
from fdir_service.estimation.drift_type import (
    ClimbOffsetSlope,
    DriftAnchor,
    DriftCorrection,
    DriftJump,
    OffsetSlope,
    drift_entries,
)
from fdir_service.estimation.fault_types import (
    ItemExclusion,
    NoisySentinels,
    TypedCorrection,
    TypedEvolution,
    TypedPredict,
    TypeSwitch,
    exclusion_matrix,
    pair_exclusion,
    same_item,
    sibling_pairs,
)
from fdir_service.estimation.gating import GatedKF, frozen_fault_scenario
from fdir_service.estimation.gyro_unwind import GyroUnwind
from fdir_service.estimation.held_mean import HeldCount, HeldMeanCorrection
from fdir_service.estimation.imm import IMMKalman
from fdir_service.estimation.inputs import RowSplit
from fdir_service.estimation.jump import (
    ActuatorCarry,
    DriftMemory,
    ExitFold,
    FaintExit,
    FixedTransition,
    FoldArming,
    ItemDriftMemory,
    MarkovJump,
    MemoryRollback,
    NoCarry,
    NoFold,
    NoJump,
)
from fdir_service.estimation.kalman import KalmanFilter
from fdir_service.estimation.kinematic import GyroSnap, KinematicProcess, PitchMoment
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.particle import ParticleFilter, Parts
from fdir_service.estimation.pitch_noise import LearnedPitchNoise
from fdir_service.estimation.pitot import wind_entry
from fdir_service.estimation.predict import DriftPredict, GaussianPredict, ModeGatedPredict
from fdir_service.estimation.process import LinearProcess, NonlinearProcess
from fdir_service.estimation.rate_window import RateWindowAmplitude
from fdir_service.estimation.recipes import Recipe, recipe
from fdir_service.estimation.regularize import GlobalJitter, NoJitter, PerModeJitter, h_opt
from fdir_service.estimation.resample import BelowEffectiveSize, EveryStep, resampler
from fdir_service.estimation.sentinels import PriorSentinels, ThesisSentinels, prior_log_constants
from fdir_service.estimator_config import BODY_RATE_ROWS, LATERAL_ROWS, EstimatorConfig

FAULT_THRESHOLD_SIGMAS = 3.0
"""Mode-free filters (KF, RPF, RRPF, bootstrap) report P(|f_j| > 3 sigma_j), sigma_j the fault's
residual standard deviation (measurement sigma for a sensor fault)."""
DRIFT_WINDOW_S = 3.0
"""A new drift fault's rate: half from the slope of its row's offset over this window (s)."""
INTEGRATOR = "expeuler"
"""Integrator of the nonlinear process model (see docs/estimation.md for the measurements)."""


@lru_cache(maxsize=8)
def _airframe(name: str) -> AirframeParams:
    return load_airframe(name)


@lru_cache(maxsize=16)
def _linear(airframe: str, which: str, airspeed: float, altitude: float, dt: float) -> LinearModel:
    return linear_model(_airframe(airframe), which, airspeed, altitude, dt)


def estimator_linear_model(config: EstimatorConfig) -> LinearModel:
    """The estimator's linear model (parts.linear_matrices) about its own airframe's trim at its
    operating point."""
    op = config.operating_point
    return _linear(config.airframe, config.settings.linear_matrices, op.airspeed_mps, op.altitude_m,
                   config.dt_s)


def trim_state(config: EstimatorConfig) -> np.ndarray:
    """Trim airframe state (5,) of the estimator's own airframe at its operating point."""
    return estimator_linear_model(config).trim.z.copy()


def trim_input(config: EstimatorConfig) -> np.ndarray:
    """Trim input [delta_e rad, delta_t] at the operating point (u before any input arrives)."""
    return np.asarray(estimator_linear_model(config).trim.u, dtype=float).copy()


def _parts(scenario: EstimatorConfig):
    layout = FaultLayout.from_estimator(scenario)
    meas = MeasurementModel.build(layout, scenario.observed_sigma())
    est = scenario.settings
    q_std = np.array(list(scenario.state_process_std()) + [f.sigma_f for f in scenario.faults])
    x0_std = np.array(list(est.x0_sigma) + [f.x0_sigma for f in scenario.faults])
    return layout, meas, q_std, x0_std


def _x0(scenario: EstimatorConfig, layout: FaultLayout, x0: np.ndarray | None) -> np.ndarray:
    x = np.zeros(layout.n)
    x[:N_AIRFRAME] = trim_state(scenario) if x0 is None else np.asarray(x0, dtype=float)[:N_AIRFRAME]
    return x


def build_kalman(scenario: EstimatorConfig, x0: np.ndarray | None = None, name: str = "KF",
                 q_std_faults: np.ndarray | None = None, h_fault_columns: bool = True,
                 particles: int | None = None) -> KalmanFilter:
    """KF on the linearised model; q_std_faults (nf,) overrides the faults' sigma_f.

    Its StepOutput.n_eff is the nominal N (particles, else estimator.particles), as base.py says.
    """
    layout, meas, q_std, x0_std = _parts(scenario)
    if q_std_faults is not None:
        q_std[N_AIRFRAME:] = q_std_faults
    if not h_fault_columns:
        meas = MeasurementModel(meas.names, meas.H.copy(), meas.sigma.copy())
        meas.H[:, N_AIRFRAME:] = 0.0
    process = LinearProcess(estimator_linear_model(scenario), layout)
    amp = AmplitudePredictor(layout, meas if h_fault_columns else MeasurementModel.build(
        layout, scenario.observed_sigma()), process.B_actuator, q_std[:N_AIRFRAME])
    return KalmanFilter(process, meas, layout, np.diag(q_std**2), _x0(scenario, layout, x0),
                        np.diag(x0_std**2), name=name,
                        fault_threshold=FAULT_THRESHOLD_SIGMAS * amp.sigma,
                        n_eff=float(particles if particles is not None else scenario.particles))


def build_imm(scenario: EstimatorConfig, x0: np.ndarray | None = None,
              particles: int | None = None) -> IMMKalman:
    """IMM-KF: mode 0 with imm.mode0_sigma_f and no fault columns in H, mode 1 with mode1_sigma_f."""
    imm = scenario.settings.imm
    f0 = build_kalman(scenario, x0, "IMM-KF mode 0", np.array(imm.mode0_sigma_f), h_fault_columns=False,
                      particles=particles)
    f0.F[:, N_AIRFRAME:] = 0.0   # fault-free mode: the fault entries are held at 0 and act on nothing
    f1 = build_kalman(scenario, x0, "IMM-KF mode 1", np.array(imm.mode1_sigma_f), particles=particles)
    p01, p10 = scenario.settings.pi01, scenario.settings.pi10
    M = np.array([[1.0 - p01, p01], [p10, 1.0 - p10]])
    return IMMKalman([f0, f1], M, np.array([1.0, 0.0]))


def _input_positions(estimator: EstimatorConfig, rows: tuple[str, ...]) -> tuple[int, ...] | None:
    """The positions of `rows` in a kinematic model's input u ([delta_e, delta_t] + the input rows),
    or None unless the estimator lists them all."""
    inputs = estimator.input_rows
    return tuple(2 + inputs.index(r) for r in rows) if all(r in inputs for r in rows) else None


def _process(estimator: EstimatorConfig, layout: FaultLayout):
    if estimator.settings.process_model == "kinematic":
        moment = (PitchMoment(_airframe(estimator.airframe), estimator.settings.moment_alpha == "stall_blend")
                  if "airspeed" in estimator.measurements else None)
        return KinematicProcess(estimator.dt_s, layout, moment, estimator.operating_point.airspeed_mps,
                                _input_positions(estimator, LATERAL_ROWS),
                                _input_positions(estimator, BODY_RATE_ROWS),
                                rotation=estimator.settings.velocity_step == "rotation",
                                angle_spread=_angle_spread(estimator), snap=_gyro_snap(estimator))
    lm = estimator_linear_model(estimator)
    if estimator.settings.process_model == "linear":
        return LinearProcess(lm, layout)
    return NonlinearProcess(_airframe(estimator.airframe), lm.trim.z, lm.trim.u, estimator.dt_s, layout,
                            INTEGRATOR)


SNAP_SHARE = 0.5
"""parts.frame_angle = "snap": the frame's angle is spread once the trapezoid could be off by more
than this share of the attitude reading's sigma in one frame, dt |dq| / 2 for the gyro reading's
change dq (at 20 Hz and 0.015 rad: 17 deg/s within a frame). Turbulence moves the gyro by at
most ~10 deg/s a frame in the real worlds (p99.9 ~4); a surface that snaps, by 30-75."""


def _angle_spread(estimator: EstimatorConfig) -> float | None:
    """The trapezoid's error bound (rad) above which some particle's angle makes the kinematic
    model spread a frame's angle (parts.frame_angle = "spread": theta's process noise over a frame;
    `KinematicProcess.angle_spread`); 0 for "snap", where the gyro decides (`_gyro_snap`); None for
    "trapezoid"."""
    kind = estimator.settings.frame_angle
    return float(estimator.state_process_std()[3]) if kind == "spread" else 0.0 if kind == "snap" else None


def _gyro_snap(estimator: EstimatorConfig) -> GyroSnap | None:
    """parts.frame_angle = "snap": the `GyroSnap` on the q row, its limit 2 `SNAP_SHARE` sigma_theta
    / dt (rad/s); else None."""
    if estimator.settings.frame_angle != "snap":
        return None
    missing = [r for r in ("theta", "q") if r not in estimator.measurements]
    if missing:
        raise ConfigError(f"parts.frame_angle = \"snap\" reads the gyro against the attitude reading's "
                          f"sigma: expected measurements.rows listing theta and q, missing {missing}")
    sigma = float(estimator.sigma[estimator.measurements.index("theta")])
    return GyroSnap(estimator.observed.index("q"), 2.0 * SNAP_SHARE * sigma / estimator.dt_s)


def _bandwidth(estimator: EstimatorConfig, n: int, N: int) -> float:
    """h: parts.bandwidth (the thesis's h at estimator.particles, scaled to N as h_opt is), else
    parts.bandwidth_k h_opt(n, N)."""
    est = estimator.settings
    if est.bandwidth is not None:
        return est.bandwidth * h_opt(n, N) / h_opt(n, estimator.particles)
    return est.bandwidth_k * h_opt(n, N)


def _transition(rec: Recipe, estimator: EstimatorConfig, amp: AmplitudePredictor, roc=None):
    """The jump's transition strategy: fixed, or adaptive (proposal unless the recipe says thesis)."""
    pi01, pi10 = (np.array(p) for p in estimator.transition_probabilities())
    if rec.jump == "fixed":
        return FixedTransition(pi01, pi10, amp.layout.nf)
    mode = rec.adaptive_transition if rec.adaptive_transition != "parts" \
        else estimator.settings.adaptive_transition
    return AdaptiveTransition(amp.sigma, estimator.settings.saddlepoint_window, roc=roc, pi01=pi01,
                              pi10=pi10, proposal=mode == "proposal", noisy=amp.layout.noisy_row >= 0)


def _gyro_fault(estimator: EstimatorConfig, layout: FaultLayout) -> int | None:
    """The gyro fault whose amplitude comes from the attitude window (parts.rate_sentinel =
    "window": a sensor fault on q, theta observed), else None."""
    if estimator.settings.rate_sentinel != "window" or "theta" not in layout.measurements:
        return None
    for j, (kind, target) in enumerate(zip(layout.kinds, layout.targets, strict=True)):
        if kind == "sensor" and target == "q" and layout.type_of(j) == "bias":
            return j
    return None


def _amplitude(estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel, process,
               q_std: np.ndarray) -> AmplitudePredictor:
    """The jump's amplitude predictor: each fault's own row, the gyro's from a window if asked."""
    gyro = _gyro_fault(estimator, layout)
    if gyro is None:
        return AmplitudePredictor(layout, meas, process.B_actuator, q_std[:N_AIRFRAME])
    frames = max(3, int(round(estimator.settings.rate_window_s / estimator.dt_s)))
    rows = layout.measurements
    return RateWindowAmplitude(layout, meas, process.B_actuator, q_std[:N_AIRFRAME], gyro,
                               rows.index("theta"), rows.index("q"), frames)


def _carry(estimator: EstimatorConfig, layout: FaultLayout, process):
    """The state a sentinel moves with its fault: an actuator's one-frame response
    (parts.actuator_sentinel = "consistent"), a windowed gyro fault's -e_q; else NoCarry."""
    cols, B = [], []
    if estimator.settings.actuator_sentinel == "consistent":
        for j in np.flatnonzero(layout.actuator_input >= 0).tolist():
            cols.append(j)
            B.append(np.asarray(process.B_actuator, dtype=float)[:, j])
    gyro = _gyro_fault(estimator, layout)
    if gyro is not None:
        cols.append(gyro)
        B.append(-np.eye(N_AIRFRAME)[4])
    if not cols:
        return NoCarry()
    return ActuatorCarry(np.array(cols), np.array(B).T)


def _sentinel_weighting(estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel,
                        amp: AmplitudePredictor, carry):
    """PriorSentinels for parts.sentinel_weighting = "prior" where some fault has amplitude_max."""
    if estimator.settings.sentinel_weighting != "prior":
        return ThesisSentinels()
    amax = np.array([f.amplitude_max if f.amplitude_max else np.nan for f in estimator.faults], dtype=float)
    carried = np.zeros(layout.nf, dtype=bool)
    carried[list(getattr(carry, "index", {}))] = True
    log_c = prior_log_constants(amax, layout.sensor_row, carried)
    log_c[[layout.type_of(j) in NO_ONSET_STEP for j in range(layout.nf)]] = np.nan   # no spread, no prior
    if not np.isfinite(log_c).any():
        return ThesisSentinels()
    return PriorSentinels(log_c, layout.sensor_row, meas.sigma, amp, carry,
                          clip=estimator.settings.sentinel_clip)


def _jump_parts(rec: Recipe, estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel,
                process, amp: AmplitudePredictor, roc=None):
    """(jump, sentinel weighting) of the recipe."""
    if not rec.has_modes:
        return NoJump(FAULT_THRESHOLD_SIGMAS * amp.sigma), ThesisSentinels()
    carry = _carry(estimator, layout, process)
    forced_zero = estimator.settings.mode0 == "forced_zero"
    folding = np.array([f.on_exit == "reset_or_fold" for f in estimator.faults], dtype=bool)
    fold = ExitFold.for_sensors(meas.H, np.where(folding, layout.sensor_row, -1),
                                _fold_arming(estimator)) if folding.any() else NoFold()
    faint = estimator.settings.pi10_faint
    exit_ = FaintExit(amp.sigma, faint) if faint > 0 else None
    jump = MarkovJump(_transition(rec, estimator, amp, roc), amp, forced_zero, carry, fold, exit_,
                      exit_to_drift=estimator.settings.mode0 == "drift")
    _memory_rollback(jump.drift, estimator)
    return jump, _sentinel_weighting(estimator, layout, meas, amp, carry)


def _kept_by_item(estimator: EstimatorConfig, layout: FaultLayout) -> np.ndarray:
    """(nf,) bool: the entries whose fault-free value is kept by item (parts.fault_free_memory):
    every entry ("item"), the inputs' ("input_item"), the inputs' and the pitot's, whose mode-0
    entry is the wind ("wind_input_item")."""
    memory = estimator.settings.fault_free_memory
    by_item = np.array([k != "sensor" or memory == "item" for k in layout.kinds], dtype=bool)
    if memory == "wind_input_item":
        by_item |= np.array([t == "airspeed" for t in layout.targets], dtype=bool)
    return by_item


def _memory_rollback(memory: DriftMemory | None, estimator: EstimatorConfig,
                     entries: np.ndarray | None = None) -> None:
    """Give the fault-free memory its `MemoryRollback` (parts.fault_free_rollback_s > 0) for the
    entries (nf,) bool (None: all)."""
    seconds = estimator.settings.fault_free_rollback_s
    if memory is not None and seconds > 0:
        steps = max(1, int(round(seconds / estimator.dt_s)))
        memory.rollback = MemoryRollback(memory.value.size, steps, entries)


def _fold_arming(estimator: EstimatorConfig) -> FoldArming | None:
    """The folds that wait for another sensor's fault (faults.fold_after), or None."""
    faults = estimator.faults
    gated = [j for j, f in enumerate(faults) if f.fold_after is not None]
    if not gated:
        return None

    def entries(row: str) -> np.ndarray:
        return np.array([i for i, f in enumerate(faults) if f.target == row], dtype=int)

    def steps(seconds: list[float]) -> np.ndarray:
        return np.rint(np.array(seconds) / estimator.dt_s).astype(np.int64)

    return FoldArming(len(faults), np.array(gated), [entries(faults[j].fold_after) for j in gated],
                      [entries(faults[j].target) for j in gated],
                      steps([faults[j].fold_window_s for j in gated]),
                      steps([faults[j].fold_young_s for j in gated]))


def _regulariser(rec: Recipe, estimator: EstimatorConfig, amp: AmplitudePredictor, h: float):
    if rec.regularise == "none":
        return NoJitter()
    if rec.regularise == "parts" and rec.has_modes and estimator.settings.jitter == "per_mode" \
            and amp.layout.nf > 0:
        floor = np.where(np.isfinite(amp.sigma), amp.sigma, 0.0) ** 2
        held = np.array([f.fault_type == "blocked" for f in estimator.faults], dtype=bool)
        return PerModeJitter(h, np.where(held, 0.0, floor))     # a blocked reading holds: no spread
    return GlobalJitter(h, shrink=rec.regularise == "shrink")


def _predictor(rec: Recipe, estimator: EstimatorConfig, process, q_std: np.ndarray):
    """Process noise by mode (parts.mode0): mode-0 faults pinned, drifting, or as in mode 1."""
    mode0 = estimator.settings.mode0 if rec.has_modes else "free"
    if mode0 == "forced_zero":
        return ModeGatedPredict(process, q_std)
    if mode0 == "drift":
        drift = np.array([f.drift_sigma for f in estimator.faults]) * np.sqrt(estimator.dt_s)
        bound = np.array([f.bound for f in estimator.faults])
        return DriftPredict(process, q_std, drift, bound, tuple(estimator.settings.q_tail))
    return GaussianPredict(process, q_std)


def _typed(parts: Parts, estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel,
           N: int) -> Parts:
    """The parts with the typed faults' wrappers (`fault_types`): the evolution after the predict,
    the noisy rows' likelihood around the correction, their prior draw after the sentinels, and
    the jump's hand-overs between an item's types (one `TypedEvolution` shared by all); the drift
    entries' rates around the jump (`drift_type.DriftJump`, N particles)."""
    if not layout.typed:
        return parts
    evolution = TypedEvolution(layout, meas.H, wind_entry(estimator.faults),
                               estimator.airframe_params().k_motor)
    pairs = sibling_pairs(layout)
    switch = TypeSwitch(pairs, estimator.switch_rates(), evolution, layout.sensor_row) \
        if pairs.size or evolution.stuck.size else None
    parts.jump.use_types(switch)
    if pairs.size:                              # one additive type per item, beside exclusive_items
        one_type = pair_exclusion(pairs, layout.nf)
        held = parts.jump.exclusion
        parts.jump.exclusion = ItemExclusion(one_type if held is None
                                             else np.maximum(one_type, held.excludes))
    memory = estimator.settings.fault_free_memory
    if memory != "entry" and parts.jump.drift is not None:
        by_item = _kept_by_item(estimator, layout)
        eye = np.eye(layout.nf, dtype=bool)
        parts.jump.drift = ItemDriftMemory(np.where(by_item[:, None], same_item(layout), eye))
        _memory_rollback(parts.jump.drift, estimator, by_item)
    parts.predict = TypedPredict(parts.predict, evolution, layout)
    noisy = evolution.noisy
    rows = np.maximum(layout.sensor_row, layout.noisy_row)
    parts.correction = TypedCorrection(parts.correction, evolution, rows, meas.sigma)
    if estimator.settings.held_value == "mean":
        _held_mean(parts, evolution, layout, N)
    if noisy.size:
        high = np.array([estimator.faults[j].amplitude_max or 9.0 for j in noisy.tolist()])
        parts.sentinel_weighting = NoisySentinels(parts.sentinel_weighting, noisy,
                                                  np.minimum(0.5, high), high)
    return _drift(parts, estimator, layout, meas, N)


def _drift_window(estimator: EstimatorConfig, layout: FaultLayout, rows: np.ndarray,
                  meas: MeasurementModel, frames: int):
    """The window a new drift rate is proposed from: `OffsetSlope`, or with parts.drift_window =
    "climb" `ClimbOffsetSlope` (the altimeters against the u, w, theta readings' climb, the attitude
    less its item's additive entries: every type but "noisy")."""
    if estimator.settings.drift_window != "climb":
        return OffsetSlope(rows, meas.H, frames)
    missing = [r for r in ("u", "w", "theta") if r not in estimator.measurements]
    if missing:
        raise ConfigError(f"parts.drift_window = \"climb\" integrates the u, w and theta readings: "
                          f"expected measurements.rows listing them, missing {missing}")
    velocity = tuple(estimator.measurements.index(r) for r in ("u", "w", "theta"))
    attitude = [j for j in range(layout.nf)
                if layout.sensor_row[j] == velocity[2] and layout.type_of(j) != "noisy"]
    return ClimbOffsetSlope(rows, meas.H, frames, velocity, estimator.dt_s, np.array(attitude, dtype=int),
                            meas.sigma[rows])


def _row_siblings(layout: FaultLayout, entries: np.ndarray) -> np.ndarray:
    """(k, nf) bool: the other fault entries on each of `entries`' (k,) measurement rows."""
    rows = layout.sensor_row[entries]
    return (layout.sensor_row[None, :] == rows[:, None]) & (np.arange(layout.nf) != entries[:, None])


def _held_mean(parts: Parts, evolution: TypedEvolution, layout: FaultLayout, N: int) -> None:
    """The held stuck entries' readings learnt as their readings' mean (`held_mean`), in place."""
    held = evolution.stuck[~evolution.blocked]
    if not held.size:
        return
    rows = layout.sensor_row[held]
    parts.jump = HeldCount(parts.jump, held, N)
    parts.correction = HeldMeanCorrection(parts.correction, parts.jump, rows, _row_siblings(layout, held))


def _drift(parts: Parts, estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel,
           N: int) -> Parts:
    """The drift entries' rates around the jump and their own correction (`drift_type`), if any."""
    drift = drift_entries(layout)
    if not drift.size:
        return parts
    sigma = np.array([estimator.faults[j].rate_sigma for j in drift.tolist()])
    rows = layout.sensor_row[drift]
    window = _drift_window(estimator, layout, rows, meas, int(round(DRIFT_WINDOW_S / estimator.dt_s)))
    rate_max = np.array([estimator.faults[j].rate_max or np.nan for j in drift.tolist()])
    parts.jump = DriftJump(parts.jump, drift, estimator.dt_s, sigma, N, window,
                           DriftAnchor(rows, meas.H, _row_siblings(layout, drift)), rate_max)
    parts.correction = DriftCorrection(parts.correction, parts.jump, rows, meas.sigma[rows])
    return parts


def particle_parts(rec: Recipe, estimator: EstimatorConfig, layout: FaultLayout, meas: MeasurementModel,
                   q_std: np.ndarray, N: int, roc=None) -> tuple[Parts, AmplitudePredictor]:
    """The parts of a particle filter of recipe `rec` (and its amplitude predictor)."""
    est = estimator.settings
    process = _process(estimator, layout)
    amp = _amplitude(estimator, layout, meas, process, q_std)
    jump, sentinels = _jump_parts(rec, estimator, layout, meas, process, amp, roc)
    every = rec.resample == "every_step"
    parts = Parts(
        predict=_predictor(rec, estimator, process, q_std),
        jump=jump, sentinel_weighting=sentinels,
        correction=(KalmanCorrection(jump.pin, rec.has_modes and est.mode0 == "drift",
                                     est.altitude_gain, est.gain_covariance, est.altimeter_gain,
                                     FaultyRowCut(layout.sensor_row)
                                     if rec.has_modes and est.faulty_row_gain == "fault_entry" else None)
                    if rec.correction == "kalman" else Likelihood()),
        resample_due=EveryStep() if every else BelowEffectiveSize(est.resample_threshold),
        resampler=resampler("systematic" if every else est.resampler),
        regulariser=_regulariser(rec, estimator, amp, _bandwidth(estimator, layout.n, N)),
    )
    if rec.has_modes and est.exclusive_items:
        jump.exclusion = ItemExclusion(exclusion_matrix(layout, est.exclusive_items))
    if rec.has_modes and est.gyro_exit_unwind > 0:
        jump.unwind = _gyro_unwind(estimator, layout, N)
    if est.q_noise == "learned":
        parts.correction = _learned_noise(parts.correction, parts.predict, estimator, layout, meas, process)
    return (_typed(parts, estimator, layout, meas, N) if rec.has_modes else parts), amp


def _gyro_unwind(estimator: EstimatorConfig, layout: FaultLayout, N: int) -> GyroUnwind:
    """The `GyroUnwind` of parts.gyro_exit_unwind: the gyro's item is the entries on target "q"."""
    entries = np.array([j for j, t in enumerate(layout.targets) if t == "q"], dtype=int)
    rows = layout.sensor_row[entries] if entries.size else entries
    if not (rows >= 0).any():
        raise ValueError(f"estimator {estimator.id!r}: parts.gyro_exit_unwind needs a fault on the \"q\" row")
    return GyroUnwind(entries, int(rows[rows >= 0][0]), estimator.dt_s,
                      estimator.settings.gyro_exit_unwind, N)


def _learned_noise(correction, predict, estimator: EstimatorConfig, layout: FaultLayout,
                   meas: MeasurementModel, process) -> LearnedPitchNoise:
    """The correction wrapped to learn the predict's pitch-rate noise from the gyro (`pitch_noise`)."""
    gyro = layout.measurements.index("q")
    return LearnedPitchNoise(correction, predict, process.moment, gyro, float(meas.sigma[gyro]),
                             estimator.dt_s, estimator.settings.q_noise_tau_s)


def build_particle_filter(name: str, estimator: EstimatorConfig, rng: np.random.Generator,
                          particles: int | None = None, x0: np.ndarray | None = None,
                          roc=None) -> ParticleFilter:
    """The particle filter of recipe `name`; roc overrides the saddlepoint ROC search (tests)."""
    rec = recipe(name)
    if rec.family != "particle":
        raise ValueError(f"{name!r} is not a particle filter")
    layout, meas, q_std, x0_std = _parts(estimator)
    N = int(particles if particles is not None else estimator.particles)
    parts, amp = particle_parts(rec, estimator, layout, meas, q_std, N, roc)
    reinit_std = x0_std.copy()
    if rec.has_modes:      # a fresh cloud spans at least one frame's amplitude uncertainty
        reinit_std[N_AIRFRAME:] = np.maximum(reinit_std[N_AIRFRAME:],
                                             np.where(np.isfinite(amp.sigma), amp.sigma, 0.0))
    return ParticleFilter(name, layout, meas, parts, rng, N, _x0(estimator, layout, x0), x0_std, reinit_std)


def build_gating_filter(estimator: EstimatorConfig, rng: np.random.Generator, particles: int | None = None,
                        x0: np.ndarray | None = None, kf_builder=None) -> GatedKF:
    """EKF-GATE: a KF with every fault frozen at 0, wrapped in innovation gating (gating.py).

    kf_builder(name, estimator, rng, particles=None, x0=None) defaults to `build_filter`;
    particles is ignored (the gate has none).
    """
    kf = (kf_builder or build_filter)("KF", frozen_fault_scenario(estimator), rng, x0=x0)
    return GatedKF(kf, estimator)


_BUILDERS = {
    "kalman": lambda name, est, rng, particles, x0: build_kalman(est, x0, particles=particles),
    "imm": lambda name, est, rng, particles, x0: build_imm(est, x0, particles),
    "gated": lambda name, est, rng, particles, x0: build_gating_filter(est, rng, particles, x0),
    "particle": build_particle_filter,
}


def build_filter(name: str, estimator: EstimatorConfig, rng: np.random.Generator,
                 particles: int | None = None, x0: np.ndarray | None = None):
    """The filter called `name` (recipes.RECIPES) for `estimator`; returns a `Filter`.

    rng drives all of the filter's randomness; particles overrides estimator.particles; x0 (5,)
    is the initial airframe-state mean (default: the estimator's own trim state).
    """
    rec = recipe(name)
    filt = _BUILDERS[rec.family](name, estimator, rng, particles, x0)
    kinematic = rec.family == "particle" and estimator.settings.process_model == "kinematic"
    filt.rows = RowSplit.of(estimator, kinematic, trim_state(estimator))
    if rec.family == "particle" and rec.has_modes and filt.rows.pitot is not None:
        filt.wind = filt.rows.pitot
        memory = getattr(filt.parts.jump, "drift", None)
        if memory is not None:
            filt.wind.use_memory(memory)
        process = filt.parts.predict.process
        if isinstance(process, KinematicProcess):
            process.use_wind(filt.wind, estimator.settings.moment_wind == "fault_free")
    return filt
