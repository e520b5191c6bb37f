"""`make demo` (`python -m sim_bridge.demo`): the simulator, the service and a ground station.

Starts `fdir run` (recording an MCAP) and `sim-bridge fly ch4` several times faster than real
time with the autopilot flying on the service's estimate, listens on UDP as a ground station
would (pymavlink), shows the fault estimates, P(fault), Pfa and Pmd live (a redrawn table on a
terminal, periodic plain lines otherwise), and ends with a summary: detection delays, estimate
errors, and where the logs are.

`GroundStation` is also what the end-to-end tests listen with.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fdir_service.mavlink import new_mavlink
from sim_bridge.faults import channel_value


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port nobody is bound to right now on host."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


RCVBUF_BYTES = 4 << 20
"""Receive buffer the ground-station listener asks for (bytes)."""


@dataclass
class GroundStation:
    """A ground-station listener on udpin:HOST:PORT (pymavlink mavutil socket, fdir dialect parser).

    Collected, by the autopilot's frame time t (s) the service stamped on each message:
    values[name] -> [(t, value)] from NAMED_VALUE_FLOAT; statustexts -> [(t, severity, text)],
    dated by the FDIR_ESTIMATE that precedes them; estimates -> [(t, msg)]; heartbeats count.
    """

    port: int
    host: str = "127.0.0.1"
    key: bytes | None = None
    values: dict[str, list[tuple[float, float]]] = field(default_factory=lambda: defaultdict(list))
    statustexts: list[tuple[float, int, str]] = field(default_factory=list)
    estimates: list[tuple[float, object]] = field(default_factory=list)
    heartbeats: int = 0
    bad: int = 0

    def __post_init__(self) -> None:
        from fdir_service.daemon import open_link

        self.conn = open_link(f"udpin:{self.host}:{self.port}", source_system=255, source_component=190)
        # A lockstep flight sends ~3000 datagrams/s; with the default ~200 kB receive buffer a pause
        # of this (Python) listener of ~0.1 s lets the kernel drop some. Ask for 4 MB (capped by
        # net.core.rmem_max); the service's own sending is what the tests check, not loopback.
        with contextlib.suppress(OSError):
            self.conn.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
        self.mav = new_mavlink(255, 190, key=self.key)
        self.last_t = math.nan

    def poll(self, timeout: float = 0.1) -> int:
        """Read whatever arrived within timeout (s); returns the number of messages decoded."""
        import select

        ready, _, _ = select.select([self.conn.port.fileno()], [], [], timeout)
        n = 0
        while ready:
            data = self.conn.recv(65536)
            if not data:
                break
            if isinstance(data, str):
                data = data.encode("latin-1")
            for msg in self.mav.parse_buffer(data) or []:
                n += 1
                self._take(msg)
        return n

    def _take(self, msg) -> None:
        mt = msg.get_type()
        if mt == "BAD_DATA":
            self.bad += 1
        elif mt == "FDIR_ESTIMATE":
            self.last_t = msg.time_boot_ms / 1000.0
            self.estimates.append((self.last_t, msg))
        elif mt == "NAMED_VALUE_FLOAT":
            name = msg.name.decode() if isinstance(msg.name, bytes) else msg.name
            self.values[name].append((msg.time_boot_ms / 1000.0, float(msg.value)))
        elif mt == "STATUSTEXT":
            text = msg.text.decode() if isinstance(msg.text, bytes) else msg.text
            self.statustexts.append((self.last_t, int(msg.severity), text))
        elif mt == "HEARTBEAT":
            self.heartbeats += 1

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t (k,), value (k,)) of a NAMED_VALUE_FLOAT name."""
        v = self.values.get(name, [])
        return np.array([a for a, _ in v]), np.array([b for _, b in v])

    def declarations(self, fault_id: str) -> list[float]:
        """Frame times (s) of the STATUSTEXTs declaring fault_id."""
        return [t for t, _, txt in self.statustexts if txt.startswith(f"FDIR {fault_id} fault ")]

    def close(self) -> None:
        self.conn.close()


# ----------------------------------------------------------------------------- the demo

def _python() -> str:
    return sys.executable


def _view_line(gs: GroundStation, fault_ids: list[str]) -> str:
    t = gs.last_t
    parts = [f"t={t:6.2f}s" if math.isfinite(t) else "t=  --  "]
    for fid in fault_ids:
        def last(name: str) -> float:
            v = gs.values.get(name)
            return v[-1][1] if v else math.nan
        def prob(name: str) -> str:  # Pfa/Pmd exist only for adaptive filters
            v = last(name)
            return f"{v:4.2f}" if math.isfinite(v) else "  - "
        decl = "DECLARED" if gs.declarations(fid) and _declared_now(gs, fid) else "ok"
        parts.append(f"{fid}: f={last('f_' + fid):+7.2f} P={last('pf_' + fid):4.2f} "
                     f"Pfa={prob('pfa_' + fid)} Pmd={prob('pmd_' + fid)} {decl:8s}")
    return " | ".join(parts)


def _declared_now(gs: GroundStation, fid: str) -> bool:
    state = False
    for _, _, txt in gs.statustexts:
        if txt.startswith(f"FDIR {fid} fault "):
            state = True
        elif txt.startswith(f"FDIR {fid} cleared"):
            state = False
    return state


def _declared_at(gs: GroundStation, fid: str, t: float) -> bool:
    state = False
    for ts, _, txt in gs.statustexts:
        if ts > t:
            break
        if txt.startswith(f"FDIR {fid} fault "):
            state = True
        elif txt.startswith(f"FDIR {fid} cleared"):
            state = False
    return state


def summary(gs: GroundStation, scenario, alt_err_m: float | None = None) -> list[str]:
    """Detection delays (first declaring STATUSTEXT after onset) and estimate errors per fault."""
    from sim_bridge.scenario import Scenario  # noqa: F401  (type of `scenario`)

    lines = []
    for f in scenario.faults:
        if not f.profile:
            continue
        onset = min(c.start_s for c in f.profile)
        end = max(c.end_s for c in f.profile)
        decl = [t for t in gs.declarations(f.id) if t >= onset - 1e-9]
        early = [t for t in gs.declarations(f.id) if t < onset - 1e-9]
        if decl:
            delay = f"declared after {decl[0] - onset:.2f} s"
        elif early and _declared_at(gs, f.id, onset):
            delay = f"already declared at onset (since {early[-1]:.2f} s)"
        else:
            delay = "not declared"
        t, v = gs.series(f"f_{f.id}")
        sel = (t >= onset + 2.0) & (t < end)
        if not t.size:
            lines.append(f"  {f.id:8s} onset {onset:5.1f} s: not watched (the service's estimator has no "
                         "such fault)")
            continue
        if sel.any():
            truth = np.asarray(channel_value(f, t[sel]))
            err = np.abs(v[sel] - truth) / f.unit_scale
            est = (f"mean |error| {err.mean():.2f} {f.unit}, max {err.max():.2f} {f.unit} "
                   f"({onset + 2:g}-{end:g} s)")
        else:
            est = "no estimates received in the fault window"
        lines.append(f"  {f.id:8s} onset {onset:5.1f} s: {delay}; {est}"
                     + (f"; {len(early)} declaration(s) before onset" if early else ""))
    if alt_err_m is not None:
        lines.append(f"  altitude: max |h - 500 m| = {alt_err_m:.2f} m while flying on the estimate")
    return lines


def max_altitude_error(truth_path: Path, command_m: float) -> float | None:
    try:
        from fdir_service.recording.logtools import McapLog

        recs = [r for _, r in McapLog(truth_path).iter_json("/sim/truth")]
    except Exception:  # noqa: BLE001 - the summary works without the truth log
        return None
    if not recs:
        return None
    return max(abs(r["h"] - command_m) for r in recs)


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m sim_bridge.demo", description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="real-turbulence")
    ap.add_argument("--speed", type=float, default=5.0, help="times real time (default 5)")
    ap.add_argument("--filter", default=None, help="estimator (default: config/service.toml)")
    ap.add_argument("--particles", type=int, default=None)
    ap.add_argument("--nav", choices=("truth", "fdir"), default="fdir")
    ap.add_argument("--profile", choices=("ardupilot", "native"), default=None,
                    help="the simulated autopilot's message set (default: ardupilot; native in a "
                         "world without accelerometer and pitot); fdir runs with --autopilot auto")
    ap.add_argument("--out", type=Path, default=Path(os.environ.get("FDIR_DEMO_DIR", "demo-output")),
                    help="where the MCAP logs go (default ./demo-output)")
    return ap.parse_args(argv)


def _commands(args: argparse.Namespace, p_ap: int, p_gcs: int, log_path: Path,
              truth_path: Path, imu: bool = True) -> tuple[list[str], list[str]]:
    """The `fdir run` and `sim-bridge fly` command lines of the demo. imu: the world sends an
    accelerometer and a pitot (else the service runs the thesis's aerodynamic estimator, which
    needs neither, instead of its default robust one)."""
    fdir_cmd = [_python(), "-m", "fdir_service.cli", "run", "--master", f"udpin:127.0.0.1:{p_ap}",
                "--gcs", f"udpout:127.0.0.1:{p_gcs}", "--record", str(log_path), "--autopilot", "auto"]
    if not imu:
        fdir_cmd += ["--estimator", "aerosonde"]
    if args.filter:
        fdir_cmd += ["--filter", args.filter]
    if args.particles:
        fdir_cmd += ["--particles", str(args.particles)]
    profile = args.profile or ("ardupilot" if imu else "native")   # ArduPlane's set needs RAW_IMU, pitot
    sim_cmd = [_python(), "-m", "sim_bridge.cli", "fly", args.scenario, "--to", f"udpout:127.0.0.1:{p_ap}",
               "--speed", str(args.speed), "--nav", args.nav, "--record", str(truth_path), "--wait", "60",
               "--profile", profile]
    return fdir_cmd, sim_cmd


class _View:
    """The ground station's live line (redrawn on a terminal, every 5 s of flight otherwise) and its
    STATUSTEXTs, each printed once."""

    def __init__(self, gs: GroundStation, fault_ids: list[str]) -> None:
        self.gs, self.fault_ids = gs, fault_ids
        self.tty = sys.stdout.isatty()
        self.last_print_t, self.last_draw, self.shown = -1e9, 0.0, 0

    def update(self) -> None:
        now, gs = time.monotonic(), self.gs
        if self.tty and now - self.last_draw > 0.2:
            self.last_draw = now
            width = os.get_terminal_size().columns - 1
            sys.stdout.write("\r\x1b[2K" + _view_line(gs, self.fault_ids)[:width])
            sys.stdout.flush()
        elif not self.tty and math.isfinite(gs.last_t) and gs.last_t - self.last_print_t >= 5.0:
            self.last_print_t = gs.last_t
            print(_view_line(gs, self.fault_ids), flush=True)
        while len(gs.statustexts) > self.shown:
            t, _, txt = gs.statustexts[self.shown]
            self.shown += 1
            print(("\r\x1b[2K" if self.tty else "") + f"[t={t:6.2f}s] STATUSTEXT {txt}", flush=True)


def _watch(gs: GroundStation, sim: subprocess.Popen, view: _View) -> None:
    """Poll the ground station while the simulator flies, and one second after."""
    while sim.poll() is None:
        gs.poll(0.05)
        view.update()
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        gs.poll(0.05)


def main(argv: list[str] | None = None) -> int:
    args = _parse_args(argv)
    from sim_bridge.scenario import load_scenario
    from sim_bridge.simulate import run_faults

    scenario = run_faults(load_scenario(args.scenario), 0)    # the faults `sim-bridge fly` (seed 0) flies
    fault_ids = [f.id for f in scenario.faults]
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%dT%H%M%S")
    log_path = (args.out / f"fdir-demo-{stamp}.mcap").resolve()
    truth_path = (args.out / f"truth-demo-{stamp}.mcap").resolve()
    p_ap, p_gcs = free_udp_port(), free_udp_port()
    gs = GroundStation(p_gcs)
    view = _View(gs, fault_ids)
    print(f"demo: scenario {scenario.id}, {args.speed:g}x real time, autopilot flying on the "
          f"{'FDIR estimate' if args.nav == 'fdir' else 'true state'}; ground station on udp {p_gcs}",
          flush=True)
    rows = scenario.sensors.measurements
    imu = all(r in rows for r in ("ax", "az", "airspeed"))
    fdir_cmd, sim_cmd = _commands(args, p_ap, p_gcs, log_path, truth_path, imu)
    service = subprocess.Popen(fdir_cmd, stderr=subprocess.PIPE, text=True)
    sim = subprocess.Popen(sim_cmd, stderr=subprocess.PIPE, text=True)
    try:
        _watch(gs, sim, view)
    except KeyboardInterrupt:
        sim.send_signal(signal.SIGINT)
    finally:
        with contextlib.suppress(ProcessLookupError):
            service.send_signal(signal.SIGINT)
        _, service_err = service.communicate(timeout=30)
        _, sim_err = sim.communicate(timeout=30)
        gs.close()
    if view.tty:
        print()
    print(_view_line(gs, fault_ids))
    print("summary:")
    for line in summary(gs, scenario, max_altitude_error(truth_path, scenario.command.altitude_m)):
        print(line)
    for line in (sim_err + service_err).splitlines():
        if line.startswith(("sim-bridge:", "fdir:")):
            print("  " + line)
    print(f"logs: {log_path} (service: fdir log info / fdir replay)\n      {truth_path} (truth)")
    return 0 if service.returncode == 0 and sim.returncode == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
