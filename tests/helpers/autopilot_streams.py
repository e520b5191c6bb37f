"""Feeding a synthetic autopilot stream through `fdir run --autopilot ...`'s pipeline, and the
checks the ArduPilot and PX4 stream tests share."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdir_service.autopilot_profile import select_autopilot
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.events import AutopilotSelected
from fdir_service.service_config import load_service_config
from tests.helpers.service import fake_factory
from tests.helpers.streams import Events


def body_to_ned(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), written out by hand."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def run(stream: bytes, autopilot: str = "auto"):
    """(pipeline, the fake filter's step calls (t, y, mask, u), events) of the stream fed in 512-byte
    chunks to the default robust estimator's pipeline under `--autopilot autopilot`."""
    config = select_autopilot(load_service_config(estimator="aerosonde-robust"), autopilot)
    filters: list = []
    events = Events()
    p = Pipeline(config, observers=[events], filter_factory=fake_factory(filters))
    for i in range(0, len(stream), 512):
        p.feed(stream[i:i + 512], i)
    p.close()
    return p, [c for f in filters for c in f.calls], events


def settled_rows(stream: bytes, profile: str) -> tuple[object, dict[str, np.ndarray], np.ndarray]:
    """Feed `stream` with `--autopilot auto`; check that `profile` was picked, that every frame's
    rows and inputs are finite where present (NaN where not), and that after the first 10 frames
    every row is in every frame (gnss_alt, at 5 Hz, in a quarter). Returns (pipeline, row name ->
    values of the settled frames, their inputs (K, 2))."""
    p, calls, events = run(stream)
    assert [e.profile for e in events.of(AutopilotSelected)] == [profile]
    names = p.assembler.names
    assert len(calls) >= 55
    for _, y, mask, u in calls:
        assert np.all(np.isfinite(y[mask])) and np.all(np.isnan(y[~mask]))
        assert np.all(np.isfinite(u))
    settled = calls[10:-1]
    for j, name in enumerate(names):
        seen = np.mean([m[j] for _, _, m, _ in settled])
        assert seen == pytest.approx(0.25 if name == "gnss_alt" else 1.0, abs=0.05), name
    y = np.array([c[1] for c in settled])
    return p, {n: y[:, j] for j, n in enumerate(names)}, np.array([c[3] for c in settled])
