"""The safety yardstick on hand-made P(fault) series with known answers, and its hysteresis against
the service's own Publisher."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import new_mavlink
from fdir_service.runtime.publishing import Publisher
from sim_bridge.report import yardstick_lines, yardstick_markdown
from sim_bridge.yardstick import (
    GRACE_S,
    Hysteresis,
    declared,
    pool,
    rate_upper_bound,
    run_yardstick,
    yardstick,
)
from tests.helpers.experiments import ch4_service

DT = 0.05
RULE = Hysteresis(0.9, 0.2, 0.5, 1.0)


def _t(seconds: float) -> np.ndarray:
    return DT * np.arange(1, int(round(seconds / DT)) + 1)


def test_hysteresis_is_the_services_own_rule():
    assert Hysteresis.of_service() == RULE        # config/service/default.toml [publish.declare]
    cfg = ch4_service()
    rng = np.random.default_rng(0)
    t = _t(150.0)
    for _ in range(5):
        p = np.clip(np.repeat(rng.random(t.size // 10), 10) + 0.05 * rng.standard_normal(t.size), 0, 1)
        pub = Publisher(cfg.publish, cfg.estimator.faults[:1], new_mavlink(1, 191), False)
        ref = []
        for tk, pk in zip(t, p, strict=True):
            out = StepOutput(tk, np.zeros(6), None, ("gnss",), np.zeros(1), np.array([pk]), 100.0, False)
            pub.update_declarations(int(round(tk * 1e6)), out)
            ref.append(pub.hyst[0].declared)
        assert np.array_equal(declared(t, p, RULE), ref)


def test_a_short_blip_is_no_declaration_a_held_excursion_is_one():
    t = _t(20.0)
    p = np.zeros(t.size)
    p[100:103] = 0.95                       # 0.15 s: below the 0.2 s hold
    p[200:206] = 0.95                       # 0.3 s: declared at its 5th frame, cleared 1 s later
    d = declared(t, p, RULE)
    assert not d[:200].any()
    assert np.flatnonzero(d)[0] == 204 and d[204:226].all() and not d[226:].any()


def test_one_false_alarm_in_ten_fault_free_minutes_is_six_per_hour():
    t = _t(600.0)
    p = np.zeros((t.size, 1))
    p[4000:4006, 0] = 0.95
    y = run_yardstick(t, p, ["gnss"], np.zeros((t.size, 1)), ["gnss"], RULE)
    assert y["false_alarms"] == 1 and y["fault_free_s"] == pytest.approx(600.0, abs=0.1)
    pooled = pool([y], ["gnss"])
    assert pooled["false_alarms_per_hour"] == pytest.approx(6.0, rel=1e-3)
    assert pooled["episodes"] == 0 and pooled["detection_fraction"] is None


def test_the_report_says_in_how_many_runs_the_false_alarms_fell():
    t = _t(600.0)
    quiet = np.zeros((t.size, 1))
    p_two, p_one = np.zeros((t.size, 1)), np.zeros((t.size, 1))
    p_two[1000:1006, 0] = p_two[4000:4006, 0] = 0.95     # two declarations in one flight
    p_one[2000:2006, 0] = 0.95
    flights = (p_two, np.zeros((t.size, 1)), p_one)
    runs = [run_yardstick(t, p, ["gnss"], quiet, ["gnss"], RULE) for p in flights]
    pooled = pool(runs, ["gnss"])
    assert (pooled["false_alarms"], pooled["runs_with_false_alarms"], pooled["runs"]) == (3, 2, 3)
    pooled.update(p_declare=0.9)
    lines = yardstick_markdown({"filters": {"RJMRPF": {"yardstick": pooled}}})
    head = next(line for line in lines if line.startswith("| filter"))
    row = next(line for line in lines if line.startswith("| RJMRPF"))
    assert dict(zip(head.split(" | "), row.split(" | "), strict=True))["false alarms"] == "3 (in 2 of 3 runs)"


def test_the_report_prints_the_false_alarm_rates_95_percent_upper_bound():
    # the exact Poisson bounds: 0 in 10 h -> 3.0 / 10 h, 2 in 30 h -> 6.30 / 30 h
    assert rate_upper_bound(0, 10.0) == pytest.approx(0.2996, abs=1e-4)
    assert rate_upper_bound(2, 30.0) == pytest.approx(0.2098, abs=1e-4)
    assert rate_upper_bound(1, 0.0) is None
    # ten hours cannot show 0.1 per hour; thirty fault-free hours with none can
    assert rate_upper_bound(0, 10.0) > 0.1 > rate_upper_bound(0, 30.0)
    y = {"false_alarms": 2, "fault_free_hours": 30.0, "false_alarms_per_hour": 2 / 30.0,
         "detected": 0, "episodes": 0, "delay_s": {"median": None, "p90": None},
         "isolation_accuracy": None, "isolation": {}, "p_declare": 0.9}
    lines = yardstick_markdown({"filters": {"RJMRPF": {"yardstick": y}}})
    head = next(line for line in lines if line.startswith("| filter"))
    row = next(line for line in lines if line.startswith("| RJMRPF"))
    cells = dict(zip(head.split(" | "), row.split(" | "), strict=True))
    assert cells["false alarms / flight hour"] == "0.07" and cells["95 % upper bound"] == "0.21"


def test_each_false_alarm_is_listed_with_its_run_item_time_and_length():
    """The report says which flights cried wolf: run, item, first declared frame, time it stood."""
    from sim_bridge.report import false_alarm_markdown

    t = _t(600.0)
    p = np.zeros((t.size, 2))
    p[4000:4006, 0] = 0.95                  # declared at frame 4004 (0.2 s hold), cleared 1 s after
    p[1000:1100, 1] = 0.95                  # 5 s above: declared from 1004, cleared 1 s after it drops
    quiet = np.zeros((t.size, 2))
    runs = [run_yardstick(t, np.zeros((t.size, 2)), ["gnss", "baro"], quiet, ["gnss"], RULE),
            run_yardstick(t, p, ["gnss", "baro"], quiet, ["gnss"], RULE)]
    y = pool(runs, ["gnss"], [7, 12])
    assert y["false_alarms"] == 2
    assert y["false_alarm_list"] == [
        {"run": 12, "item": "baro", "t_s": pytest.approx(t[1004]), "s": pytest.approx(5.8)},
        {"run": 12, "item": "gnss", "t_s": pytest.approx(t[4004]), "s": pytest.approx(1.1)}]
    text = false_alarm_markdown("RJMRPF", y, {"scenario": "real-calm-faultfree", "seed": 1})[0]
    assert "run 12: baro at 50.2 s (5.8 s); run 12: gnss at 200.2 s (1.1 s)" in text
    assert "false_alarm_runs.py real-calm-faultfree --seed 1 --first R --runs R+1" in text
    assert false_alarm_markdown("RJMRPF", pool(runs[:1], ["gnss"]), {}) == []


def test_detection_delay_isolation_and_the_grace_period():
    """theta injected 30-40 s; theta declared 0.5 s after onset (isolated right); a q declaration
    1 s after the end, cleared 1.5 s later, is inside the grace period (no false alarm); a q
    declaration at 60 s is one;
    an unmonitored elevator fault at 70-80 s gets q declared: mis-isolated."""
    t = _t(100.0)
    world = np.zeros((t.size, 2))
    world[(t >= 30) & (t < 40), 0] = 0.1
    world[(t >= 70) & (t < 80), 1] = 0.05
    p = np.zeros((t.size, 2))                                   # monitored: theta, q
    p[(t >= 30.3) & (t < 40), 0] = 1.0
    p[(t >= 41.0) & (t < 41.5), 1] = 1.0
    p[(t >= 60.0) & (t < 61), 1] = 1.0
    p[(t >= 71.0) & (t < 73), 1] = 1.0
    y = pool([run_yardstick(t, p, ["theta", "q"], world, ["theta", "de"], RULE)], ["theta", "de"])
    assert y["false_alarms"] == 1
    assert y["fault_free_hours"] * 3600 == pytest.approx(100.0 - 20.0 - 2 * GRACE_S, abs=0.2)
    assert y["episodes"] == 2 and y["detected"] == 1 and y["detection_fraction"] == 0.5
    assert y["delay_s"]["median"] == pytest.approx(0.5, abs=1e-9)     # 0.3 s crossing + 0.2 s hold
    assert y["isolation"] == {"theta": {"theta": 1}, "de": {"q": 1}}
    assert y["isolation_accuracy"] == 0.5


def test_a_fault_first_declared_after_it_ended_is_detected_but_not_while_active():
    """theta injected 30-40 s and declared from 41 s (in the grace, the state error a ramp left):
    detected with an 11.2 s delay, not while active; a second episode 60-70 s declared at 61 s is
    both. The report prints the count beside the faults declared."""
    t = _t(100.0)
    world = np.zeros((t.size, 1))
    world[(t >= 30) & (t < 40), 0] = 0.1
    world[(t >= 60) & (t < 70), 0] = 0.1
    p = np.zeros((t.size, 1))
    p[(t >= 41.0) & (t < 42.5), 0] = 1.0
    p[(t >= 61.0) & (t < 70), 0] = 1.0
    y = pool([run_yardstick(t, p, ["theta"], world, ["theta"], RULE)], ["theta"])
    assert y["detected"] == 2 and y["detected_during"] == 1
    assert sorted(y["delay_s"][k] for k in ("median", "max")) == pytest.approx([6.2, 11.2], abs=1e-9)
    assert "faults declared 2 / 2 (1 while active)" in yardstick_lines(y)[0]


@pytest.mark.parametrize("rise_s, during", [(39.75, True), (39.8, False)])
def test_while_active_ends_at_the_episodes_last_active_frame(rise_s: float, during: bool):
    """theta injected 30-40 s (last active frame 39.95 s): P rising at 39.75 s is declared on that
    frame (0.2 s hold), while active; rising at 39.8 s, on the first frame after the end."""
    t = _t(60.0)
    world = np.zeros((t.size, 1))
    world[(t >= 30 - 1e-9) & (t < 40 - 1e-9), 0] = 0.1
    p = np.zeros((t.size, 1))
    p[(t >= rise_s - 1e-9) & (t < 45), 0] = 1.0
    y = pool([run_yardstick(t, p, ["theta"], world, ["theta"], RULE)], ["theta"])
    assert y["detected"] == 1 and y["detected_during"] == int(during)
    assert y["delay_s"]["median"] == pytest.approx(9.95 if during else 10.0, abs=1e-9)


def test_a_yardstick_written_before_the_figure_prints_no_while_active():
    old = {"false_alarms": 0, "fault_free_hours": 1.0, "false_alarms_per_hour": 0.0, "episodes": 2,
           "detected": 2, "delay_s": {"median": 0.5, "p90": 0.5, "max": 0.5, "n": 2}}
    assert "faults declared 2 / 2, median delay 0.50 s" in yardstick_lines(old)[0]
    assert "while active" not in yardstick_lines(old)[0]


def test_roc_trades_false_alarms_for_detections():
    """Noise peaks at 0.75 make false alarms only below p_declare 0.8; a fault at P = 0.85 is found
    only below 0.9."""
    t = _t(600.0)
    world = np.zeros((1, t.size, 1))
    world[0, (t >= 300) & (t < 310), 0] = 1.0
    p = np.zeros((1, t.size, 1))
    for k in range(20):
        p[0, 200 + 500 * k: 210 + 500 * k, 0] = 0.75
    p[0, (t >= 300) & (t < 310), 0] = 0.85
    y = yardstick(t, p, ["f"], world, ["f"], RULE, thresholds=(0.7, 0.8, 0.9))
    roc = {r["p_declare"]: r for r in y["roc"]}
    assert roc[0.7]["false_alarms_per_hour"] > 50 and roc[0.7]["detection_fraction"] == 1.0
    assert roc[0.8]["false_alarms_per_hour"] == 0 and roc[0.8]["detection_fraction"] == 1.0
    assert roc[0.9]["false_alarms_per_hour"] == 0 and roc[0.9]["detection_fraction"] == 0.0
    assert y["detection_fraction"] == 0.0 and y["p_declare"] == 0.9


def test_a_declaration_that_outlives_its_fault_into_fault_free_time_is_a_false_alarm():
    """theta injected 30-40 s; the baro is declared from 35 s (sympathetically) and stays declared
    to 70 s: inside the fault's time it is no false alarm, standing in the fault-free time after
    the grace period it is one, and its 27 s there are falsely declared time."""
    t = _t(100.0)
    world = np.zeros((t.size, 1))
    world[(t >= 30) & (t < 40), 0] = 0.1
    p = np.zeros((t.size, 2))                                   # monitored: theta, baro
    p[(t >= 30.3) & (t < 40), 0] = 1.0
    p[(t >= 35.0) & (t < 70), 1] = 1.0
    y = pool([run_yardstick(t, p, ["theta", "baro"], world, ["theta"], RULE)], ["theta"])
    assert y["false_alarms"] == 1
    assert y["detected"] == 1 and y["isolation_accuracy"] == 1.0
    quiet_s = 100.0 - 10.0 - GRACE_S
    declared_s = 70.0 + 1.0 - (40.0 + GRACE_S)                # cleared 1 s (clear hold) after 70 s
    assert y["falsely_declared_fraction"] == pytest.approx(declared_s / quiet_s, abs=0.01)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_longer_declare_hold_declares_a_subset_later_and_clears_on_the_same_frame(seed: int):
    """benchmarks/declare_hold.py's premise: a longer hold can only take false alarms away."""
    rng = np.random.default_rng(seed)
    t = _t(120.0)
    p = np.clip(0.55 + 0.5 * np.sin(t / 1.3) + rng.normal(0.0, 0.15, t.size), 0.0, 1.0)  # over the band
    short = declared(t, p, RULE)
    assert short.sum() > 40 and (~short).sum() > 40                   # both states visited
    for hold in (0.3, 0.5, 1.0):
        long = declared(t, p, Hysteresis(0.9, hold, 0.5, 1.0))
        assert not (long & ~short).any()                              # a subset of the frames
        ends_short = np.flatnonzero(short[:-1] & ~short[1:])
        ends_long = np.flatnonzero(long[:-1] & ~long[1:])
        assert set(ends_long) <= set(ends_short)                      # each clears where the short one did
    starts = [np.count_nonzero(d[1:] & ~d[:-1]) for d in
              (short, declared(t, p, Hysteresis(0.9, 0.5, 0.5, 1.0)))]
    assert starts[0] > starts[1] > 0                                  # fewer declarations, not none
