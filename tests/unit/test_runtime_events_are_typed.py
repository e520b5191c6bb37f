"""Runtime events: typed fields, levels, and the log wording made from them (the recorded /fdir/log
text must stay what it was)."""

from __future__ import annotations

import dataclasses

import pytest

from fdir_service.runtime.events import (
    OPERATOR_REASONS,
    Cause,
    EpochOffsetJumped,
    EpochTimeUnmapped,
    FaultCleared,
    FaultDeclared,
    FilterStepFailed,
    FramesMissing,
    HealthProblem,
    LinkLost,
    LinkRegained,
    OtherSystemIgnored,
    PipelineClosed,
    Reinitialised,
    Rejected,
    RejectionSummary,
    SensorFrozen,
    SensorRecovered,
    SensorStale,
    SensorUnfrozen,
    TimeJumped,
)


def test_rejected_keys_are_the_counter_keys_and_operator_reasons_are_typed():
    assert Rejected("duplicate").key == "duplicate"
    assert Rejected("out of range", "gnss_alt").key == "gnss_alt out of range"
    assert Rejected("command ignored", "COMMAND_LONG").key == "command ignored (COMMAND_LONG)"
    assert Rejected("not matching where", "ODOMETRY").key == "ODOMETRY not matching where"
    assert Rejected("late", "delta_e").key == "delta_e late"
    # operator reasons by the reason, whatever the field is called
    assert Rejected("out of range", "theta").operator and Rejected("frozen", "q").operator
    assert Rejected("command ignored", "SET_MODE").operator and Rejected("unsigned").operator
    for normal in ("duplicate", "late measurement", "surplus (above frame rate)", "unknown message id"):
        assert not Rejected(normal).operator and normal not in OPERATOR_REASONS
    assert not Rejected("late", "unsigned_row").operator       # a row's name is not a reason
    assert Rejected("mavlink1").text == "rejected input: first mavlink1"
    assert Rejected("mavlink1").level == "warning"


def test_events_are_frozen_values_compared_by_fields():
    a, b = SensorStale("baro_alt", "SCALED_PRESSURE", 1.05), SensorStale("baro_alt", "SCALED_PRESSURE", 1.05)
    assert a == b and hash(a) == hash(b) and a != SensorStale("gnss_alt", "GPS_RAW_INT", 1.05)
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.silent_s = 2.0  # type: ignore[misc]


@pytest.mark.parametrize(("event", "level", "text", "notice"), [
    (SensorStale("baro_alt", "SCALED_PRESSURE", 1.05), "warning",
     "baro_alt stale: no SCALED_PRESSURE for 1.05 s", True),
    (SensorRecovered("baro_alt"), "info", "baro_alt recovered", True),
    (SensorFrozen("gnss_alt", 501.234, 1.0), "warning", "gnss_alt frozen at 501.234 for 1.00 s", True),
    (SensorUnfrozen("gnss_alt"), "info", "gnss_alt no longer frozen", True),
    (TimeJumped(12.35, 0.05, backward=True), "warning",
     "autopilot time jumped back from 12.35 s to 0.05 s: restarting the frame clock", True),
    (TimeJumped(1.0, 3600.0, backward=False), "warning",
     "autopilot time jumped forward from 1.00 s to 3600.00 s: restarting the frame clock", True),
    (FramesMissing(3.5), "warning", "3.50 s of frames missing (more than max_gap_s): not predicted through",
     False),
    (EpochTimeUnmapped("GPS_RAW_INT"), "info", "GPS_RAW_INT stamped in UNIX-epoch time and no SYSTEM_TIME "
     "yet: placed at the latest stamp until one arrives", False),
    (EpochOffsetJumped(-2.01), "warning",
     "SYSTEM_TIME: UNIX time moved -2.010 s against boot time: new offset taken", False),
    (OtherSystemIgnored(2, 1), "warning", "ignoring system 2 on the link (following system 1)", False),
    (RejectionSummary(5, (("duplicate", 3), ("mavlink1", 2))), "warning",
     "rejected input (5 so far): duplicate 3, mavlink1 2", False),
    (FilterStepFailed(2.0, "LinAlgError", "Singular matrix"), "error",
     "filter step failed at t=2.00 s: LinAlgError: Singular matrix", False),
    (LinkLost(2.04), "error", "link lost: no input from the autopilot for 2.0 s", False),
    (LinkRegained(1.26), "info", "link restored after 1.3 s without input", False),
    (FaultDeclared("gnss", 10.2, 0.98, 50.1, "FDIR gnss fault +50.1 m p=0.98"), "warning",
     "FDIR gnss fault +50.1 m p=0.98 (t=10.20 s)", False),
    (FaultCleared("gnss", 30.0, 0.03, "FDIR gnss cleared p=0.03"), "info",
     "FDIR gnss cleared p=0.03 (t=30.00 s)", False),
    (PipelineClosed(240, ()), "info", "pipeline closed after 240 frames; rejected input: none", False),
    (PipelineClosed(3, (("bad crc", 1),)), "info",
     "pipeline closed after 3 frames; rejected input: bad crc 1", False),
])
def test_event_wording(event, level, text, notice):
    assert event.level == level and event.text == text and event.sensor_notice is notice


def test_reinitialised_level_and_wording_follow_the_cause():
    jump = HealthProblem(Cause.STATE_JUMP, "p_d jump -2e+04/frame")
    e = Reinitialised(5.0, jump, (-500.04, 25.0, 1.234, 0.05, 0.0), ("gnss_alt",))
    assert e.level == "warning" and jump.acute
    assert e.text == ("estimator re-initialised at t=5.00 s (p_d jump -2e+04/frame) from the measurements: "
                      "p_d=-500.0 u=25.00 w=1.23 theta=0.0500 q=0.0000; rows masked this frame: gnss_alt")
    nan = Reinitialised(2.0, HealthProblem(Cause.NON_FINITE, "non-finite estimate"), (0.0,) * 5)
    assert nan.level == "error" and nan.text.endswith("q=0.0000")
    assert not HealthProblem(Cause.DEGENERATE, "N_eff < 1.5 for 10 frames").acute
    assert not HealthProblem(Cause.FILTER_RESET, "filter lost every particle").acute
    assert HealthProblem(Cause.FILTER_RAISED, "filter raised LinAlgError").acute
