"""The public API (docs/api.md) and its runnable example keep working: external scripts use them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "own_frames_and_world.py"


def _example():
    spec = importlib.util.spec_from_file_location("own_frames_and_world", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_estimator_from_files_steps_on_own_frames_and_finds_the_bias(capsys):
    _example().own_frames(seconds=6.0, bias_deg=3.0)
    lines = capsys.readouterr().out.splitlines()
    before = [ln for ln in lines if ln.startswith("t= 4.0")][0]
    after = [ln for ln in lines if ln.startswith("t= 5.2")][0]
    assert "P(theta fault)=0.0" in before
    assert "P(theta fault)=1.00" in after and abs(float(after.split("f_theta=")[1].split()[0]) - 3.0) < 0.5


def test_campaign_with_a_simulator_of_ones_own():
    doc = _example().own_world(runs=1)
    rmse = doc["filters"]["RJMRPF"]["rmse"]["f_theta"]["mean"]
    assert np.isfinite(rmse) and 0.0 < rmse < 5.0


def test_public_names_stay():
    import fdir_service.api as fa
    import sim_bridge.api as sa

    for name in ("build_estimator", "load_estimator", "StepOutput", "FILTER_NAMES", "trim_state"):
        assert hasattr(fa, name)
    for name in ("load_experiment", "run_campaign", "summarise", "simulate", "Trajectory", "run"):
        assert hasattr(sa, name)
