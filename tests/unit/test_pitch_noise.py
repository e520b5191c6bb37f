"""The pitch-rate process noise learnt from the gyro (fdir_service/estimation/pitch_noise.py,
parts.q_noise = "learned"): it finds the moment model's one-frame misfit under the gyro's noise,
stays within [FLOOR_SHARE, 1] x the configured noise (its heavy tail keeps the configured width),
learns nothing while a fault is believed or across a missing reading, and only an estimator that
asks for it carries it."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.airframe import load_airframe
from fdir_service.errors import ConfigError
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.kinematic import PitchMoment
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimation.pitch_noise import FLOOR_SHARE, LearnedPitchNoise
from fdir_service.estimation.predict import DriftPredict
from fdir_service.estimator_config import estimator_document, parse_estimator

DT = 0.05
ROWS = ("theta", "q")
LAYOUT = FaultLayout(("q",), ("sensor",), ("q",), ROWS)
SIGMA_R = 0.003                                    # rad/s: the gyro's assumed noise
MEAS = MeasurementModel.build(LAYOUT, np.array([0.015, SIGMA_R]))
TOP = 0.15 * np.sqrt(DT)                           # rad/s per step: the catalogue's configured noise
MOMENT = PitchMoment(load_airframe("aerosonde"))
U = np.array([-0.07, 0.4, 0.0, -9.5, 40.0])        # [delta_e rad, delta_t, a_x, a_z m/s^2, V m/s]


class Weightless:
    """A correction that moves nothing and weighs nothing."""

    def update(self, X, w, modes, frame):
        return np.zeros(X.shape[1])


def learner() -> LearnedPitchNoise:
    q_std = np.full(N_AIRFRAME + 1, 0.01)
    q_std[4] = TOP
    predict = DriftPredict(None, q_std, np.zeros(1), np.full(1, np.inf), q_tail=(0.05, 5.0))
    return LearnedPitchNoise(Weightless(), predict, MOMENT, 1, SIGMA_R, DT, tau_s=30.0)


def fly(part: LearnedPitchNoise, misfit: float, frames: int = 4000, seed: int = 0,
        modes: np.ndarray | None = None, gyro_every: int = 1) -> None:
    """Feed `frames` gyro readings of a pitch rate the moment drives plus `misfit` (rad/s a frame,
    white), read with the gyro's true noise 0.002 rad/s; modes (1, N) the cloud's fault modes. The
    elevator swings +-2 deg at 0.5 Hz about U's, so the moment's elevator term moves q by ~20 deg/s."""
    rng = np.random.default_rng(seed)
    X, w = np.zeros((N_AIRFRAME + 1, 4)), np.full(4, 0.25)
    modes = np.zeros((1, 4), bool) if modes is None else modes
    q = 0.0
    for k in range(frames):
        u = U.copy()
        u[0] += np.radians(2.0) * np.sin(np.pi * k * DT)
        q += DT * MOMENT.qdot(np.array([q]), u[0], u[3], u[4])[0] + misfit * rng.standard_normal()
        mask = np.array([True, k % gyro_every == 0])
        y = np.array([0.05, q + 0.002 * rng.standard_normal()])
        part.update(X, w, modes, Frame.of(k * DT, y, mask, u, MEAS))


@pytest.mark.parametrize("misfit_deg", [0.3, 0.7, 1.2])
def test_the_learnt_noise_is_the_moment_misfit_under_the_gyro_noise(misfit_deg):
    part = learner()
    fly(part, np.radians(misfit_deg))
    # the residual is the misfit plus two readings' true noise (0.002), less the assumed 2 x 0.003^2
    expect = np.sqrt(np.radians(misfit_deg) ** 2 + 2 * 0.002 ** 2 - 2 * SIGMA_R ** 2)
    assert part.sigma == pytest.approx(expect, rel=0.12)
    assert part.sigma < 0.7 * TOP
    assert part.predict.q_tail[1] * part.sigma == pytest.approx(5.0 * TOP)    # the tail keeps its width


def test_the_learnt_noise_stays_within_its_floor_and_the_configured_noise():
    loud, still = learner(), learner()
    fly(loud, 3 * TOP, frames=1500)
    fly(still, 0.0, frames=1500)
    assert loud.sigma == pytest.approx(TOP)
    assert still.sigma == pytest.approx(FLOOR_SHARE * TOP)


def test_nothing_is_learnt_while_a_fault_is_more_probable_than_not():
    part = learner()
    fly(part, np.radians(0.3), modes=np.array([[True, True, True, False]]))    # P(fault) = 0.75
    assert part.sigma == TOP
    part = learner()
    fly(part, np.radians(0.3), frames=1500, modes=np.array([[True, False, False, False]]))  # 0.25
    assert part.sigma < 0.5 * TOP


def test_while_a_fault_is_believed_the_predict_takes_the_configured_noise_back():
    part = learner()
    fly(part, np.radians(0.3), frames=1500)
    learnt = part.sigma
    assert learnt < 0.5 * TOP
    fly(part, np.radians(0.3), frames=3, modes=np.array([[True, True, True, False]]))
    assert part.sigma == TOP and part.predict.q_tail == (0.05, 5.0) and part.learnt_sigma == learnt
    fly(part, np.radians(0.3), frames=1)
    assert part.sigma == pytest.approx(learnt, rel=0.05)


def test_no_residual_spans_a_missing_reading():
    """Every other frame without the gyro: no two consecutive readings, so nothing is learnt."""
    part = learner()
    fly(part, np.radians(0.3), gyro_every=2)
    assert part.sigma == TOP


def test_a_non_finite_reading_is_skipped_not_learnt():
    part = learner()
    fly(part, np.radians(0.5), frames=500)
    X, w, modes = np.zeros((N_AIRFRAME + 1, 4)), np.full(4, 0.25), np.zeros((1, 4), bool)
    for y in (np.nan, 0.01, np.inf, 0.02):
        part.update(X, w, modes, Frame.of(30.0, np.array([0.05, y]), np.array([True, True]), U, MEAS))
    assert np.isfinite(part.sigma) and np.isfinite(part.var) and part.last == 0.02


def test_one_wild_residual_moves_the_noise_by_a_bounded_step():
    part = learner()
    fly(part, np.radians(0.5), frames=2000)
    before = part.learnt_sigma
    part._learn(1.0)                                     # 1 rad/s in one frame
    assert before < part.learnt_sigma < 1.02 * before


def test_an_estimator_learns_its_pitch_noise_only_when_it_asks():
    def learns(doc) -> bool:
        filt = build_filter("RJMRPF", parse_estimator(doc, "test.toml"), np.random.default_rng(0),
                            particles=50)
        part = filt.parts.correction
        while not isinstance(part, LearnedPitchNoise) and hasattr(part, "inner"):
            part = part.inner
        return isinstance(part, LearnedPitchNoise)

    doc, _ = estimator_document("aerosonde-catalogue")
    assert learns(doc)                                   # the catalogue's own setting
    doc["parts"].pop("q_noise")
    assert not learns(doc)                               # the default: "fixed"


def test_learning_needs_the_kinematic_moment():
    doc, _ = estimator_document("aerosonde")
    doc.setdefault("parts", {})["q_noise"] = "learned"
    with pytest.raises(ConfigError, match="parts.q_noise"):
        parse_estimator(doc, "test.toml")
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"]["q_noise"] = "sometimes"
    with pytest.raises(ConfigError, match="q_noise"):
        parse_estimator(doc, "test.toml")
