"""`sim-bridge linearize | simulate | bench` run and print what they promise."""

from __future__ import annotations

import json

import numpy as np

from fdir_service.airframe.linearize import PRINTED_B, PRINTED_F
from sim_bridge.cli import main


def test_linearize_json(capsys):
    assert main(["linearize", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    F, B = np.array(doc["F"]), np.array(doc["B"])
    assert F.shape == (5, 5) and B.shape == (5, 2)
    assert np.max(np.abs(F - PRINTED_F)) <= 0.006 and np.max(np.abs(B - PRINTED_B)) <= 0.006
    assert abs(doc["trim"]["u_mps"] - 39.954) < 1e-3 and abs(doc["trim"]["delta_t"] - 0.532) < 1e-3


def test_linearize_table_and_other_trim(capsys):
    assert main(["linearize"]) == 0
    out = capsys.readouterr().out
    assert "derived - printed" in out and "largest |derived - printed| = 0.005" in out
    assert main(["linearize", "--airspeed", "30", "--dt", "0.02", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["trim"]["airspeed_mps"] == 30.0 and doc["trim"]["alpha_deg"] > 5.0


def test_simulate_summary_and_plot(tmp_path, capsys):
    png = tmp_path / "ch5c.png"
    assert main(["simulate", "ch5c", "--seconds", "25", "--seed", "2", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "altitude" in out and "fault de" in out and "10.00- 30.00 s" in out
    assert png.stat().st_size > 20_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_bad_scenario_is_a_config_error(capsys):
    assert main(["simulate", "no_such_scenario"]) == 2
    assert "no such experiment file" in capsys.readouterr().err


def test_bench_prints_per_step_time(capsys):
    assert main(["bench", "--seconds", "1", "--repeat", "1"]) == 0
    out = capsys.readouterr().out
    assert "linear truth" in out and "nonlinear truth" in out and "per step (us)" in out
