"""Experiment files (`config/experiments/*.toml`): a world, an estimator by reference, the filters.

Only experiments know the truth. One file describes an experiment (the thesis's are SPEC section
7): `[experiment]` (id, duration, step, the filters to compare and the proposed one), `[world]` (the
truth airframe and model, the autopilot command, the true sensor noise, the injected faults with
their time profiles) and `[estimator]`: an estimator file by name (`use`, config/estimators/) with
the overrides the experiment needs laid over it (`fdir_service.estimator_config`). The lab-only
key `estimator.noise_from_world = k` sets the estimator's assumed noise to k times the world's
true sensor noise (the thesis's filters assume 1.5x). Everything is validated on load: an unknown
key, a wrong type or an impossible value raises `ConfigError` naming the file and key. Units: SI
(m, m/s, rad, rad/s, s) except a fault profile's `amplitude`, which is in the fault's `unit`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.errors import ConfigError
from fdir_service.estimation.recipes import FILTER_NAMES
from fdir_service.estimator_config import (
    ACTUATORS,
    MEASUREMENTS,
    UNITS,
    EstimatorConfig,
    estimator_document,
    merge_documents,
    parse_estimator,
)
from fdir_service.paths import config_path
from fdir_service.tomltable import NON_NEGATIVE, POSITIVE, TomlTable, load_toml
from sim_bridge.onboard_nav import NAVIGATION
from sim_bridge.world_config import RealSky, parse_real_sky

PROFILE_SHAPES = ("step", "exponential", "ramp", "intermittent")
WORLD_SENSOR_FAULT_TYPES = ("bias", "stuck", "noisy", "blocked", "drift")
"""What a world sensor fault does to its row (`sim_bridge.fault_types`); "blocked" is the pitot's
(airspeed row only)."""
WORLD_ACTUATOR_FAULT_TYPES = ("bias", "jammed", "effectiveness", "engine")
"""What a world actuator fault does to its input (`sim_bridge.fault_types`); "engine" is the
throttle's (delta_t only)."""
STUCK_NOISE = ("kept", "none")
"""A stuck row's noise: the row's usual noise on top of the held value, or none."""
_PURE_NUMBER_TYPES = {"noisy": "a noise multiplier k >= 1",
                      "effectiveness": "a remaining gain g in [0, 1]",
                      "engine": "a remaining share of the thrust g in [0, 1]"}
"""Types whose amplitude is a pure number (unit "1"), and what it is."""
def _within_unit_interval(lo: float, hi: float) -> bool:
    return lo >= 0.0 and hi <= 1.0


_AMPLITUDE_OK = {"noisy": lambda lo, hi: lo >= 1.0, "effectiveness": _within_unit_interval,
                 "engine": _within_unit_interval}


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
    varies: tuple[tuple[str, float, float], ...] = ()
    """Per-run draws (`faults.vary_profiles`): (field, lo, hi) for start_s, duration_s, amplitude
    (SI), each uniform; the fields above then hold the range's low end."""
    random_sign: bool = False
    """Per run, the amplitude's sign is + or - with equal probability."""


@dataclass(frozen=True)
class FaultChannel:
    """An injected fault on a measurement row (`kind` sensor) or an input (`kind` actuator).

    `profile` is its time course in the world (summed components, SI); `unit` is for reports.
    `fault_type` (file key `type`) is what the profile's value does to the target
    (`sim_bridge.fault_types`): "bias" adds it (the default); sensors also "stuck", "noisy",
    "blocked" (airspeed only); actuators "jammed", "effectiveness", "engine" (delta_t only).
    `noise` ("kept" | "none"): a stuck row's noise on top of the held value.
    """

    id: str
    target: str
    kind: str
    unit: str
    profile: tuple[ProfileComponent, ...]
    fault_type: str = "bias"
    noise: str = "kept"

    @property
    def unit_scale(self) -> float:
        """Multiply an SI value by 1/unit_scale to express it in `unit`."""
        return UNITS[self.unit]


@dataclass(frozen=True)
class TruthConfig:
    """The world's aircraft: its airframe file, its model and its initial trim (m/s, m)."""

    airframe: str = "aerosonde"
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
    climb_rate_mps: float | None = None
    """None: each altitude step is a step of the command (the thesis); else the command ramps to
    it at this rate (m/s), as a stock autopilot's climb-rate limit (ArduPlane TECS_CLMB_MAX) does."""


WORLD_ROWS = MEASUREMENTS + ("airspeed", "ax", "az")
"""Rows a world can produce: the estimator's known rows, the pitot airspeed (air-relative, m/s) and
the accelerometer's body-axis specific force (ax forward, az down, m/s^2)."""


@dataclass(frozen=True)
class SensorConfig:
    """The world's sensors: rows produced and their true noise std per row (SI), and the realism
    that is off in the thesis scenarios (docs/real-world.md)."""

    measurements: tuple[str, ...]
    sigma: dict[str, float]
    gnss_gauss_markov: bool = False    # eq. 3.29 error model (off in the thesis scenarios)
    gnss_rate_hz: float | None = None  # a GNSS fix every 1/rate s (None: every frame)
    gnss_latency_s: float = 0.0        # a fix reports the altitude of latency s before
    baro_bias_walk: float = 0.0        # barometer bias random walk, m / sqrt(s)
    gyro_bias_sigma: float = 0.0       # q gyro: constant bias per run ~ N(0, sigma^2), rad/s
    gyro_bias_walk: float = 0.0        # q gyro bias random walk, rad/s / sqrt(s)


@dataclass(frozen=True)
class Scenario:
    """An experiment: world (truth, command, sensors, injected faults), estimator, filters."""

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
    filters: tuple[str, ...]
    proposed: str
    source: str = ""
    sky: RealSky = RealSky()
    """Wind, turbulence, airframe dispersion and the engine (all off in the thesis experiments)."""
    navigation: str = "monitor"
    """What the autopilot flies on (`[world.autopilot] navigation`, `sim_bridge.onboard_nav`):
    "monitor", the monitor's own estimate (the thesis's closed loop), "onboard", its own through its
    faulty sensors, or "truth", a navigation the faulty sensor does not reach."""

    @property
    def steps(self) -> int:
        """Number of filter steps in the run (duration / dt)."""
        return int(round(self.duration_s / self.dt_s))

    @property
    def sensor_faults(self) -> tuple[FaultChannel, ...]:
        return tuple(f for f in self.faults if f.kind == "sensor")

    def estimator_rows(self) -> np.ndarray:
        """(m_est,) index of each estimator row in the world's sensor rows, -1 where the world has
        no such sensor (the row then never arrives)."""
        world = list(self.sensors.measurements)
        return np.array([world.index(r) if r in world else -1 for r in self.estimator.measurements])

    def estimator_fault_truth(self, world_faults: np.ndarray) -> np.ndarray:
        """The world's true faults (..., nf_world) as the estimator's faults (..., nf_est), by id (in
        a world of typed faults by item and type: `type_yardstick.truth_columns`); 0 for a
        monitored fault the world does not inject."""
        from sim_bridge.type_yardstick import truth_columns

        out = np.zeros(world_faults.shape[:-1] + (len(self.estimator.faults),), dtype=world_faults.dtype)
        for j, w in enumerate(truth_columns(self.estimator.faults, self.faults)):
            if w is not None:
                out[..., j] = world_faults[..., w]
        return out


# ----------------------------------------------------------------------------- validation

def _number_or_range(t: TomlTable, name: str, default: Any = ...) -> tuple[float, float] | None:
    """A number (lo == hi) or a [lo, hi] range (drawn per run) under `name`; None if absent."""
    kind = "numbers" if isinstance(t.peek(name), list) else "number"
    raw = t.take(name, kind, default)
    if raw is None:
        return None
    if isinstance(raw, (int, float)):
        return float(raw), float(raw)
    if len(raw) != 2 or raw[1] < raw[0]:
        raise ConfigError(f"{t.key(name)}: expected a number or a range [low, high], got {raw}")
    return float(raw[0]), float(raw[1])


def _timing(t: TomlTable) -> tuple[tuple[float, float], tuple[float, float], bool]:
    """(start range, end or duration range, whether the second is a duration) of a profile."""
    start = _number_or_range(t, "start_s")
    if start[0] < 0:
        raise ConfigError(f"{t.key('start_s')}: expected a non-negative time, got {start[0]}")
    duration = _number_or_range(t, "duration_s", None)
    if duration is not None:
        if duration[0] <= 0:
            raise ConfigError(f"{t.key('duration_s')}: expected a positive duration, got {duration[0]}")
        return start, duration, True
    end = _number_or_range(t, "end_s")
    if end[0] <= start[1]:
        raise ConfigError(f"{t.key('end_s')}: expected a time after start_s ({start[1]}), got {end[0]}")
    return start, end, False


def _amplitude(t: TomlTable, fault_type: str) -> tuple[float, float]:
    """The amplitude (range) in the fault's unit; a noisy's k >= 1, an effectiveness's g in [0, 1]."""
    amp = _number_or_range(t, "amplitude")
    if fault_type in _AMPLITUDE_OK:
        if not _AMPLITUDE_OK[fault_type](*amp):
            raise ConfigError(f"{t.key('amplitude')}: expected {_PURE_NUMBER_TYPES[fault_type]} "
                              f"for a {fault_type} fault, got {list(amp) if amp[0] != amp[1] else amp[0]}")
        if t.peek("random_sign"):
            raise ConfigError(f"{t.key('random_sign')}: expected false for a {fault_type} fault "
                              "(its amplitude is a factor), got true")
    return amp


def _profile(t: TomlTable, scale: float, fault_type: str = "bias") -> ProfileComponent:
    shape = t.take("shape", "string", choices=PROFILE_SHAPES)
    start, end, is_duration = _timing(t)
    amp = _amplitude(t, fault_type)
    ranges = (("start_s", start), ("amplitude", (amp[0] * scale, amp[1] * scale)))
    varies = [(k, lo, hi) for k, (lo, hi) in ranges if hi > lo]
    if is_duration:
        varies.append(("duration_s", *end))
    comp = ProfileComponent(
        shape=shape, start_s=start[0], end_s=start[0] + end[0] if is_duration else end[0],
        amplitude=amp[0] * scale, tau_s=t.take("tau_s", "number", 1.0, check=POSITIVE),
        on_s=t.take("on_s", "number", 1.0, check=POSITIVE),
        off_s=t.take("off_s", "number", 1.0, check=POSITIVE),
        varies=tuple(varies), random_sign=t.take("random_sign", "boolean", False))
    t.finish()
    return comp


def _fault_type(t: TomlTable, target: str) -> tuple[str, str]:
    """The fault's `type` for its target and a stuck fault's `noise` option."""
    actuator = target in ACTUATORS
    ftype = t.take("type", "string", "bias",
                   choices=WORLD_ACTUATOR_FAULT_TYPES if actuator else WORLD_SENSOR_FAULT_TYPES)
    if ftype == "blocked" and target != "airspeed":
        raise ConfigError(f"{t.key('type')}: \"blocked\" is the pitot's (target \"airspeed\"); for "
                          f"target {target!r} expected one of bias, stuck, noisy, got {ftype!r}")
    if ftype == "engine" and target != "delta_t":
        raise ConfigError(f"{t.key('type')}: \"engine\" is the throttle's (target \"delta_t\"); for "
                          f"target {target!r} expected one of bias, jammed, effectiveness, got {ftype!r}")
    if ftype != "stuck" and t.peek("noise") is not None:
        raise ConfigError(f"{t.key('noise')}: only a stuck fault has a noise option; expected no "
                          f"noise key for a {ftype} fault, got {t.peek('noise')!r}")
    return ftype, t.take("noise", "string", "kept", choices=STUCK_NOISE)


def _fault(t: TomlTable, measurements: tuple[str, ...]) -> FaultChannel:
    fid = t.take("id", "string")
    target = t.take("target", "string", choices=measurements + ACTUATORS)
    ftype, noise = _fault_type(t, target)
    unit = t.take("unit", "string", choices=tuple(UNITS))
    if ftype in _PURE_NUMBER_TYPES and unit != "1":
        raise ConfigError(f"{t.key('unit')}: expected \"1\" for a {ftype} fault (its amplitude is "
                          f"{_PURE_NUMBER_TYPES[ftype]}), got {unit!r}")
    comps = tuple(_profile(pt, UNITS[unit], ftype) for pt in t.tables("profile"))
    t.finish()
    return FaultChannel(id=fid, target=target, kind="actuator" if target in ACTUATORS else "sensor",
                        unit=unit, profile=comps, fault_type=ftype, noise=noise)


def _truth(w: TomlTable) -> TruthConfig:
    return TruthConfig(
        airframe=w.take("airframe", "string", "aerosonde"),
        model=w.take("model", "string", "nonlinear", choices=("linear", "nonlinear")),
        linear_matrices=w.take("linear_matrices", "string", "printed", choices=("printed", "derived")),
        airspeed_mps=w.take("airspeed_mps", "number", 40.0, check=POSITIVE),
        altitude_m=w.take("altitude_m", "number", 500.0))


def _command(w: TomlTable, truth: TruthConfig) -> CommandConfig:
    c = w.sub("command")
    steps = []
    for tt in c.tables("altitude_steps"):
        steps.append(AltitudeStep(tt.take("t_s", "number", check=NON_NEGATIVE),
                                  tt.take("altitude_m", "number")))
        tt.finish()
    command = CommandConfig(
        altitude_m=c.take("altitude_m", "number", truth.altitude_m),
        airspeed_mps=c.take("airspeed_mps", "number", truth.airspeed_mps, check=POSITIVE),
        altitude_steps=tuple(steps),
        climb_rate_mps=c.take("climb_rate_mps", "number", None, check=POSITIVE))
    c.finish()
    return command


def _sensors(w: TomlTable) -> SensorConfig:
    se = w.sub("sensors", required=True)
    meas = se.take("measurements", "strings", choices=WORLD_ROWS)
    if not meas or len(set(meas)) != len(meas):
        raise ConfigError(f"{se.key('measurements')}: expected a non-empty list without repeats")
    sig_t = se.sub("sigma", required=True)
    sigma = {m: sig_t.take(m, "number", check=POSITIVE) for m in meas}
    sig_t.finish()
    sensors = SensorConfig(measurements=meas, sigma=sigma,
                           gnss_gauss_markov=se.take("gnss_gauss_markov", "boolean", False),
                           gnss_rate_hz=se.take("gnss_rate_hz", "number", None, check=POSITIVE),
                           gnss_latency_s=se.take("gnss_latency_s", "number", 0.0, check=NON_NEGATIVE),
                           baro_bias_walk=se.take("baro_bias_walk", "number", 0.0, check=NON_NEGATIVE),
                           gyro_bias_sigma=se.take("gyro_bias_sigma", "number", 0.0, check=NON_NEGATIVE),
                           gyro_bias_walk=se.take("gyro_bias_walk", "number", 0.0, check=NON_NEGATIVE))
    se.finish()
    return sensors


def _world(root: TomlTable) -> dict[str, Any]:
    """The world's parts as Scenario fields: truth, command, sensors, faults, sky, navigation."""
    w = root.sub("world", required=True)
    truth = _truth(w)
    command = _command(w, truth)
    sensors = _sensors(w)
    faults = tuple(_fault(ft, sensors.measurements) for ft in w.tables("faults"))
    ids = [f.id for f in faults]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"world.faults: fault ids must be unique, got {ids}")
    sky = parse_real_sky(w, truth.model)
    navigation = _navigation(w)
    w.finish()
    return dict(truth=truth, command=command, sensors=sensors, faults=faults, sky=sky,
                navigation=navigation)


def _navigation(w: TomlTable) -> str:
    """`[world.autopilot] navigation`: "monitor" (default), "onboard" or "truth" (`onboard_nav`)."""
    ap = w.sub("autopilot")
    navigation = ap.take("navigation", "string", "monitor", choices=NAVIGATION)
    ap.finish()
    return navigation


def _estimator_doc(root: TomlTable, exp_id: str, sensors: SensorConfig) -> dict[str, Any]:
    """The experiment's estimator document: `use`'s file with the overrides laid over it."""
    e = root.sub("estimator", required=True)
    base, _ = estimator_document(e.take("use", "string", "aerosonde"))
    factor = e.take("noise_from_world", "number", None, check=POSITIVE)
    doc = merge_documents(base, e.rest())
    doc["id"] = exp_id
    if factor is not None:
        rows = doc.get("measurements", {}).get("rows", [])
        missing = [r for r in rows if r not in sensors.sigma]
        if missing:
            raise ConfigError(f"estimator.noise_from_world: the world has no {missing[0]!r} sensor")
        doc.setdefault("measurements", {})["sigma"] = {r: sensors.sigma[r] * factor for r in rows}
    return doc


def _check_fault_match(est: EstimatorConfig, faults: tuple[FaultChannel, ...]) -> None:
    """Each injected fault is scored against the monitored fault of the same id: a world fault the
    estimator does not monitor could never be detected (a missed fault, but most likely a typo)."""
    monitored = {f.id: f.target for f in est.faults}
    for f in faults:
        if monitored.get(f.id, f.target) != f.target:
            raise ConfigError(f"world.faults: {f.id!r} acts on {f.target} but the estimator's "
                              f"fault {f.id!r} watches {monitored[f.id]}")


def parse_scenario(doc: dict[str, Any], source: str = "<experiment>") -> Scenario:
    """Validate a parsed experiment document; raise ConfigError naming the first bad key."""
    root = TomlTable(doc, "")
    x = root.sub("experiment", required=True)
    head = dict(id=x.take("id", "string"), title=x.take("title", "string", ""),
                thesis_section=x.take("thesis_section", "string", ""),
                thesis_table=x.take("thesis_table", "string", ""),
                duration_s=x.take("duration_s", "number", 50.0, check=POSITIVE),
                dt_s=x.take("dt_s", "number", 0.05, check=POSITIVE),
                filters=x.take("filters", "strings", choices=FILTER_NAMES),
                proposed=x.take("proposed", "string", choices=FILTER_NAMES))
    x.finish()
    if head["proposed"] not in head["filters"]:
        raise ConfigError(f"experiment.proposed: {head['proposed']!r} must be one of experiment.filters")
    world = _world(root)
    est_doc = _estimator_doc(root, head["id"], world["sensors"])
    root.finish()
    est = parse_estimator(est_doc, f"{source} [estimator]")
    if abs(est.dt_s - head["dt_s"]) > 1e-12:
        raise ConfigError(f"estimator.dt_s: expected the experiment's step {head['dt_s']}, got {est.dt_s}")
    _check_fault_match(est, world["faults"])
    return Scenario(estimator=est, source=source, **world, **head)


def scenario_path(name_or_path: str | Path) -> Path:
    """An experiment file by id (`ch4` -> config/experiments/ch4.toml) or path."""
    return config_path("experiments", name_or_path)


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate an experiment by id (`ch4`) or path."""
    path = scenario_path(name_or_path)
    doc = load_toml(path, "experiment file")
    try:
        return parse_scenario(doc, str(path))
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


SCENARIO_IDS = ("ch4", "ch5a", "ch5b", "ch5c", "ch6")
REAL_WORLDS = ("real-calm", "real-turbulence", "real-wind", "real-dispersed", "real-jsbsim")
FAMILIES = {
    "all": SCENARIO_IDS,
    "thesis": SCENARIO_IDS,
    "real": tuple(w + suffix for w in REAL_WORLDS for suffix in ("", "-faultfree")),
}
"""`sim-bridge experiment FAMILY`: the thesis's five, and the real-sky worlds (docs/real-world.md),
each with its fault-free 10-minute variant."""


def experiment_service_config(scenario: Scenario, text: str | None = None):
    """The service config (default file, or `text`) monitoring with the experiment's estimator:
    how the lab runs `fdir_service` on its own worlds with the thesis's settings."""
    from fdir_service.service_config import ServiceConfig, default_config_path

    path = default_config_path()
    return ServiceConfig.from_toml_text(path.read_text() if text is None else text,
                                        estimator_doc=scenario.estimator.doc,
                                        source=f"{path} + {scenario.id} estimator")
