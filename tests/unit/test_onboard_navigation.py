"""The autopilot's own navigation (`sim_bridge.onboard_nav`): what each sensor fault moves, how a
world asks for it, and what a report says the autopilot flew on."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.tomltable import load_toml
from sim_bridge.onboard_nav import OnboardNavigation
from sim_bridge.report import FLIES_ON
from sim_bridge.scenario import FaultChannel, load_scenario, parse_scenario, scenario_path
from sim_bridge.simulate import Frame


def _channel(fid: str, target: str, kind: str = "sensor", fault_type: str = "bias") -> FaultChannel:
    return FaultChannel(id=fid, target=target, kind=kind, unit="m", profile=(), fault_type=fault_type)


CHANNELS = (_channel("gnss", "gnss_alt"), _channel("baro", "baro_alt"), _channel("th", "theta"),
            _channel("q", "q", fault_type="stuck"), _channel("pitot", "airspeed", fault_type="blocked"),
            _channel("nz", "w", fault_type="noisy"), _channel("de", "delta_e", "actuator", "jammed"),
            _channel("u", "u"))


def _frame(faults, wind=None) -> Frame:
    z = np.array([-500.0, 40.0, 2.0, 0.05, 0.01])
    return Frame(t=1.0, y=np.zeros(3), mask=np.ones(3, bool), static_pressure_pa=95000.0, z_true=z,
                 faults=np.asarray(faults, float), u_applied=np.zeros(2), wind_body=wind)


def test_each_sensor_fault_moves_the_state_its_row_measures():
    nav = OnboardNavigation(CHANNELS)
    # gnss 7 m, baro +3 m, theta +0.02 rad, q stuck 0.1 rad/s off, pitot +2 m/s, noisy w k-1 = 4,
    # jammed elevator NaN (its command not known yet), u +0.5 m/s
    z = nav.view(_frame([7.0, 3.0, 0.02, 0.1, 2.0, 4.0, np.nan, 0.5]))
    assert z == pytest.approx([-503.0, 40.0 + 2.0 + 0.5, 2.0, 0.07, 0.11])
    assert np.isfinite(z).all()


def test_without_faults_the_autopilot_flies_on_the_truth_made_air_relative():
    nav = OnboardNavigation(CHANNELS)
    fr = _frame(np.zeros(len(CHANNELS)), wind=np.array([-5.0, 0.5]))
    assert nav.view(fr) == pytest.approx(fr.autopilot_view(fr.z_true))
    assert nav.view(fr)[1] == pytest.approx(45.0)      # a 5 m/s head wind: 45 m/s through the air


def test_a_world_asks_for_onboard_navigation_and_a_bad_value_names_the_key():
    assert load_scenario("real-actuators").navigation == "monitor"
    doc = load_toml(scenario_path("real-actuators"), "experiment file")
    on = copy.deepcopy(doc)
    on["world"]["autopilot"] = {"navigation": "onboard"}
    assert parse_scenario(on).navigation == "onboard"
    bad = copy.deepcopy(doc)
    bad["world"]["autopilot"] = {"navigation": "ekf"}
    with pytest.raises(ConfigError, match=r"world\.autopilot\.navigation.*monitor.*onboard"):
        parse_scenario(bad)


def test_a_report_says_what_the_autopilot_flew_on():
    assert "own estimate" in FLIES_ON["monitor"]
    assert "own navigation" in FLIES_ON["onboard"] and "only watch" in FLIES_ON["onboard"]
    assert "true state" in FLIES_ON["truth"] and "only watch" in FLIES_ON["truth"]


def test_a_false_alarm_is_flown_again_on_the_campaign_s_navigation():
    from sim_bridge.report import false_alarm_markdown

    y = {"false_alarm_list": [{"run": 3, "item": "baro", "t_s": 28.2, "s": 3.5}]}
    doc = {"scenario": "real-actuators", "seed": 1}
    assert "--seed 1 --first R" in false_alarm_markdown("RJMRPF", y, doc)[0]      # before the record
    monitor = false_alarm_markdown("RJMRPF", y, {**doc, "navigation": "monitor"})[0]
    assert "--seed 1 --navigation monitor --first R" in monitor
    onboard = false_alarm_markdown("RJMRPF", y, {**doc, "navigation": "onboard"})[0]
    assert "false_alarm_runs.py real-actuators --seed 1 --navigation onboard --first R" in onboard


def test_a_report_flown_off_the_monitor_drops_the_closed_loop_note():
    from sim_bridge.report import READING_NOTES, reading_notes_for

    assert reading_notes_for({}) == READING_NOTES == reading_notes_for({"navigation": "monitor"})
    truth = reading_notes_for({"navigation": "truth"})
    assert len(truth) == len(READING_NOTES) - 1 and not any(n.startswith("Closed loop") for n in truth)
