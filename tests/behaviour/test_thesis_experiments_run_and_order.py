"""The thesis campaigns end to end with the real simulator and filters, small: every scenario runs
through `sim-bridge experiment`, results.json has the issue-4 structure, and the thesis's ch4 and
ch5a orderings hold on mean RMSE (fixed seed 0; runs and particles chosen from measurements on
seeds 0-3 so that the ordering is not a coin flip, with the filters of this commit):
- ch5a at 6 runs x 600 particles: RJMRPF < JMRPF < RPF f_theta 0.31 < 0.79 < 1.26 deg (seed 0),
  0.34 < 0.71 < 2.53 (1), 0.34 < 0.72 < 1.03 (2). Fewer particles make JMRPF vs RPF a coin flip.
- ch4 at 6 runs x 1000 particles: JMRPF vs IMM-KF f_gnss 10.0 vs 12.8 m (seed 0), 4.4 (1),
  12.0 (2), 1.4 (3); held on all four. JMRPF's error is heavy-tailed (runs locked in mode 1 stay
  20-30 m off, docs/estimation.md), so at 300 particles it failed on seed 2 with 4 and 8 runs.
"""

import json

import pytest

from sim_bridge.campaign import GATE, run_campaign
from sim_bridge.cli import main as sim_bridge_main
from sim_bridge.report import COLUMNS, check_orderings, summarise
from sim_bridge.scenario import load_scenario

ORDER_SETTINGS = {"ch4": (6, 1000), "ch5a": (6, 600)}   # (runs, particles)
SEED = 0


def _check_structure(doc, scenario):
    assert doc["scenario"] == scenario.id
    assert set(doc["filters"]) == set(scenario.filters) | {GATE}
    faults = [f.id for f in scenario.faults]
    for name, fd in doc["filters"].items():
        assert set(fd["rmse"]) == {"p_d", "u", "w", "theta", "q"} | {f"f_{i}" for i in faults}
        for q, cols in fd["rmse"].items():
            assert set(cols) == set(COLUMNS)
            if name != GATE or not q.startswith("f_"):
                assert all(v is not None and v >= 0 for v in cols.values()), (name, q, cols)
        assert set(fd["detection"]) == set(faults)
        for d in fd["detection"].values():
            assert {"delay_s", "false_alarm_fraction", "missed_fraction"} <= set(d)
            assert 0.0 <= d["false_alarm_fraction"] <= 1.0 and 0.0 <= d["missed_fraction"] <= 1.0
        assert fd["runtime_s"] > 0
        assert fd["failed_runs"] == [], (name, fd["failed_runs"])
    assert all(v["mean"] is None for q, v in doc["filters"][GATE]["rmse"].items() if q.startswith("f_"))


@pytest.mark.slow
@pytest.mark.parametrize("sid", ["ch5b", "ch5c", "ch6"])
def test_experiment_command_writes_results(sid, tmp_path, capsys):
    rc = sim_bridge_main(["experiment", sid, "--runs", "2", "--particles", "200", "--seed", "3",
                          "--workers", "2", "--out", str(tmp_path), "--quiet", "--no-figures"])
    assert rc == 0
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc["runs"] == 2 and doc["particles"] == 200 and doc["seed"] == 3
    _check_structure(doc, load_scenario(sid))
    assert "| mean | thesis mean | ratio |" in (tmp_path / "report.md").read_text()
    out = capsys.readouterr().out
    assert "wall time" in out
    assert out.count("per hour (95 % upper bound") == len(doc["filters"])   # every filter's yardstick
    if sid == "ch6":   # adaptive filters carry Pfa / Pmd
        assert doc["filters"]["AJMRPF"]["detection"]["theta"]["detected_fraction"] is not None


@pytest.mark.slow
@pytest.mark.parametrize("sid", ["ch4", "ch5a"])
def test_thesis_orderings_hold(sid):
    sc = load_scenario(sid)
    runs, particles = ORDER_SETTINGS[sid]
    camp = run_campaign(sc, runs, particles, SEED, workers=2, progress=False)
    doc = summarise(camp)
    _check_structure(doc, sc)
    rows = check_orderings({sid: doc})
    assert rows and all(r["holds"] for r in rows), rows
