"""The flight recorder on synthetic data: topics, schemas, metadata, bit-exact raw bytes, flushing,
rotation, and the MAVLink / estimate / log schemas checked against the messages written."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader
from pymavlink.dialects.v20 import common as mavlink

from fdir_service.recording import McapLog, Recorder, log_info
from fdir_service.recording import schemas as S
from sim_bridge.truth_log import TruthWriter, truth_schema
from tests.helpers.records import DT_NS, FAULTS, check_schema, record_synthetic, step_output


def test_recording_has_every_topic_with_named_schema_and_metadata(tmp_path):
    path = tmp_path / "flight.mcap"
    with Recorder(path) as rec:
        fed = record_synthetic(rec, 240, adaptive=True)

    with open(path, "rb") as f:  # mcap's own reader, through the summary
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        for ch in summary.channels.values():
            assert ch.schema_id in summary.schemas, ch.topic
            assert summary.schemas[ch.schema_id].encoding == "jsonschema"
            assert ch.message_encoding == "json"
        topics = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        assert summary.chunk_indexes and all(c.compression == "zstd" for c in summary.chunk_indexes)
        n_chunks = len(summary.chunk_indexes)
        for schema, _channel, message in reader.iter_messages():
            check_schema(json.loads(message.data), json.loads(schema.data))

    assert topics == {
        "/mavlink/raw/in": "fdir.RawMavlink", "/mavlink/raw/out": "fdir.RawMavlink",
        "/mavlink/1/1/HEARTBEAT": "mavlink.HEARTBEAT", "/mavlink/1/1/ATTITUDE": "mavlink.ATTITUDE",
        "/mavlink/1/1/GPS_RAW_INT": "mavlink.GPS_RAW_INT",
        "/mavlink/1/1/SCALED_PRESSURE": "mavlink.SCALED_PRESSURE",
        "/mavlink/1/1/SERVO_OUTPUT_RAW": "mavlink.SERVO_OUTPUT_RAW",
        "/fdir/estimate": "fdir.Estimate", "/fdir/particles": "fdir.Particles", "/fdir/log": "foxglove.Log",
    }
    assert metadata["config"]["filter"] == "RJMRPF" and metadata["config"]["seed"] == "7"
    assert set(metadata) == {"config", "versions", "dialect"}
    # 240 frames = 12 s of log time, a chunk closed at least every second
    assert n_chunks >= 11

    log = McapLog(path)
    assert log.mode == "indexed"
    raw = b"".join(S.raw_bytes(obj) for _, obj in log.iter_json("/mavlink/raw/in"))
    assert raw == fed  # bit-exact
    counts = log.message_counts()
    assert counts["/fdir/estimate"] == 240 and counts["/fdir/particles"] == 12
    assert counts["/mavlink/1/1/HEARTBEAT"] == 12 and counts["/fdir/log"] == 1
    (_, ev), = log.iter_json("/fdir/log")
    assert ev["level"] == 3 and ev["timestamp"] == {"sec": 10, "nsec": 3000}


def test_estimate_record_is_flat_and_round_trips_bit_exact(tmp_path):
    path = tmp_path / "est.mcap"
    outs = [step_output(k, adaptive=True) for k in range(30)]
    outs[5].fault_probability[1] = np.nan  # a NaN becomes null, never breaks the JSON
    with Recorder(path) as rec:
        for k, out in enumerate(outs):
            rec.on_estimate(k * 0.05, out, 2.5e-4, k * DT_NS)
    recs = [obj for _, obj in McapLog(path).iter_json("/fdir/estimate")]
    assert len(recs) == 30
    r = recs[7]
    o = outs[7]
    assert all(isinstance(v, (int, float, bool)) for v in r.values())  # flat: plot-panel paths
    assert r["x_theta"] == o.x_mean[3] and r["x_f_baro"] == o.x_mean[6]
    assert r["var_q"] == o.x_cov[4, 4] and r["var_f_gnss"] == o.x_cov[5, 5]
    assert r["f_gnss"] == o.fault_estimate[0] and r["pf_baro"] == o.fault_probability[1]
    assert r["pfa_gnss"] == o.pfa[0] and r["pmd_baro"] == o.pmd[1]
    assert r["pi01_baro"] == o.transition[1, 0, 1] and r["pi10_gnss"] == o.transition[0, 1, 0]
    assert r["n_eff"] == o.n_eff and r["resampled"] == o.resampled and r["latency_s"] == 2.5e-4
    assert recs[5]["pf_baro"] is None
    assert list(r) == S.estimate_field_names(FAULTS, 7, adaptive=True)


def test_non_adaptive_estimate_has_no_pfa_fields():
    names = S.estimate_field_names(FAULTS, 7, adaptive=False)
    assert "pf_gnss" in names and not any(n.startswith(("pfa_", "pmd_", "pi0")) for n in names)
    obj = S.estimate_json(1.0, step_output(3), 0.0)
    assert list(obj) == names


def test_estimate_without_covariance_records_null_variances():
    # a filter asked not to output its covariance (ParticleFilter.output_covariance = False)
    o = step_output(4)
    o.x_cov = None
    obj = S.estimate_json(1.0, o, 0.0)
    assert obj["x_theta"] == o.x_mean[3]
    assert all(obj[k] is None for k in obj if k.startswith("var_")) and "var_q" in obj


@pytest.mark.parametrize("name", ["HEARTBEAT", "ODOMETRY", "STATUSTEXT", "NAMED_VALUE_FLOAT", "GPS_RAW_INT"])
def test_mavlink_schema_matches_decoded_message(name):
    cls = mavlink.mavlink_map[next(k for k, v in mavlink.mavlink_map.items() if v.msgname == name)]
    schema = S.mavlink_schema(cls)
    assert schema["title"] == f"mavlink.{name}"
    enc = mavlink.MAVLink(None, srcSystem=3, srcComponent=7)
    args = []
    length = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    for t, n in zip(cls.fieldtypes, (length[f] for f in cls.fieldnames), strict=True):
        v = b"abc" if t == "char" else (float("nan") if t == "float" else 1)
        args.append([v] * n if n and t != "char" else v)
    msg = mavlink.MAVLink(None).parse_buffer(bytes(cls(*args).pack(enc)))[0]
    obj = S.mavlink_message_json(msg)
    check_schema(obj, schema)
    assert obj["_sys"] == 3 and obj["_comp"] == 7
    assert S.mavlink_topic(msg) == f"/mavlink/3/7/{name}"
    json.dumps(obj, allow_nan=False)


def test_rotation_by_duration_and_size_keeps_metadata_and_every_frame(tmp_path):
    path = tmp_path / "rot.mcap"
    with Recorder(path, rotate_seconds=5.0) as rec:
        fed = record_synthetic(rec, 240)  # 12 s -> 3 segments
    assert [p.name for p in rec.paths] == ["rot.mcap", "rot.001.mcap", "rot.002.mcap"]
    raw = b""
    for p in rec.paths:
        log = McapLog(p)
        assert log.mode == "indexed" and set(log.metadata) == {"config", "versions", "dialect"}
        raw += b"".join(S.raw_bytes(obj) for _, obj in log.iter_json("/mavlink/raw/in"))
    assert raw == fed
    assert log_info(rec.paths[0])["duration_s"] == pytest.approx(5.0, abs=0.06)

    with Recorder(tmp_path / "size.mcap", rotate_bytes=20_000) as rec2:
        record_synthetic(rec2, 240)
    assert len(rec2.paths) >= 3
    total = sum(McapLog(p).message_counts()["/fdir/estimate"] for p in rec2.paths)
    assert total == 240


def test_truth_writer_records_states_faults_inputs(tmp_path):
    path = tmp_path / "truth.mcap"
    with TruthWriter(path, FAULTS, metadata={"scenario": {"id": "ch4", "seed": 3}}) as tw:
        for k in range(100):
            f = np.array([50.0 if k >= 40 else 0.0, 0.0])
            tw.write(k * 0.05, np.array([-500.0, 39.95, 1.9, 0.048, 0.0]), f, np.array([-0.083, 0.53]))
    log = McapLog(path)
    assert log.metadata["scenario"] == {"id": "ch4", "seed": "3"}
    recs = [obj for _, obj in log.iter_json("/sim/truth")]
    assert len(recs) == 100
    assert recs[40]["f_gnss"] == 50.0 and recs[40]["active_gnss"] and not recs[39]["active_gnss"]
    assert recs[0]["h"] == 500.0 and recs[0]["delta_t"] == 0.53 and recs[10]["t"] == 0.5
    check_schema(recs[0], truth_schema(FAULTS))

