"""parts.az_input (`inputs.RowSplit`): the a_z the kinematic model integrates over a frame, its
reading at the frame's end or the mean of the frame's two readings; the other inputs and the
derived throttle row keep the frame's own readings."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.factory import trim_state
from fdir_service.estimation.inputs import RowSplit, trim_inputs
from fdir_service.estimator_config import estimator_document, parse_estimator

AZ = (-9.70, -9.90, -9.50)          # m/s^2, three frames' readings


def split_of(az_input: str) -> tuple[RowSplit, tuple[str, ...]]:
    doc, _ = estimator_document("aerosonde-catalogue")
    doc["parts"]["az_input"] = az_input
    est = parse_estimator(doc, "test.toml")
    return RowSplit.of(est, True, trim_state(est)), est.measurements


def fly(split: RowSplit, rows: tuple[str, ...], fresh: tuple[bool, ...] = (True, True, True)):
    """The process input u and the derived throttle row of three frames with AZ's readings."""
    y = np.zeros(len(rows))
    y[[rows.index(r) for r in ("ax", "airspeed")]] = [0.5, 40.0]
    out = []
    for az, ok in zip(AZ, fresh, strict=True):
        y[rows.index("az")] = az
        mask = np.ones(len(rows), bool)
        mask[rows.index("az")] = ok
        y_obs, _, u = split.split(y, mask, np.array([-0.08, 0.5]))
        out.append((u, y_obs))
    return out


def test_frame_end_takes_each_frames_reading():
    split, rows = split_of("frame_end")
    assert [u[3] for u, _ in fly(split, rows)] == list(AZ)


def test_frame_mean_takes_the_mean_of_the_frames_two_readings_starting_from_the_trim():
    split, rows = split_of("frame_mean")
    trim_az = trim_inputs(trim_state(parse_estimator(estimator_document("aerosonde-catalogue")[0],
                                                     "test.toml")))["az"]
    az = [u[3] for u, _ in fly(split, rows)]
    assert az == pytest.approx([0.5 * (trim_az + AZ[0]), -9.80, -9.70], abs=1e-12)


def test_a_missing_reading_holds_and_the_mean_follows_the_held_value():
    split, rows = split_of("frame_mean")
    az = [u[3] for u, _ in fly(split, rows, fresh=(True, False, True))]
    assert az[1] == pytest.approx(AZ[0]) and az[2] == pytest.approx(0.5 * (AZ[0] + AZ[2]))


def test_the_other_inputs_and_the_throttle_row_keep_the_frames_own_reading():
    end, rows = split_of("frame_end")
    mean, _ = split_of("frame_mean")
    for (u_end, y_end), (u_mean, y_mean) in zip(fly(end, rows), fly(mean, rows), strict=True):
        assert np.array_equal(np.delete(u_end, 3), np.delete(u_mean, 3))
        assert np.array_equal(y_end, y_mean)                     # the implied throttle: a_z at the end

