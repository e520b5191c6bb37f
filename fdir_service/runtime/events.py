"""What the runtime says, as typed objects: consumers match on the class and its fields.

Every event has a `level` ("info" | "warning" | "error") and a `text`: the wording of the log line
(`/fdir/log` in the recording, `PipelineObserver.on_event(level, text, t_ns)`). The text is made
from the fields, so nothing downstream needs to parse it; an observer that defines
`on_runtime_event(event, t_ns)` also receives the object itself.

Events whose `sensor_notice` is True (stale, recovered, frozen, unfrozen sensors and time jumps)
also go out as STATUSTEXT "FDIR <text>" when `publish.stale_statustext` is on.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import ClassVar


class Event:
    """Base of every runtime event. Subclasses are frozen dataclasses; `text` renders the log line."""

    level: ClassVar[str] = "info"
    sensor_notice: ClassVar[bool] = False

    @property
    def text(self) -> str:  # pragma: no cover - every subclass defines it
        raise NotImplementedError


# ---------------------------------------------------------------------------- screening

OPERATOR_REASONS = frozenset({"unsigned", "bad signature", "other system", "command ignored", "mavlink1",
                              "time jump", "bad crc", "malformed", "out of range", "frozen",
                              "no timestamp"})
"""Rejection reasons an operator should know about (reported by rate-limited STATUSTEXT); the rest
(late, surplus, duplicate, unknown message id, not matching where) are normal on a radio link and
only counted and logged."""


@dataclass(frozen=True)
class Rejected(Event):
    """A kind of dropped input: `reason` ("out of range", "command ignored", "duplicate", ...) and
    the `field` it concerns (a row or input name, a message type, a command; "" for none). As an
    event: the first time this kind was dropped ("rejected input: first <key>")."""

    reason: str
    field: str = ""
    level: ClassVar[str] = "warning"

    @property
    def key(self) -> str:
        """The counter key: "gnss_alt out of range", "command ignored (COMMAND_LONG)", "duplicate"."""
        if not self.field:
            return self.reason
        if self.reason == "command ignored":
            return f"{self.reason} ({self.field})"
        return f"{self.field} {self.reason}"

    @property
    def operator(self) -> bool:
        """Whether an operator should be told (STATUSTEXT), see OPERATOR_REASONS."""
        return self.reason in OPERATOR_REASONS

    @property
    def text(self) -> str:
        return f"rejected input: first {self.key}"


@dataclass(frozen=True)
class RejectionSummary(Event):
    """Dropped input so far: `total` messages or values, `counts` ((key, count), ...) sorted by key."""

    total: int
    counts: tuple[tuple[str, int], ...]
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        detail = ", ".join(f"{k} {v}" for k, v in self.counts)
        return f"rejected input ({self.total} so far): {detail}"


@dataclass(frozen=True)
class OtherSystemIgnored(Event):
    """Messages from MAVLink system `system` are ignored: the service follows system `following`."""

    system: int
    following: int
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"ignoring system {self.system} on the link (following system {self.following})"


# ---------------------------------------------------------------------------- frames

@dataclass(frozen=True)
class SensorStale(Event):
    """Row `name` silent: no `message` for `silent_s` seconds of message time."""

    name: str
    message: str
    silent_s: float
    level: ClassVar[str] = "warning"
    sensor_notice: ClassVar[bool] = True

    @property
    def text(self) -> str:
        return f"{self.name} stale: no {self.message} for {self.silent_s:.2f} s"


@dataclass(frozen=True)
class SensorRecovered(Event):
    """Row `name`, reported stale, is measured again."""

    name: str
    sensor_notice: ClassVar[bool] = True

    @property
    def text(self) -> str:
        return f"{self.name} recovered"


@dataclass(frozen=True)
class SensorFrozen(Event):
    """Row `name` has held the bit-identical `value` (SI) for `held_s` seconds of message time."""

    name: str
    value: float
    held_s: float
    level: ClassVar[str] = "warning"
    sensor_notice: ClassVar[bool] = True

    @property
    def text(self) -> str:
        return f"{self.name} frozen at {self.value:.6g} for {self.held_s:.2f} s"


@dataclass(frozen=True)
class SensorUnfrozen(Event):
    """Row `name`, reported frozen, changes value again."""

    name: str
    sensor_notice: ClassVar[bool] = True

    @property
    def text(self) -> str:
        return f"{self.name} no longer frozen"


@dataclass(frozen=True)
class TimeJumped(Event):
    """The autopilot's clock jumped (confirmed) from `from_s` to `to_s` (s): the frame clock restarts."""

    from_s: float
    to_s: float
    backward: bool
    level: ClassVar[str] = "warning"
    sensor_notice: ClassVar[bool] = True

    @property
    def text(self) -> str:
        direction = "back" if self.backward else "forward"
        return (f"autopilot time jumped {direction} from {self.from_s:.2f} s to {self.to_s:.2f} s: "
                "restarting the frame clock")


@dataclass(frozen=True)
class FramesMissing(Event):
    """`missing_s` seconds of frames never arrived, more than max_gap_s: not predicted through."""

    missing_s: float
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"{self.missing_s:.2f} s of frames missing (more than max_gap_s): not predicted through"


@dataclass(frozen=True)
class EpochTimeUnmapped(Event):
    """A `message` stamped in UNIX-epoch time arrived before any SYSTEM_TIME (the epoch - boot
    offset is unknown): such messages are placed at the latest boot-clock stamp until one arrives.
    Said once per message type."""

    message: str

    @property
    def text(self) -> str:
        return (f"{self.message} stamped in UNIX-epoch time and no SYSTEM_TIME yet: placed at the "
                "latest stamp until one arrives")


@dataclass(frozen=True)
class EpochOffsetJumped(Event):
    """SYSTEM_TIME's epoch - boot offset moved by `jump_s` (s; a GPS time correction, an RTC set):
    the new offset is taken."""

    jump_s: float
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"SYSTEM_TIME: UNIX time moved {self.jump_s:+.3f} s against boot time: new offset taken"


# ---------------------------------------------------------------------------- health

class Cause(Enum):
    """Why the estimator was re-initialised."""

    INPUT_RESUMED = "input resumed"            # frame clock restarted, or a gap > max_gap_s ended
    NON_FINITE = "non-finite estimate"
    STATE_JUMP = "state jump"                  # a non-physical jump of the airframe estimate
    FILTER_RESET = "filter reset"              # the filter's own re-initialisation counter moved
    DEGENERATE = "degenerate"                  # N_eff below min_n_eff for degenerate_frames frames
    FILTER_RAISED = "filter raised"            # filter.step raised a numerical error


@dataclass(frozen=True)
class HealthProblem:
    """A reason to re-initialise the estimator: its `cause` and the operator's wording `text`."""

    cause: Cause
    text: str

    @property
    def acute(self) -> bool:
        """Acted on at once, even within reinit_holdoff_s: the estimate must not be published."""
        return self.cause in (Cause.NON_FINITE, Cause.STATE_JUMP, Cause.FILTER_RAISED)


@dataclass(frozen=True)
class Reinitialised(Event):
    """The filter was rebuilt at frame time `time_s` (s) because of `cause`, around `state`
    (p_d m, u m/s, w m/s, theta rad, q rad/s) from the frame's measurements; `masked`: rows that
    disagreed with it, masked for this frame."""

    time_s: float
    cause: HealthProblem
    state: tuple[float, float, float, float, float]
    masked: tuple[str, ...] = ()

    @property
    def level(self) -> str:  # type: ignore[override]
        return "error" if self.cause.cause is Cause.NON_FINITE else "warning"

    @property
    def text(self) -> str:
        p_d, u, w, theta, q = self.state
        masked = f"; rows masked this frame: {', '.join(self.masked)}" if self.masked else ""
        return (f"estimator re-initialised at t={self.time_s:.2f} s ({self.cause.text}) from the "
                f"measurements: p_d={p_d:.1f} u={u:.2f} w={w:.2f} theta={theta:.4f} q={q:.4f}{masked}")


@dataclass(frozen=True)
class FilterStepFailed(Event):
    """filter.step raised `error` (the exception's type name) with `message` at frame time `time_s`."""

    time_s: float
    error: str
    message: str
    level: ClassVar[str] = "error"

    @property
    def text(self) -> str:
        return f"filter step failed at t={self.time_s:.2f} s: {self.error}: {self.message}"


@dataclass(frozen=True)
class LinkLost(Event):
    """No input bytes from the autopilot for `silent_s` seconds of wall time."""

    silent_s: float
    level: ClassVar[str] = "error"

    @property
    def text(self) -> str:
        return f"link lost: no input from the autopilot for {self.silent_s:.1f} s"


@dataclass(frozen=True)
class LinkRegained(Event):
    """Input from the autopilot again after `silent_s` seconds of wall time without."""

    silent_s: float

    @property
    def text(self) -> str:
        return f"link restored after {self.silent_s:.1f} s without input"


# ---------------------------------------------------------------------------- publishing

@dataclass(frozen=True)
class FaultDeclared(Event):
    """Fault `fault_id` declared at frame time `time_s` (s): P(fault) `p`, `estimate` in SI;
    `statustext`: the STATUSTEXT sent ("FDIR gnss fault +50.1 m p=0.98")."""

    fault_id: str
    time_s: float
    p: float
    estimate: float
    statustext: str
    fault_type: str = "bias"
    """The type the declaration names (`publishing.UNCLEAR` while no type holds a share >= p_type
    of P(item)); `estimate` is the most probable type's user-facing value (SI; a noisy k, an
    effectiveness g and an engine's thrust share unitless)."""
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"{self.statustext} (t={self.time_s:.2f} s)"


@dataclass(frozen=True)
class FaultTypeChanged(Event):
    """A declared item's named type changed from `previous_type` (`publishing.UNCLEAR` when the
    declaration named none) to `fault_type` at frame time `time_s` (s), with P(item faulty) `p`
    and the new type's user-facing `value` (SI; k and g unitless); `statustext`: the STATUSTEXT
    sent ("FDIR q stuck at 3.2 deg/s p=0.97 (was bias)")."""

    fault_id: str
    time_s: float
    p: float
    value: float
    statustext: str
    fault_type: str
    previous_type: str
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"{self.statustext} (t={self.time_s:.2f} s)"


@dataclass(frozen=True)
class FaultCleared(Event):
    """Fault `fault_id` cleared at frame time `time_s` (s) with P(fault) `p`; `statustext` as sent."""

    fault_id: str
    time_s: float
    p: float
    statustext: str

    @property
    def text(self) -> str:
        return f"{self.statustext} (t={self.time_s:.2f} s)"


@dataclass(frozen=True)
class PipelineClosed(Event):
    """The pipeline stepped `frames` frames and closed; `counts`: dropped input ((key, n), ...)."""

    frames: int
    counts: tuple[tuple[str, int], ...]

    @property
    def text(self) -> str:
        summary = ", ".join(f"{k} {v}" for k, v in self.counts) or "none"
        return f"pipeline closed after {self.frames} frames; rejected input: {summary}"


@dataclass(frozen=True)
class AutopilotSelected(Event):
    """`--autopilot auto`: the autopilot's first HEARTBEAT (its MAV_AUTOPILOT value `heartbeat`)
    chose the profile `profile` ("none": the service file's own mapping)."""

    profile: str
    heartbeat: int

    @property
    def text(self) -> str:
        return f"autopilot profile {self.profile} (HEARTBEAT autopilot {self.heartbeat})"


# ---------------------------------------------------------------------------- streams

def _rows(rows: tuple[str, ...]) -> str:
    return ",".join(rows)


@dataclass(frozen=True)
class StreamRequested(Event):
    """The autopilot's answer to the request for `message` at `interval_us` (us): `outcome`
    ("accepted", "request denied", "request unsupported", "no answer to the request", ...)."""

    message: str
    interval_us: int
    outcome: str

    @property
    def level(self) -> str:  # type: ignore[override]
        return "info" if self.outcome == "accepted" else "warning"

    @property
    def text(self) -> str:
        return (f"stream request {self.message} at {1e6 / self.interval_us:g} Hz "
                f"(interval {self.interval_us} us): {self.outcome}")


@dataclass(frozen=True)
class StreamMissing(Event):
    """`message`, read by `rows`, has not arrived at all; `reason`: what became of its request."""

    rows: tuple[str, ...]
    message: str
    reason: str
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"no {_rows(self.rows)}: {self.message} not received ({self.reason})"


@dataclass(frozen=True)
class StreamSlow(Event):
    """`message`, read by `rows`, arrives at `rate_hz` (Hz, over the rate window), below the
    wanted `wanted_hz`."""

    rows: tuple[str, ...]
    message: str
    rate_hz: float
    wanted_hz: float
    level: ClassVar[str] = "warning"

    @property
    def text(self) -> str:
        return f"{_rows(self.rows)} at {self.rate_hz:.1f} Hz, wanted {self.wanted_hz:g} Hz"


@dataclass(frozen=True)
class StreamRateOk(Event):
    """`message`, reported slow, arrives at `rate_hz` (Hz) again (wanted `wanted_hz`)."""

    rows: tuple[str, ...]
    message: str
    rate_hz: float
    wanted_hz: float

    @property
    def text(self) -> str:
        return f"{_rows(self.rows)} back at {self.rate_hz:.1f} Hz (wanted {self.wanted_hz:g} Hz)"


# ---------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class ParametersRequested(Event):
    """The parameter requests after the autopilot's first HEARTBEAT are settled (`runtime.params`):
    `confirmed` parameters were answered by the autopilot (PARAM_VALUE, its value in use),
    `defaulted` ones had no answer and stay at the profile's `[parameters]` value, `unknown` ones
    had no answer and have no default (a servo channel that may not exist)."""

    confirmed: tuple[str, ...]
    defaulted: tuple[str, ...]
    unknown: tuple[str, ...] = ()

    @property
    def level(self) -> str:  # type: ignore[override]
        return "warning" if self.defaulted else "info"

    @property
    def text(self) -> str:
        parts = [f"parameters confirmed by the autopilot: {', '.join(self.confirmed) or 'none'}"]
        if self.defaulted:
            parts.append(f"at the profile's default (no answer): {', '.join(self.defaulted)}")
        if self.unknown:
            parts.append(f"no answer, no default: {', '.join(self.unknown)}")
        return "; ".join(parts)
