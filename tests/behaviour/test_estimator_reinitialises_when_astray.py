"""Estimator health (issue 7): a one-frame 1e6 m GNSS altitude glitch that sends the particle filter
astray triggers a re-initialisation from the current measurements (event + STATUSTEXT) on that very
frame (the estimate's non-physical jump), so no astray estimate is published and nothing is falsely
declared; with the jump check off, the N_eff degeneracy check restarts it 0.45 s later; a
non-finite estimate does too. The out-of-range gate, which normally drops a 1e6 m altitude before
the filter, is configured off here so that the glitch reaches the filter."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.events import Cause, FaultDeclared, FilterStepFailed, HealthProblem, Reinitialised
from fdir_service.service_config import default_config_path
from tests.helpers.experiments import CH4, ch4_service
from tests.helpers.service import FakeFilter
from tests.helpers.streams import Events

NO_GATE = ch4_service(
    default_config_path().read_text().replace("valid_min = -500.0\nvalid_max = 20000.0\n", "", 1))
NO_GATE_NO_JUMP = ch4_service(NO_GATE.text.replace(
    "max_state_jump = [50.0, 20.0, 20.0, 1.0, 5.0]", "max_state_jump = []", 1))


def fly(pipe: Pipeline, frames: int, glitch_frame: int | None, glitch_m: float = 1e6):
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import SimStepper, default_autopilot

    sc = CH4
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

    assert NO_GATE.measurements[0].max == np.inf
    pipe = Pipeline(ch4_service(), filter_name="RJMRPF", particles=100, seed=4)
    fly(pipe, 110, 100)
    assert pipe.rejected_counts["gnss_alt out of range"] == 1 and pipe.reinitialisations == 0


def _declared(ev) -> list[tuple[float, FaultDeclared]]:
    """(frame time, event) of every fault declaration."""
    return [(e.time_s, e) for e in ev.of(FaultDeclared)]


def test_altitude_glitch_causes_no_false_declaration():
    """The real RJMRPF: whether its own gating absorbs the glitch or the state-jump check restarts it on
    that frame, nothing astray is published and nothing is falsely declared."""
    assert NO_GATE.health.max_state_jump == (50.0, 20.0, 20.0, 1.0, 5.0)
    ev = Events()
    pipe = Pipeline(NO_GATE, filter_name="RJMRPF", particles=100, seed=4, observers=[ev])
    msgs, truth = fly(pipe, 300, 100)           # glitch at t = 5.00 s; GNSS fault +50 m from 10 s
    est = ev.estimates
    assert len(est) == 300
    reinit = ev.of(Reinitialised)
    assert pipe.reinitialisations == len(reinit) <= 1
    if reinit:
        assert reinit[0].time_s == pytest.approx(5.0) and reinit[0].cause.cause is Cause.STATE_JUMP
        assert reinit[0].cause.text.startswith("p_d jump")
    for k in range(100, 200):                   # every published estimate stays on the aircraft
        (z, f), o = truth[k], est[k]
        assert abs(o.x_mean[0] - z[0]) < 5.0, (k, o.x_mean[0] - z[0])
        if k > 100:   # (on the glitch frame itself the filter may explain it as a GNSS fault)
            assert np.all(np.abs(o.fault_estimate - f) < 5.0), (k, o.fault_estimate)
    st = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    decl = [t for t in st if " fault " in t or "cleared" in t]
    assert len(decl) == 1 and decl[0].startswith("FDIR gnss fault") and 40 < float(decl[0].split()[3]) < 60
    assert [t for t, _ in _declared(ev)] and all(t >= 10.0 for t, _ in _declared(ev))
    assert np.mean(np.abs([o.fault_estimate[0] - 50.0 for o in est[240:300]])) < 5.0   # N = 100: noisy


ASTRAY_M = 20_000.0


class Astray(FakeFilter):
    """The fake filter, but as the particle filter once failed: a GNSS row 10 km off the baro sends it
    20 km astray (it explains the glitch as a fault on both sensors, P(fault) = 1) with all its weight
    on one particle (N_eff = 1) until it is rebuilt. A rebuilt filter is a fresh instance."""

    N = 100

    def __init__(self, scenario) -> None:
        super().__init__(scenario)
        self.astray = False

    def step(self, t, y, mask, u) -> StepOutput:
        out = super().step(t, y, mask, u)
        if mask[0] and mask[1] and abs(y[0] - y[1]) > 1e4:
            self.astray = True
        if self.astray:
            out.x_mean[0] -= ASTRAY_M
            out.fault_estimate[:] = -ASTRAY_M
            out.fault_probability[:] = 1.0
            out.n_eff = 1.0
        return out


def _astray_pipeline(config):
    made: list = []

    def factory(name, scenario, rng, particles, x0=None):
        made.append(Astray(scenario))
        return made[-1]

    ev = Events()
    return Pipeline(config, filter_factory=factory, observers=[ev]), ev, made


def test_state_jump_restarts_the_filter_on_that_frame_without_a_false_declaration():
    pipe, ev, made = _astray_pipeline(NO_GATE)
    msgs, truth = fly(pipe, 300, 100)           # glitch at t = 5.00 s; GNSS fault +50 m from 10 s
    # the astray step was caught before publishing: the filter was rebuilt from the frame's
    # measurements (baro wins, the glitching GNSS row is masked) and the frame stepped again
    assert pipe.reinitialisations == 1 and len(made) == 2
    (reinit,) = ev.of(Reinitialised)
    assert reinit.time_s == pytest.approx(5.0) and reinit.cause == HealthProblem(Cause.STATE_JUMP,
                                                                                 "p_d jump -2e+04/frame")
    assert reinit.masked == ("gnss_alt",) and reinit.level == "warning"
    assert abs(reinit.state[0] - truth[100][0][0]) < 15.0      # p_d from the baro, not the glitch
    assert made[1].calls[0][0] == 5.0 and not made[1].calls[0][2][0]
    st = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert "FDIR estimator restart: p_d jump -2e+04/frame" in st
    fdr = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    assert len(fdr) == 300
    assert all(abs(m.state[0] - z[0]) < 50.0 for m, (z, _) in zip(fdr, truth, strict=True))
    # no false declaration: the only one is the real GNSS fault at 10 s
    assert [t for t in st if " fault " in t or "cleared" in t][:1] == [
        t for t in st if t.startswith("FDIR gnss fault")][:1]
    assert _declared(ev) and all(t >= 10.0 for t, _ in _declared(ev)) and len(_declared(ev)) == 1


def test_without_the_jump_check_degeneracy_restarts_it_late_after_false_declarations():
    """What the jump check prevents (and the N_eff check still catching a degenerate filter): with
    max_state_jump = [] the astray filter publishes for 10 frames (0.45 s), declares both faults
    falsely, and is restarted on N_eff < 1.5 at 5.45 s; then the declarations clear."""
    assert NO_GATE_NO_JUMP.health.max_state_jump == ()
    pipe, ev, made = _astray_pipeline(NO_GATE_NO_JUMP)
    msgs, truth = fly(pipe, 300, 100)
    assert pipe.reinitialisations == 1
    (reinit,) = ev.of(Reinitialised)
    assert reinit.time_s == pytest.approx(5.45) and reinit.cause == HealthProblem(Cause.DEGENERATE,
                                                                                  "N_eff < 1.5 for 10 frames")
    st = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert "FDIR estimator restart: N_eff < 1.5 for 10 frames" in st
    false = [(t, x) for t, x in _declared(ev) if t < 10.0]
    assert len(false) == 2 and all(5.0 <= t < 5.45 for t, _ in false)
    fdr = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    assert sum(abs(m.state[0] - z[0]) > 1000 for m, (z, _) in zip(fdr, truth, strict=True)) == 9


def test_filter_exception_reinitialises_instead_of_crashing():
    class Raises(FakeFilter):
        def step(self, t, y, mask, u):
            if abs(t - 2.0) < 1e-6:
                raise np.linalg.LinAlgError("Singular matrix")
            return super().step(t, y, mask, u)

    made: list = []

    def factory(name, scenario, rng, particles, x0=None):
        made.append((Raises if not made else FakeFilter)(scenario))
        return made[-1]

    ev = Events()
    pipe = Pipeline(NO_GATE, filter_factory=factory, observers=[ev])
    msgs, _ = fly(pipe, 60, None)
    assert len(made) == 2 and pipe.reinitialisations == 1 and len(ev.estimates) == 60
    (failed,) = ev.of(FilterStepFailed)
    assert failed.time_s == pytest.approx(2.0) and failed.error == "LinAlgError" and failed.level == "error"
    assert ev.of(Reinitialised)[0].cause.cause is Cause.FILTER_RAISED
    assert "FDIR estimator restart: filter raised LinAlgError" in [m.text for m in msgs
                                                                   if m.get_type() == "STATUSTEXT"]


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
    (reinit,) = ev.of(Reinitialised)
    assert reinit.cause.cause is Cause.NON_FINITE and reinit.level == "error"
    assert reinit.time_s == pytest.approx(2.0)
    assert "FDIR estimator restart: non-finite estimate" in [m.text for m in msgs
                                                               if m.get_type() == "STATUSTEXT"]
    hb = [m for m in msgs if m.get_type() == "HEARTBEAT"]
    assert [m.system_status for m in hb[:4]] == [4, 4, 5, 4]   # CRITICAL for 1 s after the restart


def test_max_state_jump_is_validated():
    from fdir_service.service_config import ConfigError

    base = default_config_path().read_text()
    for bad in ("[1.0, 2.0]", "[50.0, 20.0, 20.0, 1.0, -5.0]", '"big"'):
        with pytest.raises(ConfigError, match="health.max_state_jump"):
            ch4_service(base.replace("max_state_jump = [50.0, 20.0, 20.0, 1.0, 5.0]",
                                                      f"max_state_jump = {bad}", 1))


def test_pipeline_publishes_adaptive_fields_for_every_adaptive_filter_name():
    # derived from the filter (its jump strategy), not from a list of names

    cfg = ch4_service()
    flags = {name: Pipeline(cfg, filter_name=name, particles=50, seed=1).adaptive
             for name in ("AJMRPF", "AJMRPF-thesis", "ARJMRPF-thesis", "JMRPF", "RJMRPF", "KF", "IMM-KF")}
    assert flags == {"AJMRPF": True, "AJMRPF-thesis": True, "ARJMRPF-thesis": True, "JMRPF": False,
                     "RJMRPF": False, "KF": False, "IMM-KF": False}
