"""Crash safety: a real recording subprocess killed with SIGKILL loses at most its last second;
SIGTERM finalises the file; a file cut at any byte reads as a prefix of what was written."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fdir_service.cli import main as fdir_main
from fdir_service.recording import McapLog, Recorder, linear_scan, log_info

DT_NS = 50_000_000
ROOT = Path(__file__).resolve().parents[2]   # the repository: `tests.helpers` imports from here

CHILD = textwrap.dedent("""
    import signal, sys, time
    sys.path.insert(0, {tests!r})
    from pymavlink.dialects.v20 import common as mavlink
    from fdir_service.recording import Recorder
    from tests.helpers.records import frame_bytes, step_output
    stop = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    rec = Recorder({path!r})
    rec.on_metadata("config", {{"filter": "RJMRPF", "seed": "1"}})
    enc = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = mavlink.MAVLink(None)
    for k in range(20000):
        if stop:
            break
        t_ns = k * {dt}
        data = frame_bytes(k, enc)
        rec.on_raw("in", data, t_ns)
        for msg in parser.parse_buffer(data) or []:
            rec.on_message(msg, t_ns)
        rec.on_estimate(k * 0.05, step_output(k), 1e-4, t_ns + 1000)
        rec.on_raw("out", b"\\xfd" + bytes([k % 256]) * 20, t_ns + 2000)
        print(k, flush=True)
        time.sleep(0.0005)
    rec.close()
""")


def run_child(path: Path, sig: int, after_frame: int) -> int:
    """Start a recording child, send `sig` once it has written `after_frame`; returns the last frame
    it reported as written."""
    code = CHILD.format(tests=str(ROOT), path=str(path), dt=DT_NS)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    last = -1
    assert proc.stdout is not None
    for line in proc.stdout:
        last = int(line)
        if last >= after_frame:
            os.kill(proc.pid, sig)
            break
    for line in proc.stdout:  # whatever it printed before it died
        last = int(line)
    proc.wait(timeout=30)
    assert last >= after_frame, "child died before reaching the kill point"
    return last


def frames_by_topic(log: McapLog) -> dict[str, set[int]]:
    out: dict[str, set[int]] = {}
    for _, ch, m in log.iter_messages():
        out.setdefault(ch.topic, set()).add(m.log_time // DT_NS)
    return out


def complete_frames(log: McapLog) -> set[int]:
    by = frames_by_topic(log)
    return (by["/mavlink/raw/in"] & by["/fdir/estimate"] & by["/mavlink/raw/out"]
            & by["/mavlink/1/1/ATTITUDE"] & by["/mavlink/1/1/GPS_RAW_INT"])


def test_sigkill_loses_at_most_the_last_second(tmp_path, capsys):
    broken = tmp_path / "killed.mcap"
    last = run_child(broken, signal.SIGKILL, after_frame=310)

    info = log_info(broken)  # `fdir log info` reads the killed file linearly
    assert info["mode"] == "linear" and not info["finalised"]
    assert info["metadata"]["config"]["filter"] == "RJMRPF"
    frames = complete_frames(McapLog(broken))
    kept = max(frames)
    assert frames == set(range(kept + 1))  # a contiguous prefix: nothing in the middle is lost
    assert kept >= last - 20  # at most 1 s (20 frames at 20 Hz) before the last written frame is lost

    fixed = tmp_path / "fixed.mcap"
    assert fdir_main(["log", "recover", str(broken), str(fixed)]) == 0
    assert "recovered" in capsys.readouterr().out
    with open(fixed, "rb") as f:  # mcap's own reader opens it and finds every schema
        summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        assert all(ch.schema_id in summary.schemas for ch in summary.channels.values())
    log = McapLog(fixed)
    assert log.mode == "indexed" and complete_frames(log) == frames
    assert log.metadata["config"]["seed"] == "1"

    assert fdir_main(["log", "info", str(broken)]) == 0
    text = capsys.readouterr().out
    assert "not finalised" in text and "/fdir/estimate" in text


def test_sigterm_finalises_the_file(tmp_path):
    path = tmp_path / "term.mcap"
    last = run_child(path, signal.SIGTERM, after_frame=60)
    log = McapLog(path)
    assert log.mode == "indexed"  # summary and footer written
    assert complete_frames(log) == set(range(last + 1))  # every frame, none lost


@pytest.mark.parametrize("cut_fraction", [0.13, 0.5, 0.77, 0.97, 0.999])
def test_file_cut_anywhere_reads_as_a_prefix(tmp_path, cut_fraction):
    from tests.helpers.records import record_synthetic

    path = tmp_path / "full.mcap"
    with Recorder(path) as rec:
        record_synthetic(rec, 200)
    full = linear_scan(path)
    assert full.finalised and full.truncated_at is None
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * cut_fraction)])
    part = linear_scan(cut)
    n = len(part.messages)
    assert 0 < n <= len(full.messages)
    # cut inside the data section: truncated; cut inside the summary: all data, just no index
    assert part.finalised == (n == len(full.messages)) and part.finalised == (part.truncated_at is None)
    assert McapLog(cut).mode == "linear" and sum(McapLog(cut).message_counts().values()) == n
    assert [m.data for m in part.messages] == [m.data for m in full.messages[:n]]
