"""Bad input (issue 7): every kind is counted, logged as an event, reported by a rate-limited
STATUSTEXT where an operator should know, never crashes the pipeline and never reaches the filter
as a non-finite value. Plus the bulk run: >= 100 000 mutated packets (hypothesis + seeded random)
through a pipeline with a real particle filter, which keeps publishing finite estimates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.events import (
    OtherSystemIgnored,
    Rejected,
    SensorFrozen,
    SensorUnfrozen,
    TimeJumped,
)
from tests.helpers.experiments import CH4
from tests.helpers.service import autopilot_stream
from tests.helpers.streams import (
    CFG,
    PACKETS,
    STREAM,
    Events,
    assert_filter_inputs_finite,
    check_output,
    encoder,
    fake_pipeline,
    feed_all,
    reencode,
    run_mutated,
    texts,
    v1_frame,
)


def test_mavlink1_unknown_ids_and_commands_are_dropped_counted_and_reported():
    pipe, filt, ev = fake_pipeline()
    mav = encoder()
    gcs = encoder(255, 190)
    cmd = bytes(dialect.MAVLink_command_long_message(1, 191, dialect.MAV_CMD_DO_SET_MODE, 0,
                                                     1, 0, 0, 0, 0, 0, 0).pack(gcs))
    unknown = bytearray(bytes(dialect.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3).pack(mav)))
    unknown[7:10] = (50_001).to_bytes(3, "little")        # a message id nobody defines
    attitude = next(p for p in PACKETS if new_mavlink(255, 0).parse_buffer(p)[0].get_type() == "ATTITUDE")
    packets = []
    for i, p in enumerate(PACKETS[:600]):
        packets.append(p)
        if i % 50 == 10:
            packets += [v1_frame(attitude), cmd, bytes(unknown)]
    msgs = feed_all(pipe, packets)
    c = pipe.rejected_counts
    assert c["mavlink1"] == 12 and c["command ignored (COMMAND_LONG)"] == 12
    assert c["unknown message id"] == 12
    assert pipe.frames >= 80 and len(filt[0].calls) == pipe.frames   # the good input still flows
    # the command changed nothing: same behaviour as without it
    ref, _, _ = fake_pipeline()
    feed_all(ref, PACKETS[:600])
    assert ref.frames == pipe.frames
    first = ev.of(Rejected)
    assert Rejected("mavlink1") in first and Rejected("command ignored", "COMMAND_LONG") in first
    assert Rejected("unknown message id") in first
    st_ = texts(msgs)
    # operator-relevant: reported, but rate-limited (first occurrence, then once per 10 s of frame time)
    assert sum("command ignored" in t for t in st_) == 1
    assert sum("mavlink1" in t for t in st_) == 1
    assert not any("unknown message id" in t for t in st_)


def test_duplicated_and_reordered_packets():
    pipe, filt, ev = fake_pipeline()
    rng = np.random.default_rng(1)
    packets = []
    for p in PACKETS[:700]:
        packets.append(p)
        if rng.random() < 0.2:
            packets.append(p)                       # duplicated
    for i in range(5, len(packets) - 1, 9):         # reordered: swap neighbours
        packets[i], packets[i + 1] = packets[i + 1], packets[i]
    msgs = feed_all(pipe, packets)
    c = pipe.rejected_counts
    assert c["duplicate"] >= 100
    assert pipe.frames >= 95
    times = [t for t, *_ in filt[0].calls]
    assert np.all(np.diff(times) > 0)               # the filter's time never goes back
    assert not any("duplicate" in t for t in texts(msgs))   # normal on a radio link: no STATUSTEXT
    assert Rejected("duplicate") in ev.of(Rejected)


def test_timestamps_jumping_back_or_forward_once_are_dropped_not_followed():
    pipe, filt, ev = fake_pipeline()
    packets = list(PACKETS)
    for i in (1000, 1300):   # frames ~140 and ~185: "boot" is more than the 100-frame late window back
        m = new_mavlink(255, 0).parse_buffer(packets[i])[0]
        field = "time_usec" if hasattr(m, "time_usec") else "time_boot_ms"
        packets[i] = reencode(packets[i], **{field: 0})                    # back to boot
        packets[i + 1] = reencode(packets[i + 1], **(
            {"time_usec": 2**62} if hasattr(m, "time_usec") else {"time_boot_ms": 2**32 - 1}))
    feed_all(pipe, packets)
    assert pipe.rejected_counts["time jump"] == 4
    assert pipe.frames >= 235
    assert not ev.of(TimeJumped)
    assert_filter_inputs_finite(filt[0])


def test_a_confirmed_time_jump_restarts_the_frame_clock():
    pipe, filt, ev = fake_pipeline()
    packets = PACKETS[: 7 * 120]   # about 6 s
    # the autopilot reboots: its clock restarts at 0 (the same stream again)
    msgs = feed_all(pipe, packets + packets)
    (jump,) = ev.of(TimeJumped)
    assert jump.backward and jump.to_s < 0.2 < 5.5 < jump.from_s, jump
    assert any("time jumped back" in t for t in texts(msgs))
    # the filter is rebuilt from the measurements when the clock restarts
    assert len(filt) == 2 and pipe.reinitialisations == 1
    assert filt[0].calls[-1][0] > 5.0 and filt[1].calls[0][0] < 0.2 and filt[1].calls[-1][0] > 5.0
    # only the messages that confirmed the jump were lost: about two frames
    assert pipe.frames >= 2 * 119 - 3 and pipe.rejected_counts["time jump"] == 9


@pytest.mark.parametrize(("field", "value"), [("pitch", math.nan), ("pitch", math.inf),
                                              ("pitch", 7.0), ("pitchspeed", -math.inf)])
def test_non_finite_and_out_of_range_values_never_reach_the_filter(field, value):
    pipe, filt, ev = fake_pipeline()
    def is_attitude(p):
        return new_mavlink(255, 0).parse_buffer(p)[0].get_type() == "ATTITUDE"

    packets = [reencode(p, **{field: value}) if is_attitude(p)
               else p for p in PACKETS[:400]]
    msgs = feed_all(pipe, packets)
    row = "theta" if field == "pitch" else "q"
    assert pipe.rejected_counts[f"{row} out of range"] >= 55
    assert_filter_inputs_finite(filt[0])
    j = CH4.sensors.measurements.index(row)
    assert not any(mask[j] for _, _, mask, _ in filt[0].calls)
    assert sum(f"{row} out of range" in t for t in texts(msgs)) == 1      # rate-limited
    assert pipe.frames >= 55


def test_frozen_sensor_is_masked_and_reported_then_recovers():
    pipe, filt, ev = fake_pipeline()
    packets = []
    for k, (_, sens, acts) in enumerate(STREAM):
        for p in sens:
            if 60 <= k < 140 and new_mavlink(255, 0).parse_buffer(p)[0].get_type() == "GPS_RAW_INT":
                p = reencode(p, alt=501_234)         # stuck for 4 s
            packets.append(p)
        packets += acts
    msgs = feed_all(pipe, packets)
    masks = np.array([m for _, _, m, _ in filt[0].calls])
    # frozen_s = 1.0: masked from 1 s after the value froze until it moves again
    assert masks[60:80, 0].all() and not masks[81:140, 0].any() and masks[141:, 0].all()
    (frozen,) = ev.of(SensorFrozen)
    assert frozen.name == "gnss_alt" and frozen.value == pytest.approx(501.234)
    assert frozen.held_s == pytest.approx(1.0) and frozen.level == "warning"
    assert ev.of(SensorUnfrozen) == [SensorUnfrozen("gnss_alt")]
    assert any("gnss_alt frozen" in t for t in texts(msgs))


@pytest.mark.parametrize("factor", [0.1, 0.5, 2.0, 10.0])
def test_message_rates_from_a_tenth_to_ten_times_nominal(factor):
    """The autopilot sends every 1/factor-th frame (slow) or factor messages per frame (fast)."""
    from sim_bridge.mavlink_bridge import AutopilotLink
    from sim_bridge.simulate import SimStepper, default_autopilot

    pipe, filt, ev = fake_pipeline()
    sc = CH4
    stepper = SimStepper(sc, 2)
    ap = default_autopilot(sc, stepper.airframe)
    link = AutopilotLink(sc)
    dt = sc.dt_s
    n_frames = 120
    out = []
    for k in range(n_frames):
        fr = stepper.frame()
        u = ap.update(fr.t, fr.z_true)
        if factor < 1 and k % round(1 / factor):
            stepper.advance(u)
            continue
        reps = int(factor) if factor >= 1 else 1
        for r in range(reps):   # sub-frame samples, stamped across the frame's half-period window
            t = max(fr.t - 0.45 * dt + r * 0.9 * dt / reps, 0.0)
            for b in link.sensor_messages(t, fr.y, fr.mask, fr.static_pressure_pa):
                out += pipe.feed(b, k)
        for b in link.actuator_messages(fr.t, u):
            out += pipe.feed(b, k)
        stepper.advance(u)
    assert_filter_inputs_finite(filt[0])
    times = np.array([t for t, *_ in filt[0].calls])
    assert np.all(np.diff(times) > 0)
    if factor < 1:
        # frames in between are predicted through (masked); every 1/factor-th one is measured
        measured = sum(m.all() for _, _, m, _ in filt[0].calls)
        assert measured == pytest.approx(n_frames * factor, abs=1)
        assert pipe.frames >= n_frames - round(1 / factor)
    else:
        assert pipe.frames >= n_frames - 1
        if factor > 1:
            assert pipe.rejected_counts["surplus (above frame rate)"] > 0


def test_second_system_on_the_link_is_ignored_counted_and_reported():
    pipe, filt, ev = fake_pipeline()
    other = autopilot_stream(5.0, seed=9)
    from sim_bridge.mavlink_bridge import AutopilotLink

    link2 = AutopilotLink(CH4, system=2)
    intruder = [b for fr, _, _ in other for b in link2.sensor_messages(fr.t, fr.y + 100.0, fr.mask, 90000.0)]
    packets = []
    for i, p in enumerate(PACKETS[:700]):
        packets.append(p)
        if i < len(intruder):
            packets.append(intruder[i])
    msgs = feed_all(pipe, packets)
    assert pipe.rejected_counts["other system"] == len(intruder[:700])
    assert pipe.frames >= 99
    ys = np.array([y[0] for _, y, m, _ in filt[0].calls if m[0]])
    assert np.abs(ys - 500.0).max() < 30.0        # never the intruder's +100 m
    assert ev.of(OtherSystemIgnored) == [OtherSystemIgnored(system=2, following=1)]
    assert sum("other system" in t for t in texts(msgs)) == 1


@pytest.fixture(scope="module")
def small_pf():
    ev = Events()
    return Pipeline(CFG, filter_name="RJMRPF", particles=20, seed=1, observers=[ev]), ev


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture],
          derandomize=True, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(seed=st.integers(0, 2**32 - 1), p_mutate=st.floats(0.0, 0.6))
def test_property_mutated_streams_keep_the_service_publishing_finite_estimates(small_pf, seed, p_mutate):
    pipe, ev = small_pf
    ev.estimates.clear()
    frames0 = pipe.frames
    fed, out = run_mutated(pipe, np.random.default_rng(seed), 1000, p_mutate)
    assert fed >= 1000
    # >= 1000 packets = ~140 frames of flight; the bulk of them must come through
    check_output(pipe, ev, out, min_frames=1)
    assert pipe.frames - frames0 >= 40


def test_bulk_random_mutation_run_keeps_publishing(small_pf):
    """Together with the property test (40 x >= 1000): >= 100 000 packets into the pipeline."""
    pipe, ev = small_pf
    ev.estimates.clear()
    frames0 = pipe.frames
    fed, out = run_mutated(pipe, np.random.default_rng(2024), 62_000, 0.3)
    assert fed >= 62_000
    check_output(pipe, ev, out, min_frames=5000)
    assert pipe.frames - frames0 >= 5000
    c = pipe.rejected_counts
    for reason in ("bad crc", "mavlink1", "duplicate", "time jump"):
        assert c[reason] > 0, c

