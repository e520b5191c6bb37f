"""The service configuration (`config/service/default.toml`): links, signing, frames, publishing, and the
mapping from MAVLink message fields to the filter's measurement vector y (m,) and input u (2,).

A mapped value is `raw * scale + offset`, then a transform: `none`, `pressure_to_altitude`
(Pa -> m above MSL, the barometric formula of `fdir_service.atmosphere`), `negate`, or `pwm`
(linear from [pwm_min, pwm_max] us to [min, max] in SI; clipped to that range). The estimator
file named in `[service] estimator` (`config/estimators/`, default `aerosonde`) supplies the
airframe, the filter and its settings, the measurement rows (in order) and the monitored faults;
`[service]` may override its filter, particles and seed. Every key is validated on load: an
unknown key, a wrong type or an impossible value raises `ConfigError` naming the key.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fdir_service.errors import ConfigError
from fdir_service.estimation.recipes import FILTER_NAMES
from fdir_service.estimator_config import (
    ACTUATORS,
    DEFAULT_ESTIMATOR,
    EstimatorConfig,
    load_estimator,
    parse_estimator,
)
from fdir_service.paths import service_path
from fdir_service.tomltable import NON_NEGATIVE, POSITIVE, Check, TomlTable

STAMPS = ("message", "unwrap32", "latest", "arrival", "epoch")
TRANSFORMS = ("none", "negate", "pressure_to_altitude", "pwm", "differential_pressure_to_airspeed")
RHO_SEA_LEVEL = 1.225
TYPE_HOLD_S = 0.0
"""s: how long a fault type holds its share of P(item) before the service names it
(`DeclareConfig.type_hold_s`; docs/faults.md, "Naming the type")."""
"""kg/m^3: a pitot's differential pressure (Pa) reads as the indicated airspeed sqrt(2 dp / rho_0)."""
_FIELD_RE = re.compile(r"^([a-z_][a-z0-9_]*)(?:\[(\d+)\])?$")


def default_config_path() -> Path:
    """`config/service/default.toml` (beside the package, or under $FDIR_CONFIG_DIR)."""
    return service_path("default")


@dataclass(frozen=True)
class FieldMap:
    """One vector entry read from one message field.

    name: the measurement (estimator row name) or input (delta_e, delta_t); message: MAVLink message
    name (e.g. "GPS_RAW_INT"); field: field name, `name[i]` for an array element; value in SI =
    transform(raw * scale + offset); `where`: field -> required value (other messages of that
    type are ignored for this entry); valid range checked on the SI value; stale_s: a measurement
    silent this long (message time) is reported stale.
    """

    name: str
    message: str
    field: str
    index: int | None = None
    scale: float = 1.0
    offset: float = 0.0
    transform: str = "none"
    pwm_min: float = 1000.0
    pwm_max: float = 2000.0
    min: float = -math.inf
    max: float = math.inf
    where: tuple[tuple[str, float], ...] = ()
    stale_s: float = 1.0
    frozen_s: float = 0.0
    """A measurement whose value stays bit-identical this long (message time) is frozen: masked and
    reported (0 = never; inputs are never checked, a constant throttle is normal)."""
    derive: str = ""
    """A derivation of `runtime.derived.DERIVATIONS` (then `field` is empty and the raw value is
    derived from `message`, the sample, and the other `sources`); "" = read `field`."""
    sources: tuple[str, ...] = ()
    options: tuple[tuple[str, float], ...] = ()
    """The derivation's options (name, value), e.g. (("function", 19.0), ("max_deflection_deg", 25.0))."""
    stamp: str = "message"
    """Where the message's time comes from: "message" (its time_usec / time_boot_ms), "unwrap32" (a
    uint32 time_usec that wraps every 71.6 min, unwrapped against the latest stamp seen), "latest"
    (a message without a timestamp, e.g. VFR_HUD: the latest stamp seen on the link) or "arrival"
    (a message whose own stamp lags its arrival, e.g. ArduPilot's GPS_RAW_INT stamped with the fix
    time: the latest stamp seen, and a repeat of the previous own stamp is dropped) or "epoch" (as
    "arrival", but a stamp counting UNIX-epoch time is mapped onto boot time with SYSTEM_TIME
    (`runtime.clock`) and the message placed there if that frame is not stepped yet)."""
    rate_hz: float = 0.0
    """The rate (Hz) the service asks the autopilot to send `message` at (MAV_CMD_SET_MESSAGE_INTERVAL)
    and expects it at; 0 = the default (`runtime.streams.DEFAULT_RATES_HZ`, else the frame rate)."""

    def convert(self, raw: float) -> float:
        """Raw field value -> SI value (NaN for a non-numeric or impossible raw value)."""
        v = float(raw) * self.scale + self.offset
        if self.transform == "negate":
            return -v
        if self.transform == "pressure_to_altitude":
            from fdir_service.atmosphere import altitude_from_pressure

            return float(altitude_from_pressure(v)) if v > 0.0 else math.nan
        if self.transform == "differential_pressure_to_airspeed":
            return math.sqrt(2.0 * v / RHO_SEA_LEVEL) if v >= 0.0 else math.nan
        if self.transform == "pwm":
            frac = (v - self.pwm_min) / (self.pwm_max - self.pwm_min)
            frac = min(max(frac, 0.0), 1.0)
            return self.min + frac * (self.max - self.min)
        return v


@dataclass(frozen=True)
class DeclareConfig:
    """STATUSTEXT hysteresis: declare when P(fault) >= p_declare for declare_hold_s of frame
    time; clear when P(fault) <= p_clear for clear_hold_s. A declared item's type is named once
    P(item) >= p_declare and the most probable type has held a share >= p_type of it for
    type_hold_s of frame time (a change of name: at least declare_hold_s too); until then it is
    declared as of an unclear type (p_type 0 and type_hold_s 0: name the most probable at once)."""

    p_declare: float = 0.9
    declare_hold_s: float = 0.2
    p_clear: float = 0.5
    clear_hold_s: float = 1.0
    p_type: float = 0.8
    type_hold_s: float = TYPE_HOLD_S


@dataclass(frozen=True)
class PublishConfig:
    named_value_rate_hz: float = 10.0   # f_/pf_/pfa_/pmd_ NAMED_VALUE_FLOAT rate (frame time)
    estimate_rate_hz: float = 20.0      # FDIR_ESTIMATE rate (frame time); >= frame rate: every frame
    heartbeat_period_s: float = 1.0
    stale_statustext: bool = True       # also announce stale / recovered sensors by STATUSTEXT
    declare: DeclareConfig = field(default_factory=DeclareConfig)


@dataclass(frozen=True)
class HealthConfig:
    """Link and estimator supervision (`[health]`).

    link_timeout_s: no input bytes for this long (wall clock) = link lost (HEARTBEAT CRITICAL,
    STATUSTEXT); min_n_eff / degenerate_frames: a particle filter whose N_eff stays below min_n_eff
    for that many consecutive frames is degenerate and is re-initialised from the current
    measurements (also on a non-finite estimate or the filter's own re-initialisation);
    reinit_gate_sigmas: on re-initialisation, rows further than this many sigma from the state made
    from the measurements are masked for that frame; reinit_holdoff_s: frame time between two
    re-initialisations; statustext_interval_s: minimum frame time between two STATUSTEXTs about the
    same kind of bad input.
    """

    link_timeout_s: float = 2.0
    min_n_eff: float = 1.5
    degenerate_frames: int = 10
    reinit_gate_sigmas: float = 20.0
    reinit_holdoff_s: float = 1.0
    statustext_interval_s: float = 10.0
    max_state_jump: tuple[float, ...] = (50.0, 20.0, 20.0, 1.0, 5.0)
    """Largest change of the airframe estimate [p_d m, u m/s, w m/s, theta rad, q rad/s] from one
    frame to the next that is still physical (far beyond any correction on healthy data); a step
    beyond it re-initialises the filter on that frame, before anything is published. () = off."""


@dataclass(frozen=True)
class StreamConfig:
    """Stream requests and rate checks (`[streams]`).

    request: after the followed autopilot's first HEARTBEAT, ask for every mapped message at its
    wanted rate (MAV_CMD_SET_MESSAGE_INTERVAL; on ArduPilot REQUEST_DATA_STREAM when the command is
    refused); off when the operator sets the rates on the autopilot. ack_timeout_s: wall time to
    wait for a COMMAND_ACK before sending again; retries: how many times to send again (then "no
    answer"). window_s: frame time over which each message's arrival rate is measured; min_fraction:
    a message arriving below this fraction of its wanted rate is reported slow.
    parameters: with an autopilot profile, after that HEARTBEAT also ask for the parameters the
    profile reads (PARAM_REQUEST_READ, `runtime.params`; unanswered ones are sent again after
    ack_timeout_s, `retries` times); parameters_in_flight: at most this many unanswered at a time.
    """

    request: bool = True
    ack_timeout_s: float = 1.0
    retries: int = 2
    window_s: float = 5.0
    min_fraction: float = 0.8
    parameters: bool = True
    parameters_in_flight: int = 4


@dataclass(frozen=True)
class RecordConfig:
    """`fdir run`'s flight recorder (`[record]`): on by default, a new file per start in `directory`
    (relative paths: from the working directory), rotated past rotate_mb MB or rotate_s seconds
    (0 = never)."""

    enabled: bool = True
    directory: str = "recordings"
    rotate_mb: float = 100.0
    rotate_s: float = 3600.0


@dataclass(frozen=True)
class ServiceConfig:
    """A validated service configuration. `text` is the TOML source and `estimator.doc` the resolved
    estimator document (both recorded in logs so that `fdir replay` rebuilds the identical pipeline);
    `filter`, `particles` and `seed` are the estimator's unless `[service]` overrides them."""

    estimator: EstimatorConfig
    filter: str
    particles: int
    seed: int
    master: str
    gcs: tuple[str, ...]
    autopilot_system: int
    component: int
    signing_key_file: str
    signing_link_id: int
    frame_rate_hz: float
    max_gap_s: float
    measurements: tuple[FieldMap, ...]
    inputs: tuple[FieldMap, ...]
    publish: PublishConfig
    health: HealthConfig = field(default_factory=HealthConfig)
    record: RecordConfig = field(default_factory=RecordConfig)
    streams: StreamConfig = field(default_factory=StreamConfig)
    text: str = ""
    source: str = "<text>"
    autopilot: str = "none"
    """The autopilot profile in force (`fdir run --autopilot`): "none" (this file's mapping), a
    profile name ("ardupilot": its mapping replaced `measurements` and `inputs`), or "auto" (this
    file's mapping until the autopilot's HEARTBEAT picks one of `auto_profiles`)."""
    parameters: tuple[tuple[str, float], ...] = ()
    """The profile's autopilot parameter defaults (name, value); PARAM_VALUE messages replace them."""
    parameter_requests: tuple[str, ...] = ()
    """The profile's `[parameter_requests] names`: asked of the autopilot besides `parameters`
    (`{n}`: every servo output 1..16, `{i}`: every PX4 control surface 0..7)."""
    parameter_channel_requests: tuple[str, ...] = ()
    """The profile's `[parameter_requests] channel`: asked for each output channel `{n}` an input
    reads (found once the names above are answered)."""
    auto_profiles: tuple[tuple[int, ServiceConfig], ...] = ()
    """For "auto": (HEARTBEAT.autopilot, the config with that profile applied)."""
    profile_texts: tuple[tuple[str, str], ...] = ()
    """(profile name, TOML text) of every profile loaded, recorded so `fdir replay` rebuilds them."""

    @property
    def frame_period_us(self) -> int:
        return int(round(1e6 / self.frame_rate_hz))

    def signing_key(self) -> bytes | None:
        """The 32-byte signing key read from `signing.key_file` (64 hex characters), or None."""
        if not self.signing_key_file:
            return None
        path = Path(self.signing_key_file)
        try:
            txt = path.read_text().strip()
        except OSError as exc:
            raise ConfigError(f"signing.key_file: cannot read {path}: {exc.strerror}") from None
        try:
            key = bytes.fromhex(txt)
        except ValueError:
            key = b""
        if len(key) != 32:
            raise ConfigError(f"signing.key_file: {path} must hold 64 hex characters (a 32-byte key)")
        return key

    @classmethod
    def from_toml_text(cls, text: str, *, estimator_doc: dict[str, Any] | None = None,
                       source: str = "<text>") -> ServiceConfig:
        """Parse and validate. With `estimator_doc` (the resolved estimator document, as recorded in
        a log) that estimator is used instead of the file named in `[service] estimator`."""
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{source}: not valid TOML: {exc}") from None
        return cls.from_document(doc, text, estimator_doc=estimator_doc, source=source)

    @classmethod
    def from_document(cls, doc: dict[str, Any], text: str = "", *,
                      estimator_doc: dict[str, Any] | None = None,
                      source: str = "<text>") -> ServiceConfig:
        """As `from_toml_text`, from an already parsed TOML document (`text` is kept for logs)."""
        try:
            return _parse(doc, text, estimator_doc, source)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from None


def load_service_config(path: str | Path | None = None, *, estimator: str | None = None) -> ServiceConfig:
    """Load and validate a service config file (default `config/service/default.toml`);
    `estimator` (a name or path) replaces its `[service] estimator`."""
    p = Path(path) if path is not None else default_config_path()
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such service config file") from None
    if estimator is None:
        return ServiceConfig.from_toml_text(text, source=str(p))
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    doc.setdefault("service", {})["estimator"] = str(estimator)
    return ServiceConfig.from_document(doc, text, source=str(p))


# ----------------------------------------------------------------------------- validation

def _message_class(t: TomlTable):
    """The dialect class of the table's `message`."""
    from fdir_service.mavlink import dialect

    msg_name = t.take("message", "string")
    cls = getattr(dialect, f"MAVLink_{msg_name.lower()}_message", None)
    if cls is None or msg_name != msg_name.upper():
        raise ConfigError(f"{t.key('message')}: {msg_name!r} is not a MAVLink message of the "
                          "fdir dialect (use the upper-case name, e.g. GPS_RAW_INT)")
    return msg_name, cls


def _field_spec(t: TomlTable, msg_name: str, cls) -> tuple[str, int | None]:
    """(field, array index or None) of the table's `field`."""
    spec = t.take("field", "string")
    m = _FIELD_RE.match(spec)
    if not m or m.group(1) not in cls.fieldnames:
        raise ConfigError(f"{t.key('field')}: {spec!r} is not a field of {msg_name} "
                          f"(fields: {', '.join(cls.fieldnames)})")
    fname, idx = m.group(1), (int(m.group(2)) if m.group(2) is not None else None)
    alen = cls.array_lengths[cls.fieldnames.index(fname)]
    if (alen > 0) != (idx is not None) or (idx is not None and idx >= alen):
        raise ConfigError(f"{t.key('field')}: {fname} "
                          + (f"is an array of {alen}: write {fname}[i], 0 <= i < {alen}" if alen
                             else "is not an array"))
    return fname, idx


def _stamp(t: TomlTable, msg_name: str, cls) -> str:
    """The table's `stamp`; a message without a timestamp needs stamp = "latest"."""
    stamp = t.take("stamp", "string", "message", choices=STAMPS)
    if stamp != "latest" and not {"time_boot_ms", "time_usec"} & set(cls.fieldnames):
        raise ConfigError(f"{t.key('message')}: {msg_name} carries no time_boot_ms/time_usec "
                          "timestamp, so it cannot be placed in a frame (stamp = \"latest\" borrows "
                          "the latest timestamp seen on the link)")
    return stamp


def _derivation(t: TomlTable, msg_name: str) -> dict[str, Any]:
    """`derive`, `sources` and the derivation's options of a derived row (FieldMap keywords)."""
    from fdir_service.runtime.derived import DERIVATIONS

    name = t.take("derive", "string", choices=tuple(DERIVATIONS))
    d = DERIVATIONS[name]
    expected = d.sources_for(msg_name)
    if expected is None:
        raise ConfigError(f"{t.key('message')}: derivation {name!r} samples "
                          f"{' or '.join((d.sources[0], *d.samples))}, got {msg_name!r}")
    sources = t.take("sources", "strings", check=Check(lambda v: tuple(v) == expected,
                                                       f"{list(expected)} (what {name} reads)"))
    options = []
    for opt, (default, expect, test) in d.options.items():
        kind_default = {} if default is None else {"default": default}
        options.append((opt, t.take(opt, "number", **kind_default, check=Check(test, expect))))
    return {"derive": name, "sources": tuple(sources), "options": tuple(options)}


def _range(t: TomlTable, transform: str) -> dict[str, Any]:
    """The PWM scaling or the valid range (FieldMap keywords)."""
    kw: dict[str, Any] = {}
    if transform == "pwm":
        kw["pwm_min"] = t.take("pwm_min", "number", 1000.0)
        kw["pwm_max"] = t.take("pwm_max", "number", 2000.0,
                               check=Check(lambda v: v > kw["pwm_min"], "a value above pwm_min"))
        kw["min"] = t.take("min", "number")
        kw["max"] = t.take("max", "number", check=Check(lambda v: v > kw["min"], "a value above min"))
    else:
        kw["min"] = t.take("valid_min", "number", -math.inf)
        kw["max"] = t.take("valid_max", "number", math.inf,
                           check=Check(lambda v: v > kw["min"], "a value above valid_min"))
    return kw


def _where(t: TomlTable, msg_name: str, cls) -> tuple[tuple[str, float], ...]:
    wt = t.sub("where")
    where = []
    for wk in wt.keys():
        if wk not in cls.fieldnames:
            raise ConfigError(f"{wt.key(wk)}: {wk!r} is not a field of {msg_name}")
        where.append((wk, wt.take(wk, "number")))
    wt.finish()
    return tuple(where)


def _field_map(t: TomlTable, name: str, is_input: bool) -> FieldMap:
    msg_name, cls = _message_class(t)
    if t.peek("derive") is not None:
        fname, idx, kw = "", None, _derivation(t, msg_name)
    else:
        (fname, idx), kw = _field_spec(t, msg_name, cls), {}
    kw["stamp"] = _stamp(t, msg_name, cls)
    transform = t.take("transform", "string", "none", choices=TRANSFORMS)
    kw.update(_range(t, transform))
    fm = FieldMap(
        name=name, message=msg_name, field=fname, index=idx,
        scale=t.take("scale", "number", 1.0, check=Check(lambda v: v != 0, "a non-zero number")),
        offset=t.take("offset", "number", 0.0), transform=transform,
        where=_where(t, msg_name, cls),
        stale_s=t.take("stale_s", "number", 1.0, check=POSITIVE.saying("a positive time (s)")),
        rate_hz=t.take("rate_hz", "number", 0.0,
                       check=NON_NEGATIVE.saying("a rate >= 0 (Hz; 0 = the default)")),
        frozen_s=(0.0 if is_input else t.take("frozen_s", "number", 0.0,
                                               check=NON_NEGATIVE.saying("a time >= 0 (s; 0 = off)"))),
        **kw,
    )
    t.finish()
    return fm


def parse_mappings(root: TomlTable,
                   est: EstimatorConfig) -> tuple[tuple[FieldMap, ...], tuple[FieldMap, ...]]:
    """The `[measurements.<row>]` (one per estimator row, in its order) and `[inputs.<name>]` (both
    actuators) tables of a service file or an autopilot profile."""
    mt = root.sub("measurements")
    maps = {k: _field_map(mt.sub(k), k, False) for k in mt.keys()}
    mt.finish()
    missing = [m for m in est.measurements if m not in maps]
    if missing:
        raise ConfigError(f"measurements.{missing[0]}: missing; estimator {est.id!r} measures "
                          f"{', '.join(est.measurements)} and each needs a mapping")
    it = root.sub("inputs")
    imaps = {}
    for k in it.keys():
        if k not in ACTUATORS:
            raise ConfigError(f"inputs.{k}: unknown input; expected {', '.join(ACTUATORS)}")
        imaps[k] = _field_map(it.sub(k), k, True)
    it.finish()
    for a in ACTUATORS:
        if a not in imaps:
            raise ConfigError(f"inputs.{a}: missing; the filter needs both {', '.join(ACTUATORS)}")
    return tuple(maps[m] for m in est.measurements), tuple(imaps[a] for a in ACTUATORS)


def _streams(st: TomlTable) -> StreamConfig:
    """`[streams]`: stream requests and rate checks."""
    cfg = StreamConfig(
        request=st.take("request", "boolean", True),
        ack_timeout_s=st.take("ack_timeout_s", "number", 1.0, check=POSITIVE.saying("a positive time (s)")),
        retries=st.take("retries", "integer", 2, check=NON_NEGATIVE.saying("a number of retries >= 0")),
        window_s=st.take("window_s", "number", 5.0, check=POSITIVE.saying("a positive time (s)")),
        min_fraction=st.take("min_fraction", "number", 0.8,
                             check=Check(lambda v: 0 < v <= 1, "a fraction in (0, 1]")),
        parameters=st.take("parameters", "boolean", True),
        parameters_in_flight=st.take("parameters_in_flight", "integer", 4,
                                     check=Check(lambda v: 1 <= v <= 32, "a number of requests 1..32")),
    )
    st.finish()
    return cfg


def _estimator(s: TomlTable, estimator_doc: dict[str, Any] | None) -> EstimatorConfig:
    """The estimator named in [service] (or the recorded one), with [service]'s overrides."""
    ref = s.take("estimator", "string", DEFAULT_ESTIMATOR)
    est = (load_estimator(ref) if estimator_doc is None
           else parse_estimator(estimator_doc, f"<recorded estimator {ref}>"))
    return est.with_filter(
        s.take("filter", "string", est.filter, choices=FILTER_NAMES),
        s.take("particles", "integer", est.particles,
               check=POSITIVE.saying("a positive number of particles")),
        s.take("seed", "integer", est.seed, check=NON_NEGATIVE.saying("a non-negative integer")))


def _parse(doc: dict[str, Any], text: str, estimator_doc: dict[str, Any] | None,
           source: str) -> ServiceConfig:
    root = TomlTable(doc, "")
    s = root.sub("service")
    est = _estimator(s, estimator_doc)
    filt, particles, seed = est.filter, est.particles, est.seed
    s.finish()

    link = root.sub("link")
    master = link.take("master", "string", "udpin:127.0.0.1:14550",
                       check=Check(lambda v: ":" in v, "a mavutil URL such as udpin:127.0.0.1:14550"))
    gcs = link.take("gcs", "strings", (),
                    check=Check(lambda v: all(":" in g for g in v), "a list of mavutil URLs"))
    ap_sys = link.take("autopilot_system", "integer", 0,
                       check=Check(lambda v: 0 <= v <= 255,
                                   "0 (learn from the first HEARTBEAT) or a system id 1..255"))
    comp = link.take("component", "integer", 191,
                     check=Check(lambda v: 1 <= v <= 255, "a component id 1..255"))
    link.finish()

    sg = root.sub("signing")
    key_file = sg.take("key_file", "string", "")
    link_id = sg.take("link_id", "integer", 0, check=Check(lambda v: 0 <= v <= 255, "0..255"))
    sg.finish()

    fr = root.sub("frames")
    rate = fr.take("rate_hz", "number", 1.0 / est.dt_s, check=POSITIVE.saying("a positive rate"))
    if abs(rate * est.dt_s - 1.0) > 1e-6:
        raise ConfigError(f"frames.rate_hz: the estimator's filter models are discretised at "
                          f"dt = {est.dt_s} s, so the rate must be {1.0 / est.dt_s:g} Hz, "
                          f"got {rate!r}")
    max_gap = fr.take("max_gap_s", "number", 2.0, check=NON_NEGATIVE.saying("a non-negative time (s)"))
    fr.finish()

    pb = root.sub("publish")
    dc = pb.sub("declare")
    p_decl = dc.take("p_declare", "number", 0.9,
                     check=Check(lambda v: 0 < v <= 1, "a probability in (0, 1]"))
    declare = DeclareConfig(
        p_declare=p_decl,
        declare_hold_s=dc.take("declare_hold_s", "number", 0.2, check=NON_NEGATIVE.saying("a time >= 0")),
        p_clear=dc.take("p_clear", "number", 0.5,
                        check=Check(lambda v: 0 <= v < p_decl, f"a probability below p_declare ({p_decl})")),
        clear_hold_s=dc.take("clear_hold_s", "number", 1.0, check=NON_NEGATIVE.saying("a time >= 0")),
        p_type=dc.take("p_type", "number", 0.8, check=Check(lambda v: 0 <= v <= 1, "a share in [0, 1]")),
        type_hold_s=dc.take("type_hold_s", "number", TYPE_HOLD_S, check=NON_NEGATIVE.saying("a time >= 0")),
    )
    dc.finish()
    publish = PublishConfig(
        named_value_rate_hz=pb.take("named_value_rate_hz", "number", 10.0,
                                    check=POSITIVE.saying("a positive rate")),
        estimate_rate_hz=pb.take("estimate_rate_hz", "number", 1.0 / est.dt_s,
                                 check=POSITIVE.saying("a positive rate")),
        heartbeat_period_s=pb.take("heartbeat_period_s", "number", 1.0,
                                   check=POSITIVE.saying("a positive period")),
        stale_statustext=pb.take("stale_statustext", "boolean", True),
        declare=declare,
    )
    pb.finish()

    measurements, inputs = parse_mappings(root, est)

    hs = root.sub("health")
    health = HealthConfig(
        link_timeout_s=hs.take("link_timeout_s", "number", 2.0, check=POSITIVE.saying("a positive time (s)")),
        min_n_eff=hs.take("min_n_eff", "number", 1.5, check=NON_NEGATIVE.saying("a number >= 0")),
        degenerate_frames=hs.take("degenerate_frames", "integer", 10,
                                  check=POSITIVE.saying("a positive number of frames")),
        reinit_gate_sigmas=hs.take("reinit_gate_sigmas", "number", 20.0,
                                   check=POSITIVE.saying("a positive number of sigmas")),
        reinit_holdoff_s=hs.take("reinit_holdoff_s", "number", 1.0,
                                 check=NON_NEGATIVE.saying("a time >= 0 (s)")),
        statustext_interval_s=hs.take("statustext_interval_s", "number", 10.0,
                                      check=NON_NEGATIVE.saying("a time >= 0 (s)")),
        max_state_jump=hs.take(
            "max_state_jump", "numbers", (50.0, 20.0, 20.0, 1.0, 5.0),
            check=Check(lambda v: len(v) in (0, 5) and all(x > 0 for x in v),
                        "[] (off) or 5 positive numbers [p_d m, u m/s, w m/s, theta rad, q rad/s]")),
    )
    hs.finish()

    streams = _streams(root.sub("streams"))

    rc = root.sub("record")
    record = RecordConfig(
        enabled=rc.take("enabled", "boolean", True),
        directory=rc.take("directory", "string", "recordings",
                          check=Check(lambda v: v.strip() != "", "a directory path")),
        rotate_mb=rc.take("rotate_mb", "number", 100.0,
                          check=NON_NEGATIVE.saying("a size >= 0 (MB; 0 = never)")),
        rotate_s=rc.take("rotate_s", "number", 3600.0,
                         check=NON_NEGATIVE.saying("a duration >= 0 (s; 0 = never)")),
    )
    rc.finish()
    root.finish()

    return ServiceConfig(
        estimator=est, filter=filt, particles=particles, seed=seed, master=master,
        gcs=tuple(gcs), autopilot_system=ap_sys, component=comp, signing_key_file=key_file,
        signing_link_id=link_id, frame_rate_hz=rate, max_gap_s=max_gap,
        measurements=measurements, inputs=inputs, publish=publish, health=health, record=record,
        streams=streams, text=text,
        source=source,
    )
