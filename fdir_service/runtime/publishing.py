"""What the service sends: HEARTBEAT, NAMED_VALUE_FLOAT, STATUSTEXT (with hysteresis) and the
dialect's FDIR_ESTIMATE, encoded (and signed, when a key is set) by one pymavlink codec.

Every message that has a `time_boot_ms` carries the autopilot's timestamp of the frame it
describes. Rates are counted in frame time, so a replay publishes the same messages. A STATUSTEXT
is sent right after the FDIR_ESTIMATE of the frame that triggered it (STATUSTEXT has no time
field; a ground station dates it by that estimate).

Items (`items.py`): the service reports on monitored items, a target watched by one or more typed
fault entries (one item per entry when every target has one entry). Per item and frame: P(item
faulty), its most probable type and that type's user-facing value. FDIR_ESTIMATE's channels are the
items; NAMED_VALUE_FLOAT stays per entry (f_<id>, pf_<id>, ...).

Hysteresis (config `[publish.declare]`), per item: an item is declared when P(item faulty) >=
p_declare on every frame for declare_hold_s of frame time, and cleared when P <= p_clear for
clear_hold_s. A type is *named* once P(item) >= p_declare and the item's most probable type
has held a share >= p_type of it for type_hold_s of frame time: a declaration carries the named
type, or UNCLEAR while none is ("FDIR de fault, type unclear p=0.95"), and while declared a new
named type (held for type_hold_s, and at least declare_hold_s) is announced (an unclear
declaration's first name too). Each change is a typed
event (`FaultDeclared`, `FaultCleared`, `FaultTypeChanged`) besides its STATUSTEXT ("FDIR q stuck
at 3.2 deg/s p=0.97").

`RateLimit` spaces the STATUSTEXTs the runtime sends about one subject in frame time;
`sensor_notice` and `link_notice` are the STATUSTEXTs of sensor, clock and link events.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimator_config import FaultSpec as FaultChannel
from fdir_service.mavlink import FAULT_TYPE_BYTES, MAX_FAULTS, dialect, frame_payload, pack_fault_types
from fdir_service.mavlink import pack as fast_pack
from fdir_service.runtime.events import (
    Event,
    FaultCleared,
    FaultDeclared,
    FaultTypeChanged,
    LinkLost,
    LinkRegained,
)
from fdir_service.runtime.items import (
    ItemFrame,
    ItemReport,
    entry_types,
    is_plain,
    item_frame,
    item_layout,
    type_code,
)
from fdir_service.service_config import PublishConfig

if TYPE_CHECKING:
    from fdir_service.runtime.frames import AssembledFrame

_EPS_US = 1  # frame-time comparisons in us
_NVF = dialect.MAVLink_named_value_float_message
UNCLEAR = "unclear"
"""The type a declaration names while no type holds a share >= p_type of P(item)."""
_EST = dialect.MAVLink_fdir_estimate_message


@dataclass
class _Hysteresis:
    """One item's declaration state (frame times in us)."""

    declared: bool = False
    since_us: int | None = None  # first frame of the current run above p_declare / below p_clear
    fault_type: str = "bias"     # the type announced by the last declaration or type change (or UNCLEAR)
    sure_type: str | None = None  # the type clear enough to name on the last frame (`Publisher._named_type`)
    sure_since_us: int | None = None  # first frame of sure_type's current run


class Change(NamedTuple):
    """A declaration change of item `item`: `what` "declared" | "cleared" | "type" (a declared
    item's type changed from `previous`), and its STATUSTEXT."""

    item: int
    what: str
    text: str
    previous: str = ""


def value_text(fault: FaultChannel, fault_type: str, value: float) -> str:
    """A fault's user-facing value in words: '+50.1 m' (bias, in the fault's unit), 'at 3.2 deg/s'
    (stuck or blocked reading, jammed position), 'x4.1' (noisy: noise multiplier k), '0%'
    (effectiveness g), '+0.30 m/s' (drift: its rate, the fault's unit per second), 'out, thrust 3%'
    (engine: the commanded thrust's share it gives)."""
    if fault_type == "noisy":
        return f"x{value:.1f}"
    if fault_type in ("effectiveness", "engine"):   # a gain, or the commanded thrust's share left
        percent = f"{round(100 * value)}%" if math.isfinite(value) else f"{value}%"
        return percent if fault_type == "effectiveness" else f"out, thrust {percent}"
    val = value / fault.unit_scale
    unit = "" if fault.unit == "1" else f" {fault.unit}"
    if fault_type in ("stuck", "jammed", "blocked"):
        return f"at {val:.1f}{unit}"
    if fault_type == "drift":                  # value: the rate, SI per second
        return f"{val:+.2f}{unit or ' '}/s"
    return f"{val:+.1f}{unit}"


def statustext_for(fault: FaultChannel, estimate_si: float, p: float, declared: bool,
                   fault_type: str = "bias", name: str | None = None) -> str:
    """'FDIR gnss fault +50.1 m p=0.98', 'FDIR q stuck at 3.2 deg/s p=0.97', 'FDIR baro noisy x4.1
    p=0.93', 'FDIR dt effectiveness 0% p=0.99' / 'FDIR gnss cleared p=0.03'. fault: the entry of the
    given type (its unit); estimate_si: that entry's user-facing value (SI; k, g unitless); p:
    P(item faulty); name: the item's name (default the entry's id)."""
    name = fault.id if name is None else name
    if not declared:
        return f"FDIR {name} cleared p={p:.2f}"
    if fault_type == UNCLEAR:
        return f"FDIR {name} fault, type unclear p={p:.2f}"
    word = "fault" if fault_type == "bias" else fault_type
    return f"FDIR {name} {word} {value_text(fault, fault_type, estimate_si)} p={p:.2f}"


def _held(since_us: int, time_us: int, hold_s: float) -> bool:
    """Whether a run that started at since_us (us) has lasted hold_s (s) at frame time time_us."""
    return time_us - since_us + _EPS_US >= hold_s * 1e6


class RateLimit:
    """At most one message per subject per `interval_s` of frame time (the first one at once)."""

    def __init__(self, interval_s: float) -> None:
        self.interval_us = interval_s * 1e6
        self.last_us: dict[str, int] = {}

    def due(self, subject: str, now_us: int) -> bool:
        """Whether a message about `subject` may go out at frame time now_us (us); if so, it is
        counted as sent."""
        last = self.last_us.get(subject)
        if last is not None and now_us - last < self.interval_us:
            return False
        self.last_us[subject] = now_us
        return True


def sensor_notice(event: Event) -> tuple[int, str]:
    """(severity, text) of the STATUSTEXT for a sensor or clock event ("FDIR <event text>")."""
    sev = dialect.MAV_SEVERITY_WARNING if event.level == "warning" else dialect.MAV_SEVERITY_INFO
    return sev, f"FDIR {event.text}"[:50]


def link_notice(event: LinkLost | LinkRegained) -> tuple[int, str]:
    """(severity, text) of the STATUSTEXT announcing a lost (CRITICAL) or regained (NOTICE) link."""
    if isinstance(event, LinkLost):
        return dialect.MAV_SEVERITY_CRITICAL, f"FDIR link lost: no input for {event.silent_s:.1f} s"
    return dialect.MAV_SEVERITY_NOTICE, f"FDIR link restored after {event.silent_s:.1f} s"


class Publisher:
    """Builds the output messages for each stepped frame. `mav` is the output codec (its
    srcSystem/srcComponent and signing are used as they are)."""

    def __init__(self, config: PublishConfig, faults: tuple[FaultChannel, ...], mav: dialect.MAVLink,
                 adaptive: bool) -> None:
        self.layout = item_layout(faults)
        if len(self.layout) > MAX_FAULTS:
            raise ValueError(f"FDIR_ESTIMATE carries at most {MAX_FAULTS} monitored items")
        self.config = config
        self.faults = faults
        self.types = entry_types(faults)
        self.plain = is_plain(self.layout, self.types)   # all single bias entries: output as before
        self.mav = mav
        self.adaptive = adaptive
        self.hyst = [_Hysteresis() for _ in self.layout.names]
        self.view: ItemFrame | None = None   # the last published frame's item view
        self.frame_seq = 0
        self._last_bucket: dict[str, int] = {}
        self.health = dialect.MAV_STATE_STANDBY
        self.text_id = 0   # the last chunked STATUSTEXT's id
        self.names = {f.id: (f"f_{f.id}".encode(), f"pf_{f.id}".encode(), f"pfa_{f.id}".encode(),
                             f"pmd_{f.id}".encode()) for f in faults}

    # ------------------------------------------------------------------ rates
    def _due(self, what: str, period_s: float, time_us: int) -> bool:
        """True on the first frame of each period_s bucket of frame time."""
        bucket = int(math.floor(time_us / (period_s * 1e6) + 1e-9))
        if self._last_bucket.get(what) == bucket:
            return False
        self._last_bucket[what] = bucket
        return True

    def _pack(self, msg) -> bytes:
        return fast_pack(msg, self.mav)

    def _frame(self, cls, payload: bytes) -> bytes | None:
        return frame_payload(self.mav, cls.id, cls.crc_extra, payload)

    def named_value_float(self, time_boot_ms: int, name: bytes, value: float) -> bytes:
        b = self._frame(_NVF, _NVF.unpacker.pack(time_boot_ms, value, name))
        return b if b is not None else self._pack(_NVF(time_boot_ms, name, value))

    # ------------------------------------------------------------------ messages
    def heartbeat(self, status: int | None = None) -> bytes:
        st = self.health if status is None else status
        return self._pack(dialect.MAVLink_heartbeat_message(
            dialect.MAV_TYPE_ONBOARD_CONTROLLER, dialect.MAV_AUTOPILOT_INVALID, 0, 0, st, 3))

    def statustext(self, severity: int, text: str) -> bytes:
        return self._pack(dialect.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0))

    def statustexts(self, severity: int, text: str) -> list[bytes]:
        """`text` as one STATUSTEXT, or, longer than 50 bytes, as MAVLink 2 chunks (same non-zero
        `id`, `chunk_seq` 0, 1, ...; a text of a multiple of 50 bytes ends with an empty chunk)."""
        data = text.encode()
        if len(data) <= 50:
            return [self.statustext(severity, text)]
        self.text_id = self.text_id % 0xFFFF + 1
        chunks = [data[i:i + 50] for i in range(0, len(data), 50)]
        if len(chunks[-1]) == 50:
            chunks.append(b"")
        return [self._pack(dialect.MAVLink_statustext_message(severity, c, self.text_id, seq))
                for seq, c in enumerate(chunks)]

    def item_view(self, out: StepOutput) -> ItemFrame:
        """The step's item view (entry types from the step, else from the config)."""
        return item_frame(self.layout, out, tuple(out.fault_types) or self.types)

    def update_declarations(self, time_us: int, out: StepOutput, view: ItemFrame | None = None
                            ) -> list[Change]:
        """Advance every item's hysteresis at frame time time_us (us); return its changes."""
        view = self.item_view(out) if view is None else view
        changes = []
        for i, h in enumerate(self.hyst):
            change = self._declaration_change(i, h, time_us, view)
            if change is not None:
                changes.append(change)
        return changes

    def _declaration_change(self, i: int, h: _Hysteresis, time_us: int, view: ItemFrame) -> Change | None:
        """Item i's declaration or type change on this frame, if any."""
        dc = self.config.declare
        self._track_type(i, h, time_us, view)
        p = float(view.p[i])
        crossing = (p <= dc.p_clear) if h.declared else (p >= dc.p_declare)
        if not crossing:
            h.since_us = None
            return self._type_change(i, h, time_us, view)
        if h.since_us is None:
            h.since_us = time_us
        if not _held(h.since_us, time_us, dc.clear_hold_s if h.declared else dc.declare_hold_s):
            return self._type_change(i, h, time_us, view)
        h.declared, h.since_us = not h.declared, None
        if h.declared:                      # a clearing keeps the last type named
            h.fault_type = self._held_type(h, time_us, dc.type_hold_s) or UNCLEAR
        text = self._text(i, view, h.declared, h.fault_type)
        return Change(i, "declared" if h.declared else "cleared", text)

    def _named_type(self, i: int, view: ItemFrame) -> str | None:
        """Item i's most probable type when P(item) >= p_declare and the type holds a share >=
        p_type of it, else None (no type is named on evidence too weak to declare)."""
        dc = self.config.declare
        sure = float(view.p[i]) >= dc.p_declare and float(view.share[i]) >= dc.p_type
        return view.types[i] if sure else None

    def _track_type(self, i: int, h: _Hysteresis, time_us: int, view: ItemFrame) -> None:
        """On every frame, declared or not: the type clear enough to name (`_named_type`) and the
        first frame of its current run."""
        ftype = self._named_type(i, view)
        if ftype != h.sure_type:
            h.sure_type, h.sure_since_us = ftype, time_us

    @staticmethod
    def _held_type(h: _Hysteresis, time_us: int, hold_s: float) -> str | None:
        """The type clear enough to name, if it has been so for hold_s (s) at frame time time_us."""
        if h.sure_type is None or h.sure_since_us is None:
            return None
        return h.sure_type if _held(h.sure_since_us, time_us, hold_s) else None

    def _type_change(self, i: int, h: _Hysteresis, time_us: int, view: ItemFrame) -> Change | None:
        """While item i is declared: a change once a new type has been clear enough to name
        (`_named_type`) for type_hold_s, and at least declare_hold_s (a flicker is not announced)."""
        if not h.declared:
            return None
        dc = self.config.declare
        ftype = self._held_type(h, time_us, max(dc.type_hold_s, dc.declare_hold_s))
        if ftype is None or ftype == h.fault_type:
            return None
        previous, h.fault_type = h.fault_type, ftype
        return Change(i, "type", f"{self._text(i, view, True, ftype)} (was {previous})", previous)

    def _text(self, i: int, view: ItemFrame, declared: bool, fault_type: str) -> str:
        """Item i's STATUSTEXT for this frame's view (declared: the named type and its value in words)."""
        entry = self.faults[int(view.entry[i])]
        return statustext_for(entry, float(view.value[i]), float(view.p[i]), declared, fault_type,
                              self.layout.names[i])

    def item_report(self) -> ItemReport | None:
        """The last published frame's items for observers (None before the first frame)."""
        if self.view is None:
            return None
        return ItemReport(self.layout.names, self.view, tuple(h.declared for h in self.hyst))

    def typed_output(self, out: StepOutput) -> StepOutput:
        """out with the config's entry types when the filter reports none and some entry is not a
        bias (so observers and the recording see the types); out itself otherwise."""
        if out.fault_types or all(t == "bias" for t in self.types):
            return out
        return dataclasses.replace(out, fault_types=self.types)

    @property
    def declared_mask(self) -> int:
        return sum(1 << i for i, h in enumerate(self.hyst) if h.declared)

    def publish(self, frame: AssembledFrame, out: StepOutput, gap: bool = False
                ) -> tuple[list[bytes], list[FaultDeclared | FaultCleared | FaultTypeChanged]]:
        """Messages for one stepped frame (HEARTBEAT, FDIR_ESTIMATE, NAMED_VALUE_FLOAT at their
        rates, then a STATUSTEXT per declaration change), and the declaration events."""
        msgs: list[bytes] = []
        self.frame_seq += 1
        self.view = view = self.item_view(out)
        changes = self.update_declarations(frame.time_us, out, view)
        if self._due("hb", self.config.heartbeat_period_s, frame.time_us):
            msgs.append(self.heartbeat())
        if self._due("est", 1.0 / self.config.estimate_rate_hz, frame.time_us):
            msgs.append(self.estimate_bytes(frame, out, gap, view))
        if self._due("nvf", 1.0 / self.config.named_value_rate_hz, frame.time_us):
            msgs += self.named_values(frame.time_boot_ms, out)
        events = [self._declaration(frame, view, c) for c in changes]
        for e in events:
            if isinstance(e, FaultTypeChanged):
                msgs += self.statustexts(dialect.MAV_SEVERITY_WARNING, e.statustext)
                continue
            declared = isinstance(e, FaultDeclared)
            sev = dialect.MAV_SEVERITY_WARNING if declared else dialect.MAV_SEVERITY_NOTICE
            msgs.append(self.statustext(sev, e.statustext))
        return msgs, events

    def named_values(self, time_boot_ms: int, out: StepOutput) -> list[bytes]:
        """NAMED_VALUE_FLOAT f_<id>, pf_<id> (and pfa_<id>, pmd_<id> for adaptive filters) per fault."""
        msgs = []
        for i, f in enumerate(self.faults):
            nf_, npf, npfa, npmd = self.names[f.id]
            vals = [(nf_, out.fault_estimate[i]), (npf, out.fault_probability[i])]
            if self.adaptive and out.pfa is not None and out.pmd is not None:
                vals += [(npfa, out.pfa[i]), (npmd, out.pmd[i])]
            for name, v in vals:
                msgs.append(self.named_value_float(time_boot_ms, name, float(v)))
        return msgs

    def _declaration(self, frame: AssembledFrame, view: ItemFrame, c: Change
                     ) -> FaultDeclared | FaultCleared | FaultTypeChanged:
        """The typed event of one declaration change (item name, frame time s, P(item faulty))."""
        name, p = self.layout.names[c.item], float(view.p[c.item])
        if c.what == "cleared":
            return FaultCleared(name, frame.time_s, p, c.text)
        ftype, value = self.hyst[c.item].fault_type, float(view.value[c.item])
        if c.what == "declared":
            return FaultDeclared(name, frame.time_s, p, value, c.text, ftype)
        return FaultTypeChanged(name, frame.time_s, p, value, c.text, ftype, c.previous)

    def _estimate_fields(self, frame: AssembledFrame, out: StepOutput, gap: bool,
                         view: ItemFrame | None = None) -> tuple:
        """FDIR_ESTIMATE's fields in declaration order (time_boot_ms, frame_seq, fault_count,
        declared, flags, mask, state[5], state_std[5], fault[8], fault_std[8], p_fault[8], pfa[8],
        pmd[8], n_eff, fault_type[4] (packed), fault_value[8]), as Python numbers and lists (NaN where a field
        has no value). Channel i is item i: its most probable entry's fault, std, pfa, pmd, type and
        value, and P(item faulty); the extensions are all 0 (not sent) when `plain`."""
        view = self.item_view(out) if view is None else view
        ni, nf = len(self.layout), len(self.faults)
        best = view.entry
        x = np.asarray(out.x_mean, dtype=float)
        nan8 = [math.nan] * MAX_FAULTS

        def pad(v, pick: bool = True) -> list[float]:
            if v is None:
                return nan8
            v = np.asarray(v, dtype=float).ravel()
            return (v[best] if pick else v[:ni]).tolist() + nan8[ni:]

        std = (np.sqrt(np.clip(np.diag(out.x_cov), 0.0, None)) if out.x_cov is not None
               else np.full(x.size, np.nan))
        fault_std = pad(std[5:]) if std.size >= 5 + nf else nan8
        ftype, fvalue = [0] * FAULT_TYPE_BYTES, [0.0] * MAX_FAULTS
        if not self.plain:
            ftype = pack_fault_types([type_code(t) for t in view.types])
            fvalue = pad(view.value, pick=False)
        return (frame.time_boot_ms, self.frame_seq & 0xFFFFFFFF, ni, self.declared_mask,
                self._flags(frame, out, gap), sum(1 << j for j, ok in enumerate(frame.mask[:8]) if ok),
                x[:5].tolist(), std[:5].tolist(), pad(out.fault_estimate), fault_std,
                pad(view.p, pick=False), pad(out.pfa), pad(out.pmd), float(out.n_eff), ftype, fvalue)

    def _flags(self, frame: AssembledFrame, out: StepOutput, gap: bool) -> int:
        """FDIR_ESTIMATE_FLAGS bits of one frame."""
        flags = 0
        if out.resampled:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_RESAMPLED
        if self.adaptive:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_ADAPTIVE
        if frame.stale:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_SENSOR_STALE
        if gap or frame.synthetic:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_GAP
        return flags

    def estimate_message(self, frame: AssembledFrame, out: StepOutput, gap: bool = False):
        """The frame's FDIR_ESTIMATE as a pymavlink message object (the reference encoding)."""
        return _EST(*self._estimate_fields(frame, out, gap))

    def estimate_bytes(self, frame: AssembledFrame, out: StepOutput, gap: bool = False,
                       view: ItemFrame | None = None) -> bytes:
        """The frame's FDIR_ESTIMATE encoded once, straight from the fields (the same bytes as
        pymavlink's pack of `estimate_message`; takes the codec's next sequence number)."""
        fields = self._estimate_fields(frame, out, gap, view)
        t_ms, seq, nf, decl, flags, mask, st, sd, f, fs, pf, pfa, pmd, n_eff, ft, fv = fields
        b = None
        if not self.mav.signing.sign_outgoing:
            b = self._frame(_EST, _EST.unpacker.pack(t_ms, seq, *st, *sd, *f, *fs, *pf, *pfa, *pmd, n_eff,
                                                     nf, decl, flags, mask, *ft, *fv))
        if b is None:
            b = self._pack(_EST(*fields))
        return b
