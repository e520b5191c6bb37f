"""The service's processing core: bytes from the autopilot link in, encoded MAVLink out.

No sockets and no wall clock decide anything here: estimates depend only on the bytes fed and
the seed, so a replay of the recorded "in" bytes through a fresh `Pipeline` with the recorded
config and seed reproduces every estimate bit for bit. `t_ns` (the receive time) is only logged
and used as the outgoing signing clock; `latency_s` (wall-clock processing time) is measured
with `time.perf_counter` and reported, never used.

Flow per `feed`: pymavlink (MAVLink 2, robust parsing, signature check) -> input screening
(MAVLink 1, unknown ids, duplicates, commands, other systems) -> source filter -> `FrameAssembler`
(ingest.py) -> filter.step(t, y, mask, u_{k-1}) -> estimator health check -> `Publisher`
(publish.py).

Bad input is dropped and counted by reason (`rejected_counts`); the first occurrence of each
reason is an event at once, a summary event follows at most once per second of frame time, and
the reasons an operator should know about (see `OPERATOR_REASONS`) also go out as STATUSTEXT, at
most once per `health.statustext_interval_s` of frame time per reason.

Estimator health (`[health]`): a non-finite estimate, the filter's own re-initialisation counter
moving, or a particle filter's N_eff below `min_n_eff` on `degenerate_frames` frames in a row
rebuilds the filter around a state made from the current measurements (`state_from_measurements`)
and steps the frame again with the rows that disagree with that state masked; likewise, without
re-stepping, when the frame clock restarted or a gap longer than max_gap_s ended. Each is an
event and a STATUSTEXT; the HEARTBEAT says CRITICAL for `reinit_holdoff_s` afterwards.
"""

from __future__ import annotations

import json
import platform
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fdir_service import __version__
from fdir_service.estimation.base import Filter, StepOutput
from fdir_service.estimator_config import EstimatorConfig
from fdir_service.ingest import AssembledFrame, FrameAssembler
from fdir_service.mavlink import dialect, dialect_text, new_mavlink
from fdir_service.publish import Publisher

try:  # the measurement -> state map of the filters' measurement model (read only)
    from fdir_service.estimation.measurement import MEASURED_STATE
except ImportError:  # pragma: no cover
    MEASURED_STATE = {"gnss_alt": (0, -1.0), "baro_alt": (0, -1.0), "u": (1, 1.0), "w": (2, 1.0),
                      "theta": (3, 1.0), "q": (4, 1.0)}

if TYPE_CHECKING:
    from fdir_service.service_config import ServiceConfig

MAVLink_message = dialect.MAVLink_message

PARTICLES_TOP_K = 20
SIGNING_EPOCH_UNIX_S = 1420070400  # MAVLink 2 signing timestamps: 10 us units since 2015-01-01 UTC
FilterFactory = Callable[..., Filter]
"""(name, estimator config, rng, particles[, x0=(5,) airframe state]) -> Filter."""

COMMAND_MESSAGES = frozenset({
    "COMMAND_LONG", "COMMAND_INT", "COMMAND_CANCEL", "SET_MODE", "PARAM_SET", "PARAM_EXT_SET",
    "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "PARAM_EXT_REQUEST_READ", "PARAM_EXT_REQUEST_LIST",
    "MISSION_ITEM", "MISSION_ITEM_INT", "MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "SETUP_SIGNING", "FILE_TRANSFER_PROTOCOL", "SET_POSITION_TARGET_LOCAL_NED", "SERIAL_CONTROL",
})
"""Messages that ask a MAVLink node to change its behaviour. The service acts on none of them
(there is no option to enable any): each is dropped and counted ("command ignored")."""

OPERATOR_REASONS = ("unsigned", "bad signature", "other system", "command ignored", "mavlink1",
                    "time jump", "bad crc", "malformed", "out of range", "frozen", "no timestamp")
"""Rejection reasons (substrings) reported by STATUSTEXT; the rest (late, surplus, duplicate,
unknown message id) are normal on a radio link and only counted and logged."""
LATENCY_WINDOW = 12_000
"""Step latencies kept (`Pipeline.latencies`, the last 10 min at 20 Hz)."""
STATE_LABELS = ("p_d", "u", "w", "theta", "q")
DUPLICATE_MEMORY = 32
"""Packets remembered per sender to recognise a duplicate (same bytes, same sequence number)."""


class PipelineObserver(Protocol):
    """Receives everything the pipeline sees and says (the MCAP recorder is one)."""

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


def _bad_data_reason(msg) -> str:
    reason = str(getattr(msg, "reason", ""))
    data = bytes(getattr(msg, "data", b"") or b"")
    if "signature" in reason.lower():
        signed = len(data) > 2 and data[0] == 0xFD and (data[2] & dialect.MAVLINK_IFLAG_SIGNED)
        return "bad signature" if signed else "unsigned"
    if "crc" in reason.lower():
        return "bad crc"
    return "malformed"


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
        import inspect

        try:
            self._factory_takes_x0 = "x0" in inspect.signature(self._factory).parameters
        except (TypeError, ValueError):
            self._factory_takes_x0 = False
        self._seedseq = np.random.SeedSequence(self.seed)
        self.filter = self._new_filter()
        key = config.signing_key()
        self.signed = key is not None
        self.system = config.autopilot_system or None
        self.mav_in = new_mavlink(255, 0, key=key, link_id=config.signing_link_id)
        self.mav_out = new_mavlink(self.system or 1, config.component, key=key,
                                   link_id=config.signing_link_id)
        # adaptive filters (AJMRPF, ARJMRPF and their -thesis variants) publish Pfa/Pmd/transitions
        self.adaptive = bool(getattr(self.filter, "adaptive", False))
        self.publisher = Publisher(config.publish, self.estimator.faults, self.mav_out, self.adaptive)
        self.assembler = FrameAssembler(config, trim_input(self.estimator))
        self.rejected: Counter[str] = Counter()
        self.frames = 0
        self.latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._reported_rejections = 0
        self._last_reject_report_us: int | None = None
        self._last_particles_bucket: int | None = None
        self._last_frame_us = 0
        self._closed = False
        # input screening
        self._recent: dict[tuple[int, int], deque[bytes]] = {}
        self._seen_reasons: set[str] = set()
        self._statustext_us: dict[str, int] = {}
        self._statustext_count: Counter[str] = Counter()
        self._other_systems: set[int] = set()
        self._pending_events: list[tuple[str, str]] = []
        self._operator_reason: dict[str, bool] = {}
        # estimator health
        self.health = config.health
        self.reinitialisations = 0
        self._filter_reinits = int(getattr(self.filter, "reinitialisations", 0))
        self._low_neff = 0
        self._last_reinit_us: int | None = None
        self._last_good_state: np.ndarray | None = None
        self._sigma = np.asarray(self.estimator.filter_sigma(), dtype=float)
        self._rows = [MEASURED_STATE.get(name) for name in self.estimator.measurements]
        jump = tuple(getattr(self.health, "max_state_jump", ()) or ())
        self._max_jump = np.asarray(jump, dtype=float) if len(jump) == 5 else None
        self._prev_state: np.ndarray | None = None   # last published airframe estimate (5,)
        self.link_lost = False
        self.accepted_messages = 0
        self._emit_metadata()

    # ------------------------------------------------------------------ setup
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
    def _event(self, level: str, text: str, t_ns: int) -> None:
        for ob in self.observers:
            ob.on_event(level, text, t_ns)

    def _set_signing_clock(self, t_ns: int) -> None:
        if self.signed:
            ts = int((t_ns * 1e-9 - SIGNING_EPOCH_UNIX_S) * 1e5)
            self.mav_out.signing.timestamp = max(self.mav_out.signing.timestamp, ts)

    def _accept_source(self, msg) -> bool:
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if src_comp == self.config.component and (self.system is None or src_sys == self.system):
            return False  # our own output echoed back
        if self.system is None:
            is_autopilot_hb = (msg.get_type() == "HEARTBEAT"
                               and msg.autopilot != dialect.MAV_AUTOPILOT_INVALID)
            if is_autopilot_hb or self.assembler.is_mapped(msg.get_type()):
                self.system = src_sys
                self.mav_out.srcSystem = src_sys
            else:
                return False
        if src_sys != self.system:
            self.rejected["other system"] += 1
            if src_sys not in self._other_systems and len(self._other_systems) < 256:
                self._other_systems.add(src_sys)
                self._pending_events.append(("warning", f"ignoring system {src_sys} on the link "
                                             f"(following system {self.system})"))
            return False
        return True

    # ------------------------------------------------------------------ the contract
    def _reject(self, reason: str, n: int = 1) -> None:
        self.rejected[reason] += n

    def _screen(self, msg) -> bool:
        """Input screening before the source filter; False = dropped (and counted)."""
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self._reject(_bad_data_reason(msg))
            return False
        buf = msg.get_msgbuf()
        if buf and buf[0] == 0xFE:
            self._reject("mavlink1")
            return False
        if mtype.startswith("UNKNOWN"):
            self._reject("unknown message id")
            return False
        if mtype in COMMAND_MESSAGES:
            self._reject(f"command ignored ({mtype})")
            return False
        key = (msg.get_srcSystem(), msg.get_srcComponent())
        recent = self._recent.get(key)
        if recent is None:
            recent = self._recent[key] = deque(maxlen=DUPLICATE_MEMORY)
        b = bytes(buf)
        if b in recent:
            self._reject("duplicate")
            return False
        recent.append(b)
        if len(self._recent) > 64:  # bounded: a flood of forged sender ids
            for k in list(self._recent)[:32]:
                del self._recent[k]
        return True

    def feed(self, data: bytes, t_ns: int) -> list[bytes]:
        """Bytes from the autopilot link (any chunking); returns encoded MAVLink frames to send."""
        t0 = time.perf_counter()
        data = bytes(data)
        observers = self.observers
        for ob in observers:
            ob.on_raw("in", data, t_ns)
        self._set_signing_clock(t_ns)
        out: list[bytes] = []
        msgs = self.mav_in.parse_buffer(data) or []
        assembler = self.assembler
        for msg in msgs:
            if not self._screen(msg) or not self._accept_source(msg):
                continue
            self.accepted_messages += 1
            for ob in observers:
                ob.on_message(msg, t_ns)
            for frame in assembler.accept(msg):
                out += self._step(frame, t_ns, t0)
            if assembler.events:
                self._drain_assembler_events(out, t_ns)
        self._report_rejections(out, t_ns)
        if out and observers:
            joined = b"".join(out)
            for ob in observers:
                ob.on_raw("out", joined, t_ns)
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
        total = self.rejected + self.assembler.rejected
        summary = ", ".join(f"{k} {v}" for k, v in sorted(total.items())) or "none"
        self._event("info", f"pipeline closed after {self.frames} frames; rejected input: {summary}", t_ns)
        return out

    def set_link_lost(self, lost: bool, silent_s: float, t_ns: int) -> list[bytes]:
        """The daemon's link supervision: no input bytes for silent_s (wall clock) when `lost`, or
        input back after silent_s. Returns the STATUSTEXT (and HEARTBEAT) to send."""
        if lost == self.link_lost:
            return []
        self.link_lost = lost
        self._set_signing_clock(t_ns)
        if lost:
            text = f"no input from the autopilot for {silent_s:.1f} s"
            self._event("error", f"link lost: {text}", t_ns)
            self.publisher.health = dialect.MAV_STATE_CRITICAL
            out = [self.publisher.statustext(dialect.MAV_SEVERITY_CRITICAL,
                                             f"FDIR link lost: no input for {silent_s:.1f} s"),
                   self.publisher.heartbeat()]
        else:
            self._event("info", f"link restored after {silent_s:.1f} s without input", t_ns)
            out = [self.publisher.statustext(dialect.MAV_SEVERITY_NOTICE,
                                             f"FDIR link restored after {silent_s:.1f} s")]
        for ob in self.observers:
            ob.on_raw("out", b"".join(out), t_ns)
        return out

    def heartbeat(self, t_ns: int) -> bytes:
        """A HEARTBEAT now (the daemon sends one when frames stop arriving)."""
        self._set_signing_clock(t_ns)
        b = self.publisher.heartbeat()
        for ob in self.observers:
            ob.on_raw("out", b, t_ns)
        return b

    # ------------------------------------------------------------------ steps
    def _drain_assembler_events(self, out: list[bytes], t_ns: int) -> None:
        for level, text in self.assembler.events:
            self._event(level, text, t_ns)
            if self.config.publish.stale_statustext and any(
                    w in text for w in ("stale", "recovered", "frozen", "time jumped")):
                sev = dialect.MAV_SEVERITY_WARNING if level == "warning" else dialect.MAV_SEVERITY_INFO
                out.append(self.publisher.statustext(sev, f"FDIR {text}"[:50]))
        self.assembler.events.clear()

    def state_from_measurements(self, y: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """An airframe state (5,) made from one frame's measurements, and the rows (m,) bool that
        agree with it within `health.reinit_gate_sigmas` sigma.

        Each state is the measurement of a row that measures it (altitudes: -p_d); where several
        rows measure one state, the one nearest the last healthy estimate (or the trim state) wins,
        so a glitching altitude sensor does not pick the state. States no row measures keep the
        last healthy estimate.
        """
        from fdir_service.estimation.factory import trim_state

        ref = self._last_good_state if self._last_good_state is not None else trim_state(self.estimator)
        x0 = ref.astype(float).copy()
        best: dict[int, float] = {}
        for j, row in enumerate(self._rows):
            if row is None or not mask[j] or not np.isfinite(y[j]):
                continue
            col, coef = row
            v = y[j] / coef
            if col not in best or abs(v - ref[col]) < abs(best[col] - ref[col]):
                best[col] = v
        for col, v in best.items():
            x0[col] = v
        keep = mask.copy()
        for j, row in enumerate(self._rows):
            if row is not None and keep[j]:
                col, coef = row
                keep[j] = abs(y[j] / coef - x0[col]) <= self.health.reinit_gate_sigmas * self._sigma[j]
        return x0, keep

    def _health_problem(self, out: StepOutput, prev: np.ndarray | None = None) -> str | None:
        """Why the filter needs re-initialising after this step's output, or None. prev: the
        previous frame's airframe estimate (5,), for the state-jump check."""
        finite = (np.isfinite(out.x_mean).all() and np.isfinite(out.fault_probability).all()
                  and np.isfinite(out.fault_estimate).all() and np.isfinite(out.n_eff))
        if not finite:
            return "non-finite estimate"
        if prev is not None and self._max_jump is not None:
            jump = np.abs(np.asarray(out.x_mean[:5], dtype=float) - prev) > self._max_jump
            if jump.any():
                j = int(np.argmax(jump))
                return f"{STATE_LABELS[j]} jump {out.x_mean[j] - prev[j]:+.3g}/frame"
        n = int(getattr(self.filter, "reinitialisations", 0))
        if n != self._filter_reinits:
            self._filter_reinits = n
            return "filter lost every particle"
        if hasattr(self.filter, "N") and out.n_eff < self.health.min_n_eff:
            self._low_neff += 1
            if self._low_neff >= self.health.degenerate_frames:
                return f"N_eff < {self.health.min_n_eff:g} for {self._low_neff} frames"
        else:
            self._low_neff = 0
        return None

    def _reinitialise(self, frame: AssembledFrame, reason: str, y: np.ndarray,
                      out: list[bytes], t_ns: int) -> np.ndarray:
        """Rebuild the filter around the state made from this frame's measurements; returns the
        rows (m,) to use for this frame."""
        x0, keep = self.state_from_measurements(y, frame.mask)
        self.filter = self._new_filter(x0)
        self._filter_reinits = int(getattr(self.filter, "reinitialisations", 0))
        self._low_neff = 0
        self._last_reinit_us = frame.time_us
        self.reinitialisations += 1
        dropped = [n for n, a, b in zip(self.assembler.names, frame.mask, keep, strict=True) if a and not b]
        self._event("error" if "non-finite" in reason else "warning",
                    f"estimator re-initialised at t={frame.time_s:.2f} s ({reason}) from the measurements: "
                    f"p_d={x0[0]:.1f} u={x0[1]:.2f} w={x0[2]:.2f} theta={x0[3]:.4f} q={x0[4]:.4f}"
                    + (f"; rows masked this frame: {', '.join(dropped)}" if dropped else ""), t_ns)
        text = self._statustext_due("reinit", frame.time_us)
        if text is not None:
            out.append(self.publisher.statustext(dialect.MAV_SEVERITY_WARNING,
                                                 f"FDIR estimator restart: {reason}"[:50]))
        return keep

    def _step(self, frame: AssembledFrame, t_ns: int, t0: float) -> list[bytes]:
        msgs: list[bytes] = []
        y = np.where(frame.mask, frame.y, np.nan)
        mask = frame.mask
        if frame.restart and self.frames > 0:
            keep = self._reinitialise(frame, "input resumed after a gap", frame.y, msgs, t_ns)
            mask = keep
            y = np.where(mask, frame.y, np.nan)
        out, problem = self._filter_step(frame, y, mask, t_ns)
        if out is not None:
            prev = None if (frame.restart or frame.synthetic) else self._prev_state
            problem = self._health_problem(out, prev)
        if problem is not None:
            holdoff = (self._last_reinit_us is not None and
                       frame.time_us - self._last_reinit_us < self.health.reinit_holdoff_s * 1e6)
            # a non-finite estimate or a non-physical jump is never published: act on this frame
            acute = out is None or problem == "non-finite estimate" or " jump " in problem
            if acute or not holdoff:
                keep = self._reinitialise(frame, problem, frame.y, msgs, t_ns)
                y = np.where(keep, frame.y, np.nan)
                out, _ = self._filter_step(frame, y, keep, t_ns)
                if out is None or self._health_problem(out) == "non-finite estimate":
                    self.publisher.health = dialect.MAV_STATE_CRITICAL
                    return msgs
        elif np.isfinite(out.x_mean[:5]).all():
            self._last_good_state = np.asarray(out.x_mean[:5], dtype=float).copy()
        x5 = np.asarray(out.x_mean[:5], dtype=float)
        self._prev_state = x5.copy() if np.isfinite(x5).all() else None
        self.frames += 1
        recovering = (self._last_reinit_us is not None
                      and frame.time_us - self._last_reinit_us < self.health.reinit_holdoff_s * 1e6)
        self.publisher.health = (dialect.MAV_STATE_CRITICAL if frame.stale or recovering or self.link_lost
                                 else dialect.MAV_STATE_ACTIVE)
        pub, events = self.publisher.publish(frame, out)
        msgs += pub
        latency = time.perf_counter() - t0
        self.latencies.append(latency)   # a fixed window: constant memory and cost on a long flight
        for level, text in events:
            self._event(level, f"{text} (t={frame.time_s:.2f} s)", t_ns)
        observers = self.observers
        if observers:
            for ob in observers:
                ob.on_estimate(frame.time_s, out, latency, t_ns)
            bucket = frame.time_us // 1_000_000
            if bucket != self._last_particles_bucket:
                self._last_particles_bucket = bucket
                states, weights = self.filter.top_particles(PARTICLES_TOP_K)
                for ob in observers:
                    ob.on_particles(frame.time_s, np.asarray(states), np.asarray(weights), t_ns)
        self._last_frame_us = frame.time_us
        return msgs

    def _filter_step(self, frame: AssembledFrame, y: np.ndarray, mask: np.ndarray, t_ns: int
                     ) -> tuple[StepOutput | None, str | None]:
        """filter.step, with an exception from the filter (a numerical failure) turned into a
        health problem: the service re-initialises instead of crashing."""
        try:
            return self.filter.step(frame.time_s, y, mask.copy(), frame.u.copy()), None
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:
            self._event("error", f"filter step failed at t={frame.time_s:.2f} s: {type(e).__name__}: {e}",
                        t_ns)
            return None, f"filter raised {type(e).__name__}"

    def _statustext_due(self, reason: str, now_us: int) -> str | None:
        """Rate limit: a STATUSTEXT about `reason` at its first occurrence, then at most once per
        health.statustext_interval_s of frame time. Returns "" when due, else None."""
        last = self._statustext_us.get(reason)
        if last is not None and now_us - last < self.health.statustext_interval_s * 1e6:
            return None
        self._statustext_us[reason] = now_us
        return ""

    def _report_rejections(self, out: list[bytes], t_ns: int) -> None:
        for level, text in self._pending_events:
            self._event(level, text, t_ns)
        self._pending_events.clear()
        n = self.rejected.total() + self.assembler.rejected.total()
        if n == self._reported_rejections:
            return
        total = self.rejected + self.assembler.rejected
        now_us = self._last_frame_us
        new = [r for r in total if r not in self._seen_reasons]
        for r in new:
            self._seen_reasons.add(r)
            self._event("warning", f"rejected input: first {r}", t_ns)
        for r, c in total.items():
            if c == self._statustext_count[r]:
                continue
            operator = self._operator_reason.get(r)
            if operator is None:
                operator = self._operator_reason[r] = any(k in r for k in OPERATOR_REASONS)
            if not operator:
                continue
            if self._statustext_due(f"reject:{r}", now_us) is not None:
                self._statustext_count[r] = c
                out.append(self.publisher.statustext(dialect.MAV_SEVERITY_WARNING,
                                                     f"FDIR rejected {c} input: {r}"[:50]))
        if (self._last_reject_report_us is not None
                and now_us - self._last_reject_report_us < 1_000_000):
            return
        self._last_reject_report_us = now_us
        self._reported_rejections = n
        detail = ", ".join(f"{k} {v}" for k, v in sorted(total.items()))
        self._event("warning", f"rejected input ({n} so far): {detail}", t_ns)

    @property
    def rejected_counts(self) -> dict[str, int]:
        """Dropped input by reason (bad signature, unsigned, bad crc, late measurement, ...)."""
        return dict(self.rejected + self.assembler.rejected)
