"""Shared pieces of the service tests: a fake filter honouring base.py's protocol, and a stream
of autopilot bytes from the simulator."""

from __future__ import annotations

import numpy as np

from fdir_service.estimation.base import StepOutput
from tests.helpers.experiments import CH4


class FakeFilter:
    """P(fault 0) = 1 when GNSS minus baro altitude exceeds 25 m; records every step's arguments."""

    name = "FAKE"

    def __init__(self, scenario) -> None:
        self.fault_ids = tuple(f.id for f in scenario.faults)
        self.calls: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []

    def step(self, t, y, mask, u) -> StepOutput:
        self.calls.append((t, y.copy(), mask.copy(), u.copy()))
        d = float(y[0] - y[1]) if mask[0] and mask[1] else 0.0
        nf = len(self.fault_ids)
        x = np.zeros(5 + nf)
        x[0] = -y[1] if mask[1] else -500.0
        f = np.zeros(nf)
        f[0] = d
        p = np.zeros(nf)
        p[0] = 1.0 if d > 25.0 else 0.0
        return StepOutput(t, x, np.eye(5 + nf), self.fault_ids, f, p, 100.0, False)

    def top_particles(self, k: int = 20):
        return np.zeros((k, 5 + len(self.fault_ids))), np.full(k, 1.0 / k)


def fake_factory(store: list):
    def make(name, scenario, rng, particles):
        f = FakeFilter(scenario)
        store.append(f)
        return f
    return make


def autopilot_stream(seconds: float, seed: int = 1, key: bytes | None = None):
    """[(frame, [sensor bytes], [actuator bytes])] of a truth-flown ch4 flight."""
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import SimStepper, default_autopilot

    st = SimStepper(CH4, seed)
    ap = default_autopilot(CH4, st.airframe)
    link = AutopilotLink(CH4, key=key)
    out = []
    for _ in range(int(round(seconds / CH4.dt_s))):
        fr = st.frame()
        sens = link.sensor_messages(fr.t, fr.y, fr.mask, fr.static_pressure_pa)
        u = ap.update(fr.t, fr.z_true)
        out.append((fr, sens, link.actuator_messages(fr.t, u)))
        st.advance(u)
    return out
