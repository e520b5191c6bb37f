"""Publishing: declaration events (typed) with their STATUSTEXT, output rates in frame time, the
STATUSTEXT rate limit and the sensor / link notices."""

from __future__ import annotations

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import FaultCleared, FaultDeclared, LinkLost, LinkRegained, SensorStale
from fdir_service.runtime.frames import AssembledFrame
from fdir_service.runtime.publishing import Publisher, RateLimit, link_notice, sensor_notice
from tests.helpers.experiments import ch4_service

CFG = ch4_service()
FAULTS = CFG.estimator.faults


def out(p_gnss: float, f_gnss: float = 50.1) -> StepOutput:
    return StepOutput(0.0, np.zeros(7), np.eye(7), ("gnss", "baro"), np.array([f_gnss, 0.0]),
                      np.array([p_gnss, 0.0]), 800.0, False)


def frame(k: int) -> AssembledFrame:
    return AssembledFrame(k, 50_000 * k, np.zeros(6), np.ones(6, dtype=bool), np.zeros(2))


def decode(chunks: list[bytes]) -> list:
    return new_mavlink(255, 0).parse_buffer(b"".join(chunks)) or []


def test_declaration_after_the_hold_is_a_typed_event_and_a_statustext():
    pub = Publisher(CFG.publish, FAULTS, new_mavlink(1, 191), adaptive=False)
    assert CFG.publish.declare.declare_hold_s == 0.2 and CFG.publish.declare.p_declare == 0.9
    events = []
    for k in range(200, 205):                                      # 10.00 .. 10.20 s at P = 0.98
        msgs, ev = pub.publish(frame(k), out(0.98))
        events += ev
    assert events == [FaultDeclared("gnss", 10.2, 0.98, 50.1, "FDIR gnss fault +50.1 m p=0.98")]
    st = [m for m in decode(msgs) if m.get_type() == "STATUSTEXT"]
    assert [(m.severity, m.text) for m in st] == [(dialect.MAV_SEVERITY_WARNING,
                                                   "FDIR gnss fault +50.1 m p=0.98")]
    assert pub.declared_mask == 0b01
    for k in range(205, 226):                                      # P = 0.03 for clear_hold_s = 1.0 s
        msgs, ev = pub.publish(frame(k), out(0.03))
        events += ev
    assert events[1:] == [FaultCleared("gnss", pytest.approx(11.25), 0.03, "FDIR gnss cleared p=0.03")]
    assert [m.severity for m in decode(msgs) if m.get_type() == "STATUSTEXT"] == [dialect.MAV_SEVERITY_NOTICE]
    assert pub.declared_mask == 0


def test_rates_in_frame_time():
    pub = Publisher(CFG.publish, FAULTS, new_mavlink(1, 191), adaptive=False)
    kinds = [[m.get_type() for m in decode(pub.publish(frame(k), out(0.0))[0])] for k in range(40)]   # 2 s
    assert sum(k.count("FDIR_ESTIMATE") for k in kinds) == 40      # 20 Hz
    assert sum(k.count("HEARTBEAT") for k in kinds) == 2           # 1 s
    assert sum(k.count("NAMED_VALUE_FLOAT") for k in kinds) == 20 * 4   # 10 Hz x (f_, pf_) x 2 faults
    adaptive = Publisher(CFG.publish, FAULTS, new_mavlink(1, 191), adaptive=True)
    o = out(0.5)
    o.pfa, o.pmd = np.array([0.01, 0.02]), np.array([0.1, 0.2])
    names = [m.name for m in decode(adaptive.named_values(1000, o))]
    assert names == ["f_gnss", "pf_gnss", "pfa_gnss", "pmd_gnss", "f_baro", "pf_baro", "pfa_baro", "pmd_baro"]


def test_estimate_bytes_decode_to_the_frame():
    pub = Publisher(CFG.publish, FAULTS, new_mavlink(1, 191), adaptive=False)
    o = out(0.75, 12.5)
    o.x_mean[:5] = [-500.0, 25.0, 1.0, 0.04, 0.001]
    (m,) = decode([pub.estimate_bytes(frame(7), o)])
    assert m.get_type() == "FDIR_ESTIMATE" and m.time_boot_ms == 350 and m.fault_count == 2
    assert m.state == pytest.approx([-500.0, 25.0, 1.0, 0.04, 0.001])
    assert m.fault[:2] == pytest.approx([12.5, 0])
    assert m.p_fault[0] == pytest.approx(0.75) and m.mask == 0b111111 and m.n_eff == 800.0


def test_rate_limit_and_notices():
    limit = RateLimit(10.0)
    assert limit.due("reinit", 5_000_000) and not limit.due("reinit", 14_999_999)
    assert limit.due("reject:mavlink1", 6_000_000)                 # subjects are independent
    assert limit.due("reinit", 15_000_000)
    assert sensor_notice(SensorStale("baro_alt", "SCALED_PRESSURE", 1.05)) == (
        dialect.MAV_SEVERITY_WARNING, "FDIR baro_alt stale: no SCALED_PRESSURE for 1.05 s")
    long = sensor_notice(SensorStale("a_very_long_row_name", "SCALED_PRESSURE", 12.0))[1]
    assert len(long) == 50                                          # STATUSTEXT's 50 characters
    assert link_notice(LinkLost(2.04)) == (dialect.MAV_SEVERITY_CRITICAL,
                                           "FDIR link lost: no input for 2.0 s")
    assert link_notice(LinkRegained(1.26)) == (dialect.MAV_SEVERITY_NOTICE,
                                               "FDIR link restored after 1.3 s")
