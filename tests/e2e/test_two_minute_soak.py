"""The two-minute soak (issue 7): memory growth and recorded == sent; the hour is benchmarks/soak.py."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def load_soak():
    spec = importlib.util.spec_from_file_location("soak", ROOT / "benchmarks" / "soak.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["soak"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_two_minute_soak_keeps_memory_flat_and_records_every_frame(tmp_path):
    soak = load_soak()
    r = soak.soak(2400, "RJMRPF", 200, tmp_path, window=600)
    assert r.frames_sent == r.frames_stepped == r.frames_recorded == 2400
    assert r.growth_mb < 20.0, r
    assert r.rejected == {}
