"""The service's processing core: bytes from the autopilot link in, encoded MAVLink out.

No sockets and no wall clock decide anything here: estimates depend only on the bytes fed and
the seed, so a replay of the recorded "in" bytes through a fresh `Pipeline` with the recorded
config and seed reproduces every estimate bit for bit. `t_ns` (the receive time) is only logged
and used as the outgoing signing clock; `latency_s` (wall-clock processing time) is measured
with `time.perf_counter` and reported, never used.

Flow per `feed`, one runtime part each: pymavlink (MAVLink 2, robust parsing, signature check) ->
`screening.MessageScreen` (MAVLink 1, unknown ids, duplicates, commands) -> `screening.SourceFilter`
(one autopilot system) -> `frames.FrameAssembler` (value checks, frames) -> per frame `_step`:
filter.step(t, y, mask, u_{k-1}) checked by `health.EstimatorHealth` (re-initialise and step again
when needed) -> `publishing.Publisher`. What the pipeline says is a typed `events.Event`, logged to
every observer as (level, text).

Bad input is dropped and counted by reason (`rejected_counts`); the first occurrence of each
reason is an event at once, a summary event follows at most once per second of frame time, and
the reasons an operator should know about (see `events.OPERATOR_REASONS`) also go out as
STATUSTEXT, at most once per `health.statustext_interval_s` of frame time per reason
(`screening.RejectionReport`).

Estimator health (`[health]`, `health.py`): a non-finite estimate, a non-physical state jump, the
filter's own re-initialisation counter moving, or a particle filter's N_eff below `min_n_eff` on
`degenerate_frames` frames in a row rebuilds the filter around a state made from the current
measurements (`state_from_measurements`) and steps the frame again with the rows that disagree with
that state masked; likewise, without re-stepping, when the frame clock restarted or a gap longer
than max_gap_s ended. Each is an event and a STATUSTEXT; the HEARTBEAT says CRITICAL for
`reinit_holdoff_s` afterwards.
"""

from __future__ import annotations

import inspect
import json
import platform
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fdir_service import __version__
from fdir_service.estimation.base import Filter, StepOutput
from fdir_service.estimator_config import EstimatorConfig
from fdir_service.mavlink import dialect, dialect_text, new_mavlink
from fdir_service.runtime.events import (
    AutopilotSelected,
    Event,
    FilterStepFailed,
    HealthProblem,
    LinkLost,
    LinkRegained,
    ParametersRequested,
    PipelineClosed,
    Reinitialised,
    Rejected,
    StreamRequested,
)
from fdir_service.runtime.frames import AssembledFrame, FrameAssembler
from fdir_service.runtime.health import INPUT_RESUMED, NON_FINITE, EstimatorHealth, filter_raised
from fdir_service.runtime.publishing import Publisher, RateLimit, link_notice, sensor_notice
from fdir_service.runtime.screening import MessageScreen, RejectionReport, Rejections, SourceFilter
from fdir_service.runtime.streams import RateMonitor, RequestOutcome, rows_by_message, wanted_rates

if TYPE_CHECKING:
    from fdir_service.service_config import ServiceConfig

MAVLink_message = dialect.MAVLink_message

PARTICLES_TOP_K = 20
SIGNING_EPOCH_UNIX_S = 1420070400  # MAVLink 2 signing timestamps: 10 us units since 2015-01-01 UTC
FilterFactory = Callable[..., Filter]
"""(name, estimator config, rng, particles[, x0=(5,) airframe state]) -> Filter."""
BEFORE_HEARTBEAT = Rejected("before the autopilot's HEARTBEAT (--autopilot auto)")
LATENCY_WINDOW = 12_000
"""Step latencies kept (`Pipeline.latencies`, the last 10 min at 20 Hz)."""
LINK_MESSAGES = frozenset({"HEARTBEAT", "COMMAND_ACK", "PARAM_VALUE"})
"""Messages of the followed autopilot kept in `Pipeline.link_messages` for the daemon's link layer
(stream and parameter requests: the first HEARTBEAT starts them, COMMAND_ACKs and PARAM_VALUEs
answer them)."""
LINK_MESSAGES_KEPT = 64


class PipelineObserver(Protocol):
    """Receives everything the pipeline sees and says (the MCAP recorder is one). An observer may
    also define `on_runtime_event(event: events.Event, t_ns: int)` to receive each event typed
    (after its `on_event(level, text, t_ns)`), and `on_items(frame_time_s: float,
    report: items.ItemReport, t_ns: int)` to receive each frame's monitored items (after its
    `on_estimate`; only for estimators with typed faults or several entries per target)."""

    def on_metadata(self, name: str, data: dict[str, str]) -> None: ...
    def on_raw(self, direction: str, data: bytes, t_ns: int) -> None: ...
    def on_message(self, msg: MAVLink_message, t_ns: int) -> None: ...
    def on_estimate(self, frame_time_s: float, out: StepOutput, latency_s: float, t_ns: int) -> None: ...
    def on_event(self, level: str, text: str, t_ns: int) -> None: ...
    def on_particles(self, frame_time_s: float, states: np.ndarray, weights: np.ndarray,
                     t_ns: int) -> None: ...


def _default_factory(name: str, estimator: EstimatorConfig, rng: np.random.Generator,
                     particles: int | None, x0: np.ndarray | None = None) -> Filter:
    from fdir_service.estimation.factory import build_filter

    return build_filter(name, estimator, rng, particles=particles, x0=x0)


def trim_input(estimator: EstimatorConfig) -> np.ndarray:
    """The trim input [delta_e rad, delta_t] at the estimator's operating point (u before any arrives)."""
    from fdir_service.estimation.factory import trim_input as estimator_trim_input

    return estimator_trim_input(estimator)


class Pipeline:
    """See the module doc. `filter_factory(name, estimator, rng, particles)` replaces
    `estimation.factory.build_filter` (tests use a fake filter)."""

    def __init__(self, config: ServiceConfig, *, filter_name: str | None = None,
                 particles: int | None = None, seed: int | None = None,
                 observers: Sequence[PipelineObserver] = (),
                 filter_factory: FilterFactory | None = None) -> None:
        self.config = config
        self.estimator = config.estimator
        self.filter_name = filter_name or config.filter
        self.particles = int(particles if particles is not None else config.particles)
        self.seed = int(seed if seed is not None else config.seed)
        self.observers = list(observers)
        self._factory = filter_factory or _default_factory
        try:
            self._factory_takes_x0 = "x0" in inspect.signature(self._factory).parameters
        except (TypeError, ValueError):
            self._factory_takes_x0 = False
        self._seedseq = np.random.SeedSequence(self.seed)
        self.filter = self._new_filter()
        key = config.signing_key()
        self.signed = key is not None
        self.mav_in = new_mavlink(255, 0, key=key, link_id=config.signing_link_id)
        self.mav_out = new_mavlink(config.autopilot_system or 1, config.component, key=key,
                                   link_id=config.signing_link_id)
        # adaptive filters (AJMRPF, ARJMRPF and their -thesis variants) publish Pfa/Pmd/transitions
        self.adaptive = bool(getattr(self.filter, "adaptive", False))
        self.publisher = Publisher(config.publish, self.estimator.faults, self.mav_out, self.adaptive)
        # the runtime parts
        self.assembler = FrameAssembler(config, trim_input(self.estimator))
        # --autopilot auto: HEARTBEAT.autopilot -> config, until the first HEARTBEAT chose one
        self._auto = dict(config.auto_profiles) if config.autopilot == "auto" else None
        self.rejected = Rejections()
        self.screen = MessageScreen()
        self.source = SourceFilter(config.component, config.autopilot_system or None,
                                   self.assembler.is_mapped, self._follow_system, self.rejected)
        self.rejection_report = RejectionReport(config.health.statustext_interval_s)
        self.health = config.health
        self.monitor = EstimatorHealth(config.health, self.estimator,
                                       int(getattr(self.filter, "reinitialisations", 0)))
        self.reinit_notices = RateLimit(config.health.statustext_interval_s)
        self.stream_notices = RateLimit(config.health.statustext_interval_s)
        self.rates = self._rate_monitor(config)
        self.link_messages: deque = deque(maxlen=LINK_MESSAGES_KEPT)
        # counters and state
        self.frames = 0
        self.reinitialisations = 0
        self.accepted_messages = 0
        self.link_lost = False
        self.latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._last_particles_bucket: int | None = None
        self._last_frame_us = 0
        self._closed = False
        self._emit_metadata()

    # ------------------------------------------------------------------ setup
    @property
    def system(self) -> int | None:
        """The autopilot's MAVLink system followed (None until the first one is seen)."""
        return self.source.system

    def _select_autopilot(self, msg, t_ns: int) -> bool:
        """`--autopilot auto`: drop (count) everything before the followed autopilot's HEARTBEAT;
        that HEARTBEAT picks the profile of its MAV_AUTOPILOT value, else the service file's mapping."""
        if msg.get_type() != "HEARTBEAT" or msg.autopilot == dialect.MAV_AUTOPILOT_INVALID:
            self.rejected.add(BEFORE_HEARTBEAT)
            return False
        chosen = self._auto.get(int(msg.autopilot)) if self._auto else None
        self._auto = None
        if chosen is not None:
            self.assembler = FrameAssembler(chosen, trim_input(self.estimator))
            self.source.is_mapped = self.assembler.is_mapped
            self.rates = self._rate_monitor(chosen)
        self._emit(AutopilotSelected(chosen.autopilot if chosen is not None else "none",
                                     int(msg.autopilot)), t_ns)
        return True

    def _rate_monitor(self, config: ServiceConfig) -> RateMonitor:
        """The arrival-rate monitor of the mapping in `config` (the service file's or a profile's)."""
        return RateMonitor(self.config.streams, wanted_rates(config), rows_by_message(config),
                           self.config.streams.request)

    def _follow_system(self, system: int) -> None:
        self.mav_out.srcSystem = system

    def _new_filter(self, x0: np.ndarray | None = None) -> Filter:
        rng = np.random.default_rng(self._seedseq.spawn(1)[0])
        if x0 is not None and self._factory_takes_x0:
            return self._factory(self.filter_name, self.estimator, rng, self.particles, x0=x0)
        return self._factory(self.filter_name, self.estimator, rng, self.particles)

    def _emit_metadata(self) -> None:
        import pymavlink

        cfg = {"service_toml": self.config.text,
               "estimator_json": json.dumps(self.estimator.doc, sort_keys=True),
               "estimator": self.estimator.id, "filter": self.filter_name,
               "particles": str(self.particles), "seed": str(self.seed),
               "source": self.config.source}
        if self.config.autopilot != "none":
            cfg["autopilot"] = self.config.autopilot
            cfg["autopilot_profiles_json"] = json.dumps(dict(self.config.profile_texts), sort_keys=True)
        versions = {"fdir_service": __version__, "python": platform.python_version(),
                    "numpy": np.__version__, "pymavlink": getattr(pymavlink, "__version__", "?"),
                    "dialect_fdir_estimate_crc_extra": str(dialect.MAVLink_fdir_estimate_message.crc_extra)}
        dia = {"fdir.xml": dialect_text()}
        for name, data in (("config", cfg), ("versions", versions), ("dialect", dia)):
            for ob in self.observers:
                ob.on_metadata(name, data)

    # ------------------------------------------------------------------ deferred observers
    def defer_observers(self, on: bool = True) -> None:
        """Let observers that can (the Recorder) only queue references during `feed`; the caller
        sends the returned bytes first and then calls `drain_observers()` (the daemon does), which
        takes the recorder's encoding off the latency path. Same file content either way."""
        for ob in self.observers:
            defer = getattr(ob, "defer", None)
            if defer is not None:
                defer(on)

    def drain_observers(self) -> None:
        """Write what deferred observers queued (before the next `feed`)."""
        for ob in self.observers:
            drain = getattr(ob, "drain", None)
            if drain is not None:
                drain()

    # ------------------------------------------------------------------ helpers
    def _emit(self, event: Event, t_ns: int) -> None:
        """Tell every observer: `on_event(level, text)`, and `on_runtime_event(event)` if it has one."""
        level, text = event.level, event.text
        for ob in self.observers:
            ob.on_event(level, text, t_ns)
            typed = getattr(ob, "on_runtime_event", None)
            if typed is not None:
                typed(event, t_ns)

    def _set_signing_clock(self, t_ns: int) -> None:
        if self.signed:
            ts = int((t_ns * 1e-9 - SIGNING_EPOCH_UNIX_S) * 1e5)
            self.mav_out.signing.timestamp = max(self.mav_out.signing.timestamp, ts)

    def _send_raw(self, out: list[bytes], t_ns: int) -> None:
        if out and self.observers:
            joined = b"".join(out)
            for ob in self.observers:
                ob.on_raw("out", joined, t_ns)

    # ------------------------------------------------------------------ the contract
    def _admit(self, msg, t_ns: int) -> bool:
        """Screening, the source filter, then (`--autopilot auto`) the wait for the autopilot's
        HEARTBEAT; a screened-out message is counted by its reason."""
        rejected = self.screen.check(msg)
        if rejected is not None:
            self.rejected.add(rejected)
            return False
        if not self.source.accept(msg):
            return False
        return self._auto is None or self._select_autopilot(msg, t_ns)

    def feed(self, data: bytes, t_ns: int) -> list[bytes]:
        """Bytes from the autopilot link (any chunking); returns encoded MAVLink frames to send."""
        t0 = time.perf_counter()
        data = bytes(data)
        observers = self.observers
        for ob in observers:
            ob.on_raw("in", data, t_ns)
        self._set_signing_clock(t_ns)
        out: list[bytes] = []
        assembler, counts = self.assembler, self.rates.counts
        for msg in self.mav_in.parse_buffer(data) or []:
            if not self._admit(msg, t_ns):
                continue
            if assembler is not self.assembler:   # --autopilot auto chose a profile
                assembler, counts = self.assembler, self.rates.counts
            self.accepted_messages += 1
            mtype = msg.get_type()
            if mtype in counts:
                counts[mtype] += 1
            elif mtype in LINK_MESSAGES:
                self.link_messages.append(msg)
            for ob in observers:
                ob.on_message(msg, t_ns)
            for frame in assembler.accept(msg):
                out += self._step(frame, t_ns, t0)
            if assembler.events:
                self._drain_assembler_events(out, t_ns)
        self._report_rejections(out, t_ns)
        self._send_raw(out, t_ns)
        return out

    def close(self, t_ns: int | None = None) -> list[bytes]:
        """Step any pending (incomplete) frame and report final counts; idempotent."""
        if self._closed:
            return []
        self._closed = True
        t_ns = int(t_ns if t_ns is not None else 0)
        out: list[bytes] = []
        t0 = time.perf_counter()
        for frame in self.assembler.flush():
            out += self._step(frame, t_ns, t0)
        self._drain_assembler_events(out, t_ns)
        self._report_rejections(out, t_ns)
        self._emit(PipelineClosed(self.frames, tuple(sorted(self.rejected_counts.items()))), t_ns)
        return out

    def set_link_lost(self, lost: bool, silent_s: float, t_ns: int) -> list[bytes]:
        """The daemon's link supervision: no input bytes for silent_s (wall clock) when `lost`, or
        input back after silent_s. Returns the STATUSTEXT (and HEARTBEAT) to send."""
        if lost == self.link_lost:
            return []
        self.link_lost = lost
        self._set_signing_clock(t_ns)
        event = LinkLost(silent_s) if lost else LinkRegained(silent_s)
        self._emit(event, t_ns)
        out = [self.publisher.statustext(*link_notice(event))]
        if lost:
            self.publisher.health = dialect.MAV_STATE_CRITICAL
            out.append(self.publisher.heartbeat())
        for ob in self.observers:
            ob.on_raw("out", b"".join(out), t_ns)
        return out

    def encode_link(self, msgs: Sequence, t_ns: int) -> bytes:
        """pymavlink messages for the autopilot only (the daemon's stream requests), encoded and
        signed like all output (receive time t_ns as the signing clock)."""
        if not msgs:
            return b""
        self._set_signing_clock(t_ns)
        b = b"".join(bytes(m.pack(self.mav_out)) for m in msgs)
        for ob in self.observers:
            ob.on_raw("out", b, t_ns)
        return b

    def stream_outcome(self, outcome: RequestOutcome, t_ns: int) -> None:
        """The daemon's stream request for a message was settled: logged, and quoted when that
        message never arrives."""
        if outcome.message in self.rates.reasons:
            self.rates.reasons[outcome.message] = outcome.outcome
        self._emit(StreamRequested(outcome.message, outcome.interval_us, outcome.outcome), t_ns)

    def parameters_outcome(self, event: ParametersRequested, t_ns: int) -> None:
        """The daemon's parameter requests are settled: who answered, who stays at the default (logged)."""
        self._emit(event, t_ns)

    def report_never_received(self, t_ns: int) -> list[bytes]:
        """The daemon's check when no frame was ever stepped (so no frame time to measure rates on):
        report every wanted message never received. Returns the STATUSTEXTs to send."""
        out: list[bytes] = []
        self._set_signing_clock(t_ns)
        self._report_streams(self.rates.never_received(), out, self._last_frame_us, t_ns)
        self._send_raw(out, t_ns)
        return out

    def heartbeat(self, t_ns: int) -> bytes:
        """A HEARTBEAT now (the daemon sends one when frames stop arriving)."""
        self._set_signing_clock(t_ns)
        b = self.publisher.heartbeat()
        for ob in self.observers:
            ob.on_raw("out", b, t_ns)
        return b

    # ------------------------------------------------------------------ events
    def _report_streams(self, events: list[Event], out: list[bytes], time_us: int, t_ns: int) -> None:
        """Log the rate monitor's events; each also goes out as STATUSTEXT "FDIR <text>" (chunked
        when long), at most once per statustext_interval_s of frame time per message."""
        for event in events:
            self._emit(event, t_ns)
            if self.stream_notices.due(f"stream:{event.message}", time_us):
                sev = dialect.MAV_SEVERITY_WARNING if event.level == "warning" else dialect.MAV_SEVERITY_INFO
                out += self.publisher.statustexts(sev, f"FDIR {event.text}")

    def _drain_assembler_events(self, out: list[bytes], t_ns: int) -> None:
        """Log the assembler's events; sensor and clock notices also go out as STATUSTEXT."""
        announce = self.config.publish.stale_statustext
        for event in self.assembler.events:
            self._emit(event, t_ns)
            if announce and event.sensor_notice:
                out.append(self.publisher.statustext(*sensor_notice(event)))
        self.assembler.events.clear()

    def _report_rejections(self, out: list[bytes], t_ns: int) -> None:
        """Log the source filter's notices, then what `RejectionReport` says about the counts."""
        if self.source.events:
            for event in self.source.events:
                self._emit(event, t_ns)
            self.source.events.clear()
        if self.rejected.added + self.assembler.rejected.added == self.rejection_report.reported:
            return   # nothing new (the common case, checked once per feed)
        events, texts = self.rejection_report.report((self.rejected, self.assembler.rejected),
                                                     self._last_frame_us)
        for text in texts:
            out.append(self.publisher.statustext(dialect.MAV_SEVERITY_WARNING, text))
        for event in events:
            self._emit(event, t_ns)

    # ------------------------------------------------------------------ steps
    def _step(self, frame: AssembledFrame, t_ns: int, t0: float) -> list[bytes]:
        """One frame through the filter and out: re-initialise first if the input resumed after
        a restart, step with the health checks, publish. Returns the messages to send."""
        msgs: list[bytes] = []
        mask = self._resume(frame, msgs, t_ns)
        out = self._checked_step(frame, mask, msgs, t_ns)
        if out is None:   # nothing publishable on this frame, even from a fresh filter
            self.publisher.health = dialect.MAV_STATE_CRITICAL
            return msgs
        self._publish(frame, out, msgs, t0, t_ns)
        return msgs

    def _resume(self, frame: AssembledFrame, msgs: list[bytes], t_ns: int) -> np.ndarray:
        """The rows (m,) to step: after the frame clock restarted or a long gap, the filter is
        rebuilt from this frame's measurements and the rows that disagree are masked; on the first
        frame of an estimator with operating_point.init = "first_frame" it starts there."""
        if frame.restart and self.frames > 0:
            return self._reinitialise(frame, INPUT_RESUMED, msgs, t_ns)
        if self.frames == 0 and self.estimator.operating_point.init == "first_frame":
            self._start_on(frame)
        return frame.mask

    def _start_on(self, frame: AssembledFrame) -> None:
        """operating_point.init = "first_frame": the cloud starts on the state made from the first
        frame's measurements (`state_from_measurements`) instead of the trim state."""
        x0, _ = self.monitor.state_from_measurements(frame.y, frame.mask)
        self.filter = self._new_filter(x0)
        self.monitor.started(self.filter)

    def _checked_step(self, frame: AssembledFrame, mask: np.ndarray, msgs: list[bytes], t_ns: int
                      ) -> StepOutput | None:
        """filter.step and the health check; on a problem to act on, re-initialise and step the
        frame again. None when even the fresh filter gives nothing finite."""
        out, problem = self._filter_step(frame, mask, t_ns)
        if out is not None:
            problem = self.monitor.check(out, self.filter, frame)
            if problem is None:
                self.monitor.healthy(out)
        if problem is None or not self.monitor.must_reinitialise(problem, frame.time_us):
            return out
        keep = self._reinitialise(frame, problem, msgs, t_ns)
        out, _ = self._filter_step(frame, keep, t_ns)
        # checked like any step (its counters advance), but only a non-finite estimate stops it
        if out is None or self.monitor.problem(out, self.filter) is NON_FINITE:
            return None
        return out

    def _filter_step(self, frame: AssembledFrame, mask: np.ndarray, t_ns: int
                     ) -> tuple[StepOutput | None, HealthProblem | None]:
        """filter.step on the rows in mask (m,), with an exception from the filter (a numerical
        failure) turned into a health problem: the service re-initialises instead of crashing."""
        y = np.where(mask, frame.y, np.nan)
        try:
            return self.filter.step(frame.time_s, y, mask.copy(), frame.u.copy()), None
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:
            self._emit(FilterStepFailed(frame.time_s, type(e).__name__, str(e)), t_ns)
            return None, filter_raised(e)

    def _reinitialise(self, frame: AssembledFrame, problem: HealthProblem, msgs: list[bytes],
                      t_ns: int) -> np.ndarray:
        """Rebuild the filter around the state made from this frame's measurements; returns the
        rows (m,) to use for this frame."""
        x0, keep = self.monitor.state_from_measurements(frame.y, frame.mask)
        self.filter = self._new_filter(x0)
        self.monitor.reinitialised(self.filter, frame.time_us)
        self.reinitialisations += 1
        names = self.assembler.names
        masked = tuple(n for n, a, b in zip(names, frame.mask, keep, strict=True) if a and not b)
        state = (float(x0[0]), float(x0[1]), float(x0[2]), float(x0[3]), float(x0[4]))
        self._emit(Reinitialised(frame.time_s, problem, state, masked), t_ns)
        if self.reinit_notices.due("reinit", frame.time_us):
            msgs.append(self.publisher.statustext(dialect.MAV_SEVERITY_WARNING,
                                                  f"FDIR estimator restart: {problem.text}"[:50]))
        return keep

    def _publish(self, frame: AssembledFrame, out: StepOutput, msgs: list[bytes], t0: float,
                 t_ns: int) -> None:
        """Count the frame, publish its messages into msgs, record the latency, tell observers."""
        out = self.publisher.typed_output(out)
        self.monitor.published(out)
        self.frames += 1
        self.publisher.health = self.monitor.heartbeat_state(frame, self.link_lost)
        pub, events = self.publisher.publish(frame, out)
        msgs += pub
        latency = time.perf_counter() - t0
        self.latencies.append(latency)   # a fixed window: constant memory and cost on a long flight
        for event in events:
            self._emit(event, t_ns)
        stream_events = self.rates.check(frame.time_us)
        if stream_events:
            self._report_streams(stream_events, msgs, frame.time_us, t_ns)
        if self.observers:
            self._observe(frame, out, latency, t_ns)
        self._last_frame_us = frame.time_us

    def _observe(self, frame: AssembledFrame, out: StepOutput, latency: float, t_ns: int) -> None:
        """The estimate to every observer; the top particles once per second of frame time."""
        for ob in self.observers:
            ob.on_estimate(frame.time_s, out, latency, t_ns)
        if not self.publisher.plain:
            self._observe_items(frame.time_s, t_ns)
        bucket = frame.time_us // 1_000_000
        if bucket != self._last_particles_bucket:
            self._last_particles_bucket = bucket
            states, weights = self.filter.top_particles(PARTICLES_TOP_K)
            for ob in self.observers:
                ob.on_particles(frame.time_s, np.asarray(states), np.asarray(weights), t_ns)

    def _observe_items(self, frame_time_s: float, t_ns: int) -> None:
        """The frame's monitored items to every observer that has `on_items` (typed estimators)."""
        report = self.publisher.item_report()
        for ob in self.observers:
            on_items = getattr(ob, "on_items", None)
            if on_items is not None and report is not None:
                on_items(frame_time_s, report, t_ns)

    # ------------------------------------------------------------------ public views
    def state_from_measurements(self, y: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """An airframe state (5,) from one frame's measurements and the rows (m,) that agree with
        it (see `health.EstimatorHealth.state_from_measurements`)."""
        return self.monitor.state_from_measurements(y, mask)

    @property
    def rejected_counts(self) -> dict[str, int]:
        """Dropped input by reason (bad signature, unsigned, bad crc, late measurement, ...)."""
        return dict(self.rejected + self.assembler.rejected)
