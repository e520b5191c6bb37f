"""Logs recorded before the estimator files (service + scenario TOML in their metadata) still
open and replay bit for bit: `tests/data/legacy-scenario-ch4.mcap` was recorded by fdir-service
0.1 (main at 9682b4f): ch4 for 5 s, JMRPF, N = 200, seed 3."""

from __future__ import annotations

from pathlib import Path

from fdir_service.cli import main as fdir_main
from fdir_service.recording.legacy import estimator_from_scenario
from fdir_service.replay import replay
from sim_bridge.scenario import load_scenario, scenario_path

LEGACY = Path(__file__).resolve().parents[1] / "data" / "legacy-scenario-ch4.mcap"


def test_legacy_log_opens_with_log_info(capsys):
    assert fdir_main(["log", "info", str(LEGACY)]) == 0
    out = capsys.readouterr().out
    assert "/fdir/estimate                            100" in out and "scenario = ch4" in out


def test_legacy_log_replays_to_the_last_bits_of_another_machine(tmp_path):
    """Recorded on another machine: OpenBLAS picks its kernels by CPU, so reductions may differ in
    their last bits (~1e-13 here) across machines; on one machine a replay is bit for bit
    (tests/e2e: record then replay). Everything the filter said agrees to 1e-9."""
    from fdir_service.recording.logtools import McapLog
    from fdir_service.replay import estimate_differences, estimates

    r = replay(LEGACY, out=tmp_path / "again.mcap")
    assert r.same_setup and r.frames == 100
    diff = estimate_differences(estimates(McapLog(LEGACY)), estimates(McapLog(tmp_path / "again.mcap")))
    worst = max((v["max_abs"] or 0.0) for v in diff.values())
    assert len(diff) > 10 and worst < 1e-9, f"replay differs by {worst:g}"


def test_legacy_conversion_gives_the_experiment_estimator():
    """The old ch4 scenario's estimator settings convert to the estimator of today's ch4 experiment."""
    import tomllib

    from fdir_service.estimator_config import parse_estimator

    old = {"scenario": {"id": "ch4", "dt_s": 0.05}, "truth": {"airspeed_mps": 40.0, "altitude_m": 500.0},
           "sensors": {"measurements": ["gnss_alt", "baro_alt"], "sigma": {"gnss_alt": 5.0, "baro_alt": 1.0},
                       "filter_noise_factor": 1.5},
           "faults": [{"id": "gnss", "target": "gnss_alt", "unit": "m", "sigma_f": 0.08,
                       "amplitude_max": 500.0,
                       "profile": [{"shape": "step", "start_s": 10.0, "end_s": 30.0, "amplitude": 50.0}]}],
           "estimator": {"filters": ["JMRPF"], "proposed": "JMRPF", "sigma_x": [1.0, 0.1, 0.1, 0.02, 0.002],
                         "x0_sigma": [1.0, 1.0, 1.0, 0.04, 0.01], "sentinel_weighting": "prior"}}
    est = parse_estimator(estimator_from_scenario(old))
    assert est.sigma == (7.5, 1.5) and est.filter == "JMRPF" and est.faults[0].amplitude_max == 500.0
    assert (est.settings.linear_matrices, est.settings.jitter, est.settings.sigma_x_basis) == (
        "printed", "global", "step")                    # the old schema's defaults, not today's
    assert tomllib.loads(scenario_path("ch4").read_text())["experiment"]["id"] == "ch4"
    assert load_scenario("ch4").estimator.settings.linear_matrices == "printed"
