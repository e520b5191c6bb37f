"""Stream requests and rates (`runtime.streams`): the wanted rate per message, the
MAV_CMD_SET_MESSAGE_INTERVAL sequence and its COMMAND_ACK handling (accepted, denied with
ArduPilot's REQUEST_DATA_STREAM fallback, no answer with retries, temporarily rejected, in
progress), the arrival-rate monitor's reports, chunked STATUSTEXT and the `[streams]` config."""

from __future__ import annotations

import pytest

from fdir_service.autopilot_profile import select_autopilot
from fdir_service.errors import ConfigError
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import StreamMissing, StreamRateOk, StreamSlow
from fdir_service.runtime.publishing import Publisher
from fdir_service.runtime.streams import (
    NO_ANSWER,
    REQUESTS_OFF,
    RateMonitor,
    StreamRequester,
    rows_by_message,
    wanted_rates,
)
from fdir_service.service_config import StreamConfig, load_service_config

CFG = load_service_config()
ACK = dialect.MAVLink_command_ack_message
SMI = dialect.MAV_CMD_SET_MESSAGE_INTERVAL
APM = dialect.MAV_AUTOPILOT_ARDUPILOTMEGA


def ack(result: int, command: int = SMI):
    return ACK(command, result)


def test_wanted_rates_default_to_the_frame_rate_and_5_hz_gnss():
    assert wanted_rates(CFG) == {"GPS_RAW_INT": 5.0, "SCALED_PRESSURE": 20.0, "ODOMETRY": 20.0,
                                 "ATTITUDE": 20.0, "SCALED_IMU": 20.0, "ACTUATOR_OUTPUT_STATUS": 20.0}
    ardu = select_autopilot(CFG, "ardupilot")
    wanted = wanted_rates(ardu)
    assert "PARAM_VALUE" not in wanted and wanted["GPS_RAW_INT"] == 5.0 and wanted["VFR_HUD"] == 20.0
    assert rows_by_message(ardu)["ATTITUDE"] == ("u", "w", "theta", "q", "roll", "v")
    assert wanted["SYSTEM_TIME"] == 1.0                      # its GPS_RAW_INT is stamped "epoch"
    assert "SYSTEM_TIME" not in wanted_rates(select_autopilot(CFG, "px4"))


def test_rate_hz_is_validated():
    text = load_service_config().text.replace("rate_hz = 5.0 ", "rate_hz = -1.0 ")
    with pytest.raises(ConfigError, match=r"measurements.gnss_alt.rate_hz: expected a rate >= 0"):
        type(CFG).from_toml_text(text)
    with pytest.raises(ConfigError, match=r"streams.bogus"):
        type(CFG).from_toml_text(CFG.text.replace("[streams]", "[streams]\nbogus = 1"))
    off = type(CFG).from_toml_text(CFG.text.replace("request = true", "request = false"))
    assert off.streams.request is False


def test_one_request_per_message_in_turn_each_accepted():
    req = StreamRequester(StreamConfig(), {"ATTITUDE": 20.0, "GPS_RAW_INT": 5.0})
    first = req.start(1, 1, dialect.MAV_AUTOPILOT_GENERIC, 0.0)
    assert [(m.target_system, m.target_component, m.command, m.param1, m.param2, m.confirmation)
            for m in first] == [(1, 1, SMI, dialect.MAVLINK_MSG_ID_ATTITUDE, 50_000.0, 0)]
    assert req.start(1, 1, 0, 0.1) == []                       # only the first HEARTBEAT starts them
    assert req.on_ack(ack(dialect.MAV_RESULT_ACCEPTED, command=dialect.MAV_CMD_DO_SET_MODE), 0.1) == []
    second = req.on_ack(ack(dialect.MAV_RESULT_ACCEPTED), 0.1)
    assert [(m.param1, m.param2) for m in second] == [(dialect.MAVLINK_MSG_ID_GPS_RAW_INT, 200_000.0)]
    assert req.on_ack(ack(dialect.MAV_RESULT_ACCEPTED), 0.2) == [] and req.done
    assert [(o.message, o.interval_us, o.outcome) for o in req.outcomes] == [
        ("ATTITUDE", 50_000, "accepted"), ("GPS_RAW_INT", 200_000, "accepted")]


def test_denied_on_ardupilot_falls_back_to_request_data_stream():
    req = StreamRequester(StreamConfig(), {"SCALED_PRESSURE": 20.0, "ODOMETRY": 20.0})
    req.start(7, 1, APM, 0.0)
    out = req.on_ack(ack(dialect.MAV_RESULT_DENIED), 0.05)
    rds, nxt = out
    assert rds.get_type() == "REQUEST_DATA_STREAM"
    assert (rds.target_system, rds.req_stream_id, rds.req_message_rate, rds.start_stop) == (
        7, dialect.MAV_DATA_STREAM_RAW_SENSORS, 20, 1)
    assert nxt.param1 == dialect.MAVLINK_MSG_ID_ODOMETRY
    assert req.on_ack(ack(dialect.MAV_RESULT_UNSUPPORTED), 0.1) == []   # no ArduPilot group has ODOMETRY
    assert [o.outcome for o in req.outcomes] == ["request denied; requested as data stream 1",
                                                 "request unsupported"]


def test_denied_elsewhere_has_no_fallback():
    req = StreamRequester(StreamConfig(), {"SCALED_PRESSURE": 20.0})
    req.start(1, 1, dialect.MAV_AUTOPILOT_PX4, 0.0)
    assert req.on_ack(ack(dialect.MAV_RESULT_DENIED), 0.05) == []
    assert req.outcomes[0].outcome == "request denied"


def test_no_answer_is_sent_again_then_given_up():
    req = StreamRequester(StreamConfig(ack_timeout_s=1.0, retries=2), {"ATTITUDE": 20.0, "VFR_HUD": 10.0})
    req.start(1, 1, APM, 0.0)
    assert req.poll(0.9) == []
    assert [m.confirmation for m in req.poll(1.0)] == [1]
    assert [m.confirmation for m in req.poll(2.0)] == [2]
    nxt = req.poll(3.0)                                        # 3 sends, no answer: the next message
    assert [(m.param1, m.param2) for m in nxt] == [(dialect.MAVLINK_MSG_ID_VFR_HUD, 100_000.0)]
    assert req.outcomes[0].outcome == NO_ANSWER
    assert req.on_ack(ack(dialect.MAV_RESULT_ACCEPTED), 3.1) == [] and req.done


def test_temporarily_rejected_and_in_progress_wait_and_retry():
    req = StreamRequester(StreamConfig(ack_timeout_s=1.0, retries=1), {"ATTITUDE": 20.0})
    req.start(1, 1, APM, 0.0)
    assert req.on_ack(ack(dialect.MAV_RESULT_IN_PROGRESS), 0.8) == []
    assert req.poll(1.5) == []                                 # the timeout restarted at 0.8 s
    assert req.on_ack(ack(dialect.MAV_RESULT_TEMPORARILY_REJECTED), 1.6) == []
    assert [m.confirmation for m in req.poll(1.9)] == [1]      # sent again after the timeout
    req.on_ack(ack(dialect.MAV_RESULT_TEMPORARILY_REJECTED), 2.0)   # retries used up: settled
    assert req.done and req.outcomes[0].outcome == "request result 1"


def monitor(requested: bool = True) -> RateMonitor:
    return RateMonitor(StreamConfig(window_s=5.0), {"GPS_RAW_INT": 5.0, "SCALED_PRESSURE": 20.0},
                       {"GPS_RAW_INT": ("gnss_alt",), "SCALED_PRESSURE": ("baro_alt", "airspeed")}, requested)


FRAMES: dict[int, int] = {}


def run(mon: RateMonitor, seconds: float, gps_hz: float, baro_hz: float) -> list:
    """The next `seconds` of 20 Hz frames (from 1 s) with arrivals at the given rates; the events."""
    events = []
    start = FRAMES.get(id(mon), 0)
    for k in range(start, start + int(round(seconds * 20))):
        if gps_hz and k % round(20 / gps_hz) == 0:
            mon.counts["GPS_RAW_INT"] += 1
        if baro_hz and k % round(20 / baro_hz) == 0:
            mon.counts["SCALED_PRESSURE"] += 1
        events += mon.check(1_000_000 + 50_000 * k)
    FRAMES[id(mon)] = start + int(round(seconds * 20))
    return events


def test_rates_missing_slow_and_recovered():
    mon = monitor()
    mon.reasons["SCALED_PRESSURE"] = "request denied"
    assert run(mon, 4.9, 2.0, 0.0) == []                       # the first window is not full
    events = run(mon, 2.0, 2.0, 0.0)
    assert events == [StreamSlow(("gnss_alt",), "GPS_RAW_INT", pytest.approx(2.0), 5.0),
                      StreamMissing(("baro_alt", "airspeed"), "SCALED_PRESSURE", "request denied")]
    assert events[0].text == "gnss_alt at 2.0 Hz, wanted 5 Hz"
    assert events[1].text == "no baro_alt,airspeed: SCALED_PRESSURE not received (request denied)"
    assert run(mon, 3.0, 2.0, 0.0) == []                       # reported once, not every second
    back = run(mon, 8.0, 5.0, 20.0)
    assert [(type(e), e.message) for e in back] == [(StreamRateOk, "GPS_RAW_INT"),
                                                    (StreamRateOk, "SCALED_PRESSURE")]
    assert back[1].text == "baro_alt,airspeed back at 20.0 Hz (wanted 20 Hz)"
    assert mon.rates["GPS_RAW_INT"] == pytest.approx(5.0, abs=0.3)
    assert mon.rates["SCALED_PRESSURE"] == pytest.approx(20.0, abs=0.5)


def test_requests_off_is_the_reason_given():
    mon = monitor(requested=False)
    events = run(mon, 7.0, 5.0, 0.0)
    assert [e.text for e in events] == ["no baro_alt,airspeed: SCALED_PRESSURE not received (requests off)"]
    assert mon.reasons["SCALED_PRESSURE"] == REQUESTS_OFF
    assert [e.message for e in monitor().never_received()] == ["GPS_RAW_INT", "SCALED_PRESSURE"]


def test_a_long_statustext_goes_out_in_chunks():
    pub = Publisher(CFG.publish, CFG.estimator.faults, new_mavlink(1, 191), adaptive=False)
    text = "FDIR no baro_alt,airspeed: SCALED_PRESSURE not received (request denied)"
    msgs = new_mavlink(255, 0).parse_buffer(b"".join(pub.statustexts(dialect.MAV_SEVERITY_WARNING, text)))
    assert [(m.id, m.chunk_seq) for m in msgs] == [(1, 0), (1, 1)]
    assert "".join(m.text for m in msgs) == text
    short = new_mavlink(255, 0).parse_buffer(b"".join(pub.statustexts(dialect.MAV_SEVERITY_INFO, "FDIR x")))
    assert [(m.id, m.text) for m in short] == [(0, "FDIR x")]
    exact = new_mavlink(255, 0).parse_buffer(b"".join(pub.statustexts(dialect.MAV_SEVERITY_INFO, "y" * 100)))
    assert [(m.id, m.chunk_seq, len(m.text)) for m in exact] == [(2, 0, 50), (2, 1, 50), (2, 2, 0)]
