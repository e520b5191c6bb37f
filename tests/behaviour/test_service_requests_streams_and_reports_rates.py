"""The service asks the autopilot for the rates it needs and says which rows are missing and why.

A synthetic autopilot stream (the service file's messages, or ArduPlane's through `--autopilot
auto`) is fed as bytes through `fdir run`'s pipeline, with the daemon's `StreamLink` between the
pipeline and a list standing in for the autopilot link; the autopilot's COMMAND_ACKs are fed back
as bytes. Time for the link layer is passed in (no sleeping, no sockets). One end-to-end test
runs the daemon over loopback UDP."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.autopilot_profile import select_autopilot
from fdir_service.daemon import Daemon, StreamLink
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.events import StreamMissing, StreamRequested, StreamSlow
from fdir_service.service_config import ServiceConfig, load_service_config
from tests.behaviour.test_ardupilot_stream_gives_every_row import ardupilot_bytes
from tests.helpers.service import fake_factory
from tests.helpers.streams import Events

CFG = load_service_config()
SMI = dialect.MAV_CMD_SET_MESSAGE_INTERVAL
GENERIC = dialect.MAV_AUTOPILOT_GENERIC
NAN21 = [math.nan] * 21


def ack_bytes(mav, result: int) -> bytes:
    """The autopilot's COMMAND_ACK of SET_MESSAGE_INTERVAL to us (system 1, component 191); a new
    sequence number each time, as a real sender (the same bytes again would be a duplicate)."""
    b = mav.command_ack_encode(SMI, result, 0, 0, 1, 191).pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return b


def frames_bytes(mav, k0: int, n: int, gps_every: int = 4, omit: tuple[str, ...] = (),
                 autopilot: int = GENERIC) -> list[bytes]:
    """Packets of frames k0..k0+n-1 (20 Hz, boot time 1 s + 50 ms k) of the service file's mapping:
    HEARTBEAT each second, ATTITUDE, ODOMETRY (body), SCALED_IMU, SCALED_PRESSURE,
    ACTUATOR_OUTPUT_STATUS every frame, GPS_RAW_INT every `gps_every` frames; `omit`: types left out."""
    press = pressure_from_altitude(500.0) / 100.0
    out = []
    for k in range(k0, k0 + n):
        t, wob = 1000 + 50 * k, 1e-3 * math.sin(0.7 * k)
        msgs = [mav.attitude_encode(t, 0.0, 0.05 + wob, 0.0, 0.0, 0.01 + wob, 0.0),
                mav.odometry_encode(t * 1000, 1, 12, 0, 0, 0, [1, 0, 0, 0], 23.0 + wob, 0, 1.0 + wob,
                                    0, 0, 0, NAN21, NAN21),
                mav.scaled_imu_encode(t, 10 + k % 3, 0, -1000 + k % 3, 0, 0, 0, 0, 0, 0),
                mav.scaled_pressure_encode(t, press + wob, 3.24 + wob, 2500),
                mav.actuator_output_status_encode(t * 1000, 3, [0.0, 0.5] + [0.0] * 30)]
        if k % 20 == 0:
            msgs.insert(0, mav.heartbeat_encode(dialect.MAV_TYPE_FIXED_WING, autopilot, 0, 0,
                                                dialect.MAV_STATE_ACTIVE))
        if k % gps_every == 0:
            msgs.append(mav.gps_raw_int_encode(t * 1000, 3, 0, 0, 500_000 + k, 100, 150, 2300, 0, 12))
        for m in msgs:
            if m.get_type() not in omit:
                out.append(m.pack(mav))
                mav.seq = (mav.seq + 1) % 256
    return out


class Rig:
    """A pipeline (fake filter) and its StreamLink; `written`: what went to the autopilot."""

    def __init__(self, config: ServiceConfig = CFG) -> None:
        self.events = Events()
        self.pipe = Pipeline(config, observers=[self.events], filter_factory=fake_factory([]))
        self.written: list[bytes] = []
        self.notified: list[bytes] = []
        self.link = StreamLink(self.pipe, self.written.append, notify=self.notified.append)
        self.ap = new_mavlink(1, 1)
        self.out: list[bytes] = []
        self.now = 0.0

    def feed(self, packets: list[bytes]) -> None:
        for b in packets:
            self.out += self.pipe.feed(b, 0)
            self.link.on_input(self.now)

    def ack(self, result: int) -> None:
        self.feed([ack_bytes(self.ap, result)])

    def requests(self) -> list:
        """The stream requests written (parameter requests: test_service_asks_for_its_parameters)."""
        msgs = new_mavlink(255, 0).parse_buffer(b"".join(self.written)) or []
        self.written.clear()
        return [m for m in msgs if m.get_type() != "PARAM_REQUEST_READ"]

    def statustexts(self) -> list[str]:
        """The STATUSTEXTs sent (on frames and by the link), chunks joined."""
        msgs = new_mavlink(255, 0).parse_buffer(b"".join(self.out + self.notified)) or []
        texts: list[str] = []
        for m in (m for m in msgs if m.get_type() == "STATUSTEXT"):
            if m.id and m.chunk_seq:
                texts[-1] += m.text
            else:
                texts.append(m.text)
        return texts


def test_after_the_heartbeat_each_mapped_message_is_requested_at_its_rate():
    rig = Rig()
    rig.feed(frames_bytes(rig.ap, 0, 3)[1:])                     # no HEARTBEAT yet: nothing asked
    assert rig.requests() == []
    rig.feed(frames_bytes(rig.ap, 20, 1)[:1])                    # the HEARTBEAT
    asked = []
    for _ in range(10):
        reqs = rig.requests()
        if not reqs:
            break
        asked += [(m.get_type(), m.target_system, m.target_component, m.command, m.param1, m.param2)
                  for m in reqs]
        rig.ack(dialect.MAV_RESULT_ACCEPTED)
    ids = {name: getattr(dialect, f"MAVLINK_MSG_ID_{name}") for name in (
        "GPS_RAW_INT", "SCALED_PRESSURE", "ODOMETRY", "ATTITUDE", "SCALED_IMU", "ACTUATOR_OUTPUT_STATUS")}
    assert asked == [("COMMAND_LONG", 1, 1, SMI, float(ids[n]), us) for n, us in (
        ("GPS_RAW_INT", 200_000.0), ("SCALED_PRESSURE", 50_000.0), ("ODOMETRY", 50_000.0),
        ("ATTITUDE", 50_000.0), ("SCALED_IMU", 50_000.0), ("ACTUATOR_OUTPUT_STATUS", 50_000.0))]
    answered = rig.events.of(StreamRequested)
    assert [(e.message, e.outcome) for e in answered] == [(n, "accepted") for n in ids]
    assert answered[0].text == "stream request GPS_RAW_INT at 5 Hz (interval 200000 us): accepted"


def test_a_stream_that_never_comes_is_reported_with_its_reason():
    rig = Rig()
    rig.feed(frames_bytes(rig.ap, 0, 1, omit=("SCALED_PRESSURE",)))
    rig.requests()
    rig.ack(dialect.MAV_RESULT_ACCEPTED)                         # GPS_RAW_INT
    rig.ack(dialect.MAV_RESULT_DENIED)                           # SCALED_PRESSURE
    for _ in range(4):
        rig.ack(dialect.MAV_RESULT_ACCEPTED)
    rig.feed(frames_bytes(rig.ap, 1, 200, omit=("SCALED_PRESSURE",)))
    missing = rig.events.of(StreamMissing)
    assert [(e.rows, e.message, e.reason) for e in missing] == [
        (("baro_alt", "airspeed"), "SCALED_PRESSURE", "request denied")]
    wanted = "FDIR no baro_alt,airspeed: SCALED_PRESSURE not received (request denied)"
    assert rig.statustexts().count(wanted) == 1                  # once, though it stays missing
    assert ("warning", wanted[5:]) in rig.events.events
    assert rig.events.of(StreamSlow) == []
    for o in rig.events.estimates:
        assert np.isfinite(o.x_mean).all()


def test_a_stream_at_2_hz_is_reported_with_its_measured_rate():
    rig = Rig(select_config(request=False))
    rig.feed(frames_bytes(rig.ap, 0, 240, gps_every=10))
    slow = rig.events.of(StreamSlow)
    assert [(e.rows, e.message, e.wanted_hz) for e in slow] == [(("gnss_alt",), "GPS_RAW_INT", 5.0)]
    assert slow[0].rate_hz == pytest.approx(2.0, abs=0.25)
    assert "FDIR gnss_alt at 2.0 Hz, wanted 5 Hz" in rig.statustexts()
    assert rig.pipe.rates.rates["ATTITUDE"] == pytest.approx(20.0, abs=0.5)


def select_config(request: bool = True, autopilot: str = "none") -> ServiceConfig:
    text = CFG.text.replace("request = true", f"request = {str(request).lower()}")
    return select_autopilot(ServiceConfig.from_toml_text(text), autopilot)


def test_requests_off_sends_nothing_and_says_so():
    rig = Rig(select_config(request=False))
    rig.feed(frames_bytes(rig.ap, 0, 160, omit=("ODOMETRY",)))
    for now in (1.0, 5.0, 30.0):
        rig.link.poll(now)
    assert rig.written == []
    assert "FDIR no u,w,v: ODOMETRY not received (requests off)" in rig.statustexts()


def test_no_answer_is_retried_then_reported():
    rig = Rig()
    rig.feed(frames_bytes(rig.ap, 0, 1))
    first = rig.requests()
    assert [(m.param1, m.confirmation) for m in first] == [(dialect.MAVLINK_MSG_ID_GPS_RAW_INT, 0)]
    for now, confirmation in ((1.0, 1), (2.0, 2)):
        rig.link.poll(now)
        assert [m.confirmation for m in rig.requests()] == [confirmation]
    rig.link.poll(3.0)
    assert [m.param1 for m in rig.requests()] == [dialect.MAVLINK_MSG_ID_SCALED_PRESSURE]
    assert [(e.message, e.outcome) for e in rig.events.of(StreamRequested)] == [
        ("GPS_RAW_INT", "no answer to the request")]


def test_ardupilot_refusal_falls_back_to_request_data_stream():
    rig = Rig(select_config(autopilot="auto"))
    rig.feed([ardupilot_bytes(0.05)])                            # its HEARTBEAT picks the profile
    assert [(m.get_type(), m.param1, m.param2) for m in rig.requests()] == [
        ("COMMAND_LONG", dialect.MAVLINK_MSG_ID_GPS_RAW_INT, 200_000.0)]
    rig.ack(dialect.MAV_RESULT_UNSUPPORTED)
    rds, nxt = rig.requests()
    assert (rds.get_type(), rds.req_stream_id, rds.req_message_rate, rds.start_stop) == (
        "REQUEST_DATA_STREAM", dialect.MAV_DATA_STREAM_EXTENDED_STATUS, 5, 1)
    assert nxt.param1 == dialect.MAVLINK_MSG_ID_SCALED_PRESSURE
    assert rig.events.of(StreamRequested)[0].outcome == "request unsupported; requested as data stream 2"


def test_without_any_frame_the_missing_streams_are_reported_after_the_window():
    rig = Rig()
    rig.feed(frames_bytes(rig.ap, 0, 1)[:1])                     # a HEARTBEAT only, ever
    for _ in range(6):
        rig.ack(dialect.MAV_RESULT_DENIED)
    rig.link.poll(4.0)
    assert rig.statustexts() == []
    rig.link.poll(5.0)
    texts = rig.statustexts()
    assert len(texts) == 6 and texts[0] == "FDIR no gnss_alt: GPS_RAW_INT not received (request denied)"


def test_the_daemon_requests_streams_over_udp():
    from sim_bridge.demo import free_udp_port
    from tests.e2e.test_link_loss_security_and_daemon import Peer

    port = free_udp_port()
    pipe = Pipeline(CFG, filter_factory=fake_factory([]))
    d = Daemon(pipe, f"udpin:127.0.0.1:{port}", log=lambda s: None)
    th = threading.Thread(target=d.run, kwargs={"install_signals": False, "max_seconds": 20}, daemon=True)
    th.start()
    try:
        peer, ap = Peer(port), new_mavlink(1, 1)
        for b in frames_bytes(ap, 0, 1)[:1]:
            peer.send(b)
        asked = []
        for _ in range(40):
            peer.poll(0.05)
            cmds = [m for m in peer.msgs if m.get_type() == "COMMAND_LONG"]
            peer.msgs.clear()
            for m in cmds:
                asked.append(int(m.param1))
                peer.send(ack_bytes(ap, dialect.MAV_RESULT_ACCEPTED))
            if len(asked) >= 6:
                break
        assert asked[:2] == [dialect.MAVLINK_MSG_ID_GPS_RAW_INT, dialect.MAVLINK_MSG_ID_SCALED_PRESSURE]
        assert len(asked) == 6
    finally:
        d.stop()
        th.join(5)
