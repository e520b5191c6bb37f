"""Monitored items (issue 17): entries grouped by target, P(item faulty) by noisy-OR, the most
probable type and its value; STATUSTEXT in words per type; per-item hysteresis whose declaration
carries the type and whose type changes are announced."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.estimator_config import FaultSpec
from fdir_service.mavlink import dialect, new_mavlink, pack_fault_types, unpack_fault_types
from fdir_service.runtime.events import FaultCleared, FaultDeclared, FaultTypeChanged
from fdir_service.runtime.frames import AssembledFrame
from fdir_service.runtime.items import (
    combine_probability,
    entry_types,
    is_plain,
    item_frame,
    item_layout,
)
from fdir_service.runtime.publishing import Publisher, statustext_for
from tests.helpers.experiments import ch4_service

DEG = math.pi / 180.0
CFG = ch4_service()


def publish_config(**declare):
    """The ch4 service's publish config with [publish.declare] keys replaced."""
    return dataclasses.replace(CFG.publish, declare=dataclasses.replace(CFG.publish.declare, **declare))


QUICK = publish_config(type_hold_s=0.2)
"""A type named after 0.2 s (the declare hold) instead of the default's second."""


def spec(fid: str, target: str, unit: str, fault_type: str = "bias") -> FaultSpec:
    kind = "actuator" if target in ("delta_e", "delta_t") else "sensor"
    return FaultSpec(fid, target, kind, unit, 0.01, fault_type=fault_type)


FAULTS = (spec("gnss", "gnss_alt", "m"), spec("q", "q", "deg/s"), spec("baro", "baro_alt", "m", "noisy"),
          spec("q_stk", "q", "deg/s", "stuck"), spec("de", "delta_e", "deg", "jammed"),
          spec("dt", "delta_t", "1", "effectiveness"))


def step(p, value=None, estimate=None, types=()) -> StepOutput:
    nf = len(p)
    est = np.zeros(nf) if estimate is None else np.asarray(estimate, dtype=float)
    return StepOutput(0.0, np.zeros(5 + nf), np.eye(5 + nf), tuple(f.id for f in FAULTS[:nf]), est,
                      np.asarray(p, dtype=float), 500.0, False, fault_types=types,
                      fault_value=None if value is None else np.asarray(value, dtype=float))


def test_items_group_entries_by_target_named_by_their_first_entry():
    lay = item_layout(FAULTS)
    assert lay.names == ("gnss", "q", "baro", "de", "dt")
    assert lay.targets == ("gnss_alt", "q", "baro_alt", "delta_e", "delta_t")
    assert lay.entries == ((0,), (1, 3), (2,), (4,), (5,))
    assert entry_types(FAULTS) == ("bias", "bias", "noisy", "stuck", "jammed", "effectiveness")
    assert not is_plain(lay, entry_types(FAULTS))
    plain = item_layout(FAULTS[:2])
    assert is_plain(plain, entry_types(FAULTS[:2])) and plain.entries == ((0,), (1,))


def test_item_probability_sums_exclusive_types_adds_noise_independently_and_keeps_a_single_entry():
    assert combine_probability(np.array([0.6, 0.3])) == pytest.approx(0.9)           # stuck or bias
    assert combine_probability(np.array([0.6, 0.6])) == 1.0                           # clipped
    assert combine_probability(np.array([0.97, 0.0])) == pytest.approx(0.97)
    assert combine_probability(np.array([0.1])) == 0.1            # 1 - (1 - 0.1) would be 0.0999...
    noisy = np.array([False, False, True])
    assert combine_probability(np.array([0.2, 0.1, 0.5]), noisy) == pytest.approx(1 - 0.7 * 0.5)
    batch = combine_probability(np.array([[0.2, 0.1, 0.5], [0.0, 0.0, 0.0]]), noisy)
    assert batch.tolist() == pytest.approx([0.65, 0.0])


def test_item_frame_picks_the_most_probable_entry_its_type_and_value():
    p = [0.02, 0.30, 0.93, 0.97, 0.95, 0.99]
    v = [1.0, 0.5 * DEG, 4.1, 3.2 * DEG, -3.1 * DEG, 0.0]
    view = item_frame(item_layout(FAULTS), step(p, v), entry_types(FAULTS))
    assert view.types == ("bias", "stuck", "noisy", "jammed", "effectiveness")
    assert view.entry.tolist() == [0, 3, 2, 4, 5]
    assert view.p.tolist() == pytest.approx([0.02, 1.0, 0.93, 0.95, 0.99])       # 0.30 + 0.97, clipped
    assert view.value.tolist() == pytest.approx([1.0, 3.2 * DEG, 4.1, -3.1 * DEG, 0.0])
    # the bias entry wins when it is the more probable one; value falls back to the estimate
    view = item_frame(item_layout(FAULTS), step([0, 0.8, 0, 0.1, 0, 0], estimate=[0, 2 * DEG, 0, 0, 0, 0]),
                      entry_types(FAULTS))
    assert view.types[1] == "bias" and view.value[1] == pytest.approx(2 * DEG)


@pytest.mark.parametrize("j, fault_type, value, text", [
    (3, "stuck", 3.2 * DEG, "FDIR q stuck at 3.2 deg/s p=0.97"),
    (4, "jammed", -3.1 * DEG, "FDIR de jammed at -3.1 deg p=0.97"),
    (2, "noisy", 4.1, "FDIR baro noisy x4.1 p=0.97"),
    (5, "effectiveness", 0.0, "FDIR dt effectiveness 0% p=0.97"),
    (5, "effectiveness", -0.004, "FDIR dt effectiveness 0% p=0.97"),
    (5, "effectiveness", 0.456, "FDIR dt effectiveness 46% p=0.97"),
    (5, "engine", 0.03, "FDIR dt engine out, thrust 3% p=0.97"),
    (0, "bias", 50.1, "FDIR gnss fault +50.1 m p=0.97"),
])
def test_statustext_in_words(j, fault_type, value, text):
    name = {3: "q"}.get(j)
    assert statustext_for(FAULTS[j], value, 0.97, True, fault_type, name) == text
    assert statustext_for(FAULTS[j], value, 0.03, False, fault_type, name).endswith("cleared p=0.03")


def frame(k: int) -> AssembledFrame:
    return AssembledFrame(k, 50_000 * k, np.zeros(6), np.ones(6, dtype=bool), np.zeros(2))


def test_item_hysteresis_declares_with_the_type_and_announces_a_type_change():
    pub = Publisher(QUICK, FAULTS[:4], new_mavlink(1, 191), adaptive=False)   # holds 0.2 s
    stuck = step([0.0, 0.02, 0.0, 0.97], value=[0, 0, 0, 3.2 * DEG])
    bias = step([0.0, 0.93, 0.0, 0.05], estimate=[0, 2.5 * DEG, 0, 0])
    events, texts = [], []
    for k, out in enumerate([stuck] * 5 + [bias] * 3 + [bias] * 2 + [step([0.0] * 4)] * 25):
        msgs, ev = pub.publish(frame(200 + k), out)
        events += ev
        texts += [m.text for m in new_mavlink(255, 0).parse_buffer(b"".join(msgs)) or []
                  if m.get_type() == "STATUSTEXT"]
    p_q = 0.02 + 0.97                       # exclusive types: their probabilities add
    assert events[0] == FaultDeclared("q", 10.2, pytest.approx(p_q), pytest.approx(3.2 * DEG),
                                      f"FDIR q stuck at 3.2 deg/s p={p_q:.2f}", "stuck")
    changed = "FDIR q fault +2.5 deg/s p=0.98 (was stuck)"
    assert events[1] == FaultTypeChanged("q", pytest.approx(10.45), pytest.approx(0.98),
                                         pytest.approx(2.5 * DEG), changed, "bias", "stuck")
    assert isinstance(events[2], FaultCleared) and events[2].fault_id == "q" and len(events) == 3
    assert texts == [e.statustext for e in events]
    assert pub.hyst[1].fault_type == "bias"


def test_a_type_flicker_shorter_than_the_hold_is_not_announced():
    pub = Publisher(QUICK, FAULTS[:4], new_mavlink(1, 191), adaptive=False)
    stuck = step([0.0, 0.1, 0.0, 0.97])
    bias = step([0.0, 0.98, 0.0, 0.05])
    seq = [stuck] * 5 + ([bias] * 3 + [stuck] * 2) * 4
    events = [e for k, o in enumerate(seq) for e in pub.publish(frame(k), o)[1]]
    assert [type(e) for e in events] == [FaultDeclared]


def test_estimate_channels_are_items_with_type_and_value_extensions():
    pub = Publisher(CFG.publish, FAULTS, new_mavlink(1, 191), adaptive=False)
    out = step([0.02, 0.01, 0.93, 0.97, 0.95, 0.99], value=[1.0, 0.5 * DEG, 4.1, 3.2 * DEG, -3.1 * DEG, 0.0],
               estimate=[1.0, 0.5 * DEG, 3.1, -0.2, -0.01, -1.0])
    msg = pub.estimate_message(frame(1), out)
    assert msg.fault_count == 5
    assert unpack_fault_types(msg.fault_type)[:6] == [
        dialect.FDIR_FAULT_TYPE_BIAS, dialect.FDIR_FAULT_TYPE_STUCK, dialect.FDIR_FAULT_TYPE_NOISY,
        dialect.FDIR_FAULT_TYPE_JAMMED, dialect.FDIR_FAULT_TYPE_EFFECTIVENESS, 0]
    assert list(msg.fault_type) == [0x10, 0x32, 0x04, 0x00]   # two channels per byte, low nibble first
    assert msg.fault_value[:5] == pytest.approx([1.0, 3.2 * DEG, 4.1, -3.1 * DEG, 0.0])
    assert msg.fault[:5] == pytest.approx([1.0, -0.2, 3.1, -0.01, -1.0])   # the chosen entry's state
    assert msg.p_fault[1] == pytest.approx(0.98) and math.isnan(msg.fault_value[5])


def test_fault_types_pack_two_per_byte_and_unpack_from_short_or_missing_fields():
    codes = [1, 2, 3, 4, 5, 0, 1, 2]
    assert pack_fault_types(codes) == [0x21, 0x43, 0x05, 0x21]
    assert unpack_fault_types(pack_fault_types(codes)) == codes
    assert unpack_fault_types([0x21]) == [1, 2, 0, 0, 0, 0, 0, 0]
    assert unpack_fault_types(None) == [0] * 8


def test_a_blocked_pitot_is_said_with_its_reading_and_every_type_has_its_own_code():
    from fdir_service.runtime.items import TYPE_CODES, TYPE_NAMES

    pitot = spec("pitot", "airspeed", "m/s", "blocked")
    assert statustext_for(pitot, 47.04, 0.97, True, "blocked") == "FDIR pitot blocked at 47.0 m/s p=0.97"
    assert TYPE_CODES["blocked"] == dialect.FDIR_FAULT_TYPE_BLOCKED == 5
    assert TYPE_CODES["drift"] == dialect.FDIR_FAULT_TYPE_DRIFT == 6
    assert TYPE_CODES["engine"] == dialect.FDIR_FAULT_TYPE_ENGINE == 7
    assert len(set(TYPE_CODES.values())) == len(TYPE_CODES) and TYPE_NAMES[6] == "drift"
    assert unpack_fault_types(pack_fault_types([5, 6, 7, 0]))[:4] == [5, 6, 7, 0]


def test_a_declaration_whose_types_share_the_evidence_is_unclear_until_one_holds_p_type():
    pub = Publisher(QUICK, FAULTS[:4], new_mavlink(1, 191), adaptive=False)   # p_type 0.8
    split = step([0.0, 0.5, 0.0, 0.45], value=[0, 0, 0, 3.2 * DEG])
    stuck = step([0.0, 0.03, 0.0, 0.95], value=[0, 0, 0, 3.2 * DEG])
    unclear_then_stuck(pub, [split] * 8 + [stuck] * 6, 0.95, 0.0, 10.6)


def unclear_then_stuck(pub: Publisher, seq: list[StepOutput], p: float, estimate: float, named_at: float):
    """Published from 10 s at 20 Hz, seq declares the gyro at 10.2 s as of an unclear type (P p,
    the most probable type's value `estimate`), then names it stuck at named_at (s), and no more."""
    events = [e for k, o in enumerate(seq) for e in pub.publish(frame(200 + k), o)[1]]
    assert events[0] == FaultDeclared("q", 10.2, pytest.approx(p), pytest.approx(estimate),
                                      f"FDIR q fault, type unclear p={p:.2f}", "unclear")
    named = "FDIR q stuck at 3.2 deg/s p=0.98 (was unclear)"
    assert events[1] == FaultTypeChanged("q", pytest.approx(named_at), pytest.approx(0.98),
                                         pytest.approx(3.2 * DEG), named, "stuck", "unclear")
    assert len(events) == 2


def test_p_type_0_and_no_type_hold_name_the_most_probable_type_at_once():
    pub = Publisher(publish_config(p_type=0.0, type_hold_s=0.0), FAULTS[:4], new_mavlink(1, 191),
                    adaptive=False)
    split = step([0.0, 0.45, 0.0, 0.5], value=[0, 0, 0, 3.2 * DEG])
    events = [e for k, o in enumerate([split] * 8) for e in pub.publish(frame(200 + k), o)[1]]
    assert [(type(e), e.fault_type) for e in events] == [(FaultDeclared, "stuck")]


def test_with_a_type_hold_a_type_is_named_once_it_has_held_its_share_that_long():
    assert CFG.publish.declare.type_hold_s == 0.0                 # the default: no hold
    pub = Publisher(publish_config(type_hold_s=0.5), FAULTS[:4], new_mavlink(1, 191), adaptive=False)
    bias = step([0.0, 0.97, 0.0, 0.02], estimate=[0, 2.5 * DEG, 0, 0])
    stuck = step([0.0, 0.03, 0.0, 0.95], value=[0, 0, 0, 3.2 * DEG])
    # a young offset for 0.45 s, then a stuck gyro: named at 10.95 s (stuck since 10.45 s, held 0.5 s)
    unclear_then_stuck(pub, [bias] * 9 + [stuck] * 30, 0.99, 2.5 * DEG, 10.95)


def test_a_type_clear_before_the_declaration_counts_toward_its_hold():
    pub = Publisher(publish_config(p_declare=0.95, type_hold_s=0.5), FAULTS[:4], new_mavlink(1, 191),
                    adaptive=False)
    sure = step([0.0, 0.0, 0.0, 0.93], value=[0, 0, 0, 3.2 * DEG])      # P 0.93: clear, not declared
    above = step([0.0, 0.0, 0.0, 0.97], value=[0, 0, 0, 3.2 * DEG])
    seq = [sure] * 10 + [above] * 10
    events = [e for k, o in enumerate(seq) for e in pub.publish(frame(200 + k), o)[1]]
    assert [type(e) for e in events] == [FaultDeclared] and events[0].fault_type == "unclear"
    pub = Publisher(publish_config(declare_hold_s=0.6, type_hold_s=0.5), FAULTS[:4], new_mavlink(1, 191),
                    adaptive=False)
    events = [e for k, o in enumerate([above] * 30) for e in pub.publish(frame(200 + k), o)[1]]
    declared_at = [(type(e), e.fault_type, e.time_s) for e in events]
    assert declared_at == [(FaultDeclared, "stuck", pytest.approx(10.6))]
