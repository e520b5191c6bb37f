"""Build any filter of the family from a scenario (SPEC sections 5-7).

`build_filter(name, scenario, rng, particles=None, x0=None)` for "KF", "IMM-KF", "RPF", "RRPF",
"JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF", "bootstrap" (a plain bootstrap particle filter on the
same process model: no jitter, systematic resampling every step) and "EKF-GATE" (delegated to
`gating.build_gating_filter`). The compositions:

    RPF     = particles + regulariser (Liu-West shrinkage, see regularize.py)
    RRPF    = RPF + Kalman correction
    JMRPF   = particles + regulariser + fixed jump (+ amplitude predictor)
    RJMRPF  = JMRPF + Kalman correction
    AJMRPF  = JMRPF with the adaptive transition matrix (estimator.adaptive_transition)
    ARJMRPF = AJMRPF + Kalman correction
    AJMRPF-thesis, ARJMRPF-thesis = the same with adaptive_transition = "thesis"

Settings come from scenario.estimator and scenario.faults; the filters assume the measurement
noise scenario.filter_sigma(). KF and IMM-KF always use the linearised model
(estimator.linear_matrices); the particle filters use estimator.process_model.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from fdir_service.airframe.linearize import LinearModel, linear_model
from fdir_service.airframe.params import AirframeParams, load_airframe
from fdir_service.estimation.adaptive import AdaptiveTransition
from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.imm import IMMKalman
from fdir_service.estimation.jump import FixedTransition
from fdir_service.estimation.kalman import KalmanFilter
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.particle import ParticleFilter
from fdir_service.estimation.process import LinearProcess, NonlinearProcess
from fdir_service.estimation.regularize import h_opt
from fdir_service.estimator_config import EstimatorConfig

PARTICLE_FILTERS = ("RPF", "RRPF", "JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF", "AJMRPF-thesis",
                    "ARJMRPF-thesis", "bootstrap")
THESIS_SUFFIX = "-thesis"
"""AJMRPF-thesis / ARJMRPF-thesis: the adaptive filters with estimator.adaptive_transition forced to
"thesis" (eq. 6.1 as written), for side-by-side reports when a scenario selects "proposal"."""
FILTERS = ("KF", "IMM-KF") + PARTICLE_FILTERS
FAULT_THRESHOLD_SIGMAS = 3.0
"""Mode-free filters (KF, RPF, RRPF, bootstrap) report P(|f_j| > 3 sigma_j), sigma_j the fault's
residual standard deviation (measurement sigma for a sensor fault)."""
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
    meas = MeasurementModel.build(layout, scenario.filter_sigma())
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
        layout, scenario.filter_sigma()), process.B_actuator, q_std[:N_AIRFRAME])
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


def _process(scenario: EstimatorConfig, layout: FaultLayout):
    lm = estimator_linear_model(scenario)
    if scenario.settings.process_model == "linear":
        return LinearProcess(lm, layout)
    return NonlinearProcess(_airframe(scenario.airframe), lm.trim.z, lm.trim.u, scenario.dt_s, layout,
                            INTEGRATOR)


def build_particle_filter(name: str, scenario: EstimatorConfig, rng: np.random.Generator,
                          particles: int | None = None, x0: np.ndarray | None = None,
                          roc=None) -> ParticleFilter:
    """One of PARTICLE_FILTERS; roc overrides the saddlepoint ROC search (tests)."""
    est = scenario.settings
    layout, meas, q_std, x0_std = _parts(scenario)
    N = int(particles if particles is not None else scenario.particles)
    process = _process(scenario, layout)
    amp = AmplitudePredictor(layout, meas, process.B_actuator, q_std[:N_AIRFRAME])
    n = layout.n
    if est.bandwidth is not None:   # the thesis's h at estimator.particles, scaled to N as h_opt is
        h = est.bandwidth * h_opt(n, N) / h_opt(n, scenario.particles)
    else:
        h = est.bandwidth_k * h_opt(n, N)
    common = dict(layout=layout, process=process, meas=meas, rng=rng, N=N,
                  x0_mean=_x0(scenario, layout, x0), x0_std=x0_std, q_std=q_std,
                  fault_threshold=FAULT_THRESHOLD_SIGMAS * amp.sigma)
    proposal = est.adaptive_transition == "proposal"
    base = name
    if name.endswith(THESIS_SUFFIX):
        base, proposal = name[: -len(THESIS_SUFFIX)], False
    if name == "bootstrap":
        return ParticleFilter(name, resampler="systematic", always_resample=True, h=None, **common)
    jm = base in ("JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF")
    correction = base in ("RRPF", "RJMRPF", "ARJMRPF")
    transition = None
    if base in ("JMRPF", "RJMRPF"):
        transition = FixedTransition(est.pi01, est.pi10, layout.nf)
    elif base in ("AJMRPF", "ARJMRPF"):
        transition = AdaptiveTransition(amp.sigma, est.saddlepoint_window, roc=roc,
                                        pi01=est.pi01, pi10=est.pi10, proposal=proposal)
    elif base not in ("RPF", "RRPF"):
        raise ValueError(f"unknown particle filter {name!r}; expected one of {PARTICLE_FILTERS}")
    prior_width = None
    if jm and est.sentinel_weighting == "prior":
        consistent = est.actuator_sentinel == "consistent"
        prior_width = np.array([2.0 * f.amplitude_max if f.amplitude_max and (
            f.kind == "sensor" or consistent) else np.nan for f in scenario.faults])
    return ParticleFilter(name, transition=transition, amplitude=amp if jm else None,
                          correction=correction, resampler=est.resampler,
                          threshold=est.resample_threshold, h=h, shrink=not jm, mode0=est.mode0,
                          sentinel_prior_width=prior_width,
                          jitter_per_mode=jm and est.jitter == "per_mode",
                          actuator_jump_state=jm and est.actuator_sentinel == "consistent", **common)


def build_filter(name: str, scenario: EstimatorConfig, rng: np.random.Generator,
                 particles: int | None = None, x0: np.ndarray | None = None):
    """The filter called `name` for `scenario` (see the module docstring); returns a `Filter`.

    rng drives all of the filter's randomness; particles overrides estimator.particles; x0 (5,)
    is the initial airframe-state mean (default: the scenario's trim state).
    """
    if name == "KF":
        return build_kalman(scenario, x0, particles=particles)
    if name == "IMM-KF":
        return build_imm(scenario, x0, particles)
    if name == "EKF-GATE":
        from fdir_service.estimation.gating import build_gating_filter
        return build_gating_filter(scenario, rng, particles, x0)
    if name in PARTICLE_FILTERS:
        return build_particle_filter(name, scenario, rng, particles, x0)
    raise ValueError(f"unknown filter {name!r}; expected one of {FILTERS + ('EKF-GATE',)}")
