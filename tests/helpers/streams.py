"""Streams of autopilot bytes for the bad-input tests: the recorded flight, mutations of its
packets, and the checks on what comes out."""

from __future__ import annotations

import math
import struct
from typing import TypeVar

import numpy as np
from pymavlink.generator.mavcrc import x25crc

from fdir_service.mavlink import new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.events import (
    Event,
)
from tests.helpers.experiments import ch4_service
from tests.helpers.service import autopilot_stream, fake_factory

E = TypeVar("E", bound=Event)


CFG = ch4_service()


STREAM = autopilot_stream(12.0, seed=4)          # 240 frames of a truth-flown ch4 flight


PACKETS = [b for _, s, a in STREAM for b in s + a]


class Events:
    """A PipelineObserver keeping events (as logged, and typed) and every estimate."""

    def __init__(self) -> None:
        self.events: list[tuple[str, str]] = []
        self.typed: list[Event] = []
        self.estimates: list = []

    def of(self, cls: type[E]) -> list[E]:
        """The typed events of one class, in order."""
        return [e for e in self.typed if isinstance(e, cls)]

    def on_metadata(self, name, data): pass
    def on_raw(self, direction, data, t_ns): pass
    def on_message(self, msg, t_ns): pass
    def on_particles(self, frame_time_s, states, weights, t_ns): pass

    def on_estimate(self, frame_time_s, out, latency_s, t_ns):
        self.estimates.append(out)

    def on_event(self, level, text, t_ns):
        self.events.append((level, text))

    def on_runtime_event(self, event, t_ns):
        self.typed.append(event)


def fake_pipeline(cfg=None):
    filters: list = []
    ev = Events()
    pipe = Pipeline(cfg or CFG, filter_factory=fake_factory(filters), observers=[ev])
    return pipe, filters, ev


def feed_all(pipe, packets) -> list:
    out = []
    for i, b in enumerate(packets):
        out += pipe.feed(b, i)
    return new_mavlink(255, 0).parse_buffer(b"".join(out)) or []


def texts(msgs) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


def assert_filter_inputs_finite(filt) -> None:
    for t, y, mask, u in filt.calls:
        assert math.isfinite(t) and np.isfinite(y[mask]).all() and np.isfinite(u).all()


def v1_frame(msg_v2: bytes) -> bytes:
    """The same message as a MAVLink 1 frame (0xFE, 6-byte header, no extensions); messages with an
    id above 255 (not expressible in MAVLink 1) are returned unchanged."""
    m = new_mavlink(255, 0).parse_buffer(msg_v2)[0]
    if m.get_msgId() > 255:
        return msg_v2
    payload = bytes(m.get_payload())
    hdr = struct.pack("<BBBBBB", 0xFE, len(payload), 7, 1, 1, m.get_msgId())
    crc = x25crc(hdr[1:] + payload)
    crc.accumulate(bytes([m.crc_extra]))
    return hdr + payload + struct.pack("<H", crc.crc)


def encoder(system=1, component=1):
    return new_mavlink(system, component)


def reencode(packet: bytes, **changes) -> bytes:
    """The packet's message with some fields changed, re-encoded (valid CRC)."""
    m = new_mavlink(255, 0).parse_buffer(packet)[0]
    for k, v in changes.items():
        setattr(m, k, v)
    mav = encoder(m.get_srcSystem(), m.get_srcComponent())
    mav.seq = m.get_seq()
    return bytes(m.pack(mav, force_mavlink1=False))


MUTATIONS = ("flip", "truncate", "random", "duplicate", "swap", "drop", "v1", "nan", "inf", "time",
             "huge", "splice", "keep")


def _flip(packets, i, rng):
    b = bytearray(packets[i])
    for _ in range(1 + int(rng.integers(3))):
        b[int(rng.integers(len(b)))] ^= 1 << int(rng.integers(8))
    return [bytes(b)]


def _splice(packets, i, rng):
    p, q = packets[i], packets[int(rng.integers(len(packets)))]
    return [p[: len(p) // 2] + q[len(q) // 2:]]


def _bad_time(packets, i, rng):
    p = packets[i]
    m = new_mavlink(255, 0).parse_buffer(p)[0]
    field = next((f for f in ("time_usec", "time_boot_ms") if hasattr(m, f)), None)
    if field is None:
        return [p]
    top = 2**63 if m.fieldtypes[m.fieldnames.index(field)] == "uint64_t" else 2**32
    return [reencode(p, **{field: int(rng.integers(0, top, dtype=np.uint64))})]


def _bad_float(kind):
    def mutate_float(packets, i, rng):
        p = packets[i]
        m = new_mavlink(255, 0).parse_buffer(p)[0]
        floats = [f for f, t in zip(m.fieldnames, m.fieldtypes, strict=True)
                  if t in ("float", "double") and not isinstance(getattr(m, f), list)]
        if not floats:
            return [p]
        value = {"nan": math.nan, "inf": -math.inf if rng.random() < 0.5 else math.inf,
                 "huge": float(rng.choice([1e30, -1e30, 3e38]))}[kind]
        return [reencode(p, **{str(rng.choice(floats)): value})]
    return mutate_float


MUTATORS = {
    "flip": _flip,
    "truncate": lambda packets, i, rng: [packets[i][: int(rng.integers(1, len(packets[i])))]],
    "random": lambda packets, i, rng: [rng.bytes(int(rng.integers(1, 300)))],
    "duplicate": lambda packets, i, rng: [packets[i], packets[i]],
    "swap": lambda packets, i, rng: [packets[i + 1], packets[i]] if i + 1 < len(packets) else [packets[i]],
    "drop": lambda packets, i, rng: [],
    "v1": lambda packets, i, rng: [v1_frame(packets[i])],
    "splice": _splice,
    "time": _bad_time,
    "nan": _bad_float("nan"),
    "inf": _bad_float("inf"),
    "huge": _bad_float("huge"),
}


def mutate(packets: list[bytes], i: int, kind: str, rng: np.random.Generator) -> list[bytes]:
    """Packet i of the stream mutated by `kind` (MUTATIONS), as the packets to send in its place."""
    return MUTATORS.get(kind, lambda packets, i, rng: [packets[i]])(packets, i, rng)


def run_mutated(pipe: Pipeline, rng: np.random.Generator, n_packets: int,
                p_mutate: float) -> tuple[int, list]:
    """Feed about n_packets packets of repeated flights with mutations; returns (packets fed, output)."""
    fed, out, rounds = 0, [], 0
    while fed < n_packets:
        base = PACKETS if rounds % 2 == 0 else PACKETS_B
        rounds += 1
        kinds = rng.choice(len(MUTATIONS), size=len(base))
        mutate_now = rng.random(len(base)) < p_mutate
        for i in range(len(base)):
            pk = mutate(base, i, MUTATIONS[kinds[i]], rng) if mutate_now[i] else [base[i]]
            for q in pk:
                out += pipe.feed(q, fed)
                fed += 1
    return fed, out


PACKETS_B = [b for _, s, a in autopilot_stream(12.0, seed=4)[::-1] for b in s + a][::-1]  # same bytes


def check_output(pipe: Pipeline, ev: Events, out: list, min_frames: int) -> None:
    msgs = new_mavlink(255, 0).parse_buffer(b"".join(out)) or []
    assert all(m.get_type() != "BAD_DATA" for m in msgs)
    est = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    assert len(est) >= min_frames
    for m in est[-50:]:
        assert np.isfinite(m.state).all() and np.isfinite(m.p_fault[:2]).all()
        assert np.isfinite(m.fault[:2]).all()
    for o in ev.estimates:
        assert np.isfinite(o.x_mean).all() and np.isfinite(o.fault_probability).all()

