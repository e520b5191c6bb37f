"""The pipeline core: what the filter receives, what goes out (names, timestamps, hysteresis),
signing, bad bytes, observers, and replay determinism with a real particle filter."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fdir_service.mavlink import new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.service_config import (
    ServiceConfig,  # noqa: F401
    default_config_path,
)
from tests.helpers.experiments import CH4, ch4_service
from tests.helpers.service import autopilot_stream, fake_factory

KEY = bytes(range(1, 33))
STREAM = autopilot_stream(14.0)   # ch4 truth flight, GNSS +50 m from 10 s


def run_pipeline(stream, cfg=None, observers=(), **kw):
    filters: list = []
    pipe = Pipeline(cfg or ch4_service(), filter_factory=fake_factory(filters),
                    observers=observers, **kw)
    out = []
    for i, (_, sens, acts) in enumerate(stream):
        for b in sens + acts:
            out += pipe.feed(b, i)
    rx = new_mavlink(255, 0)
    return pipe, filters[0], rx.parse_buffer(b"".join(out)) or []


def test_filter_gets_frame_measurements_and_previous_input():
    pipe, filt, _ = run_pipeline(STREAM)
    assert len(filt.calls) == len(STREAM) == pipe.frames
    for k in (1, 100, 250):
        t, y, mask, u = filt.calls[k]
        fr = STREAM[k][0]
        assert t == pytest.approx(fr.t) and mask.all()
        # GPS mm, float32 pressure/attitude/velocities: the wire costs < 1 mm / 1e-5 rad
        assert np.abs(y - fr.y).max() < 2e-3
        assert u == pytest.approx(fr.u_applied, abs=1e-6)   # u_{k-1}, float32 actuator outputs


def test_published_names_timestamps_and_statustext():
    _, _, msgs = run_pipeline(STREAM)
    nvf = [m for m in msgs if m.get_type() == "NAMED_VALUE_FLOAT"]
    names = {m.name for m in nvf}
    assert names == {"f_gnss", "pf_gnss", "f_baro", "pf_baro"}   # not adaptive: no pfa_/pmd_
    assert {m.time_boot_ms % 100 for m in nvf} == {0}              # 10 Hz on frame time
    est = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    assert [m.time_boot_ms for m in est] == [round(fr.t * 1000) for fr, _, _ in STREAM]
    assert all(m.get_srcSystem() == 1 and m.get_srcComponent() == 191 for m in msgs)
    texts = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert len(texts) == 1 and texts[0].startswith("FDIR gnss fault +") and texts[0].endswith("m p=1.00")
    # hysteresis: the fake is certain from 10.00 s; declare_hold_s 0.2 -> declared on the 10.20 s frame
    i = next(i for i, m in enumerate(msgs) if m.get_type() == "STATUSTEXT")
    prev = [m for m in msgs[:i] if m.get_type() == "FDIR_ESTIMATE"][-1]
    assert prev.time_boot_ms == 10_200 and prev.declared == 0b01
    hb = [m for m in msgs if m.get_type() == "HEARTBEAT"]
    assert len(hb) == 14 and hb[-1].type == 18 and hb[-1].system_status == 4   # ONBOARD_CONTROLLER, ACTIVE


def test_signing_rejects_and_counts_unsigned_and_wrongly_signed_input(tmp_path):
    kf = tmp_path / "key"
    kf.write_text(KEY.hex())
    cfg = ch4_service(
        default_config_path().read_text().replace('key_file = ""', f'key_file = "{kf}"'))
    good = autopilot_stream(1.0, key=KEY)
    unsigned = autopilot_stream(1.0)
    wrong = autopilot_stream(1.0, key=bytes(32))
    pipe, filt, msgs = run_pipeline(unsigned + wrong, cfg)
    assert pipe.frames == 0 and filt.calls == []
    counts = pipe.rejected_counts
    n_msgs = sum(len(s) + len(a) for _, s, a in unsigned)
    assert counts["unsigned"] == n_msgs and counts["bad signature"] == n_msgs
    obs = Collect()
    pipe, filt, msgs = run_pipeline(good, cfg, observers=[obs])
    assert pipe.frames == 20 and pipe.rejected_counts == {}
    out = b"".join(d for direction, d in obs.raw if direction == "out")
    keyed = new_mavlink(255, 0, key=KEY).parse_buffer(out)
    assert len(keyed) == len(msgs) > 40 and all(m.get_signed() for m in keyed)
    assert all(m.get_type() == "BAD_DATA" for m in new_mavlink(255, 0, key=bytes(32)).parse_buffer(out))


def test_garbage_never_crashes_and_is_counted():
    filters: list = []
    pipe = Pipeline(ch4_service(), filter_factory=fake_factory(filters))
    rng = np.random.default_rng(0)
    for i, (_, sens, acts) in enumerate(STREAM[:40]):
        blob = b"".join(sens + acts)
        if i % 3 == 0:   # corrupt a byte in the middle of the frame's bytes
            blob = bytearray(blob)
            blob[len(blob) // 2] ^= 0xFF
            blob = bytes(blob)
        pipe.feed(blob + rng.bytes(7), i)
    assert pipe.frames >= 38
    assert sum(pipe.rejected_counts.values()) >= 13
    assert all(np.all(np.isfinite(y[m])) for _, y, m, _ in filters[0].calls)


class Collect:
    def __init__(self):
        self.meta, self.est, self.events, self.raw, self.msgs, self.particles = {}, [], [], [], 0, 0

    def on_metadata(self, name, data):
        self.meta[name] = data

    def on_raw(self, direction, data, t_ns):
        self.raw.append((direction, data))

    def on_message(self, msg, t_ns):
        self.msgs += 1

    def on_estimate(self, frame_time_s, out, latency_s, t_ns):
        self.est.append((frame_time_s, out))

    def on_event(self, level, text, t_ns):
        self.events.append((level, text))

    def on_particles(self, frame_time_s, states, weights, t_ns):
        self.particles += 1


def test_replay_of_recorded_bytes_reproduces_every_estimate_bit_for_bit():
    cfg = ch4_service()
    stream = STREAM[:260]
    a = Collect()
    pipe = Pipeline(cfg, filter_name="JMRPF", particles=200, seed=5, observers=[a])
    for i, (_, sens, acts) in enumerate(stream):
        for b in sens + acts:
            pipe.feed(b, i)
    assert a.meta["config"]["filter"] == "JMRPF" and a.meta["config"]["seed"] == "5"
    assert "FDIR_ESTIMATE" in a.meta["dialect"]["fdir.xml"]
    assert a.msgs == sum(len(s) + len(ac) for _, s, ac in stream)
    assert a.particles == 13 and len(a.est) == 260
    # replay: the "in" bytes, rechunked, through a fresh pipeline rebuilt from the metadata
    rebuilt = ServiceConfig.from_toml_text(a.meta["config"]["service_toml"],
                                           estimator_doc=json.loads(a.meta["config"]["estimator_json"]))
    b = Collect()
    replay = Pipeline(rebuilt, filter_name=a.meta["config"]["filter"],
                      particles=int(a.meta["config"]["particles"]), seed=int(a.meta["config"]["seed"]),
                      observers=[b])
    blob = b"".join(d for direction, d in a.raw if direction == "in")
    for i in range(0, len(blob), 997):
        replay.feed(blob[i:i + 997], 0)
    assert len(b.est) == len(a.est)
    for (ta, oa), (tb, ob) in zip(a.est, b.est, strict=True):
        assert ta == tb
        assert np.array_equal(oa.x_mean, ob.x_mean) and np.array_equal(oa.fault_probability,
                                                                       ob.fault_probability)
    # and the same bytes go out (the chunking follows the input's)
    out_a = b"".join(d for x, d in a.raw if x == "out")
    assert len(out_a) > 10_000 and out_a == b"".join(d for x, d in b.raw if x == "out")


def _estimates_with_init(init: str, seconds: float = 3.0):
    """The altitude estimates (m) of an RJMRPF service whose estimator trims at 300 m (the aircraft
    flies at 500 m), starting its cloud at that trim or on the first frame."""
    from fdir_service.estimator_config import merge_documents

    doc = merge_documents(CH4.estimator.doc, {"operating_point": {"altitude_m": 300.0, "init": init}})
    cfg = ServiceConfig.from_toml_text(default_config_path().read_text(), estimator_doc=doc)
    pipe = Pipeline(cfg, filter_name="RJMRPF", particles=300, seed=3)
    heights = []
    for i, (_, sens, acts) in enumerate(STREAM[: int(seconds / CH4.dt_s)]):
        for b in sens + acts:
            for m in new_mavlink(255, 0).parse_buffer(b"".join(pipe.feed(b, i))) or []:
                if m.get_type() == "FDIR_ESTIMATE":
                    heights.append(-m.state[0])
    return pipe, np.array(heights)


def test_first_frame_init_starts_the_cloud_on_the_measurements_not_the_trim():
    pipe, h = _estimates_with_init("first_frame")
    assert abs(h[0] - 500.0) < 10.0 and np.all(np.abs(h - 500.0) < 10.0)
    assert pipe.reinitialisations == 0
    _, h_trim = _estimates_with_init("trim")
    assert abs(h_trim[0] - 500.0) > 50.0          # the trim cloud starts 200 m low
