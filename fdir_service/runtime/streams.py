"""Stream requests and rates (config `[streams]`, per mapping `rate_hz`).

`wanted_rates` says at what rate (Hz) each message the mapping reads is needed. `StreamRequester`
asks the followed autopilot for them after its first HEARTBEAT: one MAV_CMD_SET_MESSAGE_INTERVAL
(COMMAND_LONG, param1 = message id, param2 = interval in us) at a time, since a COMMAND_ACK names
only the command. Each is answered ACCEPTED, DENIED, UNSUPPORTED, FAILED, TEMPORARILY_REJECTED or
IN_PROGRESS, or not at all: without an answer within `ack_timeout_s` it is sent again (`retries`
times, the COMMAND_LONG confirmation counting up), then given up ("no answer"). On ArduPilot a
refused command falls back to REQUEST_DATA_STREAM of the stream group carrying the message (older
firmware). The requester takes the time (s, any monotonic clock) from its caller: the daemon's
link layer passes the wall clock, the tests a number; the estimator never sees it.

`RateMonitor` measures, in frame time (deterministic, replayable), how fast each wanted message
arrives over a sliding `window_s` and turns that into events: rows whose message never arrived
(`StreamMissing`, with the request's outcome as the reason), rows arriving below `min_fraction` of
the wanted rate (`StreamSlow`) and back at rate (`StreamRateOk`). Per message the cost is one dict
increment (done inline by the pipeline); the rates are computed once per second of frame time.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from fdir_service.mavlink import dialect
from fdir_service.runtime.events import Event, StreamMissing, StreamRateOk, StreamSlow
from fdir_service.service_config import ServiceConfig, StreamConfig

DEFAULT_RATES_HZ = {"GPS_RAW_INT": 5.0}
"""Wanted rates (Hz) of messages whose sensor is slower than the frame rate (a GNSS fix: 5 Hz);
any other message is wanted at the frame rate."""
CLOCK_MESSAGE, CLOCK_RATE_HZ = "SYSTEM_TIME", 1.0
"""Wanted when a row is stamped "epoch": SYSTEM_TIME maps UNIX-epoch stamps onto the boot clock
(`runtime.clock.EpochClock`); once a second follows the clocks' drift."""
NOT_STREAMED = frozenset({"PARAM_VALUE"})
"""Messages a mapping reads that are not periodic streams (never requested, never rate-checked)."""
ARDUPILOT_STREAM_GROUPS = {
    "RAW_IMU": dialect.MAV_DATA_STREAM_RAW_SENSORS,
    "SCALED_IMU": dialect.MAV_DATA_STREAM_RAW_SENSORS,
    "SCALED_IMU2": dialect.MAV_DATA_STREAM_RAW_SENSORS,
    "SCALED_PRESSURE": dialect.MAV_DATA_STREAM_RAW_SENSORS,
    "GPS_RAW_INT": dialect.MAV_DATA_STREAM_EXTENDED_STATUS,
    "SERVO_OUTPUT_RAW": dialect.MAV_DATA_STREAM_RC_CHANNELS,
    "GLOBAL_POSITION_INT": dialect.MAV_DATA_STREAM_POSITION,
    "LOCAL_POSITION_NED": dialect.MAV_DATA_STREAM_POSITION,
    "ATTITUDE": dialect.MAV_DATA_STREAM_EXTRA1,
    "VFR_HUD": dialect.MAV_DATA_STREAM_EXTRA2,
    "SYSTEM_TIME": dialect.MAV_DATA_STREAM_EXTRA3,
}
"""ArduPilot's REQUEST_DATA_STREAM group (its SRn_ parameter) of each message (GCS_Common.cpp)."""
RESULT_WORDS = {
    dialect.MAV_RESULT_ACCEPTED: "accepted",
    dialect.MAV_RESULT_DENIED: "request denied",
    dialect.MAV_RESULT_UNSUPPORTED: "request unsupported",
    dialect.MAV_RESULT_FAILED: "request failed",
}
REFUSED = frozenset({dialect.MAV_RESULT_DENIED, dialect.MAV_RESULT_UNSUPPORTED, dialect.MAV_RESULT_FAILED})
"""Answers after which ArduPilot gets the REQUEST_DATA_STREAM fallback."""
NO_ANSWER = "no answer to the request"
REQUESTS_OFF = "requests off"
PENDING = "request pending"


def wanted_rates(config: ServiceConfig) -> dict[str, float]:
    """Message name -> wanted rate (Hz) for every periodic message the mapping reads: the highest
    `rate_hz` of its rows, else DEFAULT_RATES_HZ, else the frame rate; and SYSTEM_TIME at 1 Hz when
    a row is stamped "epoch"."""
    wanted: dict[str, float] = {}
    rows = config.measurements + config.inputs
    for fm in rows:
        for message in (fm.message, *fm.sources[1:]):
            if message in NOT_STREAMED:
                continue
            rate = fm.rate_hz if message == fm.message and fm.rate_hz > 0 else 0.0
            wanted[message] = max(wanted.get(message, 0.0), rate)
    if any(fm.stamp == "epoch" for fm in rows):
        wanted[CLOCK_MESSAGE] = CLOCK_RATE_HZ
    return {m: r or DEFAULT_RATES_HZ.get(m, config.frame_rate_hz) for m, r in wanted.items()}


def rows_by_message(config: ServiceConfig) -> dict[str, tuple[str, ...]]:
    """Message name -> the rows and inputs that read it (as sample or as a derivation's source)."""
    rows: dict[str, list[str]] = {}
    for fm in config.measurements + config.inputs:
        for message in dict.fromkeys((fm.message, *fm.sources[1:])):
            rows.setdefault(message, []).append(fm.name)
    return {m: tuple(r) for m, r in rows.items()}


def interval_us(rate_hz: float) -> int:
    """The MAV_CMD_SET_MESSAGE_INTERVAL interval (us) of a rate (Hz)."""
    return int(round(1e6 / rate_hz))


# ---------------------------------------------------------------------------- requests

@dataclass
class _Request:
    """One message's SET_MESSAGE_INTERVAL: `sends` so far, when last sent (s), its outcome."""

    message: str
    msg_id: int
    interval_us: int
    sends: int = 0
    sent_s: float = 0.0
    outcome: str = PENDING


@dataclass(frozen=True)
class RequestOutcome:
    """What became of the request for `message` (interval `interval_us`, us): `outcome` ("accepted",
    "request denied", ..., NO_ANSWER, "requested as data stream N")."""

    message: str
    interval_us: int
    outcome: str


class StreamRequester:
    """The stream requests of one autopilot (see the module doc). `start` on its first HEARTBEAT,
    `on_ack` for each COMMAND_ACK from it, `poll` now and then; each returns the pymavlink
    messages to send to the autopilot. `outcomes` collects `RequestOutcome`s for the caller."""

    def __init__(self, config: StreamConfig, wanted: dict[str, float]) -> None:
        self.config = config
        self.wanted = dict(wanted)
        self.queue: deque[_Request] = deque()
        self.current: _Request | None = None
        self.target = (0, 0)
        self.ardupilot = False
        self.started = False
        self.outcomes: list[RequestOutcome] = []
        self.fallback_groups: dict[int, float] = {}

    @property
    def done(self) -> bool:
        """Whether every request has an outcome."""
        return self.started and self.current is None and not self.queue

    def start(self, system: int, component: int, autopilot: int, now_s: float) -> list:
        """The autopilot (system, component, HEARTBEAT.autopilot) was heard at now_s (s): queue a
        request per wanted message and send the first. Only the first call counts."""
        if self.started:
            return []
        self.started = True
        self.target = (system, component)
        self.ardupilot = autopilot == dialect.MAV_AUTOPILOT_ARDUPILOTMEGA
        for message, rate in self.wanted.items():
            msg_id = getattr(dialect, f"MAVLINK_MSG_ID_{message}", None)
            if msg_id is not None:
                self.queue.append(_Request(message, int(msg_id), interval_us(rate)))
        return self._next(now_s)

    def _next(self, now_s: float) -> list:
        """Send the next queued request, if none is in flight."""
        if self.current is not None or not self.queue:
            return []
        self.current = self.queue.popleft()
        return [self._send(now_s)]

    def _send(self, now_s: float):
        """The COMMAND_LONG of the current request (confirmation = sends so far)."""
        req = self.current
        assert req is not None
        req.sent_s = now_s
        confirmation = min(req.sends, 255)
        req.sends += 1
        return dialect.MAVLink_command_long_message(
            self.target[0], self.target[1], dialect.MAV_CMD_SET_MESSAGE_INTERVAL, confirmation,
            float(req.msg_id), float(req.interval_us), 0.0, 0.0, 0.0, 0.0, 0.0)

    def on_ack(self, ack, now_s: float) -> list:
        """A COMMAND_ACK from the autopilot at now_s (s): settles, retries or waits on the current
        request; returns what to send next."""
        req = self.current
        if req is None or int(ack.command) != dialect.MAV_CMD_SET_MESSAGE_INTERVAL:
            return []
        result = int(ack.result)
        if result == dialect.MAV_RESULT_IN_PROGRESS:
            req.sent_s = now_s      # still working on it: wait a timeout more
            return []
        if result == dialect.MAV_RESULT_TEMPORARILY_REJECTED and req.sends <= self.config.retries:
            return []               # poll sends it again after the timeout
        out = self._fallback(req) if result in REFUSED and self.ardupilot else []
        word = RESULT_WORDS.get(result, f"request result {result}")
        self._settle(req, word if not out else f"{word}; requested as data stream {out[0].req_stream_id}")
        return out + self._next(now_s)

    def poll(self, now_s: float) -> list:
        """At now_s (s): send the current request again after ack_timeout_s without an answer, or
        give it up after `retries` resends."""
        req = self.current
        if req is None or now_s - req.sent_s < self.config.ack_timeout_s:
            return []
        if req.sends <= self.config.retries:
            return [self._send(now_s)]
        self._settle(req, NO_ANSWER)
        return self._next(now_s)

    def _settle(self, req: _Request, outcome: str) -> None:
        req.outcome = outcome
        self.outcomes.append(RequestOutcome(req.message, req.interval_us, outcome))
        self.current = None

    def _fallback(self, req: _Request) -> list:
        """ArduPilot's REQUEST_DATA_STREAM for the message's group at its wanted rate (rounded up to
        whole Hz, at least any rate asked of that group before); [] when no group carries it."""
        group = ARDUPILOT_STREAM_GROUPS.get(req.message)
        if group is None:
            return []
        rate = max(self.fallback_groups.get(group, 0.0), self.wanted[req.message])
        self.fallback_groups[group] = rate
        hz = min(int(-(-rate // 1)), 0xFFFF)
        return [dialect.MAVLink_request_data_stream_message(self.target[0], self.target[1], group, hz, 1)]


# ---------------------------------------------------------------------------- rates

class RateMonitor:
    """Arrival rates of the wanted messages over `window_s` of frame time, and their reports.

    `counts[message]` is incremented by the caller for every accepted message of that type;
    `check(time_us)` at each stepped frame returns the events once per second of frame time.
    `reasons[message]`: the request's outcome, quoted when the message never arrives."""

    def __init__(self, config: StreamConfig, wanted: dict[str, float], rows: dict[str, tuple[str, ...]],
                 requested: bool) -> None:
        self.config = config
        self.wanted = dict(wanted)
        self.rows = {m: rows.get(m, ()) for m in wanted}
        self.counts: dict[str, int] = dict.fromkeys(wanted, 0)
        self.reasons: dict[str, str] = dict.fromkeys(wanted, PENDING if requested else REQUESTS_OFF)
        self.state: dict[str, str] = dict.fromkeys(wanted, "ok")
        self.rates: dict[str, float] = {}
        self.window_us = int(config.window_s * 1e6)
        self.history: deque[tuple[int, dict[str, int]]] = deque()
        self.first_us: dict[str, int] = {}      # the check that first saw each message (frame time, us)
        self._second: int | None = None

    def check(self, time_us: int) -> list[Event]:
        """Events at frame time time_us (us): nothing unless a new second of frame time began."""
        second = time_us // 1_000_000
        if second == self._second:
            return []
        self._second = second
        if self.history and time_us < self.history[-1][0]:
            self.history.clear()      # the frame clock restarted
        self.history.append((time_us, dict(self.counts)))
        while len(self.history) > 1 and time_us - self.history[1][0] >= self.window_us:
            self.history.popleft()
        t0, c0 = self.history[0]
        if time_us - t0 < self.window_us:
            return []                  # the first window is not full yet
        span_s = (time_us - t0) * 1e-6
        return [e for m in self.wanted if (e := self._judge(m, (self.counts[m] - c0[m]) / span_s, time_us))]

    def _judge(self, message: str, rate_hz: float, time_us: int) -> Event | None:
        """The event for a change of the message's state at this rate (Hz) at frame time time_us
        (us), or None. A message that began arriving less than a window ago is not judged yet."""
        self.rates[message] = rate_hz
        wanted, rows = self.wanted[message], self.rows[message]
        if self.counts[message]:
            first = self.first_us.setdefault(message, time_us)
            if self.state[message] == "missing" and time_us - first < self.window_us:
                return None
        if self.counts[message] == 0:
            new = "missing"
        elif rate_hz == 0.0:
            new = self.state[message]   # it stopped: the stale-row check reports that
        elif rate_hz < self.config.min_fraction * wanted:
            new = "slow"
        else:
            new = "ok"
        old, self.state[message] = self.state[message], new
        if new == "missing" and old != "missing":
            return StreamMissing(rows, message, self.reasons[message])
        if new == "slow" and (old != "slow"):
            return StreamSlow(rows, message, rate_hz, wanted)
        if new == "ok" and old != "ok":
            return StreamRateOk(rows, message, rate_hz, wanted)
        return None

    def never_received(self) -> list[Event]:
        """Without any frame (nothing stamped arrives): a `StreamMissing` for every wanted message
        not received at all and not reported yet."""
        events: list[Event] = []
        for m in self.wanted:
            if self.counts[m] == 0 and self.state[m] != "missing":
                self.state[m] = "missing"
                events.append(StreamMissing(self.rows[m], m, self.reasons[m]))
        return events
