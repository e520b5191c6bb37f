"""Two campaigns of the same flights compared flight by flight (`sim_bridge.paired`, `sim-bridge
compare`) on hand-made results with known answers."""

from __future__ import annotations

import json

import pytest

from sim_bridge.cli import main
from sim_bridge.paired import NotPairedError, compare, paired_lines


def _doc(alarms: dict[int, int], runs: int = 20, seed: int = 0) -> dict:
    """A results.json with `alarms[r]` false alarms of 2 s each in run r."""
    fa = [{"run": r, "item": "baro", "t_s": 30.0 + k, "s": 2.0} for r, n in alarms.items() for k in range(n)]
    return {"scenario": "real-drift", "runs": runs, "seed": seed, "navigation": "monitor",
            "filters": {"RJMRPF": {"yardstick": {"false_alarm_list": fa}}}}


def test_false_alarms_moved_to_other_flights_are_no_change():
    c = compare(_doc({0: 1, 1: 1, 2: 1}), _doc({5: 3}), "RJMRPF")
    assert c.total == (3, 3) and c.runs_with == (3, 1) and c.seconds == (6.0, 6.0)
    assert (c.fewer, c.more) == (3, 1) and c.sign_p == pytest.approx(0.625)
    lo, hi = c.change_95
    assert lo < 0 < hi
    assert paired_lines(c)[-1].endswith("within the flights' noise")


def test_false_alarms_gone_from_every_flight_that_had_one_are_a_change():
    c = compare(_doc({r: 1 for r in range(20)}), _doc({}), "RJMRPF")
    assert (c.fewer, c.more) == (20, 0) and c.sign_p < 1e-5
    assert c.change_95 == (-20.0, -20.0)
    assert paired_lines(c)[-1].endswith(": a change")


def test_campaigns_of_other_flights_are_not_paired():
    with pytest.raises(NotPairedError, match="seed"):
        compare(_doc({}), _doc({}, seed=1), "RJMRPF")
    with pytest.raises(ValueError, match="run 25 of a campaign of 20 runs"):
        compare(_doc({25: 1}), _doc({}), "RJMRPF")


def test_the_command_prints_each_filter_and_names_what_is_missing(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "results.json").write_text(json.dumps(_doc({0: 2})))
    (tmp_path / "b.json").write_text(json.dumps(_doc({})))
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    assert "RJMRPF: false alarms 2 -> 0 (in 1 -> 0 of 20 flights" in out
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b.json"), "--filters", "KF"]) == 2
    assert "KF not in both campaigns" in capsys.readouterr().err
