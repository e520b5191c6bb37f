"""Frame assembly by message timestamp: completion, u_{k-1}, masks, gaps, staleness, bad values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdir_service.runtime.events import SensorRecovered, SensorStale
from fdir_service.runtime.frames import FrameAssembler
from tests.helpers.experiments import ch4_service
from tests.helpers.messages import TRIM_U, actuators, feed, sensors

CFG = ch4_service()
def test_frame_completes_on_its_last_sensor_message_with_previous_input():
    asm = FrameAssembler(CFG, TRIM_U)
    msgs = sensors(0)
    assert feed(asm, msgs[:-1]) == []
    (f0,) = feed(asm, msgs[-1:])
    assert f0.index == 0 and f0.mask.all() and np.allclose(f0.u, TRIM_U)
    assert f0.y == pytest.approx([500.0, 500.0, 40.0, 1.9, 0.05, 0.0], abs=1e-3)
    feed(asm, actuators(0, -0.1, 0.6))     # u_0, stamped at frame 0, sent after the estimate
    feed(asm, actuators(50, -0.2, 0.7))    # u_1 arriving early must not be used by frame 1
    (f1,) = feed(asm, sensors(50))
    assert f1.time_boot_ms == 50 and f1.u == pytest.approx([-0.1, 0.6])
    (f2,) = feed(asm, sensors(100))
    assert f2.u == pytest.approx([-0.2, 0.7])


def test_missing_message_masks_its_rows_when_a_later_frame_starts():
    asm = FrameAssembler(CFG, TRIM_U)
    feed(asm, sensors(0))
    s1 = sensors(50)
    assert feed(asm, [s1[0], s1[2], s1[3]]) == []          # SCALED_PRESSURE lost
    out = feed(asm, sensors(100))
    assert [f.index for f in out] == [1, 2]
    assert out[0].mask.tolist() == [True, False, True, True, True, True] and math.isnan(out[0].y[1])
    assert out[1].mask.all()


def test_gap_frames_are_predicted_through_and_stale_sensors_reported():
    asm = FrameAssembler(CFG, TRIM_U)
    feed(asm, sensors(0))
    out = feed(asm, sensors(300))                      # frames 1..5 never arrived
    assert [f.index for f in out] == [1, 2, 3, 4, 5, 6]
    assert all(f.synthetic and not f.mask.any() for f in out[:5]) and out[5].mask.all()
    # baro silent for > 1 s: reported stale once, then recovered
    for k in range(7, 30):
        feed(asm, [m for m in sensors(50 * k) if m.get_type() != "SCALED_PRESSURE"])
    (stale,) = [e for e in asm.events if isinstance(e, SensorStale)]
    assert (stale.name, stale.message) == ("baro_alt", "SCALED_PRESSURE")
    assert stale.silent_s == pytest.approx(1.05)
    feed(asm, sensors(1500))
    feed(asm, sensors(1550))
    assert asm.events[-1] == SensorRecovered("baro_alt")


def test_bad_values_are_dropped_and_counted_never_nan_into_y():
    asm = FrameAssembler(CFG, TRIM_U)
    msgs = sensors(0, press_hpa=-5.0, pitch=math.nan)
    (f,) = feed(asm, msgs)
    assert f.mask.tolist() == [True, False, True, True, False, True]
    assert asm.rejected["baro_alt out of range"] == 1 and asm.rejected["theta out of range"] == 1
    assert feed(asm, sensors(0)) == [] and asm.rejected["late measurement"] == 4
