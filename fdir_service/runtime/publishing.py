"""What the service sends: HEARTBEAT, NAMED_VALUE_FLOAT, STATUSTEXT (with hysteresis) and the
dialect's FDIR_ESTIMATE, encoded (and signed, when a key is set) by one pymavlink codec.

Every message that has a `time_boot_ms` carries the autopilot's timestamp of the frame it
describes. Rates are counted in frame time, so a replay publishes the same messages. A STATUSTEXT
is sent right after the FDIR_ESTIMATE of the frame that triggered it (STATUSTEXT has no time
field; a ground station dates it by that estimate).

Hysteresis (config `[publish.declare]`): a fault is declared when P(fault) >= p_declare on every
frame for declare_hold_s of frame time, and cleared when P(fault) <= p_clear for clear_hold_s; each
change is a typed event (`FaultDeclared` / `FaultCleared`) besides its STATUSTEXT.

`RateLimit` spaces the STATUSTEXTs the runtime sends about one subject in frame time;
`sensor_notice` and `link_notice` are the STATUSTEXTs of sensor, clock and link events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimator_config import FaultSpec as FaultChannel
from fdir_service.mavlink import MAX_FAULTS, dialect, frame_payload
from fdir_service.mavlink import pack as fast_pack
from fdir_service.runtime.events import Event, FaultCleared, FaultDeclared, LinkLost, LinkRegained
from fdir_service.service_config import PublishConfig

if TYPE_CHECKING:
    from fdir_service.runtime.frames import AssembledFrame

_EPS_US = 1  # frame-time comparisons in us
_NVF = dialect.MAVLink_named_value_float_message
_EST = dialect.MAVLink_fdir_estimate_message


@dataclass
class _Hysteresis:
    declared: bool = False
    since_us: int | None = None  # first frame of the current run above p_declare / below p_clear


def statustext_for(fault: FaultChannel, estimate_si: float, p: float, declared: bool) -> str:
    """'FDIR gnss fault +50.1 m p=0.98' / 'FDIR gnss cleared p=0.03' (estimate in the fault's unit)."""
    if not declared:
        return f"FDIR {fault.id} cleared p={p:.2f}"
    val = estimate_si / fault.unit_scale
    unit = "" if fault.unit == "1" else f" {fault.unit}"
    return f"FDIR {fault.id} fault {val:+.1f}{unit} p={p:.2f}"


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
        if len(faults) > MAX_FAULTS:
            raise ValueError(f"FDIR_ESTIMATE carries at most {MAX_FAULTS} fault channels")
        self.config = config
        self.faults = faults
        self.mav = mav
        self.adaptive = adaptive
        self.hyst = [_Hysteresis() for _ in faults]
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

    def update_declarations(self, time_us: int, out: StepOutput) -> list[tuple[int, bool, str]]:
        """Advance the hysteresis; return (fault index, declared, text) for each change."""
        dc = self.config.declare
        changes = []
        for i, (f, h) in enumerate(zip(self.faults, self.hyst, strict=True)):
            p = float(out.fault_probability[i])
            crossing = (p <= dc.p_clear) if h.declared else (p >= dc.p_declare)
            if not crossing:
                h.since_us = None
                continue
            if h.since_us is None:
                h.since_us = time_us
            hold = dc.clear_hold_s if h.declared else dc.declare_hold_s
            if time_us - h.since_us + _EPS_US >= hold * 1e6:
                h.declared = not h.declared
                h.since_us = None
                changes.append((i, h.declared, statustext_for(f, float(out.fault_estimate[i]), p,
                                                              h.declared)))
        return changes

    @property
    def declared_mask(self) -> int:
        return sum(1 << i for i, h in enumerate(self.hyst) if h.declared)

    def publish(self, frame: AssembledFrame, out: StepOutput, gap: bool = False
                ) -> tuple[list[bytes], list[FaultDeclared | FaultCleared]]:
        """Messages for one stepped frame (HEARTBEAT, FDIR_ESTIMATE, NAMED_VALUE_FLOAT at their
        rates, then a STATUSTEXT per declaration change), and the declaration events."""
        msgs: list[bytes] = []
        self.frame_seq += 1
        changes = self.update_declarations(frame.time_us, out)
        if self._due("hb", self.config.heartbeat_period_s, frame.time_us):
            msgs.append(self.heartbeat())
        if self._due("est", 1.0 / self.config.estimate_rate_hz, frame.time_us):
            msgs.append(self.estimate_bytes(frame, out, gap))
        if self._due("nvf", 1.0 / self.config.named_value_rate_hz, frame.time_us):
            msgs += self.named_values(frame.time_boot_ms, out)
        events = [self._declaration(frame, out, i, declared, text) for i, declared, text in changes]
        for e in events:
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

    def _declaration(self, frame: AssembledFrame, out: StepOutput, i: int, declared: bool, text: str
                     ) -> FaultDeclared | FaultCleared:
        fid, p = self.faults[i].id, float(out.fault_probability[i])
        if declared:
            return FaultDeclared(fid, frame.time_s, p, float(out.fault_estimate[i]), text)
        return FaultCleared(fid, frame.time_s, p, text)

    def _estimate_fields(self, frame: AssembledFrame, out: StepOutput, gap: bool) -> tuple:
        """FDIR_ESTIMATE's fields in declaration order (time_boot_ms, frame_seq, fault_count,
        declared, flags, mask, state[5], state_std[5], fault[8], fault_std[8], p_fault[8], pfa[8],
        pmd[8], n_eff), as Python numbers and lists (NaN where a field has no value)."""
        nf = len(self.faults)
        x = np.asarray(out.x_mean, dtype=float)
        n = x.size
        nan8 = [math.nan] * MAX_FAULTS

        def pad(v) -> list[float]:
            if v is None:
                return nan8
            return np.asarray(v, dtype=float).ravel()[:nf].tolist() + nan8[nf:]

        if out.x_cov is not None:
            std = np.sqrt(np.clip(np.diag(out.x_cov), 0.0, None))
        else:
            std = np.full(n, np.nan)
        flags = 0
        if out.resampled:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_RESAMPLED
        if self.adaptive:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_ADAPTIVE
        if frame.stale:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_SENSOR_STALE
        if gap or frame.synthetic:
            flags |= dialect.FDIR_ESTIMATE_FLAGS_GAP
        mask_bits = sum(1 << j for j, ok in enumerate(frame.mask[:8]) if ok)
        fault_std = pad(std[5:5 + nf]) if std.size >= 5 + nf else nan8
        return (frame.time_boot_ms, self.frame_seq & 0xFFFFFFFF, nf, self.declared_mask, flags, mask_bits,
                x[:5].tolist(), std[:5].tolist(), pad(out.fault_estimate), fault_std,
                pad(out.fault_probability), pad(out.pfa), pad(out.pmd), float(out.n_eff))

    def estimate_message(self, frame: AssembledFrame, out: StepOutput, gap: bool = False):
        """The frame's FDIR_ESTIMATE as a pymavlink message object (the reference encoding)."""
        return _EST(*self._estimate_fields(frame, out, gap))

    def estimate_bytes(self, frame: AssembledFrame, out: StepOutput, gap: bool = False) -> bytes:
        """The frame's FDIR_ESTIMATE encoded once, straight from the fields (the same bytes as
        pymavlink's pack of `estimate_message`; takes the codec's next sequence number)."""
        t_ms, seq, nf, decl, flags, mask, st, sd, f, fs, pf, pfa, pmd, n_eff = self._estimate_fields(
            frame, out, gap)
        b = None
        if not self.mav.signing.sign_outgoing:
            b = self._frame(_EST, _EST.unpacker.pack(t_ms, seq, *st, *sd, *f, *fs, *pf, *pfa, *pmd, n_eff,
                                                     nf, decl, flags, mask))
        if b is None:
            b = self._pack(_EST(t_ms, seq, nf, decl, flags, mask, st, sd, f, fs, pf, pfa, pmd, n_eff))
        return b
