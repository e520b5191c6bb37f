"""parts.exclusive_items (`fault_types.ItemExclusion`): items that do not fail together, and
parts.faulty_row_gain (`correction.FaultyRowCut`): a row a particle holds faulty moves only its
fault entries."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.errors import ConfigError
from fdir_service.estimation.correction import FaultyRowCut
from fdir_service.estimation.factory import build_filter
from fdir_service.estimation.fault_types import ItemExclusion, exclusion_matrix
from fdir_service.estimation.frame import Frame
from fdir_service.estimation.layout import FaultLayout
from fdir_service.estimation.measurement import MeasurementModel
from fdir_service.estimator_config import estimator_document, load_estimator, parse_estimator

LAYOUT = FaultLayout(("th", "th_dr", "th_nz", "q", "q_st", "baro"),
                     ("sensor",) * 6, ("theta", "theta", "theta", "q", "q", "baro_alt"),
                     ("gnss_alt", "baro_alt", "u", "w", "theta", "q"),
                     ("bias", "drift", "noisy", "bias", "stuck", "bias"))


def test_the_additive_entries_of_one_item_keep_the_other_item_out():
    E = exclusion_matrix(LAYOUT, ("theta q",))
    th, q = [0, 1], [3, 4]
    assert E[np.ix_(q, th)].all() and E[np.ix_(th, q)].all()          # either way round
    assert not E[np.ix_(th, th)].any() and not E[np.ix_(q, q)].any()   # an item's own types: `TypeSwitch`
    assert not E[2].any() and not E[:, 2].any()                        # a noisy reading is no offset
    assert not E[5].any() and not E[:, 5].any()                        # the barometer is in no group
    modes = np.zeros((6, 3), bool)
    modes[4, 0] = True                                                 # particle 0: the gyro stuck
    modes[1, 1] = True                                                 # particle 1: an attitude drift
    may = ItemExclusion(E).open(np.ones(6, bool), modes)
    assert not may[[0, 1], 0].any() and may[[2, 3, 5], 0].all()
    assert not may[[3, 4], 1].any() and may[[0, 2, 5], 1].all()
    assert may[:, 2].all()                                             # particle 2: nothing held


def test_the_pitch_chain_excluded_on_the_catalogue_and_a_bad_group_names_the_key():
    assert load_estimator("aerosonde-catalogue").settings.exclusive_items == ()
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"]["exclusive_items"] = ["theta q"]
    est = parse_estimator(doc, "test.toml")
    targets = [x.target for x in est.faults]

    def excluded_targets(estimator) -> set[tuple[str, str]]:
        """{(target kept out, target in mode 1)} of the filter's one exclusion matrix."""
        jump = build_filter("RJMRPF", estimator, np.random.default_rng(0), particles=20).parts.jump
        while not hasattr(jump, "exclusion"):
            jump = jump.inner
        E = jump.exclusion.excludes
        return {(targets[b], targets[a]) for b, a in zip(*np.nonzero(E), strict=True)}

    one_type = excluded_targets(load_estimator("aerosonde-catalogue"))   # the types of one item
    assert all(b == a for b, a in one_type) and ("theta", "theta") in one_type
    assert excluded_targets(est) - one_type == {("theta", "q"), ("q", "theta")}
    assert load_estimator("aerosonde-robust").settings.exclusive_items == ()
    for bad in (["theta"], ["theta theta"], ["theta airspeed_x"]):
        doc, _ = estimator_document("aerosonde-catalogue")
        doc["parts"]["exclusive_items"] = bad
        with pytest.raises(ConfigError, match=r"parts.exclusive_items\[0\].*two or more"):
            parse_estimator(doc, "test.toml")


def test_a_row_held_faulty_moves_only_the_fault_entries():
    meas = MeasurementModel(("baro_alt", "gnss_alt"), np.zeros((2, 7)), np.array([1.5, 7.5]))
    cut = FaultyRowCut(np.array([0, -1]))                   # fault 0 on the barometer; fault 1 an actuator
    frame = Frame.of(0.0, np.array([500.0, 501.0]), np.array([True, True]), np.zeros(2), meas)
    K = np.arange(14.0).reshape(7, 2) / 10.0                # (n, m)
    innov = np.array([[2.0, 2.0, 2.0], [1.0, 1.0, 1.0]])    # (m, N)
    modes = np.array([[False, True, False], [False, False, True]])
    dX = K @ innov
    before = dX.copy()
    cut.apply(dX, K, innov, modes, frame)
    np.testing.assert_array_equal(dX[:, [0, 2]], before[:, [0, 2]])          # no row held faulty
    np.testing.assert_allclose(dX[:5, 1], K[:5, 1] * 1.0)                    # the GNSS row alone
    np.testing.assert_array_equal(dX[5:, 1], before[5:, 1])                  # the fault entries: both
