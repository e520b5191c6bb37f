"""Record -> replay: simulated autopilot bytes through a Pipeline with a Recorder, then `fdir replay`.

Bit-identity with the recorded config and seed, a comparison with another filter, SPEC section 8
metrics against the simulator truth, figures, and replay of a log cut short by a crash.
"""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.cli import main as fdir_main
from fdir_service.pipeline import Pipeline
from fdir_service.recording import McapLog, Recorder
from fdir_service.recording import schemas as S
from fdir_service.replay import compare_identity, replay
from sim_bridge.replay_score import replay_and_score, score
from sim_bridge.truth_log import TruthWriter
from tests.helpers.experiments import CH4, ch4_service

SECONDS = 20.0
PARTICLES = 200
SEED = 3
T0_NS = 1_700_000_000_000_000_000  # wall-clock receive times of the "flight"


def fly_and_record(tmp_path, filter_name: str = "JMRPF"):
    """ch4 for 20 s: sim-bridge's simulator and autopilot encoder -> Pipeline + Recorder; truth MCAP."""
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import run

    cfg = ch4_service()
    sc = CH4
    traj = run(sc, seed=5, seconds=SECONDS)
    link = AutopilotLink(sc)
    log, truth = tmp_path / "flight.mcap", tmp_path / "truth.mcap"
    rec = Recorder(log)
    pipe = Pipeline(cfg, filter_name=filter_name, particles=PARTICLES, seed=SEED, observers=[rec])
    sent = bytearray()
    with TruthWriter(truth, [f.id for f in sc.faults]) as tw:
        for k in range(len(traj.t)):
            ps = traj.static_pressure_pa[k]
            data = b"".join(link.sensor_messages(traj.t[k], traj.y[k], traj.mask[k], ps))
            data += b"".join(link.actuator_messages(traj.t[k], traj.u[k]))
            t_ns = T0_NS + int(traj.t[k] * 1e9) + 1_234_567
            sent += b"".join(pipe.feed(data, t_ns))
            tw.write(traj.t[k], traj.z[k], traj.faults[k], traj.u[k])
        sent += b"".join(pipe.close(t_ns))
    rec.close()
    return log, truth, bytes(sent)


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    return fly_and_record(tmp_path_factory.mktemp("flight"))


def test_replay_with_recorded_config_and_seed_is_bit_identical(flight, tmp_path):
    log, _, sent = flight
    recorded = [obj for _, obj in McapLog(log).iter_json("/fdir/estimate")]
    assert len(recorded) == 400
    r = replay(log, out=tmp_path / "again.mcap")
    assert r.same_setup and (r.filter, r.particles, r.seed) == ("JMRPF", PARTICLES, SEED)
    assert r.identity.identical and r.identity.mismatched_frames == 0
    assert len(r.replayed) == 400
    assert r.replayed[250]["f_gnss"] == recorded[250]["f_gnss"]  # exact float equality
    assert r.replayed[399]["var_p_d"] == recorded[399]["var_p_d"]
    # the replay's own recording carries the same estimates and the same output bytes
    again = McapLog(tmp_path / "again.mcap")
    assert compare_identity(recorded, [o for _, o in again.iter_json("/fdir/estimate")]).identical
    out_flight = b"".join(S.raw_bytes(o) for _, o in McapLog(log).iter_json("/mavlink/raw/out"))
    out_again = b"".join(S.raw_bytes(o) for _, o in again.iter_json("/mavlink/raw/out"))
    assert out_flight == sent and out_again == sent
    # log times are the recorded receive times, not the replay's wall clock
    assert next(again.iter_messages("/fdir/estimate"))[2].log_time >= T0_NS


def test_identity_check_detects_a_different_seed(flight):
    log, _, _ = flight
    r = replay(log, seed=SEED + 1)
    assert not r.same_setup and not r.identity.identical
    assert r.identity.mismatched_frames > 300
    assert r.differences is not None and r.differences["f_gnss"]["rms"] > 0


def test_replay_with_another_filter_and_truth_scores_and_draws(flight, tmp_path):
    log, truth, _ = flight
    report = tmp_path / "report"
    scored = replay_and_score(log, filter_name="IMM-KF", truth=truth, report_dir=report)
    r = scored.result
    assert not r.same_setup and r.filter == "IMM-KF"
    assert set(r.differences) >= {"f_gnss", "pf_gnss", "f_baro", "x_p_d", "var_theta", "n_eff"}
    for run in ("recorded", "replayed"):
        m = scored.metrics[run]
        assert m["frames"] == 400 and m["frames_unmatched"] == 0
        g = m["faults"]["gnss"]
        assert g["episodes"][0]["onset_s"] == pytest.approx(10.0)
        assert g["delay_s"] is not None and 0.0 <= g["delay_s"] <= 1.0  # +50 m GNSS step: found fast
        assert g["missed_fraction"] < 0.1
        assert 0.0 < g["rmse"] < 15.0
        assert m["faults"]["baro"]["episodes"] == []  # baro fault starts at 20 s: not in this log
        assert m["states"]["theta"]["rmse_deg"] < 2.0
    names = sorted(p.name for p in scored.report_files)
    assert names == ["faults.png", "report.md", "states.png", "summary.json"]
    assert (report / "faults.png").stat().st_size > 20_000
    assert "| replayed | gnss |" in (report / "report.md").read_text()


def test_fdir_replay_cli_reports_identity(flight, capsys):
    log, _, _ = flight
    assert fdir_main(["replay", str(log)]) == 0
    out = capsys.readouterr().out
    assert "bit-identical: 400 estimates" in out and "x real time" in out


def test_sim_bridge_replay_cli_scores_against_the_truth(flight, capsys):
    from sim_bridge.cli import main as sim_main

    log, truth, _ = flight
    assert sim_main(["replay", str(log), "--truth", str(truth)]) == 0
    out = capsys.readouterr().out
    assert "bit-identical: 400 estimates" in out
    assert "replayed gnss: RMSE" in out and "recorded gnss: RMSE" in out


def test_replay_of_a_log_cut_short_by_a_crash(flight, tmp_path):
    log, _, _ = flight
    cut = tmp_path / "cut.mcap"
    data = log.read_bytes()
    cut.write_bytes(data[: len(data) * 6 // 10])
    assert McapLog(cut).mode == "linear"
    r = replay(cut)
    # every input that survived replays to exactly the estimates that survived with it
    assert r.same_setup and r.identity.identical
    assert 150 < r.identity.frames_a == r.identity.frames_b < 400


def test_score_detection_delay_and_false_alarm_fraction():
    t = np.round(np.arange(0, 20, 0.05), 2)
    active = (t >= 10.0) & (t < 15.0)
    p = np.where(t >= 10.3, 0.9, 0.1)
    p[(t >= 10.1) & (t < 10.2)] = 0.8          # a blip shorter than 0.25 s: not a detection
    p[(t >= 3.0) & (t < 4.0)] = 0.7            # 1 s false alarm out of 15 s fault-free
    p[(t >= 16.0)] = 0.1
    est = [{"frame_time_s": float(tk), "x_p_d": -500.0, "f_gnss": 50.0 * a + 1.0, "pf_gnss": float(pk)}
           for tk, a, pk in zip(t, active, p, strict=True)]
    truth = [{"t": float(tk), "p_d": -500.0, "f_gnss": 50.0 * a, "active_gnss": bool(a)}
             for tk, a in zip(t, active, strict=True)]
    m = score(est, truth)["faults"]["gnss"]
    assert m["delay_s"] == pytest.approx(0.3)
    assert m["false_alarm_fraction"] == pytest.approx((20 + 20) / 300)  # 3-4 s and 15-16 s
    assert m["missed_fraction"] == pytest.approx(4 / 100)  # 10.0-10.3 s (6 frames) but the 2 blip frames
    assert m["rmse"] == pytest.approx(1.0)
