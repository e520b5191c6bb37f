"""The per-fault-type yardstick (issue 17) on hand-made P(fault) series, estimates and world
activity with known answers: right and wrong type, wrong item, missed, a blocked pitot, the
confusion table, the magnitude error, activity from the profile's intervals, the report's table."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from sim_bridge.report import by_type_lines, by_type_markdown, yardstick_markdown
from sim_bridge.scenario import ProfileComponent
from sim_bridge.type_yardstick import (
    Kind,
    WorldFault,
    channel_active,
    is_typed,
    item_type_matches,
    pool_by_type,
    scenario_yardsticks,
    truth_columns,
    typed_run,
    world_fault,
)
from sim_bridge.yardstick import Hysteresis, pool, run_yardstick

DT = 0.05
RULE = Hysteresis(0.9, 0.2, 0.5, 1.0)
ENTRIES = [Kind("baro_alt", "bias"), Kind("baro_alt", "stuck"), Kind("baro_alt", "noisy"),
           Kind("theta", "bias"), Kind("airspeed", "stuck")]
NAMES = ["baro", "baro_st", "baro_nz", "theta", "as_st"]
BARO_STUCK = WorldFault(Kind("baro_alt", "stuck"), "m", 1.0)
T = DT * np.arange(1, int(round(60.0 / DT)) + 1)


def _between(a: float, b: float) -> np.ndarray:
    return (T >= a - 1e-9) & (T < b - 1e-9)


def _one(fault: WorldFault, declare: dict[int, float], f_hat: np.ndarray | None = None,
         truth: np.ndarray | None = None) -> dict:
    """The single episode of `fault` active 10-20 s; entry j's P is 1 from declare[j] s to 20 s."""
    prob = np.zeros((T.size, len(ENTRIES)))
    for j, at in declare.items():
        prob[_between(at, 20.0), j] = 1.0
    active = _between(10.0, 20.0)[:, None]
    f_hat = np.zeros((T.size, len(ENTRIES))) if f_hat is None else f_hat
    truth = np.zeros((T.size, 1)) if truth is None else truth
    (ep,) = typed_run(T, prob, f_hat, ENTRIES, NAMES, [fault], truth, active, RULE)
    return ep


def test_the_right_type_declared_is_detected_and_right():
    ep = _one(BARO_STUCK, {1: 10.5})
    assert ep["detected"] and ep["delay_s"] == pytest.approx(0.7, abs=1e-9)   # 0.5 s + 0.2 s hold
    assert ep["declared"] == "baro_alt:stuck" and ep["right"] and ep["right_item"]


def test_the_wrong_type_first_is_detected_on_its_item_but_not_right():
    ep = _one(BARO_STUCK, {0: 11.0, 1: 12.0})                  # the bias entry first, stuck later
    assert ep["detected"] and ep["delay_s"] == pytest.approx(1.2, abs=1e-9)
    assert ep["declared"] == "baro_alt:bias" and not ep["right"] and ep["right_item"]


def test_a_declaration_after_the_end_is_detected_but_not_while_active():
    assert _one(BARO_STUCK, {1: 10.5})["during"]
    prob = np.zeros((T.size, len(ENTRIES)))
    prob[_between(21.0, 22.5), 1] = 1.0                       # declared 1 s after the 10-20 s episode
    (ep,) = typed_run(T, prob, np.zeros_like(prob), ENTRIES, NAMES, [BARO_STUCK], np.zeros((T.size, 1)),
                      _between(10.0, 20.0)[:, None], RULE)
    assert ep["detected"] and not ep["during"] and ep["delay_s"] == pytest.approx(11.2, abs=1e-9)
    row = pool_by_type([ep])["types"]["stuck"]
    assert row["detected"] == 1 and row["detected_during"] == 0


def test_a_ramp_is_timed_from_the_onset_and_from_where_it_stood_3_sigma_out():
    ramp = np.where(_between(10.0, 20.0), 0.5 * (T - 10.0), 0.0)[:, None]      # 0.5 m/s from 10 s
    drift = WorldFault(Kind("baro_alt", "drift"), "m", 1.0, three_sigma=3.0)   # 3 sigma at 16 s
    ep = _one(drift, {0: 16.5}, truth=ramp)
    assert ep["delay_s"] == pytest.approx(6.7, abs=1e-9)                         # 6.5 s + 0.2 s hold
    assert ep["delay_3sigma_s"] == pytest.approx(0.7, abs=0.06)
    assert _one(drift, {0: 12.0}, truth=ramp)["delay_3sigma_s"] == 0.0          # declared before
    assert _one(drift._replace(three_sigma=9.0), {0: 12.0}, truth=ramp)["delay_3sigma_s"] is None
    assert _one(drift._replace(three_sigma=0.0), {0: 12.0}, truth=ramp)["delay_3sigma_s"] == \
        pytest.approx(2.2, abs=1e-9)                                              # 0: from the onset
    row = pool_by_type([ep])["types"]["drift"]
    assert row["delay_3sigma_s"]["median"] == pytest.approx(0.7, abs=0.06)
    line = next(ln for ln in by_type_markdown([("RJMRPF", {"false_alarms_per_hour": 0.0,
                                                            "by_type": pool_by_type([ep])})])
                if ln.startswith("| RJMRPF"))
    assert "| 6.70 (missed) | 6.70 | 0.70 |" in line


def test_a_sensor_fault_stands_out_at_3_sigma_of_the_worlds_row():
    ch = SimpleNamespace(target="baro_alt", fault_type="drift", unit="m", unit_scale=1.0)
    assert world_fault(ch, {"baro_alt": 1.0, "theta": 0.01}).three_sigma == 3.0
    assert world_fault(ch).three_sigma == 0.0
    jam = SimpleNamespace(target="delta_e", fault_type="jammed", unit="deg", unit_scale=0.0174533)
    assert world_fault(jam, {"baro_alt": 1.0}).three_sigma == 0.0


def test_another_item_declared_is_not_detected_and_the_wrong_item():
    ep = _one(BARO_STUCK, {3: 11.0})
    assert not ep["detected"] and ep["delay_s"] is None
    assert ep["declared"] == "theta:bias" and not ep["right"] and not ep["right_item"]


def test_nothing_declared_is_missed():
    ep = _one(BARO_STUCK, {})
    assert not ep["detected"] and ep["declared"] == "missed" and not ep["right"] and not ep["right_item"]


def test_a_blocked_pitot_is_answered_by_the_stuck_airspeed_entry():
    blocked = WorldFault(Kind("airspeed", "blocked"), "m/s", 1.0)
    assert item_type_matches(ENTRIES, [blocked.kind, BARO_STUCK.kind]) == [[4], [1]]
    ep = _one(blocked, {4: 10.0})
    assert ep["right"] and ep["declared"] == "airspeed:stuck"
    assert ep["delay_s"] == pytest.approx(0.2, abs=1e-9)


def test_an_engine_loss_is_answered_by_the_engine_entry_or_where_there_is_none_by_the_lost_gain():
    engine = Kind("delta_t", "engine")
    bias, weak, dead = Kind("delta_t", "bias"), Kind("delta_t", "effectiveness"), Kind("delta_t", "engine")
    assert item_type_matches([bias, weak, dead], [engine]) == [[2]]
    assert item_type_matches([bias, weak], [engine]) == [[1]]
    assert item_type_matches([bias], [engine]) == [[]]


def test_the_magnitude_error_is_the_right_entrys_over_the_active_frames_in_the_faults_unit():
    deg = math.pi / 180.0
    fault = WorldFault(Kind("baro_alt", "stuck"), "deg", deg)   # any unit: SI / scale
    truth = np.where(_between(10.0, 20.0), 5 * deg, 0.0)[:, None]
    f_hat = np.zeros((T.size, len(ENTRIES)))
    f_hat[:, 1] = truth[:, 0] + 0.5 * deg                       # right entry: 0.5 deg off throughout
    f_hat[:, 0] = 100.0                                         # the bias entry: never used
    ep = _one(fault, {0: 11.0}, f_hat, truth)                   # even when the wrong type is declared
    assert ep["n"] == 200 and math.sqrt(ep["sq_err"] / ep["n"]) == pytest.approx(0.5, rel=1e-9)
    row = pool_by_type([ep])["types"]["stuck"]
    assert row["magnitude_rmse"] == {"deg": pytest.approx(0.5, rel=1e-9)}


def test_an_unmonitored_type_has_no_magnitude():
    ep = _one(WorldFault(Kind("theta", "stuck"), "deg", 1.0), {3: 10.5})
    assert ep["n"] == 0 and ep["declared"] == "theta:bias" and ep["right_item"] and not ep["right"]
    assert pool_by_type([ep])["types"]["stuck"]["magnitude_rmse"] == {}


def test_pooling_per_type_counts_the_confusion_table():
    eps = [_one(BARO_STUCK, {1: 10.5}), _one(BARO_STUCK, {1: 10.0}), _one(BARO_STUCK, {0: 11.0}),
           _one(BARO_STUCK, {}), _one(WorldFault(Kind("baro_alt", "noisy"), "-", 1.0), {3: 12.0})]
    y = pool_by_type(eps)
    assert y["confusion"] == {"baro_alt:stuck": {"baro_alt:stuck": 2, "baro_alt:bias": 1, "missed": 1},
                              "baro_alt:noisy": {"theta:bias": 1}}
    st = y["types"]["stuck"]
    assert st["episodes"] == 4 and st["detected"] == 3 and st["detection_fraction"] == 0.75
    assert st["right_fraction"] == 0.5 and st["right_item_fraction"] == 0.75
    assert st["delay_s"]["median"] == pytest.approx(0.7, abs=1e-9)          # of 0.2, 0.7, 1.2
    nz = y["types"]["noisy"]
    assert nz["detection_fraction"] == 0.0 and nz["right_fraction"] == 0.0 and nz["delay_s"]["median"] is None


def test_activity_comes_from_the_profiles_intervals_not_the_value():
    comps = (ProfileComponent("step", 10.0, 20.0, 0.0),                     # value 0 while active
             ProfileComponent("intermittent", 30.0, 40.0, 1.0, on_s=2.0, off_s=3.0))
    ch = SimpleNamespace(id="nz", target="baro_alt", kind="sensor", unit="m", unit_scale=1.0,
                         fault_type="noisy", profile=comps)
    act = channel_active(ch, T)
    assert np.array_equal(act, _between(10, 20) | _between(30, 32) | _between(35, 37))
    assert world_fault(ch) == WorldFault(Kind("baro_alt", "noisy"), "-", 1.0)
    # the strict yardstick with that activity: the episode counts although the value is 0
    prob = np.zeros((T.size, len(ENTRIES)))
    prob[_between(10.5, 20.0), 2] = 1.0
    y = pool([run_yardstick(T, prob, NAMES, np.zeros((T.size, 1)), ["nz"], RULE, right=[[2]],
                            world_active=_between(10, 20)[:, None])], ["nz"])
    assert y["episodes"] == 1 and y["detected"] == 1 and y["false_alarms"] == 0
    assert y["isolation"] == {"nz": {"baro_nz": 1}} and y["isolation_accuracy"] == 1.0


def _scenario() -> SimpleNamespace:
    """A typed world (stuck baro 10-20 s) on the catalogue-like entries, as the report sees it."""
    est = tuple(SimpleNamespace(id=n, target=k.target, fault_type=k.type) for n, k in zip(NAMES, ENTRIES,
                                                                                           strict=True))
    ch = SimpleNamespace(id="baro_stuck", target="baro_alt", kind="sensor", unit="m", unit_scale=1.0,
                         fault_type="stuck", profile=(ProfileComponent("step", 10.0, 20.0, 3.0),))
    return SimpleNamespace(estimator=SimpleNamespace(faults=est), faults=(ch,))


def test_a_typed_world_is_scored_by_item_and_type_and_reported_per_type():
    sc = _scenario()
    assert is_typed(sc.faults) and not is_typed([SimpleNamespace(target="theta")])
    prob = np.zeros((2, T.size, len(ENTRIES)))
    prob[0, _between(10.5, 20.0), 1] = 1.0                     # run 0: stuck entry, right
    prob[1, _between(11.0, 20.0), 0] = 1.0                     # run 1: bias entry, wrong type
    f_hat = np.zeros_like(prob)
    f_hat[:, :, 1] = np.where(_between(10.0, 20.0), 2.0, 0.0)  # 1 m below the truth of 3 m
    world = np.where(_between(10.0, 20.0), 3.0, 0.0)[None, :, None].repeat(2, axis=0)
    matching, by_type = scenario_yardsticks(sc, T, prob, f_hat, world, np.array([1, 2]))
    assert matching["right"] == [[0]] and matching["fault_ids"] == ["baro", "theta", "as_st"]   # items
    assert matching["world_active"].shape == (2, T.size, 1) and matching["prob"].shape == (2, T.size, 3)
    st = by_type["types"]["stuck"]
    assert st["detection_fraction"] == 1.0 and st["right_fraction"] == 0.5
    assert st["right_settled_fraction"] == 0.5                  # run 1 still says bias 2 s later
    assert st["magnitude_rmse"] == {"m": pytest.approx(1.0)}
    y = {"false_alarms_per_hour": 0.0, "by_type": by_type}
    md = "\n".join(by_type_markdown([("RJMRPF", y)]))
    assert "## Per fault type" in md and "(goal >= 95%)" in md and "(goal <= 2 s)" in md
    assert "| RJMRPF | stuck | 2 | 1.00 (met) (2 while active) | 0.95 (met) |" in md
    assert "0.50 (missed)" in md
    assert "| baro_alt:stuck | 1 | 1 | 0 |" in md                # columns: bias, stuck, missed
    assert by_type_lines(y) == ["stuck: detected 1.00 (met) of 2 (2 while active), median delay 0.95 s "
                                "(met), right item and type 0.50 (missed)"]


def test_a_bias_only_world_has_no_per_type_section():
    y = {"false_alarms_per_hour": 0.0, "false_alarms": 0, "fault_free_hours": 1.0, "detected": 0,
         "episodes": 0, "delay_s": {"median": None, "p90": None}, "isolation_accuracy": None,
         "isolation": {}, "p_declare": 0.9}
    assert by_type_markdown([("RJMRPF", y)]) == [] and by_type_lines(y) == []
    assert "Per fault type" not in "\n".join(yardstick_markdown({"filters": {"RJMRPF": {"yardstick": y}}}))


def test_the_estimators_truth_comes_by_id_in_a_bias_world_and_by_item_and_type_in_a_typed_one():
    est = _scenario().estimator.faults                         # baro, baro_st, baro_nz, theta, as_st
    bias = [SimpleNamespace(id="theta", target="theta"), SimpleNamespace(id="gnss", target="gnss_alt")]
    assert truth_columns(est, bias) == [None, None, None, 0, None]
    typed = [SimpleNamespace(id="th", target="theta", fault_type="bias"),
             SimpleNamespace(id="pitot", target="airspeed", fault_type="blocked"),
             SimpleNamespace(id="b", target="baro_alt", fault_type="stuck")]
    assert truth_columns(est, typed) == [None, 2, None, 0, 1]


def test_a_declaration_whose_type_settles_within_2_s_is_right_2_s_later():
    sc = _scenario()
    prob = np.zeros((1, T.size, len(ENTRIES)))
    prob[0, _between(10.5, 12.0), 0] = 1.0                     # first called biased (named at 11.5 s) ...
    prob[0, _between(12.0, 20.0), 1] = 1.0                     # ... stuck from 12 s
    _, by_type = scenario_yardsticks(sc, T, prob, np.zeros_like(prob),
                                     np.where(_between(10.0, 20.0), 3.0, 0.0)[None, :, None], np.array([1]))
    st = by_type["types"]["stuck"]
    assert st["right_fraction"] == 0.0 and st["right_settled_fraction"] == 1.0


def test_a_typed_estimators_fault_free_flight_is_scored_by_item_as_the_service_declares():
    from sim_bridge.report import _yardstick

    sc = _scenario()
    sc.faults = ()                                             # a fault-free world
    prob = np.zeros((1, T.size, len(ENTRIES)))
    prob[0, _between(30.0, 40.0), 0] = 0.5                     # the barometer's bias and stuck entries
    prob[0, _between(30.0, 40.0), 1] = 0.45                    # share P(item) = 0.95: one item declared
    fr = SimpleNamespace(t=T, prob=prob, f_hat=np.zeros_like(prob), world_faults=np.zeros((1, T.size, 0)),
                         world_active=None, sim_seeds=np.array([1]))
    y = _yardstick(SimpleNamespace(scenario=sc), fr)
    assert y["false_alarms"] == 1                              # per entry (0.5, 0.45) it was 0


def _split(shares: list[tuple[float, float, dict[int, float]]]) -> dict:
    """The single baro stuck episode (10-20 s) with P per entry given by stretches (from, to, {j: p})."""
    prob = np.zeros((T.size, len(ENTRIES)))
    for a, b, ps in shares:
        for j, p in ps.items():
            prob[_between(a, b), j] = p
    (ep,) = typed_run(T, prob, np.zeros_like(prob), ENTRIES, NAMES, [BARO_STUCK], np.zeros((T.size, 1)),
                      _between(10.0, 20.0)[:, None], RULE)
    return ep


def test_a_type_is_named_once_it_holds_its_share_and_the_name_is_what_is_scored():
    ep = _split([(10.5, 12.0, {0: 0.5, 1: 0.45}), (12.0, 20.0, {0: 0.03, 1: 0.95})])
    assert ep["detected"] and ep["delay_s"] == pytest.approx(0.7, abs=1e-9)   # declared on P(item) 0.95
    assert ep["declared"] == "baro_alt:stuck" and ep["right"] and not ep["right_probable"]
    assert ep["named_s"] == pytest.approx(12.2 - 10.7, abs=1e-9)              # the share held 0.2 s


def test_a_declaration_whose_type_never_holds_its_share_stays_unclear():
    ep = _split([(10.5, 20.0, {0: 0.5, 1: 0.45})])
    assert ep["detected"] and ep["declared"] == "baro_alt:unclear" and ep["named_s"] is None
    assert not ep["right"] and not ep["right_probable"] and ep["right_item"]


def test_with_p_type_0_and_no_hold_the_most_probable_type_at_the_declaration_is_named():
    rule = Hysteresis(0.9, 0.2, 0.5, 1.0, p_type=0.0, type_hold_s=0.0)
    prob = np.zeros((T.size, len(ENTRIES)))
    prob[_between(10.5, 20.0), 0], prob[_between(10.5, 20.0), 1] = 0.5, 0.45
    (ep,) = typed_run(T, prob, np.zeros_like(prob), ENTRIES, NAMES, [BARO_STUCK], np.zeros((T.size, 1)),
                      _between(10.0, 20.0)[:, None], rule)
    assert ep["declared"] == "baro_alt:bias" and ep["named_s"] == 0.0 and not ep["right"]


def test_a_type_that_leads_for_less_than_the_hold_is_not_named():
    held = Hysteresis(0.9, 0.2, 0.5, 1.0, type_hold_s=0.5)
    prob = np.zeros((T.size, len(ENTRIES)))
    prob[_between(10.5, 10.9), 0], prob[_between(10.9, 20.0), 1] = 0.95, 0.95   # offset 0.4 s, then stuck
    (ep,) = typed_run(T, prob, np.zeros_like(prob), ENTRIES, NAMES, [BARO_STUCK], np.zeros((T.size, 1)),
                      _between(10.0, 20.0)[:, None], held)
    assert ep["declared"] == "baro_alt:stuck" and ep["right"] and not ep["right_probable"]
    assert ep["named_s"] == pytest.approx(11.4 - 10.7, abs=1e-9)
    ep = _split([(10.5, 10.9, {0: 0.95}), (10.9, 20.0, {1: 0.95})])          # no hold: the offset is named
    assert ep["declared"] == "baro_alt:bias" and not ep["right"]
