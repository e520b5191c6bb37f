"""`/sim/truth`: the simulator's truth, written frame by frame by `sim-bridge fly --record TRUTH.mcap`.

The truth never goes on the wire; it is recorded beside the flight so `sim-bridge replay --truth`
can score the estimates (RMSE, detection delay, false-alarm fraction). Fields: `truth_field_names`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fdir_service.recording.logtools import McapLog
from fdir_service.recording.schemas import NULLABLE_NUMBER, STATE_NAMES, finite_or_none
from fdir_service.recording.sink import JsonMcapFile

TRUTH_TOPIC = "/sim/truth"


def truth_field_names(fault_ids: Sequence[str]) -> list[str]:
    """Flat fields of `/sim/truth`: time, airframe state, altitude, fault values and mode flags, inputs."""
    names = ["t", *STATE_NAMES, "h"]
    names += [f"f_{f}" for f in fault_ids]
    names += [f"active_{f}" for f in fault_ids]
    names += ["delta_e", "delta_t"]
    return names


def truth_schema(fault_ids: Sequence[str]) -> dict[str, Any]:
    props: dict[str, Any] = {}
    for name in truth_field_names(fault_ids):
        props[name] = {"type": "boolean"} if name.startswith("active_") else dict(NULLABLE_NUMBER)
    props["t"]["description"] = "simulation time, s (the clock of time_boot_ms on the wire)"
    return {
        "title": "fdir.SimTruth",
        "description": "Simulator truth at one frame: state z = [p_d, u, w, theta, q] (SI), altitude h, "
        "each fault's true value (SI) and whether it is active, inputs [delta_e rad, delta_t 0..1].",
        "type": "object",
        "properties": props,
        "required": list(props),
    }


def truth_records(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The `/sim/truth` records of a truth MCAP, in order."""
    return [obj for _, obj in McapLog(path).iter_json(TRUTH_TOPIC)]


class TruthWriter:
    """Writes one `/sim/truth` record per simulated frame.

    path: output MCAP; fault_ids: the scenario's fault channels in order; metadata: optional MCAP
    metadata records {name: {key: value}} (e.g. {"scenario": {"id": "ch4", "toml": text, "seed": "1"}}).
    """

    def __init__(self, path: str | os.PathLike[str], fault_ids: Sequence[str], *,
                 metadata: Mapping[str, Mapping[str, Any]] | None = None) -> None:
        self.path = Path(path)
        self.fault_ids = tuple(fault_ids)
        self._file = JsonMcapFile(self.path)
        for name, data in (metadata or {}).items():
            self._file.add_metadata(name, {str(k): str(v) for k, v in data.items()})
        self._file.register(TRUTH_TOPIC, truth_schema(self.fault_ids))

    def write(self, t: float, z: np.ndarray, faults: np.ndarray, u: np.ndarray, *,
              active: np.ndarray | None = None, t_ns: int | None = None) -> None:
        """Record one frame.

        t: simulation time (s, the clock of `time_boot_ms` on the wire); z (5,) true state
        [p_d, u, w, theta, q]; faults (nf,) true fault values (SI, scenario order); u (2,) applied
        [delta_e rad, delta_t]; active (nf,) bool, default faults != 0; t_ns: log time, default t in ns.
        """
        z = np.asarray(z, dtype=float).ravel()
        f = np.asarray(faults, dtype=float).ravel()
        uu = np.asarray(u, dtype=float).ravel()
        if z.size != 5 or f.size != len(self.fault_ids) or uu.size != 2:
            raise ValueError(f"truth shapes: z {z.shape} (5,), faults {f.shape} ({len(self.fault_ids)},), "
                             f"u {uu.shape} (2,)")
        act = (f != 0.0) if active is None else np.asarray(active, dtype=bool).ravel()
        rec: dict[str, Any] = {"t": float(t)}
        for name, v in zip(STATE_NAMES, z, strict=True):
            rec[name] = finite_or_none(v)
        rec["h"] = finite_or_none(-z[0])
        for fid, v in zip(self.fault_ids, f, strict=True):
            rec[f"f_{fid}"] = finite_or_none(v)
        for fid, a in zip(self.fault_ids, act, strict=True):
            rec[f"active_{fid}"] = bool(a)
        rec["delta_e"], rec["delta_t"] = finite_or_none(uu[0]), finite_or_none(uu[1])
        self._file.write(TRUTH_TOPIC, rec, round(t * 1e9) if t_ns is None else t_ns)

    def close(self) -> None:
        """Finalise the file. Idempotent."""
        self._file.close()

    def __enter__(self) -> TruthWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
