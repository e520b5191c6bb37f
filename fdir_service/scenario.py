"""Scenario files (`config/scenarios/*.toml`): the world, the faults and the estimator settings.

One file describes a thesis experiment (SPEC section 7): the truth model, the measurement set and
its true noise, the fault channels (each with its true time profile, possibly empty, and the
estimator's settings for it), the autopilot command and the filters to compare. Everything is
validated on load: an unknown key, a wrong type or an impossible value raises `ConfigError`
naming the key. Units: SI (m, m/s, rad, rad/s, s) except a fault's `amplitude`, which is in the
fault's `unit`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fdir_service.errors import ConfigError
from fdir_service.paths import scenario_path
from fdir_service.tomltable import (
    ALL_NON_NEGATIVE,
    NON_NEGATIVE,
    POSITIVE,
    UNIT_INTERVAL,
    TomlTable,
    load_toml,
)

MEASUREMENTS = ("gnss_alt", "baro_alt", "u", "w", "theta", "q")
"""Measurement names, in the order a scenario may list them; SI units (m, m, m/s, m/s, rad, rad/s)."""
ACTUATORS = ("delta_e", "delta_t")
FILTER_NAMES = ("KF", "IMM-KF", "RPF", "RRPF", "JMRPF", "RJMRPF", "AJMRPF", "ARJMRPF", "AJMRPF-thesis",
                "ARJMRPF-thesis", "EKF-GATE")
PROFILE_SHAPES = ("step", "exponential", "ramp", "intermittent")
UNITS = {"m": 1.0, "m/s": 1.0, "rad": 1.0, "rad/s": 1.0, "deg": math.pi / 180.0,
         "deg/s": math.pi / 180.0, "1": 1.0}


@dataclass(frozen=True)
class ProfileComponent:
    """One additive piece of a fault's time course (values in SI once loaded).

    step: `amplitude` on [start_s, end_s); exponential: amplitude * exp((t - end_s) / tau_s) on
    [start_s, end_s) (the thesis's 10 e^(t-40) deg is amplitude 10 deg, tau 1 s, end 40 s); ramp:
    0 at start_s rising linearly to amplitude at end_s; intermittent: amplitude during on_s, then
    0 during off_s, repeating from start_s until end_s.
    """

    shape: str
    start_s: float
    end_s: float
    amplitude: float
    tau_s: float = 1.0
    on_s: float = 1.0
    off_s: float = 1.0


@dataclass(frozen=True)
class FaultChannel:
    """An additive fault on a measurement row (`kind` sensor) or an input (`kind` actuator).

    `profile` is the truth (summed components, SI); `sigma_f` and `x0_sigma` are the estimator's
    fault process-noise and initial standard deviations, SI. `amplitude_max` (SI; in the file in
    the fault's `unit`): the half-width of the uniform amplitude prior p(f | jump) on
    [-amplitude_max, amplitude_max] used by `estimator.sentinel_weighting = "prior"`.
    """

    id: str
    target: str
    kind: str
    unit: str
    profile: tuple[ProfileComponent, ...]
    sigma_f: float
    x0_sigma: float = 0.0
    amplitude_max: float | None = None   # |f| <= this under the jump's amplitude prior (SI); see
                                         # EstimatorConfig.sentinel_weighting

    @property
    def unit_scale(self) -> float:
        """Multiply an SI value by 1/unit_scale to express it in `unit`."""
        return UNITS[self.unit]


@dataclass(frozen=True)
class TruthConfig:
    model: str = "nonlinear"          # "linear" | "nonlinear"
    linear_matrices: str = "printed"  # for a linear truth: "printed" | "derived"
    airspeed_mps: float = 40.0
    altitude_m: float = 500.0


@dataclass(frozen=True)
class AltitudeStep:
    t_s: float
    altitude_m: float


@dataclass(frozen=True)
class CommandConfig:
    altitude_m: float = 500.0
    airspeed_mps: float = 40.0
    altitude_steps: tuple[AltitudeStep, ...] = ()


@dataclass(frozen=True)
class SensorConfig:
    measurements: tuple[str, ...]
    sigma: dict[str, float]            # true noise std per measurement, SI
    filter_noise_factor: float = 1.5   # filters assume this times the true sigma
    gnss_gauss_markov: bool = False    # eq. 3.29 error model (off in the thesis scenarios)

    def filter_sigma(self) -> list[float]:
        """Measurement noise std the filters assume, in measurement order (SI)."""
        return [self.sigma[m] * self.filter_noise_factor for m in self.measurements]


@dataclass(frozen=True)
class ImmConfig:
    mode0_sigma_f: tuple[float, ...] = ()
    mode1_sigma_f: tuple[float, ...] = ()


@dataclass(frozen=True)
class GatingConfig:
    """PX4-EKF2-style innovation gating: test ratio = nu^2 / (gate^2 S); faulty if > 1 for hold_s."""

    gate_sigma: float = 5.0
    hold_s: float = 0.25


@dataclass(frozen=True)
class EstimatorConfig:
    filters: tuple[str, ...]
    proposed: str
    particles: int = 1000
    process_model: str = "nonlinear"     # "linear" | "nonlinear"
    linear_matrices: str = "printed"     # for a linear process model
    sigma_x: tuple[float, ...] = ()      # state process noise (5,), SI; see sigma_x_basis
    sigma_x_basis: str = "step"          # "step": per-step std | "sqrt_second": density, std = sigma sqrt(dt)
    x0_sigma: tuple[float, ...] = ()     # initial state std (5,), SI
    resample_threshold: float = 0.5      # Gamma: resample when N_eff < Gamma N
    bandwidth: float | None = None       # h (thesis value); if None, bandwidth_k * h_opt
    bandwidth_k: float = 0.2
    resampler: str = "multinomial"       # "multinomial" | "systematic"
    mode0: str = "forced_zero"           # "forced_zero" | "reset_on_exit"
    pi01: float = 0.01
    pi10: float = 0.01
    saddlepoint_window: int = 3
    sentinel_weighting: str = "thesis"   # "thesis" (Alg. 4.1 as written) | "prior": a sensor-fault
                                         # sentinel's weight carries p(f | jump) / q(f), see
                                         # docs/estimation.md; needs faults.amplitude_max
    jitter: str = "global"               # "global" (thesis: one kernel from the whole cloud) |
                                         # "per_mode": one kernel per mode pattern (jump filters)
    adaptive_transition: str = "thesis"  # AJMRPF/ARJMRPF: "thesis" (eq. 6.1: pi01 from Pfa and pi10
                                         # from Pmd drive the jump) | "proposal": the Pfa-driven pi01
                                         # proposes sentinels, importance-weighted against pi01/pi10
                                         # above, and pi10 stays the fixed one (docs/estimation.md)
    actuator_sentinel: str = "thesis"    # "thesis" (Alg. 4.1: only the fault entry jumps) |
                                         # "consistent": an actuator-fault jump also applies its last
                                         # frame's effect B_a dF to the airframe state (eq. 4.13)
    imm: ImmConfig = field(default_factory=ImmConfig)
    gating: GatingConfig = field(default_factory=GatingConfig)


@dataclass(frozen=True)
class Scenario:
    id: str
    title: str
    thesis_section: str
    thesis_table: str
    duration_s: float
    dt_s: float
    truth: TruthConfig
    command: CommandConfig
    sensors: SensorConfig
    faults: tuple[FaultChannel, ...]
    estimator: EstimatorConfig
    source: str = ""

    def state_process_std(self) -> tuple[float, ...]:
        """Per-step std (5,) of the airframe-state process noise the filters use (SI)."""
        est = self.estimator
        scale = math.sqrt(self.dt_s) if est.sigma_x_basis == "sqrt_second" else 1.0
        return tuple(v * scale for v in est.sigma_x)

    @property
    def steps(self) -> int:
        """Number of filter steps in the run (duration / dt)."""
        return int(round(self.duration_s / self.dt_s))

    @property
    def sensor_faults(self) -> tuple[FaultChannel, ...]:
        return tuple(f for f in self.faults if f.kind == "sensor")

    @property
    def actuator_faults(self) -> tuple[FaultChannel, ...]:
        return tuple(f for f in self.faults if f.kind == "actuator")


# ----------------------------------------------------------------------------- validation

def _profile(t: TomlTable) -> ProfileComponent:
    shape = t.take("shape", "string", choices=PROFILE_SHAPES)
    start = t.take("start_s", "number", check=NON_NEGATIVE)
    end = t.take("end_s", "number", check=POSITIVE)
    if end <= start:
        raise ConfigError(f"{t.key('end_s')}: expected a time after start_s ({start}), got {end}")
    comp = ProfileComponent(
        shape=shape, start_s=start, end_s=end, amplitude=t.take("amplitude", "number"),
        tau_s=t.take("tau_s", "number", 1.0, check=POSITIVE),
        on_s=t.take("on_s", "number", 1.0, check=POSITIVE),
        off_s=t.take("off_s", "number", 1.0, check=POSITIVE),
    )
    t.finish()
    return comp


def _fault(t: TomlTable, measurements: tuple[str, ...]) -> FaultChannel:
    fid = t.take("id", "string")
    if not fid.isidentifier() or len(fid) > 7:
        raise ConfigError(f"{t.key('id')}: expected a short identifier (<= 7 chars, for "
                          f"MAVLink names like pfa_<id>), got {fid!r}")
    target = t.take("target", "string", choices=measurements + ACTUATORS)
    kind = "actuator" if target in ACTUATORS else "sensor"
    unit = t.take("unit", "string", choices=tuple(UNITS))
    scale = UNITS[unit]
    comps = []
    for pt in t.tables("profile"):
        pc = _profile(pt)
        comps.append(ProfileComponent(pc.shape, pc.start_s, pc.end_s, pc.amplitude * scale,
                                      pc.tau_s, pc.on_s, pc.off_s))
    ch = FaultChannel(
        id=fid, target=target, kind=kind, unit=unit, profile=tuple(comps),
        sigma_f=t.take("sigma_f", "number", check=NON_NEGATIVE),
        x0_sigma=t.take("x0_sigma", "number", 0.0, check=NON_NEGATIVE),
        amplitude_max=_scaled(t.take("amplitude_max", "number", None, check=POSITIVE), scale),
    )
    t.finish()
    return ch


def _scaled(v: float | None, scale: float) -> float | None:
    return None if v is None else v * scale


def parse_scenario(doc: dict[str, Any], source: str = "<scenario>") -> Scenario:
    """Validate a parsed scenario TOML document; raise ConfigError naming the first bad key."""
    root = TomlTable(doc, "")
    s = root.sub("scenario", required=True)
    sid = s.take("id", "string")
    title = s.take("title", "string", "")
    section = s.take("thesis_section", "string", "")
    table = s.take("thesis_table", "string", "")
    duration = s.take("duration_s", "number", 50.0, check=POSITIVE)
    dt = s.take("dt_s", "number", 0.05, check=POSITIVE)
    s.finish()

    t = root.sub("truth")
    truth = TruthConfig(
        model=t.take("model", "string", "nonlinear", choices=("linear", "nonlinear")),
        linear_matrices=t.take("linear_matrices", "string", "printed",
                               choices=("printed", "derived")),
        airspeed_mps=t.take("airspeed_mps", "number", 40.0, check=POSITIVE),
        altitude_m=t.take("altitude_m", "number", 500.0),
    )
    t.finish()

    c = root.sub("command")
    steps = []
    for tt in c.tables("altitude_steps"):
        steps.append(AltitudeStep(tt.take("t_s", "number", check=NON_NEGATIVE),
                                  tt.take("altitude_m", "number")))
        tt.finish()
    command = CommandConfig(
        altitude_m=c.take("altitude_m", "number", truth.altitude_m),
        airspeed_mps=c.take("airspeed_mps", "number", truth.airspeed_mps, check=POSITIVE),
        altitude_steps=tuple(steps),
    )
    c.finish()

    se = root.sub("sensors", required=True)
    meas = se.take("measurements", "strings", choices=MEASUREMENTS)
    if not meas or len(set(meas)) != len(meas):
        raise ConfigError("sensors.measurements: expected a non-empty list without repeats")
    sig_t = se.sub("sigma", required=True)
    sigma = {m: sig_t.take(m, "number", check=POSITIVE) for m in meas}
    sig_t.finish()
    sensors = SensorConfig(
        measurements=meas, sigma=sigma,
        filter_noise_factor=se.take("filter_noise_factor", "number", 1.5, check=POSITIVE),
        gnss_gauss_markov=se.take("gnss_gauss_markov", "boolean", False),
    )
    se.finish()

    faults = tuple(_fault(ft, meas) for ft in root.tables("faults"))
    ids = [f.id for f in faults]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"faults: fault ids must be unique, got {ids}")

    e = root.sub("estimator", required=True)
    filters = e.take("filters", "strings", choices=FILTER_NAMES)
    proposed = e.take("proposed", "string", choices=FILTER_NAMES)
    if proposed not in filters:
        raise ConfigError(f"estimator.proposed: {proposed!r} must be one of estimator.filters")
    sigma_x = e.take("sigma_x", "numbers", check=ALL_NON_NEGATIVE)
    x0_sigma = e.take("x0_sigma", "numbers", check=ALL_NON_NEGATIVE)
    for key, val in (("sigma_x", sigma_x), ("x0_sigma", x0_sigma)):
        if len(val) != 5:
            raise ConfigError(f"estimator.{key}: expected 5 values [p_d, u, w, theta, q], "
                              f"got {len(val)}")
    bw = e.take("bandwidth", "number", None, check=POSITIVE)
    imm_t = e.sub("imm")
    nf = len(faults)
    imm = ImmConfig(mode0_sigma_f=imm_t.take("mode0_sigma_f", "numbers", (0.0,) * nf,
                                             check=ALL_NON_NEGATIVE),
                    mode1_sigma_f=imm_t.take("mode1_sigma_f", "numbers",
                                             tuple(f.sigma_f for f in faults), check=ALL_NON_NEGATIVE))
    for key, val in (("mode0_sigma_f", imm.mode0_sigma_f), ("mode1_sigma_f", imm.mode1_sigma_f)):
        if len(val) != nf:
            raise ConfigError(f"estimator.imm.{key}: expected {nf} values (one per fault), "
                              f"got {len(val)}")
    imm_t.finish()
    g_t = e.sub("gating")
    gating = GatingConfig(gate_sigma=g_t.take("gate_sigma", "number", 5.0, check=POSITIVE),
                          hold_s=g_t.take("hold_s", "number", 0.25, check=NON_NEGATIVE))
    g_t.finish()
    est = EstimatorConfig(
        filters=filters, proposed=proposed,
        particles=e.take("particles", "integer", 1000, check=POSITIVE),
        process_model=e.take("process_model", "string", "nonlinear",
                             choices=("linear", "nonlinear")),
        linear_matrices=e.take("linear_matrices", "string", "printed",
                               choices=("printed", "derived")),
        sigma_x=sigma_x, x0_sigma=x0_sigma,
        sigma_x_basis=e.take("sigma_x_basis", "string", "step", choices=("step", "sqrt_second")),
        resample_threshold=e.take("resample_threshold", "number", 0.5, check=UNIT_INTERVAL),
        bandwidth=bw,
        bandwidth_k=e.take("bandwidth_k", "number", 0.2, check=POSITIVE),
        resampler=e.take("resampler", "string", "multinomial",
                         choices=("multinomial", "systematic")),
        mode0=e.take("mode0", "string", "forced_zero", choices=("forced_zero", "reset_on_exit")),
        pi01=e.take("pi01", "number", 0.01, check=UNIT_INTERVAL),
        pi10=e.take("pi10", "number", 0.01, check=UNIT_INTERVAL),
        saddlepoint_window=e.take("saddlepoint_window", "integer", 3, check=POSITIVE),
        sentinel_weighting=e.take("sentinel_weighting", "string", "thesis",
                                  choices=("thesis", "prior")),
        jitter=e.take("jitter", "string", "global", choices=("global", "per_mode")),
        adaptive_transition=e.take("adaptive_transition", "string", "thesis",
                                   choices=("thesis", "proposal")),
        actuator_sentinel=e.take("actuator_sentinel", "string", "thesis",
                                 choices=("thesis", "consistent")),
        imm=imm, gating=gating,
    )
    e.finish()
    if est.sentinel_weighting == "prior":
        missing = [f.id for f in faults if f.kind == "sensor" and f.amplitude_max is None]
        if missing:
            raise ConfigError(f"estimator.sentinel_weighting = \"prior\" needs faults.amplitude_max "
                              f"for every sensor fault; missing for {missing}")
    root.finish()
    return Scenario(sid, title, section, table, duration, dt, truth, command, sensors, faults,
                    est, source)


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario by id (`ch4`) or path."""
    path = scenario_path(name_or_path)
    doc = load_toml(path, "scenario file")
    try:
        return parse_scenario(doc, str(path))
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


SCENARIO_IDS = ("ch4", "ch5a", "ch5b", "ch5c", "ch6")
