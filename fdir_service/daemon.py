"""`fdir run`'s loop: sockets (pymavlink mavutil URLs), signals, and the `Pipeline` in between.

Reads raw bytes from the autopilot link (`--master`), feeds them to the pipeline with the wall
receive time, and writes whatever it returns back on the autopilot link and to every `--gcs`
endpoint (one datagram per read). When no frame has produced a HEARTBEAT for a heartbeat period
of wall time (autopilot silent, or just started) it sends one itself, so a ground station sees
the service alive. SIGINT/SIGTERM stop the loop; the pipeline and recorder are closed cleanly.

Stream requests (`[streams] request`, `StreamLink`): after the followed autopilot's first
HEARTBEAT the mapped messages are requested at their wanted rates (`runtime.streams`), one
MAV_CMD_SET_MESSAGE_INTERVAL at a time, sent on the autopilot link only; COMMAND_ACK timeouts and
retries run on the wall clock here, never in the pipeline. Each outcome is logged and told to the
pipeline (quoted when a message never arrives); if no frame was ever stepped once the requests are
settled and `streams.window_s` of wall time has passed, the pipeline reports the missing messages.
With an autopilot profile (`[streams] parameters`) the same HEARTBEAT starts the parameter
requests (`runtime.params`: PARAM_REQUEST_READ by name, a few in flight, retried on the same
timeout); once settled, who answered and who stays at the profile's default is logged.

Link supervision: no input bytes for `health.link_timeout_s` of wall time after input had
started = link lost (STATUSTEXT, HEARTBEAT CRITICAL); the first bytes after it = restored.
Binding: a `udpin:HOST:PORT` link binds exactly HOST:PORT; a `udpout:` link's socket is
connected to its destination (the kernel gives it the local address of that route, and it
accepts datagrams from that peer only); nothing else is opened. Replies on a `udpin:` autopilot
link go only to senders whose datagrams contained accepted input (not to anyone who sends bytes).
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable

from fdir_service.mavlink import dialect
from fdir_service.pipeline import Pipeline
from fdir_service.runtime.params import ParamRequester
from fdir_service.runtime.streams import StreamRequester, wanted_rates

DRAIN_BACKLOG = 64
"""Datagrams fed without stepping a frame after which the recorder's queue is drained anyway."""


def open_link(url: str, *, source_system: int = 1, source_component: int = 191):
    """A pymavlink mavutil connection (udpin:, udpout:, tcp:, tcpin:, serial device) for raw I/O."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(url, source_system=source_system,
                                      source_component=source_component, autoreconnect=True)
    if isinstance(conn, mavutil.mavudp) and not conn.udp_server:
        import socket

        host, port = conn.destination_addr
        try:
            conn.port.connect((socket.gethostbyname(host), int(port)))
        except OSError:
            pass  # unreachable now: the kernel binds on first send, as pymavlink would
    return conn


def _fileno(conn) -> int | None:
    port = getattr(conn, "port", None)
    if port is not None and hasattr(port, "fileno"):
        try:
            return port.fileno()
        except (OSError, ValueError):
            return None
    fd = getattr(conn, "fd", None)
    return fd if isinstance(fd, int) else None


class _Progress:
    """When the pipeline last stepped a frame and when an idle HEARTBEAT was last sent (monotonic s)."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.frames = -1
        self.last_progress = -1e9
        self.last_idle_hb = -1e9

    def seen(self, frames: int, now: float) -> None:
        if frames != self.frames:
            self.frames, self.last_progress = frames, now

    def heartbeat_due(self, frames: int, now: float) -> bool:
        """Whether no frame for a heartbeat period and no idle HEARTBEAT for one; if so, counts it sent."""
        self.seen(frames, now)
        if now - self.last_progress >= self.period_s and now - self.last_idle_hb >= self.period_s:
            self.last_idle_hb = now
            return True
        return False


class StreamLink:
    """The daemon's stream requests (see the module doc): reads the pipeline's `link_messages`,
    runs a `StreamRequester` on the time passed in (monotonic s) and writes the requests with
    `write(bytes)` (the autopilot link). `log` gets each outcome's line."""

    def __init__(self, pipeline: Pipeline, write: Callable[[bytes], None],
                 log: Callable[[str], None] = lambda s: None,
                 notify: Callable[[bytes], None] | None = None) -> None:
        self.pipeline = pipeline
        self.write = write
        self.notify = notify or write   # STATUSTEXTs: the autopilot link and the ground stations
        self.log = log
        self.config = pipeline.config.streams
        self.requester: StreamRequester | None = None
        self.params: ParamRequester | None = None
        self.heard = False
        self.silence_due: float | None = None   # when to check for "no frame at all" (s)

    def on_input(self, now: float) -> None:
        """After a feed: the autopilot's HEARTBEAT starts the requests, its COMMAND_ACKs answer them."""
        msgs = self.pipeline.link_messages
        out: list = []
        while msgs:
            m = msgs.popleft()
            if m.get_type() == "HEARTBEAT":
                out += self._start(m, now)
            elif m.get_type() == "PARAM_VALUE":
                out += self.params.on_value(m, now) if self.params is not None else []
            elif self.requester is not None and self._for_us(m):
                out += self.requester.on_ack(m, now)
        self._send(out)

    def poll(self, now: float) -> None:
        """Now and then: resend or give up unanswered requests; report streams if no frame ever came."""
        for requester in (self.requester, self.params):
            if requester is not None:
                self._send(requester.poll(now))
        done = self.requester is None or self.requester.done
        if self.silence_due is not None and done and now >= self.silence_due:
            self.silence_due = None
            if self.pipeline.frames == 0:
                self.notify(b"".join(self.pipeline.report_never_received(time.time_ns())))

    def _start(self, hb, now: float) -> list:
        """The first autopilot HEARTBEAT: build the requester for the mapping now in force."""
        if self.heard or hb.autopilot == dialect.MAV_AUTOPILOT_INVALID:
            return []
        self.heard = True
        self.silence_due = now + self.config.window_s
        return self._start_streams(hb, now) + self._start_params(hb, now)

    def _start_streams(self, hb, now: float) -> list:
        """The stream requests (`[streams] request`) for the mapping now in force."""
        if not self.config.request:
            return []
        self.requester = StreamRequester(self.config, wanted_rates(self.pipeline.assembler.config))
        return self.requester.start(hb.get_srcSystem(), hb.get_srcComponent(), int(hb.autopilot), now)

    def _start_params(self, hb, now: float) -> list:
        """The parameter requests (`[streams] parameters`) of the profile now in force, if any."""
        config = self.pipeline.assembler.config
        if not self.config.parameters or config.autopilot in ("none", "auto"):
            return []
        self.params = ParamRequester(self.config, config)
        return self.params.start(hb.get_srcSystem(), hb.get_srcComponent(), now)

    def _for_us(self, ack) -> bool:
        """Whether a COMMAND_ACK is addressed to us (or to nobody in particular)."""
        mav = self.pipeline.mav_out
        ts, tc = int(getattr(ack, "target_system", 0)), int(getattr(ack, "target_component", 0))
        return ts in (0, mav.srcSystem) and tc in (0, mav.srcComponent)

    def _send(self, msgs: list) -> None:
        """Write the requests, then hand the settled outcomes to the pipeline (and the log)."""
        t_ns = time.time_ns()
        if msgs:
            self.write(self.pipeline.encode_link(msgs, t_ns))
        if self.requester is not None and self.requester.outcomes:
            for o in self.requester.outcomes:
                self.pipeline.stream_outcome(o, t_ns)
                self.log(f"fdir: stream request {o.message} every {o.interval_us} us: {o.outcome}")
            self.requester.outcomes.clear()
        if self.params is not None and self.params.report is not None:
            report, self.params.report = self.params.report, None
            self.pipeline.parameters_outcome(report, t_ns)
            self.log(f"fdir: {report.text}")


class Daemon:
    """Runs a `Pipeline` between an autopilot link and ground-station links until stopped."""

    def __init__(self, pipeline: Pipeline, master: str, gcs: tuple[str, ...] = (),
                 log: Callable[[str], None] | None = None) -> None:
        self.pipeline = pipeline
        self.master_url = master
        self.gcs_urls = tuple(gcs)
        self.log = log or (lambda s: print(s, file=sys.stderr, flush=True))
        self.stop_event = threading.Event()
        self.master = open_link(master, source_component=pipeline.config.component)
        self.gcs = [open_link(u, source_component=pipeline.config.component) for u in self.gcs_urls]
        self.bytes_in = 0
        self.bytes_out = 0
        self.send_errors = 0
        self.last_input = time.monotonic()
        self.link_lost_events = 0
        self._trusted_peers: set = set()
        self._undrained = 0
        self.streams = StreamLink(pipeline, self._send_master, self.log, self._send)

    def stop(self, *_args) -> None:
        self.stop_event.set()

    def _send(self, data: bytes) -> None:
        for conn in [self.master, *self.gcs]:
            try:
                conn.write(data)
                self.bytes_out += len(data)
            except OSError:
                self.send_errors += 1

    def _send_master(self, data: bytes) -> None:
        """Bytes for the autopilot only (stream requests)."""
        if not data:
            return
        try:
            self.master.write(data)
            self.bytes_out += len(data)
        except OSError:
            self.send_errors += 1

    def run(self, *, install_signals: bool = True, max_seconds: float | None = None) -> int:
        """Serve until SIGINT/SIGTERM (or `stop()`, or max_seconds of wall time); returns 0."""
        old = ({s: signal.signal(s, self.stop) for s in (signal.SIGINT, signal.SIGTERM)}
               if install_signals else {})
        t_end = None if max_seconds is None else time.monotonic() + max_seconds
        self.log(self._banner())
        self.pipeline.defer_observers(True)
        try:
            self._serve(t_end)
        finally:
            self._shutdown(old)
        return 0

    def _banner(self) -> str:
        p = self.pipeline
        return (f"fdir: {p.filter_name} N={p.particles} on estimator {p.estimator.id}; "
                f"autopilot link {self.master_url}"
                + (f"; ground stations {', '.join(self.gcs_urls)}" if self.gcs_urls else "")
                + ("; signing on" if p.signed else ""))

    def _serve(self, t_end: float | None) -> None:
        """The loop: wait up to 0.1 s for input, feed it, supervise the link (wall clock)."""
        watch = _Progress(self.pipeline.config.publish.heartbeat_period_s)
        while not self.stop_event.is_set():
            if t_end is not None and time.monotonic() >= t_end:
                break
            try:
                ready = self._wait_for_input()
            except InterruptedError:
                continue
            if ready:
                self._drain_master()
            else:   # idle link: write what the recorder still holds
                self.pipeline.drain_observers()
                self._undrained = 0
            self._supervise(watch, time.monotonic())

    def _wait_for_input(self) -> bool:
        """Whether the autopilot link has input (select, 0.1 s); True for a link without a pollable
        descriptor (after a 1 ms nap). May raise InterruptedError."""
        fds = [fd for fd in (_fileno(self.master),) if fd is not None]
        if not fds:
            time.sleep(0.001)
            return True
        ready, _, _ = select.select(fds, [], [], 0.1)
        return bool(ready)

    def _supervise(self, watch: _Progress, now: float) -> None:
        """Link loss after health.link_timeout_s without input; an idle HEARTBEAT when no frame
        has produced one for a heartbeat period (monotonic s)."""
        if not self.bytes_in:
            watch.seen(self.pipeline.frames, now)
            return
        self.streams.poll(now)
        silent = now - self.last_input
        if not self.pipeline.link_lost and silent >= self.pipeline.config.health.link_timeout_s:
            self.link_lost_events += 1
            self.log(f"fdir: link lost: no input for {silent:.1f} s")
            self._send(b"".join(self.pipeline.set_link_lost(True, silent, time.time_ns())))
            self.pipeline.drain_observers()
        if watch.heartbeat_due(self.pipeline.frames, now):
            self._send(self.pipeline.heartbeat(time.time_ns()))
            self.pipeline.drain_observers()

    def _shutdown(self, old_handlers: dict) -> None:
        """Close the pipeline (sending its tail), restore signals, close links, log the counts."""
        tail = self.pipeline.close(time.time_ns())
        if tail:
            self._send(b"".join(tail))
        self.pipeline.drain_observers()
        for s, h in old_handlers.items():
            signal.signal(s, h)
        for conn in [self.master, *self.gcs]:
            try:
                conn.close()
            except OSError:
                pass
        counts = self.pipeline.rejected_counts
        self.log(f"fdir: stopped after {self.pipeline.frames} frames; "
                 f"{self.bytes_in} bytes in, {self.bytes_out} bytes out; rejected input: "
                 + (", ".join(f"{k} {v}" for k, v in sorted(counts.items())) or "none"))

    def _drain_master(self) -> None:
        """Read and feed what the autopilot link has. The recorder's queue is drained right after a
        frame was stepped and its output sent, so the rest of a frame's messages never wait behind
        the encoding (or the once-a-second chunk compression) of its first ones; input that steps
        no frame is drained after DRAIN_BACKLOG datagrams or when the link is idle (run loop)."""
        for _ in range(1000):  # bounded: keep heartbeats and signals serviced under a flood
            try:
                data = self.master.recv(65536)
            except OSError:
                return
            if not data:
                return
            if isinstance(data, str):
                data = data.encode("latin-1")
            now = time.monotonic()
            if self.pipeline.link_lost:
                silent = now - self.last_input
                self.log(f"fdir: link restored after {silent:.1f} s")
                self._send(b"".join(self.pipeline.set_link_lost(False, silent, time.time_ns())))
            self.last_input = now
            self.bytes_in += len(data)
            accepted, frames = self.pipeline.accepted_messages, self.pipeline.frames
            out = self.pipeline.feed(data, time.time_ns())
            self._vet_peer(self.pipeline.accepted_messages > accepted)
            if self.pipeline.link_messages:
                self.streams.on_input(now)
            if out:
                self._send(b"".join(out))
            self._undrained += 1
            if out or self.pipeline.frames != frames or self._undrained >= DRAIN_BACKLOG:
                self.pipeline.drain_observers()   # the recorder encodes after the frame went out
                self._undrained = 0

    def _vet_peer(self, accepted: bool) -> None:
        """Keep a udpin link's reply list to senders that delivered accepted input."""
        clients = getattr(self.master, "clients", None)
        if not isinstance(clients, set):
            return
        if accepted:
            self._trusted_peers |= clients
        else:
            clients &= self._trusted_peers
            alive = getattr(self.master, "clients_last_alive", None)
            if isinstance(alive, dict):
                for a in [a for a in alive if a not in clients]:
                    del alive[a]
