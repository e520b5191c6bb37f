"""The pitot parts on their own (fdir_service/estimation/pitot.py, the blocked type in fault_types.py,
the wind's fold in jump.ExitFold): the airspeed row observed against u with the wind in its bias
entry, the wind started on the first reading and held under another pitot type, a blocked pitot's
reading following the altitude, a returning pitot re-anchoring the wind, and the file's checks."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from fdir_service.airframe.params import load_airframe
from fdir_service.errors import ConfigError
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.fault_types import TypedEvolution, TypeSwitch, sibling_pairs
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.inputs import G
from fdir_service.estimation.jump import DriftMemory, ItemDriftMemory
from fdir_service.estimation.kinematic import KinematicProcess, PitchMoment
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.pitot import (
    HOLD_SETTLE_S,
    PitotRow,
    gust_sigma,
    near_level_flight,
    pitot_row,
    wind_entry,
)
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator

ROWS = ("u", "airspeed")
SIGMA = np.array([1.5, 0.75])
# the pitot's bias entry (it carries the wind), its blockage, a u-sensor bias
LAYOUT = FaultLayout(("pitot", "pit_blk", "u"), ("sensor",) * 3, ("airspeed", "airspeed", "u"), ROWS,
                     ("bias", "blocked", "bias"))
MEAS = MeasurementModel.build(LAYOUT, SIGMA)
WIND, BLK = 0, 1


def cloud(N: int = 3) -> np.ndarray:
    X = np.zeros((LAYOUT.n, N))
    X[0], X[1], X[3] = -500.0, 32.0, 0.05
    X[N_AIRFRAME + WIND] = 8.0                     # an 8 m/s head wind: the pitot reads 40
    return X


def test_the_airspeed_row_measures_u_plus_the_pitot_entries_and_the_wind_is_its_drifting_bias():
    assert MEAS.H[1, 1] == 1.0 and MEAS.H[1, N_AIRFRAME + WIND] == 1.0 and MEAS.H[1, N_AIRFRAME + BLK] == 1.0
    assert not MEAS.H[1, N_AIRFRAME + 2]
    np.testing.assert_allclose(MEAS.predict(cloud())[1], 40.0)
    est = load_estimator("aerosonde-catalogue")
    j = wind_entry(est.faults)
    assert est.faults[j].id == "pitot" and est.observed[-1] == "airspeed"
    assert est.derived_rows == ("throttle", "airspeed")


def pitot_part(gust=(1.5, 10.0, 60.0)) -> PitotRow:
    return PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05, gust=gust)


def test_the_wind_starts_on_the_first_pitot_reading_and_the_airspeed_input_is_trusted_less_its_fault():
    part = pitot_part()
    X = cloud(2000)
    X[N_AIRFRAME + WIND] = 0.0
    modes = np.zeros((LAYOUT.nf, 2000), dtype=bool)
    y = np.array([32.0, 41.0])
    part.evolve(X, modes, y, np.array([True, False]), np.random.default_rng(0))  # no pitot yet
    assert not X[N_AIRFRAME + WIND].any() and part.mean is None
    part.evolve(X, modes, y, np.array([True, True]), np.random.default_rng(0))
    w = X[N_AIRFRAME + WIND]
    assert abs(w.mean() - 9.0) < 0.05 and abs(w.std() - 0.75) < 0.05      # y - u, spread by sigma
    assert part.mean == pytest.approx(w.mean())
    part.follow(np.array([1.5, 2.0, 7.0]))
    assert part.trusted(43.0) == pytest.approx(39.5)                        # 43 - (1.5 + 2.0)
    part.follow(np.array([np.nan, 0.0, 0.0]))
    assert part.trusted(43.0) == 43.0


def test_the_gusts_return_to_the_mean_wind_with_their_sigma_and_time_constant():
    part = pitot_part(gust=(1.5, 10.0, 1e9))        # a mean that does not move
    part.mean = 8.0
    X = cloud(4000)
    modes = np.zeros((LAYOUT.nf, 4000), dtype=bool)
    rng = np.random.default_rng(1)
    X[N_AIRFRAME + WIND] = 12.0                      # a 4 m/s gust
    for _ in range(200):                             # 10 s = one time constant
        part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng)
    w = X[N_AIRFRAME + WIND]
    assert w.mean() == pytest.approx(8.0 + 4.0 * np.exp(-1.0), abs=0.1)
    assert w.std() == pytest.approx(1.5 * np.sqrt(1.0 - np.exp(-2.0)), abs=0.05)
    for _ in range(2000):                            # 100 s: stationary
        part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng)
    assert X[N_AIRFRAME + WIND].std() == pytest.approx(1.5, abs=0.06)


def test_a_held_pitot_does_not_follow_the_wind_and_the_mean_follows_only_fault_free_winds():
    part = pitot_part(gust=(1.5, 10.0, 60.0))
    part.mean = 8.0
    X = cloud(4)
    X[N_AIRFRAME + WIND] = 9.0
    X[N_AIRFRAME + BLK] = 1.0
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    modes[BLK, :3] = True                            # three of four particles: the pitot is blocked
    before = MEAS.predict(X)[1].copy()
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(2))
    after = MEAS.predict(X)[1]
    np.testing.assert_allclose(after[:3], before[:3])                       # held readings
    assert after[3] != before[3]                                           # the air moves the other
    assert part.mean == 8.0                                                # most are faulty: M holds
    modes[BLK] = False
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(2))
    assert 8.0 < part.mean < 8.1                                           # M moves towards 9 by dt / 60 s


def test_under_an_airspeed_hold_the_wind_takes_the_ground_speeds_change_and_a_held_reading_stays():
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 60.0), hold=1.0)   # no gust: only the hold moves the wind
    part.mean = 40.0                                 # kappa = 1: the mean is the held airspeed, u + W
    X = cloud(2)
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    modes[BLK, 1] = True                             # the second particle holds the pitot blocked
    X[N_AIRFRAME + BLK, 1] = 1.0
    before = MEAS.predict(X)[1].copy()
    u_before = X[1].copy()
    X[1] += 1.5                                      # the prediction sped the aircraft up by 1.5 m/s ...
    X[N_AIRFRAME + BLK, 1] -= 1.5                    # ... which a held reading does not see (TypedEvolution)
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(3), u_before)
    np.testing.assert_allclose(X[N_AIRFRAME + WIND], [6.5, 6.5])          # the head wind fell by 1.5
    np.testing.assert_allclose(MEAS.predict(X)[1], before)                # healthy: the airspeed held
    np.testing.assert_allclose(X[N_AIRFRAME + BLK, 1], 1.0)               # blocked: held, wind moves anyway
    assert part.hold == 1.0 and load_estimator("aerosonde-catalogue").settings.wind_hold == 1.0


def test_under_a_pitot_fault_the_winds_fault_free_value_takes_the_ground_speeds_change():
    """Exits return to the drift memory's value (parts.mode0 = "drift"); while a pitot fault holds
    every particle no reading sees the wind, and under the hold it must still take the ground
    speed's change (and its gust return to the mean), not stay at the fault's onset."""
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 60.0), hold=1.0)
    part.mean = 40.0
    memory = DriftMemory(LAYOUT.nf)
    memory.value[WIND] = 8.0                         # the head wind at the onset: u + W = 40
    part.use_memory(memory)
    X = cloud(4)
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    modes[WIND] = True                               # every particle holds the pitot biased
    X[N_AIRFRAME + WIND] = 3.0                       # the wind plus a -5 m/s offset
    u_before = X[1].copy()
    X[1] -= 2.0                                      # climbing into the wind: 2 m/s less over the ground
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(3), u_before)
    np.testing.assert_allclose(X[N_AIRFRAME + WIND], 3.0)      # mode 1: the entry is the reading's
    np.testing.assert_allclose(memory.value, [10.0, 0.0, 0.0])  # the wind a healthy pitot returns to
    memory.value[WIND] = 9.0                         # 1 m/s of gust above the held airspeed ...
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(3))
    a = np.exp(-0.05 / 10.0)
    np.testing.assert_allclose(memory.value[WIND], 40.0 + a * (9.0 + 30.0 - 40.0) - 30.0)   # ... returns


def test_the_catalogue_filters_wind_memory_is_the_jumps():
    est = load_estimator("aerosonde-catalogue")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=50)
    assert filt.wind.memory is filt.parts.jump.drift


def test_at_full_throttle_the_hold_lets_go_and_takes_the_airspeed_it_finds_when_it_holds_again():
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 1e9), hold=1.0, free_sigma=0.0)   # no gusts, a mean that stays
    part.mean = 40.0                                 # the held airspeed
    X = cloud(2)
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    rng = np.random.default_rng(4)
    part.command(1.0)                                # full throttle: no authority over the airspeed
    assert not part.authority
    for _ in range(20):                              # the engine is gone: 2 m/s slower over 1 s
        u_before = X[1].copy()
        X[1] -= 0.1
        part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng, u_before)
    np.testing.assert_allclose(X[N_AIRFRAME + WIND], [8.0, 8.0])          # the wind stays ...
    np.testing.assert_allclose(MEAS.predict(X)[1], [38.0, 38.0])          # ... the airspeed follows u
    assert part.kappa == 0.0 and part.mean == pytest.approx(8.0)           # M: the head wind now
    for k in range(int(round(HOLD_SETTLE_S / 0.05))):   # off the limit: the airspeed loop settles
        part.command(0.6)
        assert part.authority == (k + 1 == round(HOLD_SETTLE_S / 0.05))
    u_before = X[1].copy()
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng, u_before)
    assert part.kappa == 1.0 and part.mean == pytest.approx(38.0)          # M: the airspeed it found
    np.testing.assert_allclose(MEAS.predict(X)[1], [38.0, 38.0])
    part.command(float("nan"))                       # no command known: the hold stays assumed
    assert part.authority


def resumed_mean(resume_held: bool, pitot_declared: bool) -> float:
    """M after the hold lets go at full throttle for 1 s and takes over again 3 s later, the
    particles' u + W then 43 m/s (their winds 11, the ground speed 32)."""
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 1e9), hold=1.0, free_sigma=0.0, resume_held=resume_held)
    part.mean = 40.0                                 # the held airspeed
    X = cloud(4)
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    rng = np.random.default_rng(4)
    part.command(1.0)
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng)
    X[N_AIRFRAME + WIND] = 11.0
    modes[BLK, :3 if pitot_declared else 1] = True   # three of four particles hold the pitot blocked
    for _ in range(int(round(HOLD_SETTLE_S / 0.05))):
        part.command(0.6)
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), rng)
    assert part.kappa == 1.0
    return part.mean


def test_with_the_pitot_declared_the_resumed_hold_returns_to_the_airspeed_it_held():
    """parts.hold_resume = "held": with the fault-free particles most of the cloud M is their mean
    of u + W either way; without them, every particle's mean took the blocked and biased winds
    (42.5 m/s where the pitot read 40 in real-engine run 96, and M, following only fault-free
    particles, never came back): M returns to the airspeed held before the let-go."""
    assert resumed_mean(False, pitot_declared=False) == pytest.approx(43.0)
    assert resumed_mean(True, pitot_declared=False) == pytest.approx(43.0)
    assert resumed_mean(False, pitot_declared=True) == pytest.approx(43.0)
    assert resumed_mean(True, pitot_declared=True) == pytest.approx(40.0)
    assert load_estimator("aerosonde-catalogue").settings.hold_resume == "held"


def test_in_an_upset_the_hold_lets_go_until_the_airspeed_loop_has_settled():
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 1e9), hold=1.0, free_sigma=0.0)
    part.command(0.6)
    assert part.authority
    part.command(0.6, level=False)                   # a freed elevator's pull-up: no airspeed held
    assert not part.authority
    settle = int(round(HOLD_SETTLE_S / 0.05))
    for k in range(settle):                          # level again: the airspeed loop settles first
        part.command(0.6, level=True)
        assert part.authority == (k + 1 == settle)


def test_under_a_hold_the_airspeeds_gusts_have_the_held_sigma_not_the_winds():
    est = load_estimator("aerosonde-catalogue")
    s = est.settings
    assert (s.wind_hold, s.wind_gust_sigma, s.held_airspeed_sigma) == (1.0, 1.5, 0.5)
    assert s.held_airspeed_tau_s is None                                   # the wind's 10 s
    assert gust_sigma(s) == 0.5                                            # kappa = 1: the hold's
    assert gust_sigma(dataclasses.replace(s, wind_hold=0.0)) == 1.5        # no hold: the wind's
    assert gust_sigma(dataclasses.replace(s, wind_hold=0.5)) == pytest.approx(1.0)
    part = pitot_row(est)
    assert part.step_sigma == pytest.approx(0.5 * np.sqrt(1.0 - np.exp(-2 * 0.05 / 10.0)))
    nf = len(est.faults)
    X = np.zeros((N_AIRFRAME + nf, 4000))
    X[1] = 38.0
    X[N_AIRFRAME + part.wind] = 2.0                  # the airspeed c = u + W starts at its mean
    part.mean = 40.0
    modes = np.zeros((nf, 4000), dtype=bool)
    rng = np.random.default_rng(4)
    for _ in range(2000):                            # 100 s: stationary
        u_before = X[1].copy()
        X[1] += 0.3 * rng.standard_normal(4000)      # the ground speed swings; the hold takes it
        part.evolve(X, modes, np.zeros(1), np.zeros(1, dtype=bool), rng, u_before)
    assert (X[1] + X[N_AIRFRAME + part.wind]).std() == pytest.approx(0.5, abs=0.03)


def test_under_a_hold_the_airspeeds_gusts_have_the_holds_time_constant_and_the_wind_its_own():
    part = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, dt=0.05,
                    gust=(0.0, 10.0, 1e9), hold=1.0, free_sigma=0.0, held_tau=1.0)
    part.mean = 40.0
    X = cloud(2)
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    X[N_AIRFRAME + WIND] = 10.0                      # the airspeed u + W 2 m/s over the held 40
    for _ in range(20):                              # 1 s = the hold's time constant
        part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(0))
    np.testing.assert_allclose(X[1] + X[N_AIRFRAME + WIND], 40.0 + 2.0 * np.exp(-1.0))
    part.command(1.0)                                # full throttle: the hold lets go, the wind's 10 s
    X[N_AIRFRAME + WIND] = 10.0
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(0))
    mean = part.mean                                 # the head wind's mean, taken as the hold let go
    part.evolve(X, modes, np.zeros(2), np.zeros(2, dtype=bool), np.random.default_rng(0))
    np.testing.assert_allclose(X[N_AIRFRAME + WIND] - mean, (10.0 - mean) * np.exp(-0.05 / 10.0))
    unset = PitotRow(np.array([WIND, BLK]), WIND, np.array([BLK]), row=1, sigma=0.75, hold=1.0)
    assert unset.a == unset.free_a == np.exp(-0.05 / 10.0)   # not set: the wind's time constant for both


def test_a_blocked_pitot_in_mode_1_reads_g_dh_over_v_more_in_a_climb_and_holds_in_level_flight():
    ev = TypedEvolution(LAYOUT, MEAS.H, WIND)
    X = cloud(2)
    X[N_AIRFRAME + BLK] = 1.0                        # blocked while reading 41 m/s
    before = X[:N_AIRFRAME].copy()
    X[0] -= [10.0, 0.0]                              # particle 0 climbed 10 m, particle 1 did not
    X[1] -= 2.0                                      # both slowed by 2 m/s over the ground
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    modes[BLK] = True
    ev.apply(before, X, modes, np.zeros(2), None)
    reading = MEAS.predict(X)[1]
    np.testing.assert_allclose(reading, [41.0 + G * 10.0 / 41.0, 41.0], rtol=1e-3)
    assert np.sqrt(41.0**2 + 2 * G * 10.0) == pytest.approx(reading[0], abs=0.1)   # first order in dh


def test_a_returning_pitot_moves_no_state():
    ev = TypedEvolution(LAYOUT, MEAS.H, WIND)
    part = TypeSwitch(sibling_pairs(LAYOUT), 0.0, ev, LAYOUT.sensor_row)
    X = cloud(2)
    X[N_AIRFRAME + BLK] = 3.0                        # held 3 m/s above u + wind
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    modes[BLK] = True
    v = np.full((LAYOUT.nf, 2), 0.9)
    v[BLK] = [0.001, 0.5]                            # the first would anchor, were it another sensor
    y = np.array([32.0, 41.0])
    innov = y[:, None] - MEAS.H @ X
    frame = Frame.of(1.0, y, np.ones(2, dtype=bool), np.zeros(2), MEAS)
    before = X.copy()
    part.apply_anchor(X, part.anchor(X[N_AIRFRAME:], modes, v, np.full((LAYOUT.nf, 1), 0.01), innov, frame))
    np.testing.assert_array_equal(X, before)


def test_a_hand_over_between_types_keeps_the_rows_offset():
    ev = TypedEvolution(LAYOUT, MEAS.H, WIND)
    assert sorted(map(tuple, sibling_pairs(LAYOUT).tolist())) == [(WIND, BLK), (BLK, WIND)]
    part = TypeSwitch(np.array([[WIND, BLK]]), 1.0, ev, LAYOUT.sensor_row)
    X = cloud(1)
    X[N_AIRFRAME + WIND] = 11.0                      # wind 8 (fault-free) + a 3 m/s bias in mode 1
    modes = np.zeros((LAYOUT.nf, 1), dtype=bool)
    modes[WIND] = True
    before = MEAS.predict(X)[1].copy()
    part.apply(X[N_AIRFRAME:], modes, np.array([8.0, 0.0, 0.0]), np.random.default_rng(0))
    assert modes[BLK, 0] and not modes[WIND, 0]
    np.testing.assert_allclose(X[N_AIRFRAME:N_AIRFRAME + 2, 0], [8.0, 3.0])
    np.testing.assert_allclose(MEAS.predict(X)[1], before)


def test_the_catalogue_filter_watches_the_pitot_and_steps():
    est = load_estimator("aerosonde-catalogue")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=200,
                        x0=np.array([-500.0, 32.0, 1.5, 0.05, 0.0]))     # as the first frame starts it
    assert filt.wind is filt.rows.pitot and filt.wind.wind == wind_entry(est.faults)
    y = np.array([500.0, 500.0, 32.0, 1.5, 0.05, 0.0, 0.49, -9.78, 40.0, 0.0, 0.0])
    out = filt.step(0.05, y, np.ones(11, dtype=bool), np.array([-0.02, 0.5]))
    j = wind_entry(est.faults)
    assert abs(out.x_mean[N_AIRFRAME + j] - 8.0) < 1.0                     # the head wind, 40 - 32


def _doc_with(fault: dict) -> dict:
    doc, _ = estimator_document("aerosonde-robust")
    doc = copy.deepcopy(doc)
    doc["faults"].append(fault)
    return doc


def test_only_the_pitot_can_be_blocked_and_only_the_kinematic_model_watches_it():
    bad = {"id": "b_blk", "target": "baro_alt", "type": "blocked", "unit": "m", "sigma_f": 0.02,
           "amplitude_max": 50.0}
    with pytest.raises(ConfigError, match="only the pitot can be blocked"):
        parse_estimator(_doc_with(bad), "x.toml")
    pitot = {"id": "pitot", "target": "airspeed", "unit": "m/s", "sigma_f": 0.1, "amplitude_max": 30.0}
    assert parse_estimator(_doc_with(pitot), "x.toml").derived_rows == ("airspeed",)
    doc = _doc_with(pitot)
    doc["parts"]["process_model"] = "nonlinear"
    doc["faults"] = [f for f in doc["faults"] if f["target"] != "delta_e"] + []
    with pytest.raises(ConfigError, match="watch the pitot"):
        parse_estimator(doc, "x.toml")
    with pytest.raises(ConfigError, match="cannot fold"):
        parse_estimator(_doc_with(dict(pitot, on_exit="reset_or_fold")), "x.toml")
    with pytest.raises(ConfigError, match="no drift_sigma"):
        parse_estimator(_doc_with(dict(pitot, drift_sigma=0.5)), "x.toml")


def test_the_pitot_is_read_near_level_flight_only():
    assert near_level_flight(0.1, 0.05) and near_level_flight(None, None)
    assert near_level_flight(float("nan"), 0.0)              # not measured: no limit
    assert not near_level_flight(np.radians(30.0), 0.0)      # an upset's attitude
    assert not near_level_flight(0.0, np.radians(20.0))      # an upset's pitch rate
    assert near_level_flight(0.1, 0.0, np.radians(12.0))     # a climb's, read through noise
    assert not near_level_flight(0.1, 0.0, np.radians(33.0))  # a stalled wing at 6 deg of pitch
    est = load_estimator("aerosonde-catalogue")
    filt = build_filter("RJMRPF", est, np.random.default_rng(0), particles=50)
    rows = est.measurements
    y = np.array([500.0, 500.0, 32.0, 1.5, 0.05, 0.0, 0.49, -9.78, 40.0, 0.0, 0.0])
    mask = np.ones(len(rows), dtype=bool)
    assert filt.rows.split(y, mask, np.array([-0.02, 0.5]))[1][-1]
    y[rows.index("theta")] = np.radians(40.0)
    assert not filt.rows.split(y, mask, np.array([-0.02, 0.5]))[1][-1]   # the row is masked
    y[rows.index("theta")] = 0.05
    y[rows.index("u")], y[rows.index("w")] = 32.0, 21.0                  # 33 deg of angle of attack
    assert not filt.rows.split(y, mask, np.array([-0.02, 0.5]))[1][-1]


def moment_process(fault_free: bool, part: PitotRow) -> KinematicProcess:
    proc = KinematicProcess(0.05, LAYOUT, PitchMoment(load_airframe()))
    proc.use_wind(part, fault_free)
    return proc


def test_a_biased_pitot_particle_flies_the_moment_on_the_fault_free_wind():
    """parts.moment_wind = "fault_free": the wind entry in mode 1 is the wind plus the pitot's
    offset, so u + entry is the biased reading; the moment takes the wind the exits return to.
    On real-pitot run 84 the moment of a +5 m/s reading (28 % more dynamic pressure) had pushed
    the elevator's mis-trim drift to 1.2 deg by the bias's end, and the elevator was declared for
    18 s after it (docs/faults.md, "The moment's wind under a biased pitot")."""
    part = pitot_part()
    part.mean = 40.0
    memory = DriftMemory(LAYOUT.nf)
    memory.value[WIND] = 8.0
    part.use_memory(memory)
    X = cloud(2)
    X[4] = 0.05
    modes = np.zeros((LAYOUT.nf, 2), dtype=bool)
    modes[WIND, 1] = True                            # particle 1 holds the pitot biased ...
    X[N_AIRFRAME + WIND, 1] = 13.0                   # ... by +5 m/s: its entry reads 45 m/s
    u = np.array([-0.05, 0.5, 0.0, -9.5, 45.0])
    plain, fair = moment_process(False, part), moment_process(True, part)
    q_plain, q_fair = plain.propagate(X, u, modes)[4], fair.propagate(X, u, modes)[4]
    assert q_fair[1] == q_fair[0] == q_plain[0]      # the fault-free wind: both fly 40 m/s
    assert abs(q_plain[1] - q_plain[0]) > 0.01       # rad/s a frame: the biased reading's moment
    np.testing.assert_array_equal(fair.propagate(X, u)[4], q_plain)   # no modes: the entry
    assert load_estimator("aerosonde-catalogue").settings.moment_wind == "fault_free"


def test_the_item_memory_keeps_the_wind_of_particles_with_no_pitot_fault():
    """parts.fault_free_memory = "item" (`jump.ItemDriftMemory`): a blocked particle's wind entry is
    in mode 0 but unobserved (it wanders with the gust model); the fault-free wind exits return to
    is the mean over the particles whose pitot has no fault of any type, while they hold most of
    the weight, and stays otherwise."""
    F = np.zeros((LAYOUT.nf, 4))
    F[WIND] = [8.0, 8.2, 11.0, 11.0]                  # two blocked particles' winds wandered off
    modes = np.zeros((LAYOUT.nf, 4), dtype=bool)
    modes[BLK, 2:] = True
    w = np.array([0.3, 0.3, 0.2, 0.2])
    same = np.array([[1, 1, 0], [1, 1, 0], [0, 0, 1]], dtype=float)
    entry, item = DriftMemory(LAYOUT.nf), ItemDriftMemory(same)
    assert entry.update(F, modes, w)[WIND] == pytest.approx(9.26)        # the blocked winds pulled in
    assert item.update(F, modes, w)[WIND] == pytest.approx(8.1)          # only the fault-free pitots'
    modes[BLK, 1] = True                              # 0.3 of the weight left with no pitot fault
    F[WIND, 0] = 5.0
    assert item.update(F, modes, w)[WIND] == pytest.approx(8.1)          # no majority: kept
    settings = load_estimator("aerosonde-catalogue").settings    # every entry's by item, since stop 53
    assert settings.fault_free_memory == "item" and settings.fault_free_rollback_s == 2.0


def _catalogue_memory(memory: str):
    """(estimator, the fault-free memory of its RJMRPF) of the catalogue with that fault_free_memory."""
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"]["fault_free_memory"] = memory
    est = parse_estimator(doc, "catalogue.toml")
    return est, build_filter("RJMRPF", est, np.random.default_rng(0), particles=20).parts.jump.drift


def test_the_catalogues_memory_keeps_every_entry_by_item_and_rolls_every_one_back():
    """The catalogue's (since stop 53): every entry's fault-free value from the particles whose whole
    item is fault-free, rolled back 2 s when it freezes."""
    est = load_estimator("aerosonde-catalogue")
    memory = build_filter("RJMRPF", est, np.random.default_rng(0), particles=20).parts.jump.drift
    targets = [f.target for f in est.faults]
    same = np.array([[a == b for b in targets] for a in targets], dtype=float)
    assert isinstance(memory, ItemDriftMemory) and memory.rollback.entries.all()
    np.testing.assert_array_equal(memory.item, same)


def test_the_input_item_memory_keeps_its_inputs_by_item_and_rolls_only_them_back():
    """parts.fault_free_memory = "input_item" with fault_free_rollback_s = 2 (the catalogue's at
    stop 52): an input's entries (elevator, throttle: every type) share their item's fault-free
    particles and roll back 2 s when they freeze; a sensor's entry is kept by its own mode, as
    "entry" keeps it."""
    est, memory = _catalogue_memory("input_item")
    ids = [f.id for f in est.faults]
    inputs = [j for j, f in enumerate(est.faults) if f.target in ("delta_e", "delta_t")]
    assert isinstance(memory, ItemDriftMemory)
    assert [ids[j] for j in np.flatnonzero(memory.rollback.entries)] == [ids[j] for j in inputs]
    assert memory.rollback.past.shape[0] == round(2.0 / est.dt_s)
    sensors = np.setdiff1d(np.arange(len(ids)), inputs)
    np.testing.assert_array_equal(memory.item[np.ix_(sensors, sensors)], np.eye(sensors.size))
    de = [j for j in inputs if est.faults[j].target == "delta_e"]
    assert (memory.item[np.ix_(de, de)] == 1).all() and len(de) == 3
