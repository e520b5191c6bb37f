"""The service's cheap output and recording paths produce exactly what the plain pymavlink / eager
paths produce: the publisher's direct MAVLink 2 framing of NAMED_VALUE_FLOAT and FDIR_ESTIMATE
(bytes equal to pymavlink's `pack`, unsigned and signed), and the recorder's deferred mode (the
daemon's: queue references during `feed`, encode after sending) writes the same MCAP content."""

from __future__ import annotations

import math

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.frames import AssembledFrame
from fdir_service.runtime.publishing import Publisher
from sim_bridge.scenario import load_scenario
from tests.helpers.experiments import CH4, ch4_service


def _outputs(rng, k: int, nf: int, adaptive: bool):
    for i in range(k):
        x = rng.normal(size=5 + nf) * 10
        cov = np.diag(rng.random(5 + nf))
        if i % 5 == 1:
            x[:] = 0.0                               # trailing zeros are truncated on the wire
            cov[:] = 0.0
        fe, fp = rng.normal(size=nf), rng.random(nf)
        if i % 7 == 3:
            fe[0] = math.nan
        yield StepOutput(t=0.05 * i, x_mean=x, x_cov=cov, fault_ids=tuple(f"f{j}" for j in range(nf)),
                         fault_estimate=fe, fault_probability=fp, n_eff=float(rng.random() * 1000),
                         resampled=bool(i % 2), pfa=rng.random(nf) if adaptive else None,
                         pmd=rng.random(nf) if adaptive else None,
                         transition=rng.random((nf, 2, 2)) if adaptive else None)


def test_publisher_fast_framing_equals_pymavlink_pack():
    cfg = ch4_service()
    faults = load_scenario("ch4").faults
    rng = np.random.default_rng(0)
    for key in (None, bytes(range(32))):
        for adaptive in (False, True):
            mav = new_mavlink(1, 191, key=key)
            ref = new_mavlink(1, 191, key=key)
            pub = Publisher(cfg.publish, faults, mav, adaptive)
            for i, out in enumerate(_outputs(rng, 40, len(faults), adaptive)):
                mask = np.array([j % 3 != i % 3 for j in range(6)])
                frame = AssembledFrame(i, 50_000 * i + 7, np.zeros(6), mask, np.zeros(2),
                                       synthetic=i % 11 == 0, stale=("baro_alt",) if i % 4 == 0 else ())
                pub.frame_seq += 1
                seq_before = mav.seq
                got = pub.estimate_bytes(frame, out, gap=False)
                assert mav.seq == (seq_before + 1) % 256   # every frame out takes the next sequence number
                ref.seq = seq_before
                ref.signing.timestamp = mav.signing.timestamp - (1 if key else 0)
                want = bytes(pub.estimate_message(frame, out, False).pack(ref))
                assert got == want, i
                v = float(out.fault_estimate[0])
                ref.seq = mav.seq
                got = pub.named_value_float(frame.time_boot_ms, b"pf_gnss", v)
                ref.signing.timestamp = mav.signing.timestamp - (1 if key else 0)
                want = bytes(dialect.MAVLink_named_value_float_message(frame.time_boot_ms, b"pf_gnss",
                                                                       v).pack(ref))
                assert got == want, i
            m = new_mavlink(255, 0, key=key).parse_buffer(got)
            assert m and m[0].get_type() == "NAMED_VALUE_FLOAT" and m[0].name == "pf_gnss"


def test_deferred_recorder_writes_the_same_file(tmp_path):
    from fdir_service.pipeline import Pipeline
    from fdir_service.recording import Recorder
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import run

    cfg = ch4_service()
    traj = run(CH4, seed=2, seconds=3.0)
    link = AutopilotLink(CH4)
    data = [b"".join(link.sensor_messages(traj.t[k], traj.y[k], traj.mask[k], traj.static_pressure_pa[k]))
            + b"".join(link.actuator_messages(traj.t[k], traj.u[k])) for k in range(len(traj.t))]
    files = []
    for deferred in (False, True):
        path = tmp_path / f"d{int(deferred)}.mcap"
        rec = Recorder(path)
        pipe = Pipeline(cfg, filter_name="RJMRPF", particles=50, seed=3, observers=[rec])
        if deferred:
            pipe.defer_observers(True)
        for k, d in enumerate(data):
            pipe.feed(d, 10**9 + k * 50_000_000)
            if deferred:
                assert rec.queued                   # nothing encoded yet: only references queued
                pipe.drain_observers()
                assert rec.queued == 0
        pipe.close(10**9 + len(data) * 50_000_000)
        pipe.drain_observers()
        rec.close()
        files.append(path)

    from fdir_service.recording.logtools import McapLog

    a, b = McapLog(files[0]), McapLog(files[1])
    ta = [(t, o) for t, o in a.iter_json("/fdir/estimate")]
    tb = [(t, o) for t, o in b.iter_json("/fdir/estimate")]
    strip = [(t, {k: v for k, v in o.items() if k != "latency_s"}) for t, o in ta]
    assert len(ta) == len(data) and strip == [(t, {k: v for k, v in o.items() if k != "latency_s"})
                                              for t, o in tb]
    for topic in ("/mavlink/raw/in", "/mavlink/raw/out", "/fdir/log", "/fdir/particles"):
        assert list(a.iter_json(topic)) == list(b.iter_json(topic)), topic


def test_generic_fast_pack_equals_pymavlink_pack():
    from fdir_service.mavlink import pack

    nan = math.nan
    msgs = [
        lambda: dialect.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3),
        lambda: dialect.MAVLink_statustext_message(4, b"FDIR gnss fault +50.1 m p=0.98", 0, 0),
        lambda: dialect.MAVLink_gps_raw_int_message(123456789, 3, 0, 0, 500123, 100, 150, 65535, 65535, 12),
        lambda: dialect.MAVLink_scaled_pressure_message(1234, 954.6, 0.0, 1500),
        lambda: dialect.MAVLink_attitude_message(1234, 0.0, 0.05, 0.0, 0.0, nan, 0.0),
        lambda: dialect.MAVLink_odometry_message(1234000, 1, 12, nan, nan, nan, [1.0, 0.0, 0.02, 0.0], 25.0,
                                                 nan, 1.5, nan, nan, nan, [nan] * 21, [nan] * 21, 0, 1, 0),
        lambda: dialect.MAVLink_servo_output_raw_message(1234000, 0, 1500, 1480, 1600, 1500, *[0] * 12),
        lambda: dialect.MAVLink_actuator_output_status_message(1234000, 3, [0.01, 0.6] + [0.0] * 30),
        lambda: dialect.MAVLink_heartbeat_message(0, 0, 0, 0, 0, 0),          # all-zero payload
    ]
    for key in (None, bytes(range(32))):
        a, b = new_mavlink(7, 191, key=key), new_mavlink(7, 191, key=key)
        a.seq = b.seq = 42
        for make in msgs:
            assert pack(make(), a) == bytes(make().pack(b))
            assert a.seq == (b.seq + 1) % 256     # pack takes the next sequence number, as send() does
            b.seq = a.seq
