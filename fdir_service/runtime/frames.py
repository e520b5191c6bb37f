"""Frame assembly: screened, decoded MAVLink messages -> filter frames (t, y (m,), mask (m,), u (2,)).

Frame assembly is by message timestamp only (never the arrival time): a message stamped t (its
`time_usec`, else `time_boot_ms`) belongs to frame k = round(t / T), T = 1 / frames.rate_hz.
Frame k is complete, and handed to the filter at once, when every message type that feeds a
measurement row and is due at frame k has arrived for it; a type's period (in frames) is learned
from its arrivals (`KindRates`: a 5 Hz GNSS in 20 Hz frames is due every 4th frame), so a slower
sensor does not hold the frames between its samples. A frame is handed over incomplete (missing
rows masked) as soon as any message stamped later than frame k arrives. Frames that never
arrived, up to `max_gap_s`, are stepped with every row masked (pure prediction). The input of
frame k is u_{k-1}: for each input channel, the latest value stamped at or before frame k-1 (the
trim input until one arrives).

A measurement row silent (in message time) for longer than its `stale_s` is reported stale; a
non-finite or out-of-range value is dropped and counted, never handed to the filter (the value
checks are in `screening`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fdir_service.runtime.clock import SYSTEM_TIME, EpochClock
from fdir_service.runtime.derived import SourceCache, derive_value
from fdir_service.runtime.events import (
    Event,
    FramesMissing,
    Rejected,
    SensorRecovered,
    SensorStale,
    TimeJumped,
)
from fdir_service.runtime.screening import (
    LATE_MEASUREMENT,
    NO_TIMESTAMP,
    SURPLUS,
    TIME_JUMP,
    FrozenRows,
    Rejections,
    checked_value,
    field_value,
    matches_where,
    message_time_us,
)
from fdir_service.service_config import FieldMap, ServiceConfig

JUMP_CONFIRM_MESSAGES = 10
"""Messages in a row that must agree on a timestamp outside the frame clock's window before the
clock restarts there (one corrupt timestamp must not move the clock)."""
LATE_WINDOW_FRAMES = 100
"""Messages stamped up to this many frames (or max_gap_s, if longer) before the last stepped frame
are late (dropped, counted); further back is a time jump."""
INPUT_HISTORY = 8
"""Values kept per input channel (frame index, value)."""
WRAP32_US = 1 << 32
"""A uint32 time_usec (e.g. ArduPilot's SERVO_OUTPUT_RAW) wraps every 2^32 us (71.6 min)."""


def unwrap32(raw_us: int, reference_us: int) -> int:
    """The time raw_us + n 2^32 (us) nearest reference_us (the latest full timestamp seen)."""
    n = (reference_us - raw_us + WRAP32_US // 2) // WRAP32_US
    return raw_us + n * WRAP32_US


class KindRates:
    """The period, in frames, of each message kind: the smallest gap between its last RATE_GAPS + 1
    arrivals (1 until RATE_MIN_GAPS gaps were seen: due every frame)."""

    RATE_GAPS = 8
    RATE_MIN_GAPS = 3

    def __init__(self) -> None:
        self.last: dict[str, int] = {}
        self.gaps: dict[str, list[int]] = {}

    def seen(self, kind: str, k: int) -> None:
        """A message of `kind` for frame k."""
        last = self.last.get(kind)
        if last is not None and k > last:
            gaps = self.gaps.setdefault(kind, [])
            gaps.append(k - last)
            del gaps[:-self.RATE_GAPS]
        if last is None or k > last:
            self.last[kind] = k

    def due(self, kind: str, k: int) -> bool:
        """Whether frame k should wait for a message of `kind`."""
        gaps = self.gaps.get(kind, ())
        if len(gaps) < self.RATE_MIN_GAPS:
            return True
        return k - self.last[kind] >= min(gaps)

    def clear(self) -> None:
        self.last.clear()
        self.gaps.clear()


@dataclass
class AssembledFrame:
    """One filter step. index k; time_us: the autopilot's timestamp of the frame (us); y (m,) SI
    (NaN where mask is False); mask (m,) bool; u (2,) = u_{k-1} [delta_e rad, delta_t];
    synthetic: a frame that never arrived (all rows masked); stale: names of stale or frozen rows;
    restart: the frame clock restarted (time jump) or frames beyond max_gap_s are missing, so the
    filter's state is out of date."""

    index: int
    time_us: int
    y: np.ndarray
    mask: np.ndarray
    u: np.ndarray
    synthetic: bool = False
    stale: tuple[str, ...] = ()
    restart: bool = False

    @property
    def time_s(self) -> float:
        return self.time_us * 1e-6

    @property
    def time_boot_ms(self) -> int:
        return self.time_us // 1000


@dataclass
class _Partial:
    y: np.ndarray
    mask: np.ndarray
    seen: set[str] = field(default_factory=set)
    time_us: int = 0


class Route:
    """Where one mapped field of a message goes: a measurement row ("y") or an input channel
    ("u") j, with its FieldMap, `where` filter and the rejections it can cause."""

    __slots__ = ("kind", "j", "fm", "where", "out_of_range", "late", "frozen", "options", "underived")

    def __init__(self, kind: str, j: int, fm: FieldMap) -> None:
        self.kind, self.j, self.fm, self.where = kind, j, fm, fm.where
        self.out_of_range = Rejected("out of range", fm.name)
        self.late = Rejected("late", fm.name)
        self.frozen = Rejected("frozen", fm.name)
        self.options = dict(fm.options)
        self.underived = Rejected("not derivable", fm.name)


def routes_by_message(config: ServiceConfig) -> dict[str, list[Route]]:
    """Message name -> the routes of its mapped fields (measurement rows first, then inputs)."""
    routes: dict[str, list[Route]] = {}
    for j, fm in enumerate(config.measurements):
        routes.setdefault(fm.message, []).append(Route("y", j, fm))
    for j, fm in enumerate(config.inputs):
        routes.setdefault(fm.message, []).append(Route("u", j, fm))
    return routes


class InputHistory:
    """Per input channel, the last INPUT_HISTORY values (frame index, value) in frame order."""

    def __init__(self, initial_input: np.ndarray) -> None:
        self.initial = np.asarray(initial_input, dtype=float).copy()
        self.hist: list[list[tuple[int, float]]] = [[] for _ in self.initial]

    def record(self, j: int, k: int, v: float) -> bool:
        """Channel j takes value v at frame k; False (not taken) if stamped before its latest."""
        hist = self.hist[j]
        if hist and k < hist[-1][0]:
            return False
        if hist and hist[-1][0] == k:
            hist[-1] = (k, v)
        else:
            hist.append((k, v))
            if len(hist) > INPUT_HISTORY:
                del hist[0]
        return True

    def for_frame(self, k: int) -> np.ndarray:
        """u_{k-1} (2,): per channel the latest value stamped at or before frame k - 1."""
        u = self.initial.copy()
        for j, hist in enumerate(self.hist):
            for kk, v in reversed(hist):
                if kk <= k - 1:
                    u[j] = v
                    break
        return u

    def prune(self, k: int) -> None:
        """Frame k was stepped: keep the value in force for frame k + 1 plus anything newer."""
        for h in self.hist:
            while len(h) > 1 and h[1][0] <= k - 1:
                del h[0]

    def clear(self) -> None:
        self.hist = [[] for _ in self.hist]


class StaleRows:
    """Rows silent (message time) for longer than their stale_s; announces stale and recovered."""

    def __init__(self, measurements: tuple[FieldMap, ...], events: list[Event]) -> None:
        self.measurements = measurements
        self.last_seen_us: list[int | None] = [None] * len(measurements)
        self.now: set[str] = set()
        self.events = events

    def seen(self, j: int, t_us: int) -> None:
        """Row j had a valid value stamped t_us."""
        self.last_seen_us[j] = t_us

    def check(self, time_us: int, first_time_us: int) -> list[str]:
        """Names of the rows stale at frame time time_us (us); rows never seen count from
        first_time_us, the first frame's time."""
        stale = []
        for j, fm in enumerate(self.measurements):
            seen = self.last_seen_us[j]
            silent_s = (time_us - (seen if seen is not None else first_time_us)) * 1e-6
            if silent_s > fm.stale_s:
                stale.append(fm.name)
                if fm.name not in self.now:
                    self.now.add(fm.name)
                    self.events.append(SensorStale(fm.name, fm.message, silent_s))
            elif fm.name in self.now:
                self.now.discard(fm.name)
                self.events.append(SensorRecovered(fm.name))
        return stale

    def forget(self) -> None:
        """The clock restarted: no row has been seen yet."""
        self.last_seen_us = [None] * len(self.measurements)


class FrameAssembler:
    """Turns accepted messages into `AssembledFrame`s (see module doc). Pure: no clock, no I/O.

    `accept(msg)` returns the frames completed by that message; `events` collects typed events
    (stale / frozen / recovered sensors, time jumps, missing frames) for the caller to drain;
    `rejected` counts dropped values by reason (`screening.Rejections`).

    Timestamps: a message is placed in a frame only if it lies in the clock's window, from
    LATE_WINDOW_FRAMES (or max_gap_s) before the last stepped frame to max_gap_s after it. Outside,
    it is dropped ("time jump") unless JUMP_CONFIRM_MESSAGES messages in a row agree on the new
    time: then the clock restarts there (autopilot reboot, long link loss) and the next frame is
    flagged `restart` (the filter's state is out of date).
    """

    def __init__(self, config: ServiceConfig, initial_input: np.ndarray) -> None:
        self.config = config
        self.period_us = config.frame_period_us
        self.max_gap = int(round(config.max_gap_s * 1e6 / self.period_us))
        self.back_window = max(self.max_gap, LATE_WINDOW_FRAMES)
        self.names = tuple(fm.name for fm in config.measurements)
        self.m = len(self.names)
        self.by_message = routes_by_message(config)
        # message types without a where-filter: every route applies; value = has a measurement row
        self.plain = {mtype: any(r.kind == "y" for r in routes) for mtype, routes in self.by_message.items()
                      if not any(r.where for r in routes)}
        # message "kinds" a frame waits for: message name + its where-filter
        self.kinds = [self._kind(fm) for fm in config.measurements]
        self.required = set(self.kinds)
        self.rates = KindRates()
        self.pending: dict[int, _Partial] = {}
        self.last_index: int | None = None
        self.last_time_us: int | None = None
        self.first_time_us: int | None = None
        self.inputs = InputHistory(initial_input)
        self.rejected = Rejections()
        self.events: list[Event] = []
        self.stale = StaleRows(config.measurements, self.events)
        self.frozen = FrozenRows(config.measurements, self.events)
        self._jump: tuple[int, int] | None = None   # (candidate frame, messages agreeing)
        self._restart = False
        # derived rows: the messages they read besides their sample, message stamps, the latest stamp
        maps = config.measurements + config.inputs
        self.observed = frozenset(s for fm in maps if fm.derive for s in fm.sources[1:])
        self.sources = SourceCache(dict(config.parameters))
        self.stamps = {fm.message: fm.stamp for fm in maps if fm.stamp != "message"}
        self.latest_us: int | None = None
        self._own_stamps: dict[str, int] = {}   # stamp = "arrival" / "epoch": each type's last own stamp
        self.clock = EpochClock(self.events)   # stamp = "epoch": UNIX-epoch stamps -> boot time
        self.clock_messages = frozenset({SYSTEM_TIME} if "epoch" in self.stamps.values() else ())

    @staticmethod
    def _kind(fm: FieldMap) -> str:
        return fm.message + "".join(f"|{k}={v:g}" for k, v in fm.where)

    def is_mapped(self, msg_type: str) -> bool:
        """Whether any measurement row or input channel reads this message type (or, with a
        stamp = "epoch" row, it is SYSTEM_TIME)."""
        return msg_type in self.by_message or msg_type in self.clock_messages

    # ------------------------------------------------------------------ time
    def frame_index(self, t_us: int) -> int:
        """The frame k = round(t / T) a message stamped t_us (us) belongs to."""
        return (t_us + self.period_us // 2) // self.period_us

    def _in_clock(self, k: int) -> bool:
        """Whether frame k is inside the clock's window; handles jump confirmation. May restart."""
        last = self.last_index
        if last is None or last - self.back_window <= k <= last + self.max_gap + 1:
            self._jump = None
            return True
        if not self._jump_confirmed(k):
            self.rejected.add(TIME_JUMP)
            return False
        self._restart_clock(self._jump[0], last)
        self._jump = None
        return True

    def _jump_confirmed(self, k: int) -> bool:
        """Count one more message agreeing on out-of-window frame k; True once enough agree."""
        cand = self._jump
        if cand is not None and abs(k - cand[0]) <= self.max_gap + 1:
            self._jump = (max(k, cand[0]), cand[1] + 1)
        else:
            self._jump = (k, 1)
        return self._jump[1] >= JUMP_CONFIRM_MESSAGES

    def _restart_clock(self, k_new: int, last: int) -> None:
        """A confirmed time jump from frame `last` to k_new: restart the frame clock just before it."""
        self.events.append(TimeJumped(last * self.period_us * 1e-6, k_new * self.period_us * 1e-6,
                                      backward=k_new < last))
        self.pending.clear()
        self.rates.clear()
        self.last_index = None   # a fresh start: the next frames are not predicted through
        self.last_time_us = None
        self.inputs.clear()
        self.stale.forget()
        self.first_time_us = None
        self.sources.forget_time()
        self.latest_us = None
        self.clock.forget()
        self._restart = True

    # ------------------------------------------------------------------ messages
    def accept(self, msg) -> list[AssembledFrame]:
        """Take one decoded message; return the frames it completes (oldest first)."""
        mtype = msg.get_type()
        self._observe(msg, mtype)
        routes = self.by_message.get(mtype)
        if not routes:
            return []
        stamped = self._time_us(msg, mtype)
        if stamped is None:
            return []
        t_us, borrowed = stamped
        is_meas = self.plain.get(mtype)
        matched = routes if is_meas is not None else self._matching(msg, routes)
        if not matched:
            self.rejected.add(Rejected("not matching where", mtype))
            return []
        if is_meas is None:
            is_meas = any(r.kind == "y" for r in matched)
        k = (t_us + self.period_us // 2) // self.period_us   # frame_index(t_us)
        if not self._placed(k, t_us, borrowed):
            return []
        self._take_inputs(msg, matched, k, t_us)
        if self.last_index is not None and k <= self.last_index:
            if is_meas:
                self._count_late(k, t_us)
            return []
        out = self._flush_before(k) if self.pending else []   # anything stamped later closes a frame
        if is_meas:
            out += self._take_measurements(msg, matched, k, t_us)
        return out

    def _observe(self, msg, mtype: str) -> None:
        """A derivation's source message into the source cache; SYSTEM_TIME into the epoch clock."""
        if mtype in self.observed:
            self.sources.observe(msg, message_time_us(msg))
        if mtype in self.clock_messages:
            self.clock.observe(msg)

    def _placed(self, k: int, t_us: int, borrowed: bool) -> bool:
        """Whether frame k is in the clock (`_in_clock`); the latest stamp moves on. A message with a
        borrowed stamp (the latest stamp seen) is in the clock by construction and plays no part in
        confirming a time jump."""
        if borrowed:
            return True
        if not self._in_clock(k):
            return False
        if self.latest_us is None or t_us > self.latest_us:
            self.latest_us = t_us
        return True

    def _time_us(self, msg, mtype: str) -> tuple[int, bool] | None:
        """(time us, borrowed) of the message by its mapping's `stamp`: its own, unwrapped, mapped
        from UNIX-epoch time, or borrowed (the latest stamp seen: borrowed = True); None (counted)
        when it has none or repeats the sample before it."""
        stamp = self.stamps.get(mtype)
        if stamp == "latest":
            return self._borrowed()
        t = message_time_us(msg)
        if t is None:
            self.rejected.add(NO_TIMESTAMP)
            return None
        if stamp in ("arrival", "epoch") and self._repeated(mtype, t):
            return None
        if stamp == "arrival":
            return self._borrowed()
        if stamp == "epoch":
            return self._epoch(mtype, t)
        if stamp == "unwrap32" and self.latest_us is not None:
            t = unwrap32(t, self.latest_us)
        return t, False

    def _repeated(self, mtype: str, own_us: int) -> bool:
        """Whether the message repeats its type's previous own stamp (us): the same sample sent
        again (dropped, counted)."""
        if self._own_stamps.get(mtype) == own_us:
            self.rejected.add(Rejected("repeated sample", mtype))
            return True
        self._own_stamps[mtype] = own_us
        return False

    def _borrowed(self) -> tuple[int, bool] | None:
        """(the latest stamp seen (us), True); None (counted) before any stamped message."""
        if self.latest_us is None:
            self.rejected.add(NO_TIMESTAMP)
            return None
        return self.latest_us, True

    def _epoch(self, mtype: str, own_us: int) -> tuple[int, bool] | None:
        """stamp = "epoch": the own stamp (us) on the boot clock (`EpochClock.boot_us`) if its frame
        has not been stepped yet; else, before any SYSTEM_TIME or before boot, the latest stamp seen
        (as "arrival": a sample sent up to a stream period after it was taken is not dropped as late)."""
        boot = self.clock.boot_us(own_us, mtype)
        if boot is None or boot < 0 or self._stepped(boot):
            return self._borrowed()
        return boot, False

    def _stepped(self, t_us: int) -> bool:
        """Whether the frame of time t_us (us) has already been stepped."""
        return self.last_index is not None and self.frame_index(t_us) <= self.last_index

    def _value(self, msg, r: Route, t_us: int) -> float | None:
        """Route r's SI value of the message (read or derived) if valid; None (counted) if not."""
        if not r.fm.derive:
            v = field_value(msg, r.fm)
            if v is None:
                self.rejected.add(r.out_of_range)
            return v
        raw = derive_value(r.fm.derive, msg, t_us, self.sources, r.options)
        if raw != raw:   # NaN: a source is missing or too old
            self.rejected.add(r.underived)
            return None
        v = checked_value(r.fm, raw)
        if v is None:
            self.rejected.add(r.out_of_range)
        return v

    @staticmethod
    def _matching(msg, routes: list[Route]) -> list[Route]:
        """The routes whose where-filter the message passes."""
        return [r for r in routes if matches_where(msg, r.where)]

    def _take_inputs(self, msg, routes: list[Route], k: int, t_us: int) -> None:
        """Record the message's input values (u) for frame k; bad or late ones are counted."""
        for r in routes:
            if r.kind != "u":
                continue
            v = self._value(msg, r, t_us)
            if v is not None and not self.inputs.record(r.j, k, v):
                self.rejected.add(r.late)

    def _count_late(self, k: int, t_us: int) -> None:
        """A measurement for an already stepped frame: a surplus one (stamped later within the last
        frame: above the frame rate) or a late one."""
        if k == self.last_index and self.last_time_us is not None and t_us > self.last_time_us:
            self.rejected.add(SURPLUS)
        else:
            self.rejected.add(LATE_MEASUREMENT)

    def _take_measurements(self, msg, routes: list[Route], k: int, t_us: int) -> list[AssembledFrame]:
        """Put the message's measurement rows into pending frame k; return it if now complete."""
        part = self.pending.get(k)
        if part is None:
            part = self.pending[k] = _Partial(np.full(self.m, np.nan), np.zeros(self.m, dtype=bool))
        if t_us > part.time_us:
            part.time_us = t_us
        for r in routes:
            if r.kind == "y":
                part.seen.add(self.kinds[r.j])
                self.rates.seen(self.kinds[r.j], k)
                self._take_row(msg, r, part, t_us)
        if all(kind in part.seen or not self.rates.due(kind, k) for kind in self.required):
            return self._emit(k, self.pending.pop(k))
        return []

    def _take_row(self, msg, r: Route, part: _Partial, t_us: int) -> None:
        """Row r's value into the partial frame, unless out of range or frozen (counted)."""
        v = self._value(msg, r, t_us)
        if v is None:
            return
        self.stale.seen(r.j, t_us)
        if self.frozen.watched(r.j) and self.frozen.check(r.j, v, t_us):
            self.rejected.add(r.frozen)
            return
        part.y[r.j] = v
        part.mask[r.j] = True

    def flush(self) -> list[AssembledFrame]:
        """Hand over every pending (incomplete) frame, e.g. at shutdown."""
        return self._flush_before(None)

    # ------------------------------------------------------------------ frames
    def _flush_before(self, k: int | None) -> list[AssembledFrame]:
        out: list[AssembledFrame] = []
        for j in sorted(self.pending):
            if k is None or j < k:
                out += self._emit(j, self.pending.pop(j))
        return out

    def _emit(self, k: int, part: _Partial) -> list[AssembledFrame]:
        """Frame k, preceded by the synthetic frames of a gap up to max_gap_s."""
        out = self._gap_frames(k)
        out.append(self._frame(k, part.time_us, part.y, part.mask))
        self.last_index = k
        self.last_time_us = part.time_us
        self.inputs.prune(k)
        return out

    def _gap_frames(self, k: int) -> list[AssembledFrame]:
        """All-masked frames for the frames missing before k; none (and a restart) past max_gap_s."""
        if self.last_index is None or k <= self.last_index + 1:
            return []
        missing = k - self.last_index - 1
        if missing > self.max_gap:
            self.events.append(FramesMissing(missing * self.period_us * 1e-6))
            self._restart = True
            return []
        return [self._frame(g, g * self.period_us, np.full(self.m, np.nan), np.zeros(self.m, dtype=bool),
                            synthetic=True) for g in range(self.last_index + 1, k)]

    def _frame(self, k: int, time_us: int, y: np.ndarray, mask: np.ndarray,
               synthetic: bool = False) -> AssembledFrame:
        if self.first_time_us is None:
            self.first_time_us = time_us
        stale = self.stale.check(time_us, self.first_time_us)
        stale += [n for n in self.frozen.now if n not in stale]
        restart, self._restart = self._restart, False
        return AssembledFrame(k, int(time_us), y, mask, self.inputs.for_frame(k), synthetic, tuple(stale),
                              restart)
