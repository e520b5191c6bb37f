"""Frame assembly parts: frame index, input history (u_{k-1}), stale rows, gaps beyond max_gap_s,
time-jump confirmation and the typed events and rejections the assembler produces."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.runtime.events import FramesMissing, SensorRecovered, SensorStale, TimeJumped
from fdir_service.runtime.frames import (
    INPUT_HISTORY,
    JUMP_CONFIRM_MESSAGES,
    FrameAssembler,
    InputHistory,
    StaleRows,
    routes_by_message,
)
from tests.helpers.experiments import ch4_service
from tests.helpers.messages import P500_HPA, TRIM_U, actuators, feed, sensors

CFG = ch4_service()


def test_routes_and_frame_index():
    routes = routes_by_message(CFG)
    assert [(r.kind, r.j, r.fm.name) for r in routes["ODOMETRY"]] == [("y", 2, "u"), ("y", 3, "w")]
    assert [(r.kind, r.j) for r in routes["ACTUATOR_OUTPUT_STATUS"]] == [("u", 0), ("u", 1)]
    assert routes["ATTITUDE"][0].out_of_range.key == "theta out of range"
    asm = FrameAssembler(CFG, TRIM_U)
    assert asm.period_us == 50_000 and asm.max_gap == 40
    # round(t / T): frame 3 spans 125 ms (inclusive) to 175 ms
    assert [asm.frame_index(t) for t in (124_999, 125_000, 150_000, 174_999, 175_000)] == [2, 3, 3, 3, 4]
    assert asm.is_mapped("GPS_RAW_INT") and not asm.is_mapped("HEARTBEAT")


def test_input_history_gives_u_of_the_previous_frame():
    h = InputHistory(np.array([-0.083, 0.532]))
    assert h.for_frame(0).tolist() == [-0.083, 0.532]             # trim until a value arrives
    assert h.record(0, 3, -0.1) and h.record(1, 3, 0.6) and h.record(0, 5, -0.2)
    assert not h.record(0, 4, -0.15)                               # stamped before the latest: late
    assert h.for_frame(4).tolist() == [-0.1, 0.6]                  # u_3
    assert h.for_frame(6).tolist() == [-0.2, 0.6]                  # u_5, throttle held from frame 3
    assert h.record(0, 5, -0.25) and h.for_frame(6)[0] == -0.25    # same frame: replaced
    h.prune(6)
    assert h.hist[0] == [(5, -0.25)] and h.hist[1] == [(3, 0.6)]   # what is in force for frame 6
    for k in range(10, 10 + 2 * INPUT_HISTORY):
        h.record(1, k, k / 100)
    assert len(h.hist[1]) == INPUT_HISTORY


def test_stale_rows_report_once_and_recover():
    events: list = []
    st = StaleRows(CFG.measurements, events)
    for j in range(6):
        st.seen(j, 0)
    assert st.check(1_000_000, 0) == []                            # exactly stale_s: not yet
    st.seen(0, 1_000_000)
    assert st.check(1_050_000, 0) == ["baro_alt", "u", "w", "theta", "q"]
    assert events[0] == SensorStale("baro_alt", "SCALED_PRESSURE", pytest.approx(1.05))
    assert len(events) == 5 and st.check(2_050_000, 0) == ["gnss_alt", "baro_alt", "u", "w", "theta", "q"]
    assert len(events) == 6 and events[-1].name == "gnss_alt"     # newly stale, no repeats
    st.seen(1, 2_100_000)
    st.check(2_100_000, 0)
    assert events[-1] == SensorRecovered("baro_alt")
    st.forget()
    assert st.check(500_000, 0) == []                              # counted from the first frame again
    assert st.check(1_050_000, 0) == ["gnss_alt", "baro_alt", "u", "w", "theta", "q"]


def test_short_gap_is_predicted_through_a_long_one_is_a_time_jump():
    asm = FrameAssembler(CFG, TRIM_U)
    feed(asm, sensors(0))
    out = feed(asm, sensors(2050))                                 # 40 frames missing = max_gap_s
    assert [f.index for f in out] == list(range(1, 42))
    assert all(f.synthetic and not f.mask.any() for f in out[:-1]) and not out[-1].synthetic
    assert not any(isinstance(e, FramesMissing) for e in asm.events)
    msgs = sensors(5100) + sensors(5150) + sensors(5200)           # 3 s later: outside the window
    out = feed(asm, msgs)
    assert asm.rejected["time jump"] == JUMP_CONFIRM_MESSAGES - 1
    (jump,) = [e for e in asm.events if isinstance(e, TimeJumped)]
    assert not jump.backward and jump.from_s == pytest.approx(2.05) and jump.to_s == pytest.approx(5.2)
    out += feed(asm, sensors(5250))
    assert [(f.index, f.restart, f.synthetic) for f in out] == [(104, True, False), (105, False, False)]


def test_time_jump_needs_confirmation_then_restarts_the_clock():
    asm = FrameAssembler(CFG, TRIM_U)
    for k in range(200):                                           # 10 s of frames
        feed(asm, sensors(50 * k) + actuators(50 * k, -0.1, 0.6))
    assert asm.last_index == 199
    msgs = sensors(0) + sensors(50) + sensors(100)                 # the autopilot rebooted
    out = feed(asm, msgs[:JUMP_CONFIRM_MESSAGES - 1])
    assert out == [] and asm.rejected["time jump"] == JUMP_CONFIRM_MESSAGES - 1 and asm.last_index == 199
    out = feed(asm, msgs[JUMP_CONFIRM_MESSAGES - 1:])              # the 10th agreeing message confirms
    (jump,) = [e for e in asm.events if isinstance(e, TimeJumped)]
    assert jump.backward and jump.from_s == pytest.approx(9.95) and jump.to_s == pytest.approx(0.1)
    out += feed(asm, sensors(150))
    assert [(f.index, f.restart) for f in out] == [(2, True), (3, False)]
    assert out[0].mask.tolist() == [False, True, True, True, True, True]   # its GNSS message voted
    assert np.allclose(out[0].u, TRIM_U)                           # inputs restart with the clock


def test_late_and_surplus_measurements_are_counted_apart():
    asm = FrameAssembler(CFG, TRIM_U)
    feed(asm, sensors(0))
    feed(asm, sensors(50))
    assert feed(asm, sensors(60)[:1]) == []                       # frame 1 again, stamped later
    assert feed(asm, sensors(0)[:2]) == []                        # frame 0: late
    assert asm.rejected["surplus (above frame rate)"] == 1 and asm.rejected["late measurement"] == 2


def test_a_slower_sensor_does_not_hold_the_frames_between_its_samples():
    """GNSS at 5 Hz in 20 Hz frames: once its period is learned (3 gaps), the frames between its
    fixes complete on their own last message (GNSS masked) instead of waiting for the next frame."""
    asm = FrameAssembler(CFG, TRIM_U)
    completed_on_own = []
    for k in range(40):
        e = 0.001 * ((k * 7) % 5)                        # changing values: no frozen sensor
        msgs = sensors(50 * k, alt=500.0 + e, press_hpa=P500_HPA - e, pitch=0.05 + e, q=e,
                       u=40.0 + e, w=1.9 + e)
        if k % 4:
            msgs = msgs[1:]                              # no GPS_RAW_INT between fixes
        frames = feed(asm, msgs)
        completed_on_own.append(any(f.index == k for f in frames))
        for f in frames:
            assert f.mask[0] == (f.index % 4 == 0)       # the GNSS row exactly on fix frames
    assert not any(completed_on_own[1:12:4])             # still learning: waits for the next frame
    assert all(completed_on_own[20:])                     # learned: every frame completes at once
    assert asm.rates.due("GPS_RAW_INT", 40) and not asm.rates.due("GPS_RAW_INT", 39)   # last fix: 36
