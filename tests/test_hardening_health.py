"""Estimator health (issue 7): a one-frame 1e6 m GNSS altitude glitch that sends the particle filter
astray triggers a re-initialisation from the current measurements (event + STATUSTEXT), and the
filter recovers; a non-finite estimate does too. The out-of-range gate, which normally drops a
1e6 m altitude before the filter, is configured off here so that the glitch reaches the filter."""

from __future__ import annotations

import numpy as np
from test_hardening_input import Events
from test_service_helpers import FakeFilter

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.service_config import ServiceConfig, default_config_path

NO_GATE = ServiceConfig.from_toml_text(
    default_config_path().read_text().replace("valid_min = -500.0\nvalid_max = 20000.0\n", "", 1))


def fly(pipe: Pipeline, frames: int, glitch_frame: int | None, glitch_m: float = 1e6):
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import SimStepper, default_autopilot

    sc = pipe.scenario
    st = SimStepper(sc, 1)
    ap = default_autopilot(sc, st.airframe)
    link = AutopilotLink(sc)
    out, truth = [], []
    for k in range(frames):
        fr = st.frame()
        y = fr.y.copy()
        if k == glitch_frame:
            y[0] += glitch_m
        u = ap.update(fr.t, fr.z_true)
        data = b"".join(link.sensor_messages(fr.t, y, fr.mask, fr.static_pressure_pa))
        out += pipe.feed(data + b"".join(link.actuator_messages(fr.t, u)), k)
        truth.append((fr.z_true.copy(), fr.faults.copy()))
        st.advance(u)
    return new_mavlink(255, 0).parse_buffer(b"".join(out)) or [], truth


def test_gate_drops_the_glitch_by_default():
    from fdir_service.service_config import load_service_config

    assert NO_GATE.measurements[0].max == np.inf
    pipe = Pipeline(load_service_config(), filter_name="RJMRPF", particles=100, seed=4)
    fly(pipe, 110, 100)
    assert pipe.rejected_counts["gnss_alt out of range"] == 1 and pipe.reinitialisations == 0


def test_altitude_glitch_reinitialises_the_filter_which_recovers():
    ev = Events()
    pipe = Pipeline(NO_GATE, filter_name="RJMRPF", particles=100, seed=4, observers=[ev])
    msgs, truth = fly(pipe, 300, 100)           # glitch at t = 5.00 s; GNSS fault +50 m from 10 s
    est = ev.estimates
    assert len(est) == 300
    # the glitch sent the filter 20 km astray (it explains the glitch as a fault on both sensors)
    assert abs(est[100].x_mean[0] - truth[100][0][0]) > 1000
    # ... its weight then sat on one particle for 10 frames: re-initialised from the measurements
    assert pipe.reinitialisations == 1
    reinit = [t for _, t in ev.events if "re-initialised" in t]
    assert len(reinit) == 1 and "t=5.45 s (N_eff < 1.5 for 10 frames)" in reinit[0]
    st = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert "FDIR estimator restart: N_eff < 1.5 for 10 frames" in st
    # recovered: from 0.5 s after the restart the altitude is within 5 m and no fault is believed
    for k in range(120, 200):
        (z, f), o = truth[k], est[k]
        assert abs(o.x_mean[0] - z[0]) < 5.0, (k, o.x_mean[0] - z[0])
        assert np.all(np.abs(o.fault_estimate - f) < 5.0), (k, o.fault_estimate)
    # the astray filter's false declarations (during the 0.5 s before the restart) are cleared
    i = st.index("FDIR estimator restart: N_eff < 1.5 for 10 frames")
    assert set(st[i + 1:i + 3]) == {"FDIR gnss cleared p=0.03", "FDIR baro cleared p=0.05"}
    # and it still detects the real GNSS fault at 10 s
    decl = [t for t in st[i + 1:] if t.startswith("FDIR gnss fault")]
    assert len(decl) == 1 and 40 < float(decl[0].split()[3]) < 60
    assert np.mean(np.abs([o.fault_estimate[0] - 50.0 for o in est[240:300]])) < 5.0   # N = 100: noisy


class NaNAfter(FakeFilter):
    """The fake filter, but its estimate turns NaN at one frame time (a numerical blow-up)."""

    def __init__(self, scenario, t_nan: float | None) -> None:
        super().__init__(scenario)
        self.t_nan = t_nan

    def step(self, t, y, mask, u) -> StepOutput:
        out = super().step(t, y, mask, u)
        if self.t_nan is not None and abs(t - self.t_nan) < 1e-6:
            out.x_mean[:] = np.nan
        return out


def test_non_finite_estimate_reinitialises_and_is_never_published():
    made: list = []

    def factory(name, scenario, rng, particles, x0=None):
        f = NaNAfter(scenario, 2.0 if not made else None)
        f.x0 = x0
        made.append(f)
        return f

    ev = Events()
    pipe = Pipeline(NO_GATE, filter_factory=factory, observers=[ev])
    msgs, truth = fly(pipe, 80, None)
    assert len(made) == 2 and pipe.reinitialisations == 1
    # rebuilt around the state made from that frame's measurements (altitude, u, w, pitch, q)
    assert abs(made[1].x0[0] - truth[40][0][0]) < 15.0 and abs(made[1].x0[3] - truth[40][0][3]) < 0.01
    assert made[1].calls[0][0] == 2.0          # the frame is stepped again by the new filter
    est = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    assert len(est) == 80 and all(np.isfinite(m.state).all() for m in est)
    assert any("non-finite estimate" in t for lvl, t in ev.events if lvl == "error")
    assert "FDIR estimator restart: non-finite estimate" in [m.text for m in msgs
                                                               if m.get_type() == "STATUSTEXT"]
    hb = [m for m in msgs if m.get_type() == "HEARTBEAT"]
    assert [m.system_status for m in hb[:4]] == [4, 4, 5, 4]   # CRITICAL for 1 s after the restart
