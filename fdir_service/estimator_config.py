"""Estimator files (`config/estimators/*.toml`): everything the monitor assumes, nothing it cannot know.

An estimator file names its airframe (a file in `config/airframes/`), the operating point it trims
that airframe at (commanded airspeed and altitude), the measurement rows it uses and the noise it
assumes on each, the faults it monitors (target, unit, prior amplitude range, process noise,
transition probabilities), the filter and the settings of its parts, the particle count and the
seed. It never holds a truth: no true noise, no injected fault, no world. Experiments (the lab)
take an estimator file by reference and override what they need; the service names one.

Validated on load: an unknown key, a wrong type or an impossible value raises `ConfigError` naming
the file, the dotted key and what was expected. Units: SI (m, m/s, rad, rad/s, s) except a fault's
`amplitude_max`, which is in the fault's `unit` in the file and SI once loaded.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fdir_service.errors import ConfigError
from fdir_service.estimation.correction import (
    ALTIMETER_GAINS,
    ALTITUDE_GAINS,
    FAULTY_ROW_GAINS,
    GAIN_COVARIANCES,
)
from fdir_service.estimation.recipes import FILTER_NAMES
from fdir_service.paths import airframe_path, estimator_path
from fdir_service.tomltable import (
    ALL_NON_NEGATIVE,
    NON_NEGATIVE,
    POSITIVE,
    UNIT_INTERVAL,
    TomlTable,
    load_toml,
)

OBSERVED_ROWS = ("gnss_alt", "baro_alt", "u", "w", "theta", "q")
"""Rows the filters observe (y = H x + v); SI units (m, m, m/s, m/s, rad, rad/s)."""
IMU_ROWS = ("ax", "az")
"""Accelerometer rows: body-axis specific force, forward and down (m/s^2). The kinematic process
model takes them as inputs (parts.process_model = "kinematic"); no filter observes them."""
AIR_ROWS = ("airspeed",)
"""The pitot's airspeed (m/s): an input of the kinematic model's pitching moment (dynamic pressure)."""
LATERAL_ROWS = ("roll", "v")
"""The lateral motion the longitudinal state leaves out: the roll attitude (rad) and the body-axis
velocity along y over the ground (m/s). The kinematic model's climb rate takes them (an aircraft
that banks and sideslips climbs at u sin(theta) - (v sin(phi) + w cos(phi)) cos(theta)); missing,
they are 0 (wings level, no sideslip)."""
BODY_RATE_ROWS = ("p", "r")
"""The roll and yaw rates (rad/s, body axes; the gyro's x and z). With the roll and v, the kinematic
model's velocity and attitude equations take the lateral terms of a 6-DOF aircraft (u' gains r v,
w' -p v and g cos(theta) (cos(phi) - 1), theta' = q cos(phi) - r sin(phi)); missing, they are 0."""
INPUT_ROWS = IMU_ROWS + AIR_ROWS + LATERAL_ROWS + BODY_RATE_ROWS
"""Rows a process model takes as inputs, in the order they extend the input vector."""
THRUST_ROW = "throttle"
"""A derived row (`thrust.ThrustCheck`): the throttle the accelerometer implies minus the commanded
one (unitless, 0..1 scale); observed by a kinematic estimator that lists ax, az and airspeed and
watches the throttle, so an engine that quits is seen though the IMU-driven model has no thrust."""
AIRSPEED_ROW = "airspeed"
"""The pitot observed as well as taken as an input (`inputs.RowSplit`): a kinematic estimator with a
fault on the airspeed observes it as u - the head wind along body x (measurement.DERIVED_STATE), the
wind being the fault entry's fault-free drift (docs/faults.md, "Pitot")."""
MEASUREMENTS = OBSERVED_ROWS + INPUT_ROWS
"""Measurement rows an estimator may list."""
ACTUATORS = ("delta_e", "delta_t")
"""Inputs a fault may act on: elevator (rad) and throttle (0..1)."""
UNITS = {"m": 1.0, "m/s": 1.0, "rad": 1.0, "rad/s": 1.0, "deg": math.pi / 180.0,
         "deg/s": math.pi / 180.0, "1": 1.0}
"""A fault's display unit -> SI factor (value_SI = value_unit * factor)."""
SENSOR_FAULT_TYPES = ("bias", "stuck", "noisy", "blocked", "drift")
"""What a sensor fault does to its row (docs/faults.md): adds an offset; holds a value whatever the
state does (stuck); multiplies its noise by k >= 1 (noisy); a blocked pitot (airspeed only) holds
its total pressure, so its reading follows the altitude, V^2 = V0^2 + 2 g (h - h0); an offset that
ramps at a rate of its own (drift)."""
ACTUATOR_FAULT_TYPES = ("bias", "jammed", "effectiveness", "engine")
"""What an actuator fault does to its input (docs/faults.md): adds an offset; holds a position
whatever the command (jammed); scales the command by a gain 0..1 (loss of effectiveness); the
engine gives no thrust (throttle only, in thrust terms: the throttle it delivers is V / k_m
whatever the command)."""
INITIALISATIONS = ("trim", "first_frame")
DEFAULT_ESTIMATOR = "aerosonde"
"""`config/estimators/aerosonde.toml`: what `fdir run` monitors with no arguments."""


@dataclass(frozen=True)
class FaultSpec:
    """A monitored additive fault on a measurement row (`kind` sensor) or an input (`kind` actuator).

    sigma_f, x0_sigma: the fault entry's process-noise and initial standard deviations (SI);
    amplitude_max: half-width of the uniform amplitude prior p(f | jump) on [-a, a] (SI), used by
    `parts.sentinel_weighting = "prior"`; pi01, pi10: this fault's mode transition probabilities
    per step (SPEC section 5, thesis eq. 4.11), None = the filter's.
    """

    id: str
    target: str
    kind: str
    unit: str
    sigma_f: float
    x0_sigma: float = 0.0
    amplitude_max: float | None = None
    pi01: float | None = None
    pi10: float | None = None
    pi_switch: float | None = None
    """Per step and sibling: this fault's hand-over of its offset to another type of its item
    (`fault_types.TypeSwitch`), None = parts.pi_switch. Each hand-over out of a fault costs its
    type share of P(item) (the catalogue's drifts: docs/faults.md, "Hand-overs out of a drift")."""
    drift_sigma: float = 0.0
    """parts.mode0 = "drift": random-walk std (SI per sqrt(s)) of the fault entry in mode 0, the
    sensor's slow fault-free error (a gyro bias walk, a GNSS Gauss-Markov wander)."""
    fault_type: str = "bias"
    """What the fault does to its target (`SENSOR_FAULT_TYPES`, `ACTUATOR_FAULT_TYPES`), file key
    `type`. Its entry in the extended state: bias the offset (SI); stuck and jammed the offset from
    the truth that holds the target still (the published value is the held reading/position);
    noisy k - 1 (k the noise multiplier); effectiveness g - 1 (g the remaining gain); engine the
    delivered throttle minus the commanded one (the published value is the thrust's share left)."""
    rate_sigma: float = 0.0
    """A drift fault's rate random walk (SI per s per sqrt(s); `drift_type.DriftJump`)."""
    rate_max: float | None = None
    """A drift fault's largest rate (SI per s): a new drift's rate has the prior uniform on
    +-rate_max, and its sentinel carries p / q of the proposed rate (`drift_type.rate_log_weight`);
    None: the proposal is taken as the prior."""
    value_max: float | None = None
    """The largest |entry| the fault can reach (SI), file key `value_max` (default amplitude_max):
    under parts.mode0 = "drift" every entry is held within it (`predict.DriftPredict`). A held
    value's entry grows past its onset (amplitude_max, the jump's prior) as its target moves: a
    jammed elevator's offset from its command spans the surface's travel."""
    on_exit: str = "reset"
    """A sensor fault's 1 -> 0 exit: "reset" (the fault ended: its entry to 0) or "reset_or_fold"
    (half the exits fold the entry into the airframe state instead: the state was wrong, this
    sensor right; `jump.ExitFold`)."""
    fold_after: str | None = None
    """With "reset_or_fold": the sensor row whose fault must have been declared (its entries'
    P >= 0.5) within fold_window_s, unless this fault's own declaration is younger than
    fold_young_s, for this fault to fold (`jump.FoldArming`); None: it always may."""
    fold_window_s: float = 10.0
    """s after a step with the fold_after row's P >= 0.5 during which this fault may fold."""
    fold_young_s: float = 3.0
    """s after this fault's own item's P rose past 0.5 during which it may fold anyway."""

    @property
    def bound(self) -> float:
        """The entry's clip bound, SI (value_max, else amplitude_max, else unbounded)."""
        top = self.value_max if self.value_max is not None else self.amplitude_max
        return math.inf if top is None else top

    @property
    def unit_scale(self) -> float:
        """Multiply an SI value by 1/unit_scale to express it in `unit`."""
        return UNITS[self.unit]


@dataclass(frozen=True)
class ImmSettings:
    """IMM-KF: per-fault process-noise std (SI) of the fault entries in mode 0 and in mode 1."""

    mode0_sigma_f: tuple[float, ...] = ()
    mode1_sigma_f: tuple[float, ...] = ()


@dataclass(frozen=True)
class GatingSettings:
    """PX4-EKF2-style innovation gating: test ratio = nu^2 / (gate^2 S); faulty if > 1 for hold_s."""

    gate_sigma: float = 5.0
    hold_s: float = 0.25


@dataclass(frozen=True)
class FilterSettings:
    """Settings of the filters' parts (SPEC sections 5-6); see docs/estimation.md for each choice."""

    process_model: str = "nonlinear"     # "linear" | "nonlinear" | "kinematic"
    linear_matrices: str = "derived"     # "printed" (thesis) | "derived" (own airframe)
    sigma_x: tuple[float, ...] = (0.1, 0.1, 0.1, 0.001, 0.002)   # airframe-state process noise (5,)
    sigma_x_basis: str = "sqrt_second"   # "step": per-step std | "sqrt_second": std = sigma sqrt(dt)
    x0_sigma: tuple[float, ...] = (1.0, 1.0, 1.0, 0.005, 0.002)  # initial airframe-state std (5,)
    resample_threshold: float = 0.5      # Gamma: resample when N_eff < Gamma N
    bandwidth: float | None = None       # h (thesis value); if None, bandwidth_k * h_opt
    bandwidth_k: float = 0.2
    resampler: str = "multinomial"       # "multinomial" | "systematic"
    mode0: str = "forced_zero"           # "forced_zero" | "reset_on_exit" | "drift"
    pi01: float = 0.01
    pi10: float = 0.01
    pi10_faint: float = 0.0              # per step: exit rate of a mode-1 fault fainter than one frame's
    #                                      amplitude noise (0: pi10 for all)
    pi_switch: float = 0.0               # per step: a mode-1 fault hands its offset to another type of
    #                                      the same item (stuck <-> bias ...; `fault_types.TypeSwitch`)
    saddlepoint_window: int = 3
    sentinel_weighting: str = "prior"    # "thesis" (Alg. 4.1 as written) | "prior" (p(f | jump) / q(f))
    sentinel_clip: float = 0.0           # "prior": a sentinel's draw clipped at this many sigmas (0: off)
    jitter: str = "per_mode"             # "global" (one kernel) | "per_mode"
    adaptive_transition: str = "proposal"  # "thesis" (eq. 6.1) | "proposal" (importance-weighted)
    actuator_sentinel: str = "consistent"  # "thesis" | "consistent" (B_a dF moves the state)
    rate_sentinel: str = "row"           # gyro fault amplitude: "row" (eq. 4.16) | "window" (theta slope)
    held_value: str = "sentinel"         # a stuck reading's held value: "sentinel" (its draw) | "mean"
    #                                      (the mean of its readings since it stuck; held_mean.py)
    rate_window_s: float = 1.0           # the window of rate_sentinel = "window" (s)
    thrust_sigma: float = 0.01           # noise of the derived throttle row (0..1 throttle scale)
    q_tail: tuple[float, ...] = (0.0, 1.0)  # (share, scale): heavy-tailed pitch-rate process noise
    q_noise: str = "fixed"               # the pitch-rate process noise: "fixed" (sigma_x[4]) | "learned"
    #                                      (from the gyro; at most sigma_x[4]; pitch_noise.py)
    q_noise_tau_s: float = 30.0          # s: the learning time constant of q_noise = "learned"
    az_input: str = "frame_end"          # the a_z the kinematic model integrates: "frame_end" (the
    #                                      frame's reading) | "frame_mean" (its two readings' mean)
    velocity_step: str = "euler"         # the kinematic model's body velocity: "euler" (u - q w dt) |
    #                                      "rotation" (turned by the frame's pitch angle exactly)
    frame_angle: str = "trapezoid"       # the kinematic model's pitch angle over a frame: "trapezoid"
    #                                      of its pitch rates | "spread" (drawn between dt q and dt q+) |
    #                                      "snap" (drawn so only where a surface snaps)
    moment_alpha: str = "lift"           # the pitching moment's angle of attack: "lift" (read from a_z) |
    #                                      "stall_blend" (the velocity's past the airframe's stall angle)
    moment_wind: str = "entry"           # the moment's head wind under a biased pitot: "entry" (the pitot
    #                                      entry, wind plus offset: the reading) | "fault_free" (the wind
    #                                      the exits return to)
    wind_gust_sigma: float = 1.5         # m/s: the head wind's gusts about its mean (pitot.PitotRow) ...
    wind_gust_tau_s: float = 10.0        # ... and their correlation time L_u / V (MIL-F-8785C, moderate)
    wind_mean_tau_s: float = 60.0        # s: how fast the mean wind the gusts return to follows the wind
    wind_hold: float = 0.0               # 0..1: the share of a ground-speed change that is the wind's
    held_airspeed_sigma: float = 0.5     # m/s: the airspeed's gusts an airspeed hold lets through
    held_airspeed_tau_s: float | None = None  # s: their time constant (None: wind_gust_tau_s)
    engine_tau_s: float = 0.0            # s: the throttle delivered lags the command by this (0: at once)
    hold_resume: str = "cloud"           # the held airspeed when the hold takes over again under a
    #                                      declared pitot: "cloud" (every particle's) | "held" (the
    #                                      airspeed held before the let-go)
    fault_free_memory: str = "entry"     # the fault-free value exits return to, from the particles whose
    #                                      entry is in mode 0 ("entry") | whose whole item is ("item") |
    #                                      the inputs' by item, the rows' by entry ("input_item") |
    #                                      the inputs' and the pitot's (its wind) by item ("wind_input_item")
    fault_free_rollback_s: float = 0.0   # s: a fault-free value that freezes takes back its value of
    #                                      that long before (0: off; `jump.MemoryRollback`)
    gyro_exit_unwind: float = 0.0        # 0..1: the share of the particles leaving a gyro fault that take
    #                                      back the attitude it integrated (0: off; `gyro_unwind.GyroUnwind`)
    drift_window: str = "offset"         # a new drift rate's window: the offset against the cloud
    #                                      ("offset") | the altimeters' against the readings' climb ("climb")
    altitude_gain: str = "all_rows"      # "all_rows" | "altimeters" | "no_pitch_rate": which rows'
    #                                      innovations may move the altitude in the Kalman correction
    gain_covariance: str = "cloud"       # "cloud" | "within_mode": the Kalman gain's covariance
    exclusive_items: tuple[str, ...] = ()  # groups of fault targets ("theta q": space-separated) whose
    #                                      entries a particle may not hold in mode 1 together
    faulty_row_gain: str = "all_states"  # "all_states" | "fault_entry": what a row moves in a particle
    #                                      that holds one of its sensor faults in mode 1
    altimeter_gain: str = "all_states"   # "all_states" | "altitude": which states the altimeters'
    #                                      innovations may move in the Kalman correction
    imm: ImmSettings = field(default_factory=ImmSettings)
    gating: GatingSettings = field(default_factory=GatingSettings)


@dataclass(frozen=True)
class OperatingPoint:
    """Where the estimator linearises its airframe and starts its cloud: the airframe's own trim at
    the commanded airspeed (m/s) and altitude (m); init "first_frame" starts the cloud on the first
    frame's measurements instead of the trim state."""

    airspeed_mps: float = 40.0
    altitude_m: float = 500.0
    init: str = "trim"


@dataclass(frozen=True)
class EstimatorConfig:
    """A validated estimator file; `doc` is the resolved TOML document (recorded in logs)."""

    id: str
    airframe: str
    dt_s: float
    operating_point: OperatingPoint
    measurements: tuple[str, ...]
    sigma: tuple[float, ...]
    faults: tuple[FaultSpec, ...]
    filter: str
    particles: int
    seed: int
    settings: FilterSettings
    doc: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    source: str = ""

    def filter_sigma(self) -> list[float]:
        """Measurement noise std (m,) the filters assume, in row order (SI)."""
        return list(self.sigma)

    @property
    def observed(self) -> tuple[str, ...]:
        """The rows the filters observe (m_obs,): `measurements` without the input rows, then the
        derived rows (`derived_rows`)."""
        return tuple(r for r in self.measurements if r not in INPUT_ROWS) + self.derived_rows

    @property
    def derived_rows(self) -> tuple[str, ...]:
        """Rows the filters make from other rows, for a kinematic process model with ax, az and
        airspeed: `THRUST_ROW` when it watches a throttle fault, then `AIRSPEED_ROW` when it watches
        the pitot; else ()."""
        needs = {"ax", "az", "airspeed"} <= set(self.measurements)
        if not (needs and self.settings.process_model == "kinematic"):
            return ()
        watched = {f.target for f in self.faults}
        return tuple(r for r, t in ((THRUST_ROW, "delta_t"), (AIRSPEED_ROW, AIRSPEED_ROW)) if t in watched)

    @property
    def input_rows(self) -> tuple[str, ...]:
        """The input rows listed (a kinematic process model's), in `INPUT_ROWS` order."""
        return tuple(r for r in INPUT_ROWS if r in self.measurements)

    def observed_sigma(self) -> list[float]:
        """Measurement noise std (m_obs,) of the observed rows (SI; the throttle row's unitless)."""
        listed = dict(zip(self.measurements, self.sigma, strict=True))
        derived = [self.settings.thrust_sigma if r == THRUST_ROW else listed[r] for r in self.derived_rows]
        return [s for r, s in listed.items() if r not in INPUT_ROWS] + derived

    def state_process_std(self) -> tuple[float, ...]:
        """Per-step std (5,) of the airframe-state process noise (SI)."""
        s = self.settings
        scale = math.sqrt(self.dt_s) if s.sigma_x_basis == "sqrt_second" else 1.0
        return tuple(v * scale for v in s.sigma_x)

    def transition_probabilities(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Per-fault (pi01 (nf,), pi10 (nf,)): each fault's own, else the filter's."""
        s = self.settings
        return (tuple(s.pi01 if f.pi01 is None else f.pi01 for f in self.faults),
                tuple(s.pi10 if f.pi10 is None else f.pi10 for f in self.faults))

    def switch_rates(self) -> tuple[float, ...]:
        """Per-fault hand-over probability per step and sibling (nf,): its own, else parts.pi_switch."""
        s = self.settings.pi_switch
        return tuple(s if f.pi_switch is None else f.pi_switch for f in self.faults)

    @property
    def sensor_faults(self) -> tuple[FaultSpec, ...]:
        return tuple(f for f in self.faults if f.kind == "sensor")

    def with_filter(self, name: str | None = None, particles: int | None = None,
                    seed: int | None = None) -> EstimatorConfig:
        """The same estimator with another filter, particle count or seed (None: unchanged)."""
        return dataclasses.replace(
            self, filter=self.filter if name is None else name,
            particles=self.particles if particles is None else int(particles),
            seed=self.seed if seed is None else int(seed))

    def airframe_params(self):
        """The estimator's own airframe (`AirframeParams`), loaded from its airframe file."""
        from fdir_service.airframe.params import load_airframe

        return load_airframe(airframe_path(self.airframe))


# ----------------------------------------------------------------------------- validation

EXIT_CHOICES = ("reset", "reset_or_fold")
"""faults.on_exit values."""


def _fault(t: TomlTable, rows: tuple[str, ...]) -> FaultSpec:
    fid = t.take("id", "string")
    if not fid.isidentifier() or len(fid) > 7:
        raise ConfigError(f"{t.key('id')}: expected a short identifier (<= 7 chars, for "
                          f"MAVLink names like pfa_<id>), got {fid!r}")
    watchable = tuple(r for r in rows if r not in INPUT_ROWS or r == AIRSPEED_ROW)
    target = t.take("target", "string", choices=watchable + ACTUATORS)
    unit = t.take("unit", "string", choices=tuple(UNITS))
    amax = t.take("amplitude_max", "number", None, check=POSITIVE)
    vmax = t.take("value_max", "number", None, check=POSITIVE)
    spec = FaultSpec(
        id=fid, target=target, kind="actuator" if target in ACTUATORS else "sensor", unit=unit,
        sigma_f=t.take("sigma_f", "number", check=NON_NEGATIVE),
        x0_sigma=t.take("x0_sigma", "number", 0.0, check=NON_NEGATIVE),
        amplitude_max=None if amax is None else amax * UNITS[unit],
        pi01=t.take("pi01", "number", None, check=UNIT_INTERVAL),
        pi10=t.take("pi10", "number", None, check=UNIT_INTERVAL),
        pi_switch=t.take("pi_switch", "number", None, check=UNIT_INTERVAL),
        drift_sigma=t.take("drift_sigma", "number", 0.0, check=NON_NEGATIVE),
        on_exit=t.take("on_exit", "string", "reset", choices=EXIT_CHOICES),
        fold_after=t.take("fold_after", "string", None, choices=watchable),
        fold_window_s=t.take("fold_window_s", "number", 10.0, check=POSITIVE),
        fold_young_s=t.take("fold_young_s", "number", 3.0, check=NON_NEGATIVE),
        rate_sigma=t.take("rate_sigma", "number", 0.0, check=NON_NEGATIVE),
        rate_max=t.take("rate_max", "number", None, check=POSITIVE),
        value_max=None if vmax is None else vmax * UNITS[unit],
        fault_type=t.take("type", "string", "bias",
                          choices=ACTUATOR_FAULT_TYPES if target in ACTUATORS else SENSOR_FAULT_TYPES),
    )
    _check_fault(t, spec)
    t.finish()
    return spec


def _check_fault(t: TomlTable, spec: FaultSpec) -> None:
    """What one fault entry's keys must agree on (ConfigError naming the key)."""
    if spec.value_max is not None and spec.amplitude_max is not None and spec.value_max < spec.amplitude_max:
        scale = spec.unit_scale
        raise ConfigError(f"{t.key('value_max')}: expected at least amplitude_max "
                          f"({spec.amplitude_max / scale:g} {spec.unit}): the entry must reach the "
                          f"amplitudes it may jump to, got {spec.value_max / scale:g}")
    if spec.kind == "actuator" and spec.on_exit != "reset":
        raise ConfigError(f"{t.key('on_exit')}: an actuator fault has no sensor row to fold; "
                          f"expected \"reset\", got {spec.on_exit!r}")
    if spec.fault_type == "blocked" and spec.target != AIRSPEED_ROW:
        raise ConfigError(f"{t.key('type')}: only the pitot can be blocked; expected target = "
                          f"\"{AIRSPEED_ROW}\" for a blocked fault, got {spec.target!r}")
    if spec.fault_type == "engine" and spec.target != "delta_t":
        raise ConfigError(f"{t.key('type')}: only the throttle has an engine; expected target = "
                          f"\"delta_t\" for an engine fault, got {spec.target!r}")
    if spec.fold_after is not None and spec.on_exit != "reset_or_fold":
        raise ConfigError(f"{t.key('fold_after')}: only a fault that folds can wait for another's; "
                          f"expected on_exit = \"reset_or_fold\", got {spec.on_exit!r}")
    if spec.rate_max is not None and spec.fault_type != "drift":
        raise ConfigError(f"{t.key('rate_max')}: only a drift has a rate; expected type = \"drift\" "
                          f"for a fault with rate_max, got {spec.fault_type!r}")
    if spec.fold_after == spec.target:
        raise ConfigError(f"{t.key('fold_after')}: expected another sensor's row than the fault's "
                          f"own, got {spec.fold_after!r}")
    if spec.fault_type != "bias" and spec.on_exit != "reset":
        raise ConfigError(f"{t.key('on_exit')}: only a bias can be folded into the state; "
                          f"expected \"reset\" for a {spec.fault_type} fault, got {spec.on_exit!r}")


def _faults(root: TomlTable, rows: tuple[str, ...]) -> tuple[FaultSpec, ...]:
    faults = tuple(_fault(ft, rows) for ft in root.tables("faults"))
    ids = [f.id for f in faults]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"faults: fault ids must be unique, got {ids}")
    watched = {f.target for f in faults}
    for i, f in enumerate(faults):
        if f.fold_after is not None and f.fold_after not in watched:
            raise ConfigError(f"faults[{i}].fold_after: expected the row of another fault of this "
                              f"estimator ({', '.join(sorted(watched))}), got {f.fold_after!r}")
    return faults


def _measurements(root: TomlTable) -> tuple[tuple[str, ...], tuple[float, ...]]:
    m = root.sub("measurements", required=True)
    rows = m.take("rows", "strings", choices=MEASUREMENTS)
    if not rows or len(set(rows)) != len(rows):
        raise ConfigError(f"{m.key('rows')}: expected a non-empty list without repeats")
    sig = m.sub("sigma", required=True)
    sigma = tuple(sig.take(r, "number", check=POSITIVE) for r in rows)
    for other in set(sig.keys()) & set(MEASUREMENTS):     # noise of a sensor not used: allowed
        sig.take(other, "number", check=POSITIVE)
    sig.finish()
    m.finish()
    return rows, sigma


def _operating_point(root: TomlTable) -> OperatingPoint:
    t = root.sub("operating_point")
    op = OperatingPoint(airspeed_mps=t.take("airspeed_mps", "number", 40.0, check=POSITIVE),
                        altitude_m=t.take("altitude_m", "number", 500.0),
                        init=t.take("init", "string", "trim", choices=INITIALISATIONS))
    t.finish()
    return op


def _five(t: TomlTable, key: str, default: tuple[float, ...]) -> tuple[float, ...]:
    val = t.take(key, "numbers", default, check=ALL_NON_NEGATIVE)
    if len(val) != 5:
        raise ConfigError(f"{t.key(key)}: expected 5 values [p_d, u, w, theta, q], got {len(val)}")
    return tuple(val)


def _per_fault(t: TomlTable, key: str, default: tuple[float, ...], nf: int) -> tuple[float, ...]:
    val = t.take(key, "numbers", default, check=ALL_NON_NEGATIVE)
    if len(val) != nf:
        raise ConfigError(f"{t.key(key)}: expected {nf} values (one per fault), got {len(val)}")
    return tuple(val)


def _imm(f: TomlTable, faults: tuple[FaultSpec, ...]) -> ImmSettings:
    t = f.sub("imm")
    nf = len(faults)
    imm = ImmSettings(mode0_sigma_f=_per_fault(t, "mode0_sigma_f", (0.0,) * nf, nf),
                      mode1_sigma_f=_per_fault(t, "mode1_sigma_f", tuple(x.sigma_f for x in faults), nf))
    t.finish()
    return imm


def _gating(f: TomlTable) -> GatingSettings:
    t = f.sub("gating")
    g = GatingSettings(gate_sigma=t.take("gate_sigma", "number", 5.0, check=POSITIVE),
                       hold_s=t.take("hold_s", "number", 0.25, check=NON_NEGATIVE))
    t.finish()
    return g


_CHOICES = {
    "process_model": ("linear", "nonlinear", "kinematic"), "linear_matrices": ("printed", "derived"),
    "sigma_x_basis": ("step", "sqrt_second"), "resampler": ("multinomial", "systematic"),
    "mode0": ("forced_zero", "reset_on_exit", "drift"), "sentinel_weighting": ("thesis", "prior"),
    "jitter": ("global", "per_mode"), "adaptive_transition": ("thesis", "proposal"),
    "actuator_sentinel": ("thesis", "consistent"), "rate_sentinel": ("row", "window"),
    "held_value": ("sentinel", "mean"), "q_noise": ("fixed", "learned"),
    "az_input": ("frame_end", "frame_mean"), "velocity_step": ("euler", "rotation"),
    "frame_angle": ("trapezoid", "spread", "snap"),
    "moment_alpha": ("lift", "stall_blend"),
    "moment_wind": ("entry", "fault_free"),
    "hold_resume": ("cloud", "held"),
    "fault_free_memory": ("entry", "item", "input_item", "wind_input_item"),
    "drift_window": ("offset", "climb"),
    "altitude_gain": ALTITUDE_GAINS, "gain_covariance": GAIN_COVARIANCES, "altimeter_gain": ALTIMETER_GAINS,
    "faulty_row_gain": FAULTY_ROW_GAINS,
}
"""String settings of [parts] and their allowed values (the first field default applies)."""


def _settings(root: TomlTable, faults: tuple[FaultSpec, ...]) -> FilterSettings:
    f = root.sub("parts")
    d = FilterSettings()
    words = {k: f.take(k, "string", getattr(d, k), choices=c) for k, c in _CHOICES.items()}
    s = FilterSettings(
        sigma_x=_five(f, "sigma_x", d.sigma_x), x0_sigma=_five(f, "x0_sigma", d.x0_sigma),
        resample_threshold=f.take("resample_threshold", "number", d.resample_threshold,
                                  check=UNIT_INTERVAL),
        bandwidth=f.take("bandwidth", "number", None, check=POSITIVE),
        bandwidth_k=f.take("bandwidth_k", "number", d.bandwidth_k, check=POSITIVE),
        pi01=f.take("pi01", "number", d.pi01, check=UNIT_INTERVAL),
        pi10=f.take("pi10", "number", d.pi10, check=UNIT_INTERVAL),
        pi10_faint=f.take("pi10_faint", "number", d.pi10_faint, check=UNIT_INTERVAL),
        pi_switch=f.take("pi_switch", "number", d.pi_switch, check=UNIT_INTERVAL),
        saddlepoint_window=f.take("saddlepoint_window", "integer", d.saddlepoint_window,
                                  check=POSITIVE),
        rate_window_s=f.take("rate_window_s", "number", d.rate_window_s, check=POSITIVE),
        thrust_sigma=f.take("thrust_sigma", "number", d.thrust_sigma, check=POSITIVE),
        sentinel_clip=f.take("sentinel_clip", "number", d.sentinel_clip, check=NON_NEGATIVE),
        fault_free_rollback_s=f.take("fault_free_rollback_s", "number", d.fault_free_rollback_s,
                                     check=NON_NEGATIVE),
        gyro_exit_unwind=f.take("gyro_exit_unwind", "number", d.gyro_exit_unwind, check=UNIT_INTERVAL),
        q_tail=tuple(f.take("q_tail", "numbers", d.q_tail, check=ALL_NON_NEGATIVE)),
        q_noise_tau_s=f.take("q_noise_tau_s", "number", d.q_noise_tau_s, check=POSITIVE),
        wind_gust_sigma=f.take("wind_gust_sigma", "number", d.wind_gust_sigma, check=NON_NEGATIVE),
        wind_gust_tau_s=f.take("wind_gust_tau_s", "number", d.wind_gust_tau_s, check=POSITIVE),
        wind_mean_tau_s=f.take("wind_mean_tau_s", "number", d.wind_mean_tau_s, check=POSITIVE),
        wind_hold=f.take("wind_hold", "number", d.wind_hold, check=UNIT_INTERVAL),
        held_airspeed_sigma=f.take("held_airspeed_sigma", "number", d.held_airspeed_sigma,
                                   check=NON_NEGATIVE),
        held_airspeed_tau_s=f.take("held_airspeed_tau_s", "number", d.held_airspeed_tau_s, check=POSITIVE),
        engine_tau_s=f.take("engine_tau_s", "number", d.engine_tau_s, check=NON_NEGATIVE),
        exclusive_items=_exclusive_items(f, faults),
        imm=_imm(f, faults), gating=_gating(f), **words)
    f.finish()
    return s


def _exclusive_items(f: TomlTable, faults: tuple[FaultSpec, ...]) -> tuple[str, ...]:
    """parts.exclusive_items: groups of two or more fault targets, each a space-separated string."""
    groups = f.take("exclusive_items", "strings", ())
    targets = sorted({x.target for x in faults})
    for i, group in enumerate(groups):
        names = group.split()
        unknown = [n for n in names if n not in targets]
        if len(set(names)) < 2 or unknown:
            raise ConfigError(f"{f.key('exclusive_items')}[{i}] = {group!r}: expected two or more "
                              f"distinct fault targets separated by spaces, of {', '.join(targets)}"
                              + (f"; {unknown} watched by no fault" if unknown else ""))
    return tuple(groups)


def _check_prior(settings: FilterSettings, faults: tuple[FaultSpec, ...]) -> None:
    if settings.sentinel_weighting != "prior":
        return
    missing = [f.id for f in faults if f.kind == "sensor" and f.amplitude_max is None]
    if missing:
        raise ConfigError(f"parts.sentinel_weighting = \"prior\" needs faults.amplitude_max for "
                          f"every sensor fault; missing for {missing}")


def _check_kinematic(settings: FilterSettings, faults: tuple[FaultSpec, ...],
                     rows: tuple[str, ...]) -> None:
    """The kinematic process model needs the accelerometer rows; it sees the elevator through the
    pitching moment and the throttle through the thrust check (`thrust.ThrustCheck`), both of
    which need the airspeed row."""
    if settings.process_model != "kinematic":
        return
    missing = [r for r in IMU_ROWS if r not in rows]
    if missing:
        raise ConfigError(f"parts.process_model = \"kinematic\" integrates the accelerometer: "
                          f"measurements.rows must list {', '.join(IMU_ROWS)}; missing {missing}")
    unseen = [f.id for f in faults if f.kind == "actuator" and f.target != "delta_e"
              and "airspeed" not in rows]
    if unseen:
        raise ConfigError(f"parts.process_model = \"kinematic\" sees the throttle only through the "
                          f"thrust its accelerometer implies (measurements.rows must list airspeed): "
                          f"it cannot see actuator faults {unseen}; list airspeed, or watch them with "
                          f"process_model = \"nonlinear\"")
    elevator = [f.id for f in faults if f.target == "delta_e"]
    if elevator and "airspeed" not in rows:
        raise ConfigError(f"parts.process_model = \"kinematic\" sees the elevator {elevator} through the "
                          f"pitching moment, which needs the dynamic pressure: measurements.rows must list "
                          f"airspeed")


def _check_learned_noise(settings: FilterSettings, rows: tuple[str, ...]) -> None:
    """parts.q_noise = "learned" learns from the pitching moment's residuals on the gyro's row: the
    kinematic model with its airspeed (the moment) and q rows (`pitch_noise`)."""
    if settings.q_noise != "learned":
        return
    missing = [r for r in ("airspeed", "q") if r not in rows]
    if settings.process_model != "kinematic" or missing:
        raise ConfigError(f"parts.q_noise = \"learned\" learns the pitching moment's misfit from the "
                          f"gyro: expected process_model = \"kinematic\" and measurements.rows listing "
                          f"airspeed and q; got process_model = \"{settings.process_model}\""
                          + (f", missing {missing}" if missing else ""))


KINEMATIC_PARTS = {"az_input": "pairs the accelerometer the kinematic model integrates",
                   "velocity_step": "is the kinematic model's body-velocity step",
                   "frame_angle": "is the kinematic model's pitch angle over a frame",
                   "moment_alpha": "is the kinematic model's pitching-moment angle of attack",
                   "moment_wind": "is the kinematic model's pitching-moment head wind"}
"""[parts] settings only the kinematic model has (their first value is every model's default)."""


def _check_kinematic_parts(settings: FilterSettings) -> None:
    """parts.az_input, velocity_step, frame_angle, moment_alpha and moment_wind other than their
    defaults need the kinematic model."""
    for key, what in KINEMATIC_PARTS.items():
        value = getattr(settings, key)
        if value != _CHOICES[key][0] and settings.process_model != "kinematic":
            raise ConfigError(f"parts.{key} = \"{value}\" {what}: expected process_model = "
                              f"\"kinematic\"; got \"{settings.process_model}\"")


def _check_engine(settings: FilterSettings, faults: tuple[FaultSpec, ...], rows: tuple[str, ...]) -> None:
    """An engine fault is seen in the throttle the accelerometer implies (`thrust.ThrustCheck`): the
    kinematic model with its ax, az and airspeed rows."""
    engine = [f.id for f in faults if f.fault_type == "engine"]
    needs = (*IMU_ROWS, "airspeed")
    if engine and not (settings.process_model == "kinematic" and set(needs) <= set(rows)):
        raise ConfigError(f"faults {engine}: an engine fault is seen in the throttle the accelerometer "
                          f"implies (thrust.py): expected parts.process_model = \"kinematic\" and "
                          f"measurements.rows listing {', '.join(needs)}")


def _check_pitot(settings: FilterSettings, faults: tuple[FaultSpec, ...], rows: tuple[str, ...]) -> None:
    """A pitot fault needs the derived airspeed row: the kinematic model and its ax, az rows."""
    pitot = [f.id for f in faults if f.target == AIRSPEED_ROW]
    folding = [f.id for f in faults if f.target == AIRSPEED_ROW and f.on_exit != "reset"]
    if folding:
        raise ConfigError(f"faults {folding}: a pitot fault cannot fold into the state (the wind, "
                          f"which nothing else sees, would explain it away); expected on_exit = \"reset\"")
    drifting = [f.id for f in faults if f.target == AIRSPEED_ROW and f.drift_sigma > 0]
    if drifting:
        raise ConfigError(f"faults {drifting}: the pitot's fault-free motion is the wind's "
                          f"(parts.wind_gust_sigma, held_airspeed_sigma, wind_gust_tau_s, "
                          f"wind_mean_tau_s); expected no drift_sigma on an airspeed fault")
    if pitot and not (settings.process_model == "kinematic" and set(IMU_ROWS) <= set(rows)):
        raise ConfigError(f"faults {pitot} watch the pitot, which only the kinematic model observes "
                          f"(against its ground speed): expected parts.process_model = \"kinematic\" "
                          f"and measurements.rows listing {', '.join(IMU_ROWS)}")


def parse_estimator(doc: dict[str, Any], source: str = "<estimator>") -> EstimatorConfig:
    """Validate a parsed estimator document; raise ConfigError naming the first bad key."""
    root = TomlTable(doc, "")
    head = dict(
        id=root.take("id", "string"), airframe=root.take("airframe", "string", "aerosonde"),
        dt_s=root.take("dt_s", "number", 0.05, check=POSITIVE),
        filter=root.take("filter", "string", "RJMRPF", choices=FILTER_NAMES),
        particles=root.take("particles", "integer", 1000, check=POSITIVE),
        seed=root.take("seed", "integer", 0, check=NON_NEGATIVE))
    rows, sigma = _measurements(root)
    faults = _faults(root, rows)
    settings = _settings(root, faults)
    _check_prior(settings, faults)
    _check_kinematic(settings, faults, rows)
    _check_learned_noise(settings, rows)
    _check_kinematic_parts(settings)
    _check_pitot(settings, faults, rows)
    _check_engine(settings, faults, rows)
    op = _operating_point(root)
    root.finish()
    return EstimatorConfig(operating_point=op, measurements=rows, sigma=sigma, faults=faults,
                           settings=settings, doc=copy.deepcopy(doc), source=source, **head)


def merge_documents(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """`base` with `override` laid over it: tables merge key by key, anything else is replaced."""
    out = copy.deepcopy(base)
    for key, val in override.items():
        if isinstance(val, dict) and isinstance(out.get(key), dict):
            out[key] = merge_documents(out[key], val)
        else:
            out[key] = copy.deepcopy(val)
    return out


def estimator_document(name_or_path: str | os.PathLike[str]) -> tuple[dict[str, Any], Path]:
    """The parsed TOML of an estimator file, by name (`aerosonde`) or path, and its path."""
    path = estimator_path(name_or_path)
    return load_toml(path, "estimator file"), path


def load_estimator(name_or_path: str | os.PathLike[str] = DEFAULT_ESTIMATOR,
                   overrides: dict[str, Any] | None = None) -> EstimatorConfig:
    """Load and validate an estimator file by name or path, with optional overrides laid over it."""
    doc, path = estimator_document(name_or_path)
    if overrides:
        doc = merge_documents(doc, overrides)
    try:
        return parse_estimator(doc, str(path))
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
