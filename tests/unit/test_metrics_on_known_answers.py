"""SPEC section 8 metrics (sim_bridge.metrics, shared by the campaigns and the replay scorer) on
hand-made data with known answers."""

import numpy as np
import pytest

from sim_bridge.metrics import (
    detection_metrics,
    fault_episodes,
    held_above,
    median_run,
    rmse_over_runs,
    table_columns,
)

T = np.arange(1, 1001) * 0.05  # 0.05 .. 50 s, as the campaigns record it


def test_rmse_over_runs_matches_hand_computation_and_skips_nan():
    truth = np.zeros((3, 4))
    est = np.array([[1.0, 2, 0, 3], [1, -2, 0, np.nan], [1, 2, 3, np.nan]])
    r = rmse_over_runs(est, truth)
    np.testing.assert_allclose(r, [1.0, 2.0, np.sqrt(3.0), 3.0])
    assert np.isnan(rmse_over_runs(np.full((2, 1), np.nan), np.zeros((2, 1))))[0]


def test_table_columns_pick_the_thesis_instants_and_time_mean():
    rmse_k = T.copy()  # RMSE equal to time: the column at 20.05 s must read 20.05
    cols = table_columns(rmse_k, T)
    assert set(cols) == {"10.05", "20.05", "30.05", "40.05", "mean"}
    assert cols["10.05"] == pytest.approx(10.05)
    assert cols["40.05"] == pytest.approx(40.05)
    assert cols["mean"] == pytest.approx(np.mean(T))


def test_median_run_standardises_faults_and_takes_rank_floor_half():
    # fault 0 errors on a scale of metres, fault 1 on a scale of millimetres: standardisation must
    # make both count equally. Run scores (z-averaged) are ordered 2 < 0 < 4 < 1 < 3.
    s0 = np.array([2.0, 8.0, 0.0, 10.0, 5.0])
    s1 = np.array([0.002, 0.008, 0.0, 0.010, 0.005]) * 1e-3
    e = np.stack([np.repeat(s0[:, None], 10, 1), np.repeat(s1[:, None], 10, 1)], axis=-1)
    # floor(5/2 + 1/2) = 3rd smallest -> run 4 (score 5)
    assert median_run(e) == 4
    # even count: floor(4/2 + 1/2) = 2nd smallest
    assert median_run(e[[0, 1, 2, 3]]) == 0
    assert median_run(e[:1]) == 0


def test_median_run_ignores_a_fault_with_constant_scores():
    e = np.zeros((3, 5, 2))
    e[:, :, 0] = np.array([3.0, 1.0, 2.0])[:, None]
    assert median_run(e) == 2


def test_fault_episodes_and_hold():
    a = np.array([0, 1, 1, 0, 0, 1, 1, 1], bool)
    assert fault_episodes(a) == [(1, 3), (5, 8)]
    p = np.array([0.9, 0.9, 0.2, 0.9, 0.9, 0.9, 0.9])
    np.testing.assert_array_equal(held_above(p, 3), [0, 0, 0, 1, 1, 0, 0])


def test_detection_metrics_on_a_synthetic_detector():
    # truth: fault on 10-30 s; run 0 detects 0.5 s late and has a 1 s false alarm at 40 s,
    # run 1 detects 1.0 s late but flickers: a 0.1 s blip at 10.2 s must not count (hold 0.25 s).
    truth = np.where((T >= 10.0) & (T < 30.0), 50.0, 0.0)
    truth = np.stack([truth, truth])
    p = np.zeros((2, T.size))
    p[0, (T >= 10.5) & (T < 30.0)] = 0.99
    p[0, (T >= 40.0) & (T < 41.0)] = 0.99
    p[1, (T >= 10.2) & (T < 10.3)] = 0.99
    p[1, (T >= 11.0) & (T < 30.0)] = 0.99
    m = detection_metrics(T, p, truth, hold_s=0.25)
    assert m["delay_s"] == pytest.approx((0.5 + 1.0) / 2, abs=1e-9)
    assert m["detected_fraction"] == 1.0
    n_free = np.sum(truth == 0)
    assert m["false_alarm_fraction"] == pytest.approx(20 / n_free)
    n_faulty = np.sum(truth != 0)
    assert m["missed_fraction"] == pytest.approx((10 + 18) / n_faulty)


def test_detection_metrics_counts_a_missed_episode():
    truth = np.where((T >= 10.0) & (T < 20.0), 1.0, 0.0)[None, :].repeat(2, 0)
    p = np.zeros_like(truth)
    p[0, (T >= 12.0) & (T < 20.0)] = 1.0
    m = detection_metrics(T, p, truth)
    assert m["detected_fraction"] == 0.5
    assert m["delay_s"] == pytest.approx(2.0)
    assert m["false_alarm_fraction"] == 0.0


def test_single_run_helpers():
    from sim_bridge.metrics import episode_delays, false_alarm_fraction, missed_fraction, rmse

    assert rmse([1.0, -1.0, np.nan, 3.0], [0.0, 0.0, 0.0, 0.0]) == pytest.approx(np.sqrt(11 / 3))
    assert np.isnan(rmse([np.nan], [0.0]))
    active = (T >= 10.0) & (T < 20.0)
    p = np.where((T >= 11.0) & (T < 20.0), 0.9, 0.0)
    p[T >= 45.0] = 0.9
    eps = episode_delays(T, p, active, hold_steps=5)
    assert len(eps) == 1 and eps[0][2] == pytest.approx(1.0)
    assert false_alarm_fraction(p, active) == pytest.approx(np.sum(T >= 45.0) / np.sum(~active))
    assert missed_fraction(p, active) == pytest.approx(20 / np.sum(active))
    assert missed_fraction(p, np.zeros_like(active)) is None
    assert episode_delays(T, np.zeros_like(p), active, 5)[0][2] is None


def test_replay_scorer_uses_the_campaign_definitions():
    """The replay scorer scores with the campaign's metric functions (one definition, SPEC 8)."""
    import sim_bridge.metrics as campaign
    import sim_bridge.replay_score as scorer

    for name in ("episode_delays", "false_alarm_fraction", "missed_fraction", "rmse"):
        assert getattr(scorer, name) is getattr(campaign, name)
