"""JSON schemas of every recorded topic (MCAP `jsonschema` encoding, `json` messages).

One named schema per MAVLink message type (`mavlink.<MSG>`, built from pymavlink's field tables),
the flat `/fdir/estimate` record (`fdir.Estimate`, one numeric field per quantity so Foxglove's
plot panel addresses `/fdir/estimate.f_gnss`), the per-item view of estimators with typed faults
or several entries per target (`fdir.Items`, `/fdir/items`), the top-particle snapshot (`fdir.Particles`), the
raw MAVLink byte stream (`fdir.RawMavlink`, base64 bytes) and Foxglove's own `foxglove.Log` (the name
Foxglove's Log panel recognises).
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.runtime.items import ItemReport, type_code

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"

STATE_NAMES: tuple[str, ...] = ("p_d", "u", "w", "theta", "q")
"""Airframe state order z = [p_d, u, w, theta, q] (SI: m, m/s, m/s, rad, rad/s)."""

_INTEGER_TYPES = {"int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t", "int64_t", "uint64_t",
                  "uint8_t_mavlink_version"}
NULLABLE_NUMBER = {"type": ["number", "null"]}  # null carries a NaN / inf (JSON has no NaN)
_INTEGER = {"type": "integer"}


def schema_bytes(schema: dict[str, Any]) -> bytes:
    """The schema as the UTF-8 JSON text stored in the MCAP Schema record."""
    return json.dumps(schema, sort_keys=True).encode()


# ----------------------------------------------------------------------------- MAVLink messages

def _field_schema(mav_type: str, array_length: int, unit: str | None) -> dict[str, Any]:
    base = mav_type.split("[")[0]
    if base == "char":
        item: dict[str, Any] = {"type": "string"}
    elif base in _INTEGER_TYPES:
        item = dict(_INTEGER)
    else:
        item = dict(NULLABLE_NUMBER)
    if base != "char" and array_length:
        item = {"type": "array", "items": item, "minItems": array_length, "maxItems": array_length}
    if unit:
        item["description"] = f"unit: {unit}"
    return item


def mavlink_schema_name(msg_name: str) -> str:
    """`mavlink.GPS_RAW_INT`: the schema name of one MAVLink message type."""
    return f"mavlink.{msg_name}"


def mavlink_schema(msg_class: type) -> dict[str, Any]:
    """JSON schema of a pymavlink message class (any dialect): its fields with their MAVLink units,
    plus `mavpackettype` and the sender's `_sys` / `_comp` ids."""
    names = list(msg_class.fieldnames)
    types = list(msg_class.fieldtypes)
    # pymavlink lists array_lengths in wire order (ordered_fieldnames), fieldtypes in declaration order
    wire_order = list(getattr(msg_class, "ordered_fieldnames", names))
    length_by_name = dict(zip(wire_order, msg_class.array_lengths, strict=True))
    lengths = [length_by_name.get(n, 0) for n in names]
    units = getattr(msg_class, "fieldunits_by_name", {}) or {}
    props: dict[str, Any] = {
        "mavpackettype": {"type": "string"},
        "_sys": {"type": "integer", "description": "MAVLink source system id"},
        "_comp": {"type": "integer", "description": "MAVLink source component id"},
    }
    for name, mav_type, length in zip(names, types, lengths, strict=True):
        props[name] = _field_schema(mav_type, length, units.get(name))
    msg_name = getattr(msg_class, "msgname", None) or (
        msg_class.__name__.removeprefix("MAVLink_").removesuffix("_message").upper())
    return {
        "title": mavlink_schema_name(msg_name),
        "description": f"MAVLink message {msg_name} (id {getattr(msg_class, 'id', '?')}) via pymavlink",
        "type": "object",
        "properties": props,
        "required": ["mavpackettype", *names],
    }


def _json_safe(value: Any) -> Any:
    t = type(value)
    if t is int or t is str:
        return value
    if t is float:
        return value if math.isfinite(value) else None
    if t is list and all(type(v) is float for v in value):
        return [v if math.isfinite(v) else None for v in value]
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).decode("utf-8", errors="replace")
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return _json_safe(value.item())
    return value


def mavlink_message_json(msg: Any) -> dict[str, Any]:
    """A decoded pymavlink message as the JSON object of its `mavlink.<MSG>` schema."""
    # = {k: _json_safe(v) for k, v in msg.to_dict().items()}, without to_dict's per-field calls
    d: dict[str, Any] = {"mavpackettype": msg.get_type()}
    isfinite = math.isfinite
    for a in msg._fieldnames:
        v = getattr(msg, a)
        t = type(v)
        if t is float:
            d[a] = v if isfinite(v) else None
        elif t is int:
            d[a] = v
        elif t is bytes:
            d[a] = v.decode(errors="backslashreplace").rstrip("\x00")
        else:
            d[a] = _json_safe(v)
    d["_sys"] = int(msg.get_srcSystem())
    d["_comp"] = int(msg.get_srcComponent())
    return d


def mavlink_topic(msg: Any) -> str:
    """`/mavlink/<sys>/<comp>/<MSG>` for a decoded message."""
    return f"/mavlink/{msg.get_srcSystem()}/{msg.get_srcComponent()}/{msg.get_type()}"


# ----------------------------------------------------------------------------- raw bytes

RAW_SCHEMA: dict[str, Any] = {
    "title": "fdir.RawMavlink",
    "description": "Bytes exactly as read from (direction 'in') or written to ('out') the autopilot link; "
    "replaying the 'in' bytes through a fresh pipeline reproduces every estimate.",
    "type": "object",
    "properties": {
        "direction": {"type": "string", "enum": ["in", "out"]},
        "data": {"type": "string", "contentEncoding": "base64"},
        "length": {"type": "integer"},
    },
    "required": ["direction", "data", "length"],
}


def raw_json(direction: str, data: bytes) -> dict[str, Any]:
    return {"direction": direction, "data": base64.b64encode(data).decode("ascii"), "length": len(data)}


def raw_bytes(record: dict[str, Any]) -> bytes:
    """Inverse of `raw_json`: the exact bytes of one raw record."""
    return base64.b64decode(record["data"])


# ----------------------------------------------------------------------------- estimate

def estimate_field_names(fault_ids: Sequence[str], n_state: int, *, adaptive: bool,
                         typed: bool = False) -> list[str]:
    """Flat field names of `/fdir/estimate`, in record order.

    `x_<s>` / `var_<s>`: extended-state mean and covariance diagonal (airframe states by name, then
    one `x_f_<id>` per fault); `f_<id>` fault estimate (SI), `pf_<id>` P(fault); adaptive filters add
    `pfa_<id>`, `pmd_<id>` and the transition matrix `pi00_<id>` .. `pi11_<id>`; a step with a
    non-bias fault type (`is_typed`) adds, after latency_s, `ft_<id>` (FDIR_FAULT_TYPE code) and
    `fv_<id>` (user-facing value: SI, or unitless k and g) per entry.
    """
    states = state_names(fault_ids, n_state)
    names = ["frame_time_s"]
    names += [f"x_{s}" for s in states]
    names += [f"var_{s}" for s in states]
    names += [f"f_{f}" for f in fault_ids]
    names += [f"pf_{f}" for f in fault_ids]
    if adaptive:
        names += [f"pfa_{f}" for f in fault_ids]
        names += [f"pmd_{f}" for f in fault_ids]
        for ij in ("00", "01", "10", "11"):
            names += [f"pi{ij}_{f}" for f in fault_ids]
    names += ["n_eff", "resampled", "latency_s"]
    if typed:
        names += [f"ft_{f}" for f in fault_ids] + [f"fv_{f}" for f in fault_ids]
    return names


def state_names(fault_ids: Sequence[str], n_state: int) -> list[str]:
    """Names of the extended-state entries: the 5 airframe states, then `f_<id>` per fault channel
    (a filter whose state is longer than 5 + nf gets `s<i>` names for the extras)."""
    names = list(STATE_NAMES[: min(n_state, 5)]) + [f"f_{f}" for f in fault_ids]
    names += [f"s{i}" for i in range(len(names), n_state)]
    return names[:n_state]


def estimate_schema(fault_ids: Sequence[str], n_state: int, *, adaptive: bool,
                    typed: bool = False) -> dict[str, Any]:
    """The `fdir.Estimate` schema for one filter layout (flat numbers: Foxglove plot-panel paths)."""
    props: dict[str, Any] = {}
    for name in estimate_field_names(fault_ids, n_state, adaptive=adaptive, typed=typed):
        props[name] = {"type": "boolean"} if name == "resampled" else dict(NULLABLE_NUMBER)
    for f in fault_ids if typed else ():
        props[f"ft_{f}"] = {"type": "integer", "description": "fault type (FDIR_FAULT_TYPE: 0 bias, "
                            "1 stuck, 2 noisy, 3 jammed, 4 effectiveness, 5 blocked, 6 drift, 7 engine)"}
    props["frame_time_s"]["description"] = "frame time, s (the autopilot's timestamp of the frame)"
    props["latency_s"]["description"] = "wall-clock processing time of the step, s (not reproducible)"
    props["n_eff"]["description"] = "effective sample size 1 / sum w^2"
    return {
        "title": "fdir.Estimate",
        "description": "One filter step: extended-state mean and covariance diagonal (SI), per-fault "
        "estimate and P(fault), Pfa/Pmd and transition probabilities (adaptive filters), N_eff, latency.",
        "type": "object",
        "properties": props,
        "required": list(props),
    }


def finite_or_none(v: Any) -> float | None:
    """float(v), or None when it is NaN or infinite (JSON has no NaN)."""
    f = float(v)
    return f if math.isfinite(f) else None


_ESTIMATE_KEYS: dict[tuple[tuple[str, ...], int, bool], list[str]] = {}


def _estimate_keys(fault_ids: tuple[str, ...], n: int, adaptive: bool) -> list[str]:
    """The numeric keys of `estimate_json` after frame_time_s, in record order (cached per layout)."""
    key = (fault_ids, n, adaptive)
    keys = _ESTIMATE_KEYS.get(key)
    if keys is None:
        states = state_names(fault_ids, n)
        keys = [f"x_{s}" for s in states] + [f"var_{s}" for s in states]
        keys += [f"f_{f}" for f in fault_ids] + [f"pf_{f}" for f in fault_ids]
        if adaptive:
            keys += [f"pfa_{f}" for f in fault_ids] + [f"pmd_{f}" for f in fault_ids]
            keys += [f"pi{i}{j}_{f}" for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)) for f in fault_ids]
        keys.append("n_eff")
        _ESTIMATE_KEYS[key] = keys
    return keys


def estimate_json(frame_time_s: float, out: StepOutput, latency_s: float) -> dict[str, Any]:
    """A StepOutput as the flat `fdir.Estimate` object (floats round-trip exactly through JSON;
    NaN / inf -> null). Built from one concatenated array (`tolist` gives the same Python floats
    as `float(v)` element by element)."""
    fault_ids = tuple(out.fault_ids)
    x = np.asarray(out.x_mean, dtype=float).ravel()
    nf = len(fault_ids)
    var = (np.diag(np.asarray(out.x_cov, dtype=float)) if out.x_cov is not None
           else np.full(x.size, np.nan))                 # a filter asked not to output it
    parts = [x, var,
             np.asarray(out.fault_estimate, dtype=float).ravel()[:nf],
             np.asarray(out.fault_probability, dtype=float).ravel()[:nf]]
    adaptive = is_adaptive(out)
    if adaptive:
        parts += [np.asarray(out.pfa, dtype=float).ravel()[:nf],
                  np.asarray(out.pmd, dtype=float).ravel()[:nf],
                  np.asarray(out.transition, dtype=float).reshape(nf, 2, 2).transpose(1, 2, 0).ravel()]
    parts.append(np.asarray([out.n_eff], dtype=float))
    v = np.concatenate(parts)
    keys = _estimate_keys(fault_ids, x.size, adaptive)
    if len(keys) != v.size:
        raise ValueError(f"estimate layout: {v.size} values for {len(keys)} fields")
    vals = v.tolist()
    if not np.isfinite(v).all():
        vals = [f if math.isfinite(f) else None for f in vals]
    d: dict[str, Any] = {"frame_time_s": float(frame_time_s)}
    d.update(zip(keys, vals, strict=True))
    d["resampled"] = bool(out.resampled)
    d["latency_s"] = float(latency_s)
    if is_typed(out):
        d.update(typed_fields(out))
    return d


def is_typed(out: StepOutput) -> bool:
    """Whether a step reports a fault type other than bias (then its record carries ft_ and fv_)."""
    return any(t != "bias" for t in out.fault_types)


def typed_fields(out: StepOutput) -> dict[str, Any]:
    """`ft_<id>` (FDIR_FAULT_TYPE code) and `fv_<id>` (user-facing value, SI or unitless; None for
    NaN) of every entry of one step."""
    ids = out.fault_ids
    d: dict[str, Any] = {f"ft_{f}": type_code(out.type_of(j)) for j, f in enumerate(ids)}
    d.update({f"fv_{f}": finite_or_none(out.value_of(j)) for j, f in enumerate(ids)})
    return d


def is_adaptive(out: StepOutput) -> bool:
    """Whether a step carries Pfa/Pmd and a transition matrix (AJMRPF / ARJMRPF)."""
    return out.pfa is not None and out.pmd is not None and out.transition is not None


# ----------------------------------------------------------------------------- items

def items_field_names(names: Sequence[str]) -> list[str]:
    """Flat field names of `/fdir/items`, in record order: per item `p_<name>` P(item faulty),
    `type_<name>` its most probable type (FDIR_FAULT_TYPE code), `v_<name>` that type's value (SI;
    k, g unitless), `declared_<name>` (0/1, after hysteresis)."""
    out = ["frame_time_s"]
    for prefix in ("p", "type", "v", "declared"):
        out += [f"{prefix}_{n}" for n in names]
    return out


def items_schema(names: Sequence[str]) -> dict[str, Any]:
    """The `fdir.Items` schema for one item layout (flat numbers, like `fdir.Estimate`)."""
    props: dict[str, Any] = {k: dict(NULLABLE_NUMBER) for k in items_field_names(names)}
    for n in names:
        props[f"type_{n}"] = {"type": "integer", "description": "FDIR_FAULT_TYPE code"}
        props[f"declared_{n}"] = {"type": "integer", "enum": [0, 1]}
    return {
        "title": "fdir.Items",
        "description": "One frame's monitored items (a target and its typed fault entries, named by its "
        "first entry): P(item faulty), most probable type and its value, declared (after hysteresis).",
        "type": "object",
        "properties": props,
        "required": list(props),
    }


def items_json(frame_time_s: float, report: ItemReport) -> dict[str, Any]:
    """The flat `fdir.Items` object of one frame (frame time s; see `items_field_names`)."""
    names, view = report.names, report.view
    d: dict[str, Any] = {"frame_time_s": float(frame_time_s)}
    d.update({f"p_{n}": finite_or_none(v) for n, v in zip(names, view.p, strict=True)})
    d.update({f"type_{n}": c for n, c in zip(names, report.type_codes, strict=True)})
    d.update({f"v_{n}": finite_or_none(v) for n, v in zip(names, view.value, strict=True)})
    d.update({f"declared_{n}": int(v) for n, v in zip(names, report.declared, strict=True)})
    return d


# ----------------------------------------------------------------------------- particles

PARTICLES_SCHEMA: dict[str, Any] = {
    "title": "fdir.Particles",
    "description": "The most weighted particles of one frame (once per second of frame time): "
    "states[i] is particle i's extended state in the order of `names` (SI), weights[i] its weight.",
    "type": "object",
    "properties": {
        "frame_time_s": {"type": "number"},
        "names": {"type": "array", "items": {"type": "string"}},
        "weights": {"type": "array", "items": NULLABLE_NUMBER},
        "states": {"type": "array", "items": {"type": "array", "items": NULLABLE_NUMBER}},
    },
    "required": ["frame_time_s", "names", "weights", "states"],
}


def particles_json(frame_time_s: float, states: np.ndarray, weights: np.ndarray,
                   names: Sequence[str]) -> dict[str, Any]:
    s = np.atleast_2d(np.asarray(states, dtype=float))
    return {
        "frame_time_s": float(frame_time_s),
        "names": list(names),
        "weights": [finite_or_none(w) for w in np.asarray(weights, dtype=float).ravel()],
        "states": [[finite_or_none(v) for v in row] for row in s],
    }


# ----------------------------------------------------------------------------- foxglove.Log

LOG_LEVELS = {"unknown": 0, "debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}

FOXGLOVE_LOG_SCHEMA: dict[str, Any] = {
    "title": "foxglove.Log",
    "description": "A log message",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
            "description": "Timestamp of log message",
        },
        "level": {
            "title": "foxglove.LogLevel",
            "description": "Log level",
            "oneOf": [{"title": k.upper(), "const": v} for k, v in LOG_LEVELS.items()],
        },
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}


def log_json(level: str, text: str, t_ns: int, name: str = "fdir") -> dict[str, Any]:
    """A `foxglove.Log` object; level is "debug" | "info" | "warning" | "error" | "fatal"."""
    t_ns = max(int(t_ns), 0)
    return {
        "timestamp": {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000},
        "level": LOG_LEVELS.get(level.lower(), 0),
        "message": text,
        "name": name,
        "file": "",
        "line": 0,
    }
