"""Parameter requests: ask the followed autopilot for the parameters its profile reads.

An autopilot profile derives inputs from servo PWM with the autopilot's parameters: its
`[parameters]` hold defaults, replaced when a PARAM_VALUE of the same name arrives
(`derived.SourceCache`). A stock autopilot sends PARAM_VALUE only when asked or on a change, so
after its first HEARTBEAT `ParamRequester` asks, by name (PARAM_REQUEST_READ, param_index = -1,
to the HEARTBEAT's system and component):

1. every `[parameters]` name and every `[parameter_requests] names` pattern expanded (`{n}`: each
   servo output 1..16, `{i}`: each PX4 control surface 0..7), in that order, duplicates once;
2. once all of those are settled: every `[parameter_requests] channel` pattern for each output
   channel n an input reads under the parameters then known (answers over defaults; e.g. the
   elevator's SERVOn_FUNCTION = 19 on SERVO5 -> SERVO5_MIN / TRIM / MAX / REVERSED).

Pacing: at most `[streams] parameters_in_flight` requests are unanswered at a time; each answer
lets the next one go. A request unanswered for `[streams] ack_timeout_s` is sent again, `retries`
times, then given up. When nothing is left the requester's `report` holds who answered and who
did not (`events.ParametersRequested`). The time (s, any monotonic clock) comes from the caller.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from fdir_service.mavlink import dialect
from fdir_service.runtime.derived import (
    PX4_SURFACES,
    SERVO_CHANNELS,
    SourceCache,
    output_channel,
    param_name,
)
from fdir_service.runtime.events import ParametersRequested
from fdir_service.service_config import ServiceConfig, StreamConfig


def expand(pattern: str) -> list[str]:
    """A name pattern's names: `{n}` -> 1..16 (servo outputs), `{i}` -> 0..7 (PX4 surfaces)."""
    if "{n}" in pattern:
        return [pattern.replace("{n}", str(n)) for n in range(1, SERVO_CHANNELS + 1)]
    if "{i}" in pattern:
        return [pattern.replace("{i}", str(i)) for i in range(PX4_SURFACES)]
    return [pattern]


def first_requests(config: ServiceConfig) -> list[str]:
    """The names asked first: the profile's `[parameters]`, then its expanded request names."""
    names = [name for name, _ in config.parameters]
    for pattern in config.parameter_requests:
        names += expand(pattern)
    return list(dict.fromkeys(names))


def channel_requests(config: ServiceConfig, cache: SourceCache) -> list[str]:
    """The channel pattern names for every output channel an input reads under `cache`'s parameters."""
    channels = dict.fromkeys(n for fm in config.inputs
                             if (n := output_channel(fm.derive, fm.options, cache)) is not None)
    return [p.replace("{n}", str(n)) for n in channels for p in config.parameter_channel_requests]


@dataclass
class _Sent:
    """A request in flight: how many times sent and when last (s)."""

    sends: int
    sent_s: float


class ParamRequester:
    """The parameter requests to one autopilot (see the module doc). `start` on its first HEARTBEAT,
    `on_value` for each PARAM_VALUE from it, `poll` now and then; each returns the pymavlink
    messages to send. `report` is set once, when every request is settled (the caller takes it
    and clears it)."""

    def __init__(self, streams: StreamConfig, config: ServiceConfig) -> None:
        self.streams = streams
        self.config = config
        self.cache = SourceCache(dict(config.parameters))
        self.queue: deque[str] = deque()
        self.in_flight: dict[str, _Sent] = {}
        self.asked: set[str] = set()
        self.confirmed: dict[str, float] = {}
        self.unanswered: list[str] = []
        self.target = (0, 0)
        self.started = False
        self.channels_asked = False
        self.reported = False
        self.report: ParametersRequested | None = None

    @property
    def done(self) -> bool:
        """Whether every request is settled (answered or given up)."""
        return self.started and self.channels_asked and not self.queue and not self.in_flight

    def start(self, system: int, component: int, now_s: float) -> list:
        """The autopilot (system, component) was heard at now_s (s): queue the first requests and
        send up to `parameters_in_flight` of them. Only the first call counts."""
        if self.started:
            return []
        self.started = True
        self.target = (system, component)
        self._queue(first_requests(self.config))
        return self._fill(now_s)

    def _queue(self, names: list[str]) -> None:
        """Queue the names not asked before."""
        for name in names:
            if name not in self.asked:
                self.asked.add(name)
                self.queue.append(name)

    def on_value(self, msg, now_s: float) -> list:
        """A PARAM_VALUE from the autopilot at now_s (s): its value is known (an asked name is
        confirmed, and not asked again); returns the next requests."""
        self.cache.observe(msg, None)
        name = param_name(msg)
        if name in self.asked and name not in self.confirmed and name in self.cache.params:
            self.confirmed[name] = self.cache.params[name]
            self.in_flight.pop(name, None)
            if name in self.queue:
                self.queue.remove(name)
        return self._fill(now_s)

    def poll(self, now_s: float) -> list:
        """At now_s (s): send again each request unanswered for ack_timeout_s, or give it up after
        `retries` resends; then the next requests."""
        out = []
        for name, sent in list(self.in_flight.items()):
            if now_s - sent.sent_s < self.streams.ack_timeout_s:
                continue
            if sent.sends <= self.streams.retries:
                out.append(self._send(name, now_s))
            else:
                del self.in_flight[name]
                self.unanswered.append(name)
        return out + self._fill(now_s)

    def _fill(self, now_s: float) -> list:
        """Send queued requests up to `parameters_in_flight` unanswered; queue the channel requests
        once the first ones are settled; set `report` when all are."""
        if self.started and not self.channels_asked and not self.queue and not self.in_flight:
            self.channels_asked = True
            self._queue(channel_requests(self.config, self.cache))
        out = []
        while self.queue and len(self.in_flight) < self.streams.parameters_in_flight:
            out.append(self._send(self.queue.popleft(), now_s))
        if self.done and not self.reported:
            self.reported = True
            self.report = self._report()
        return out

    def _send(self, name: str, now_s: float):
        """The PARAM_REQUEST_READ of `name` (by name: param_index -1), counted as sent at now_s (s)."""
        sent = self.in_flight.setdefault(name, _Sent(0, now_s))
        sent.sends += 1
        sent.sent_s = now_s
        return dialect.MAVLink_param_request_read_message(self.target[0], self.target[1],
                                                          name.encode("ascii"), -1)

    def _report(self) -> ParametersRequested:
        """Who answered, who stays at the profile's default, who is unknown."""
        defaults = dict(self.config.parameters)
        return ParametersRequested(
            confirmed=tuple(n for n in self._order() if n in self.confirmed),
            defaulted=tuple(n for n in self.unanswered if n in defaults),
            unknown=tuple(n for n in self.unanswered if n not in defaults))

    def _order(self) -> list[str]:
        """Every name asked, in the order first asked."""
        return list(dict.fromkeys([*first_requests(self.config), *self.confirmed]))
