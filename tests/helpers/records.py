"""Synthetic frames and step outputs for the recording tests, and a JSON-schema check."""

from __future__ import annotations

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from fdir_service.estimation.base import StepOutput
from fdir_service.recording import Recorder

FAULTS = ("gnss", "baro")


DT_NS = 50_000_000  # 20 Hz frames


def frame_bytes(k: int, enc: mavlink.MAVLink) -> bytes:
    """MAVLink 2 bytes an autopilot would send for frame k (sim time k * 50 ms)."""
    ms = k * 50
    msgs = [
        mavlink.MAVLink_attitude_message(ms, 0.0, 0.048 + 1e-3 * np.sin(k / 7), 0.0, 0.0, 1e-3 * k % 3, 0.0),
        mavlink.MAVLink_gps_raw_int_message(ms * 1000, 3, 0, 0, 500_000 + k, 65535, 65535, 4000, 0, 10),
        mavlink.MAVLink_scaled_pressure_message(ms, 95_461.0 / 100.0, 0.0, 2000),
        mavlink.MAVLink_servo_output_raw_message(ms * 1000, 0, 1450, 1532, *[1500] * 6),
    ]
    if k % 20 == 0:
        msgs.insert(0, mavlink.MAVLink_heartbeat_message(1, 3, 81, 0, 4, 3))
    return b"".join(bytes(m.pack(enc)) for m in msgs)


def step_output(k: int, adaptive: bool = False) -> StepOutput:
    rng = np.random.default_rng(k)
    n = 5 + len(FAULTS)
    a = rng.normal(size=(n, n))
    return StepOutput(
        t=k * 0.05, x_mean=rng.normal(size=n), x_cov=a @ a.T, fault_ids=FAULTS,
        fault_estimate=rng.normal(size=2) * 10, fault_probability=rng.uniform(size=2),
        n_eff=float(rng.uniform(100, 1000)), resampled=bool(k % 3 == 0),
        pfa=rng.uniform(size=2) if adaptive else None, pmd=rng.uniform(size=2) if adaptive else None,
        transition=rng.dirichlet([1, 1], size=(2, 2)) if adaptive else None)


def record_synthetic(rec: Recorder, frames: int, *, adaptive: bool = False, t0_ns: int = 0) -> bytes:
    """Drive the recorder like the pipeline would; returns all 'in' bytes fed."""
    rec.on_metadata("config", {"service_toml": "[link]\nrate_hz = 20\n", "filter": "RJMRPF", "seed": "7"})
    rec.on_metadata("versions", {"fdir-service": "0.1.0", "numpy": np.__version__})
    rec.on_metadata("dialect", {"fdir.xml": "<mavlink/>"})
    enc = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = mavlink.MAVLink(None)
    out_enc = mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
    fed = bytearray()
    for k in range(frames):
        t_ns = t0_ns + k * DT_NS
        data = frame_bytes(k, enc)
        fed += data
        rec.on_raw("in", data, t_ns)
        for msg in parser.parse_buffer(data) or []:
            rec.on_message(msg, t_ns)
        rec.on_estimate(k * 0.05, step_output(k, adaptive), 1e-4, t_ns + 1000)
        out = mavlink.MAVLink_named_value_float_message(k * 50, b"f_gnss", float(k)).pack(out_enc)
        rec.on_raw("out", bytes(out), t_ns + 2000)
        if k % 20 == 0:
            states = np.random.default_rng(k).normal(size=(20, 7))
            rec.on_particles(k * 0.05, states, np.full(20, 1e-3), t_ns + 1000)
        if k == 200:
            rec.on_event("warning", "FDIR gnss fault +50.1 m p=0.98", t_ns + 3000)
    return bytes(fed)


def check_schema(obj, schema) -> None:
    """A small jsonschema check (types, required, array lengths) - enough for our schemas."""
    t = schema.get("type")
    types = t if isinstance(t, list) else [t] if t else []
    py = {"number": (int, float), "integer": (int,), "string": (str,), "boolean": (bool,),
          "object": (dict,), "array": (list,), "null": (type(None),)}
    if types:
        assert any(isinstance(obj, py[x]) and not (x in ("number", "integer") and isinstance(obj, bool))
                   for x in types), (obj, schema)
    if "oneOf" in schema:
        assert any(obj == o["const"] for o in schema["oneOf"])
    if isinstance(obj, dict):
        for key in schema.get("required", []):
            assert key in obj, key
        for key, sub in schema.get("properties", {}).items():
            if key in obj:
                check_schema(obj[key], sub)
        assert set(obj) <= set(schema.get("properties", obj)), set(obj) - set(schema["properties"])
    if isinstance(obj, list) and "items" in schema:
        if "minItems" in schema:
            assert schema["minItems"] <= len(obj) <= schema["maxItems"]
        for o in obj:
            check_schema(o, schema["items"])

