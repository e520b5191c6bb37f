"""Decoded MAVLink messages -> filter frames: (t, y (m,), mask (m,), u (2,)).

Frame assembly is by message timestamp only (never the arrival time): a message stamped t (its
`time_usec`, else `time_boot_ms`) belongs to frame k = round(t / T), T = 1 / frames.rate_hz.
Frame k is complete, and handed to the filter at once, when every message type that feeds a
measurement row has arrived for it; it is handed over incomplete (missing rows masked) as soon as
any message stamped later than frame k arrives. Frames that never arrived, up to `max_gap_s`, are
stepped with every row masked (pure prediction). The input of frame k is u_{k-1}: for each input
channel, the latest value stamped at or before frame k-1 (the trim input until one arrives).

A measurement row silent (in message time) for longer than its `stale_s` is reported stale; a
non-finite or out-of-range value is dropped and counted, never handed to the filter.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from fdir_service.service_config import FieldMap, ServiceConfig


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


def message_time_us(msg) -> int | None:
    """The message's autopilot timestamp in us (time_usec, else time_boot_ms * 1000), or None."""
    t = getattr(msg, "time_usec", None)
    if t is not None:
        return int(t)
    t = getattr(msg, "time_boot_ms", None)
    return None if t is None else int(t) * 1000


def _read(msg, fm: FieldMap) -> float:
    raw = getattr(msg, fm.field)
    if fm.index is not None:
        raw = raw[fm.index]
    try:
        return fm.convert(raw)
    except (TypeError, ValueError, OverflowError):
        return math.nan


JUMP_CONFIRM_MESSAGES = 10
"""Messages in a row that must agree on a timestamp outside the frame clock's window before the
clock restarts there (one corrupt timestamp must not move the clock)."""
LATE_WINDOW_FRAMES = 100
"""Messages stamped up to this many frames (or max_gap_s, if longer) before the last stepped frame
are late (dropped, counted); further back is a time jump."""


class FrameAssembler:
    """Turns accepted messages into `AssembledFrame`s (see module doc). Pure: no clock, no I/O.

    `accept(msg)` returns the frames completed by that message; `events` collects (level, text)
    notices (stale / frozen / recovered sensors, time jumps) for the caller to drain; `rejected`
    counts dropped values by reason.

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
        # message name -> [(kind "y"|"u", row, FieldMap, where)], built once
        self.by_message: dict[str, list[tuple[str, int, FieldMap, tuple]]] = {}
        for j, fm in enumerate(config.measurements):
            self.by_message.setdefault(fm.message, []).append(("y", j, fm, fm.where))
        for j, fm in enumerate(config.inputs):
            self.by_message.setdefault(fm.message, []).append(("u", j, fm, fm.where))
        # message "kinds" a frame waits for: message name + its where-filter
        self.kinds = [self._kind(fm) for fm in config.measurements]
        self.required = set(self.kinds)
        self.pending: dict[int, _Partial] = {}
        self.last_index: int | None = None
        self.last_time_us: int | None = None
        self.first_time_us: int | None = None
        self.inputs: list[list[tuple[int, float]]] = [[] for _ in config.inputs]
        self.initial_input = np.asarray(initial_input, dtype=float).copy()
        self.last_seen_us: list[int | None] = [None] * self.m
        self.stale_now: set[str] = set()
        self.frozen_value: list[float | None] = [None] * self.m
        self.frozen_since_us: list[int] = [0] * self.m
        self.frozen_now: set[str] = set()
        self.frozen_us = [int(fm.frozen_s * 1e6) for fm in config.measurements]
        self.rejected: Counter[str] = Counter()
        self.events: list[tuple[str, str]] = []
        self._jump: tuple[int, int] | None = None   # (candidate frame, messages agreeing)
        self._restart = False

    @staticmethod
    def _kind(fm: FieldMap) -> str:
        return fm.message + "".join(f"|{k}={v:g}" for k, v in fm.where)

    def is_mapped(self, msg_type: str) -> bool:
        return msg_type in self.by_message

    # ------------------------------------------------------------------ time
    def _in_clock(self, k: int) -> bool:
        """Whether frame k is inside the clock's window; handles jump confirmation. May restart."""
        last = self.last_index
        if last is None or last - self.back_window <= k <= last + self.max_gap + 1:
            self._jump = None
            return True
        cand = self._jump
        if cand is not None and abs(k - cand[0]) <= self.max_gap + 1:
            self._jump = (max(k, cand[0]), cand[1] + 1)
        else:
            self._jump = (k, 1)
        if self._jump[1] < JUMP_CONFIRM_MESSAGES:
            self.rejected["time jump"] += 1
            return False
        # confirmed: restart the frame clock just before the new time
        k_new = self._jump[0]
        self._jump = None
        direction = "back" if k_new < last else "forward"
        self.events.append(("warning", f"autopilot time jumped {direction} from "
                            f"{last * self.period_us * 1e-6:.2f} s to {k_new * self.period_us * 1e-6:.2f} s: "
                            "restarting the frame clock"))
        self.pending.clear()
        self.last_index = None   # a fresh start: the next frames are not predicted through
        self.last_time_us = None
        self.inputs = [[] for _ in self.inputs]
        self.last_seen_us = [None] * self.m
        self.first_time_us = None
        self._restart = True
        return True

    # ------------------------------------------------------------------ messages
    def accept(self, msg) -> list[AssembledFrame]:
        """Take one decoded message; return the frames it completes (oldest first)."""
        entries = self.by_message.get(msg.get_type())
        if not entries:
            return []
        t_us = message_time_us(msg)
        if t_us is None:
            self.rejected["no timestamp"] += 1
            return []
        k = (t_us + self.period_us // 2) // self.period_us
        matched = []
        for entry in entries:
            where = entry[3]
            if where:
                try:
                    if not all(float(getattr(msg, wk)) == wv for wk, wv in where):
                        continue
                except (TypeError, ValueError, AttributeError):
                    continue
            matched.append(entry)
        if not matched:
            self.rejected[f"{msg.get_type()} not matching where"] += 1
            return []
        if not self._in_clock(k):
            return []
        out: list[AssembledFrame] = []
        is_meas = False
        for kind, j, fm, _ in matched:
            if kind != "u":
                is_meas = True
                continue
            v = _read(msg, fm)
            if not (math.isfinite(v) and fm.min <= v <= fm.max):
                self.rejected[f"{fm.name} out of range"] += 1
                continue
            hist = self.inputs[j]
            if hist and k < hist[-1][0]:
                self.rejected[f"{fm.name} late"] += 1
                continue
            if hist and hist[-1][0] == k:
                hist[-1] = (k, v)
            else:
                hist.append((k, v))
                if len(hist) > 8:
                    del hist[0]
        if self.last_index is not None and k <= self.last_index:
            if is_meas:
                if k == self.last_index and self.last_time_us is not None and t_us > self.last_time_us:
                    self.rejected["surplus (above frame rate)"] += 1
                else:
                    self.rejected["late measurement"] += 1
            return out
        # anything stamped after a pending frame closes it
        if self.pending:
            out += self._flush_before(k)
        if not is_meas:
            return out
        part = self.pending.get(k)
        if part is None:
            part = self.pending[k] = _Partial(np.full(self.m, np.nan), np.zeros(self.m, dtype=bool))
        if t_us > part.time_us:
            part.time_us = t_us
        for kind, j, fm, _ in matched:
            if kind != "y":
                continue
            part.seen.add(self.kinds[j])
            v = _read(msg, fm)
            if not (math.isfinite(v) and fm.min <= v <= fm.max):
                self.rejected[f"{fm.name} out of range"] += 1
                continue
            self.last_seen_us[j] = t_us
            if self.frozen_us[j] and self._frozen(j, fm, v, t_us):
                self.rejected[f"{fm.name} frozen"] += 1
                continue
            part.y[j] = v
            part.mask[j] = True
        if self.required <= part.seen:
            out += self._emit(k, self.pending.pop(k))
        return out

    def _frozen(self, j: int, fm: FieldMap, v: float, t_us: int) -> bool:
        """Whether row j has held the bit-identical value v for frozen_s (message time)."""
        if v != self.frozen_value[j]:
            self.frozen_value[j] = v
            self.frozen_since_us[j] = t_us
            if fm.name in self.frozen_now:
                self.frozen_now.discard(fm.name)
                self.events.append(("info", f"{fm.name} no longer frozen"))
            return False
        held = t_us - self.frozen_since_us[j]
        if held < self.frozen_us[j]:
            return False
        if fm.name not in self.frozen_now:
            self.frozen_now.add(fm.name)
            self.events.append(("warning", f"{fm.name} frozen at {v:.6g} for {held * 1e-6:.2f} s"))
        return True

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

    def _input_for(self, k: int) -> np.ndarray:
        """u_{k-1}: per channel the latest value stamped at or before frame k - 1."""
        u = self.initial_input.copy()
        for j, hist in enumerate(self.inputs):
            for kk, v in reversed(hist):
                if kk <= k - 1:
                    u[j] = v
                    break
        return u

    def _emit(self, k: int, part: _Partial) -> list[AssembledFrame]:
        out: list[AssembledFrame] = []
        if self.last_index is not None and k > self.last_index + 1:
            missing = k - self.last_index - 1
            if missing <= self.max_gap:
                for g in range(self.last_index + 1, k):
                    out.append(self._frame(g, g * self.period_us, np.full(self.m, np.nan),
                                           np.zeros(self.m, dtype=bool), synthetic=True))
            else:
                self.events.append(("warning", f"{missing * self.period_us * 1e-6:.2f} s of frames "
                                    f"missing (more than max_gap_s): not predicted through"))
                self._restart = True
        out.append(self._frame(k, part.time_us, part.y, part.mask))
        self.last_index = k
        self.last_time_us = part.time_us
        for h in self.inputs:  # keep the value in force plus anything newer
            while len(h) > 1 and h[1][0] <= k - 1:
                del h[0]
        return out

    def _frame(self, k: int, time_us: int, y: np.ndarray, mask: np.ndarray,
               synthetic: bool = False) -> AssembledFrame:
        if self.first_time_us is None:
            self.first_time_us = time_us
        stale = []
        for j, fm in enumerate(self.config.measurements):
            seen = self.last_seen_us[j]
            ref = seen if seen is not None else self.first_time_us
            silent_s = (time_us - ref) * 1e-6
            if silent_s > fm.stale_s:
                stale.append(fm.name)
                if fm.name not in self.stale_now:
                    self.stale_now.add(fm.name)
                    self.events.append(("warning", f"{fm.name} stale: no {fm.message} for "
                                        f"{silent_s:.2f} s"))
            elif fm.name in self.stale_now:
                self.stale_now.discard(fm.name)
                self.events.append(("info", f"{fm.name} recovered"))
        stale += [n for n in self.frozen_now if n not in stale]
        restart, self._restart = self._restart, False
        return AssembledFrame(k, int(time_us), y, mask, self._input_for(k), synthetic, tuple(stale), restart)
