"""A stuck sensor's held reading learnt as the mean of its readings (fdir_service/estimation/
held_mean.py, parts.held_value = "mean"): the held value is the mean of the readings since the
entry stuck, the sensor's other entries are left alone meanwhile, the counts restart on exit and
follow their particles, and the catalogue learns its held values while "sentinel" still draws them."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.held_mean import HeldCount, HeldMeanCorrection
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator

ROWS = ("baro_alt", "theta")
LAYOUT = FaultLayout(("baro_st", "baro_dr"), ("sensor", "sensor"), ("baro_alt", "baro_alt"), ROWS,
                     ("stuck", "drift"))
SIGMA = np.array([1.5, 0.015])
MEAS = MeasurementModel.build(LAYOUT, SIGMA)
J = N_AIRFRAME                                           # the stuck entry's index in X
D = N_AIRFRAME + 1                                       # the drift entry's (its sibling)


class Jump:
    """A jump that sets the modes it is given (what HeldCount wraps, reduced to its interface)."""

    def __init__(self) -> None:
        self.next_modes = None

    def jump(self, X, modes, w, frame, rng):
        if self.next_modes is not None:
            modes[:] = self.next_modes
        return None

    def resample_modes(self, modes, idx):
        return np.take(modes, idx, axis=1)

    def reinitialise(self, modes):
        pass


class NoCorrection:
    """A correction that weighs nothing and moves only the drift entry, by 1 m a frame (as a
    Kalman gain from a few particles may)."""

    def update(self, X, w, modes, frame):
        X[D] += 1.0
        return np.zeros(X.shape[1])


def frame(y_baro: float) -> Frame:
    return Frame.of(1.0, np.array([y_baro, 0.0]), np.array([True, False]), np.zeros(2), MEAS)


def parts(N: int):
    count = HeldCount(Jump(), np.array([0]), N)
    siblings = np.array([[False, True]])
    return count, HeldMeanCorrection(NoCorrection(), count, np.array([0]), siblings)


def held(X: np.ndarray) -> np.ndarray:
    """The baro row's predicted reading h_r z + f per particle (N,)."""
    return MEAS.H[0] @ X


def test_the_held_value_is_the_mean_of_the_readings_since_it_stuck():
    count, corr = parts(2)
    X = np.zeros((LAYOUT.n, 2))
    X[0] = -500.0                                        # altitude 500 m (p_d down)
    X[J] = [7.0, 7.0]                                    # both held at 507 m by their sentinel's draw
    modes = np.array([[True, False], [False, False]])    # particle 1 is healthy
    readings = np.random.default_rng(0).normal(503.0, 1.5, 25)
    for y in readings:
        corr.update(X, np.full(2, 0.5), modes, frame(y))
    assert held(X)[0] == pytest.approx(readings.mean(), abs=1e-9)   # the draw forgotten
    assert X[D, 0] == 0.0                                # its held sensor's drift left as it was
    assert held(X)[1] == pytest.approx(507.0 + 25.0)     # mode 0: only the inner correction
    assert count.n[0].tolist() == [25.0, 0.0]


def test_the_gain_is_one_over_the_readings_averaged_and_the_weight_is_the_inner_corrections():
    count, corr = parts(3)
    X = np.zeros((LAYOUT.n, 3))
    X[J] = 2.0                                           # each particle's held reading: 2 m
    count.n[0] = [0.0, 1.0, 4.0]
    modes = np.array([[True] * 3, [False] * 3])
    ll = corr.update(X, np.full(3, 1 / 3), modes, frame(3.0))
    assert not ll.any()                                  # the inner's, unchanged
    np.testing.assert_allclose(held(X), [3.0, 2.5, 2.2])  # gains 1, 1/2, 1/5
    assert count.n[0].tolist() == [1.0, 2.0, 5.0]


def test_each_held_entry_learns_from_its_own_row_only_on_the_frames_it_arrives():
    layout = FaultLayout(("baro_st", "th_st", "baro_dr"), ("sensor",) * 3,
                         ("baro_alt", "theta", "baro_alt"), ROWS, ("stuck", "stuck", "drift"))
    meas = MeasurementModel.build(layout, SIGMA)
    class MovesTheDrift:
        def update(self, X, w, modes, frame):
            X[N_AIRFRAME + 2] += 1.0
            return np.zeros(X.shape[1])

    count = HeldCount(Jump(), np.array([0, 1]), 2)
    siblings = np.array([[False, False, True], [False, False, False]])
    corr = HeldMeanCorrection(MovesTheDrift(), count, np.array([0, 1]), siblings)
    X = np.zeros((layout.n, 2))
    modes = np.array([[True, False], [True, False], [False, False]])   # particle 1 is healthy
    only_theta = Frame.of(1.0, np.array([0.0, 0.02]), np.array([False, True]), np.zeros(2), meas)
    corr.update(X, np.full(2, 0.5), modes, only_theta)
    assert count.n.tolist() == [[0.0, 0.0], [1.0, 0.0]]   # the barometer did not arrive
    assert X[N_AIRFRAME + 1].tolist() == [0.02, 0.0]      # theta's held value
    assert X[N_AIRFRAME].tolist() == [0.0, 0.0]
    assert X[N_AIRFRAME + 2].tolist() == [1.0, 1.0]       # no barometer frame: nothing restored
    both = Frame.of(1.0, np.array([10.0, 0.04]), np.ones(2, dtype=bool), np.zeros(2), meas)
    corr.update(X, np.full(2, 0.5), modes, both)
    assert count.n.tolist() == [[1.0, 0.0], [2.0, 0.0]]
    assert X[N_AIRFRAME + 2].tolist() == [1.0, 2.0]       # kept where the barometer is held
    assert meas.H[0] @ X[:, 0] == pytest.approx(10.0)     # the barometer's first reading, held
    np.testing.assert_allclose(X[N_AIRFRAME + 1], [0.03, 0.0])


def test_the_counts_restart_when_an_entry_leaves_mode_1_and_follow_resampling():
    count, _ = parts(4)
    count.n[0] = [5.0, 6.0, 7.0, 8.0]
    modes = np.ones((2, 4), dtype=bool)
    count.inner.next_modes = np.array([[True, False, True, True], [False] * 4])
    count.jump(np.zeros((LAYOUT.n, 4)), modes, np.full(4, 0.25), frame(0.0), None)
    assert count.n[0].tolist() == [5.0, 0.0, 7.0, 8.0]   # particle 1 left mode 1
    count.resample_modes(modes, np.array([3, 3, 0, 1]))
    assert count.n[0].tolist() == [8.0, 8.0, 5.0, 0.0]
    count.reinitialise(modes)
    assert not count.n.any()


def test_no_reading_no_change():
    count, corr = parts(2)
    X = np.ones((LAYOUT.n, 2))
    none = Frame.of(1.0, np.zeros(2), np.zeros(2, dtype=bool), np.zeros(2), MEAS)
    ll = corr.update(X, np.full(2, 0.5), np.ones((2, 2), dtype=bool), none)
    assert not ll.any() and (X[J] == 1.0).all() and not count.n.any()


def test_the_catalogue_learns_its_held_values_and_the_sentinels_draw_is_still_a_choice():
    catalogue = load_estimator("aerosonde-catalogue")
    assert catalogue.settings.held_value == "mean"
    filt = build_filter("RJMRPF", catalogue, np.random.default_rng(0), particles=20)
    held_ids = [catalogue.faults[j].id for j in filt.parts.jump.inner.faults]
    assert held_ids == ["baro_st", "th_st", "q_st"]      # the stuck sensors, not the blocked pitot
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"] = dict(doc["parts"]) | {"held_value": "sentinel"}
    drawn = build_filter("RJMRPF", parse_estimator(doc, "drawn.toml"), np.random.default_rng(0),
                         particles=20)
    assert not isinstance(drawn.parts.jump.inner, HeldCount)
    assert not isinstance(drawn.parts.correction.inner, HeldMeanCorrection)
