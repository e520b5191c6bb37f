"""Service latency and throughput over real UDP on loopback (issue 5 benchmark).

Runs `fdir run` as a subprocess and plays the autopilot itself (simulated ch4 Aerosonde, truth
navigation): latency = wall time from sending a frame's last input message (its ODOMETRY) to
receiving that frame's FDIR_ESTIMATE back on the link, at 20 Hz and 100 Hz input; then the
sustained frame rate in lockstep (`--speed 0`: send frame k, wait for its estimate, next).

    python benchmarks/service_latency.py [--filter RJMRPF] [--particles 1000] [--seconds 20]
Goal: p99 < 5 ms with RJMRPF at N = 1000; >= 1000 frames/s sustained at N = 100.
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fdir_service.daemon import open_link  # noqa: E402
from sim_bridge.demo import free_udp_port  # noqa: E402
from sim_bridge.mavlink_bridge import AutopilotLink  # noqa: E402
from sim_bridge.scenario import load_scenario  # noqa: E402
from sim_bridge.simulate import SimStepper, default_autopilot  # noqa: E402


class Service:
    def __init__(self, filter_name: str, particles: int, record: Path | None = None) -> None:
        self.port = free_udp_port()
        rec = ["--record", str(record)] if record is not None else ["--no-record"]
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "fdir_service.cli", "run", "--master", f"udpin:127.0.0.1:{self.port}",
             "--filter", filter_name, "--particles", str(particles), *rec],
            cwd=ROOT, env=dict(os.environ, PYTHONUNBUFFERED="1"), stderr=subprocess.PIPE, text=True)

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGINT)
        return self.proc.communicate(timeout=30)[1]


class Autopilot:
    """The simulated aircraft as the service's autopilot link."""

    def __init__(self, port: int) -> None:
        self.scenario = load_scenario("ch4")
        self.stepper = SimStepper(self.scenario, 0)
        self.ap = default_autopilot(self.scenario, self.stepper.airframe)
        self.link = AutopilotLink(self.scenario)
        self.conn = open_link(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
        self.k0 = 0
        self.gcs_s = 0.0   # this process decoding the replies (the ground station's work, not the service's)

    def handshake(self, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.conn.write(self.link.heartbeat())
            if self.wait_estimate(None, time.monotonic() + 0.2) is not None:
                return
        raise SystemExit("the service did not answer")

    def wait_estimate(self, t_ms: int | None, deadline: float) -> float | None:
        """Wall time at which the FDIR_ESTIMATE of t_ms (any message if None) arrived."""
        fd = self.conn.port.fileno()
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                return None
            now = time.perf_counter()
            try:
                while True:
                    data = self.conn.recv(65536)
                    if not data:
                        break
                    for m in self.link.parse(data.encode("latin-1") if isinstance(data, str) else data):
                        if t_ms is None or (m.get_type() == "FDIR_ESTIMATE" and m.time_boot_ms == t_ms):
                            return now
            finally:
                self.gcs_s += time.perf_counter() - now

    def frame(self) -> tuple[int, list[bytes], np.ndarray, float]:
        fr = self.stepper.frame()
        u = self.ap.update(fr.t, fr.z_true)
        sens = self.link.sensor_messages(fr.t, fr.y, fr.mask, fr.static_pressure_pa)
        return int(round(fr.t * 1000)), sens, u, fr.t

    def run(self, frames: int, rate_hz: float | None) -> tuple[np.ndarray, float]:
        """Latencies (s) of `frames` frames sent at rate_hz (None: lockstep), and the wall time.
        `self.sim_s` / `self.encode_s`: wall time of the simulator's own stepping (truth, sensors,
        autopilot) and MAVLink encoding in this process, the simulator's share of lockstep."""
        lat = []
        self.sim_s = self.encode_s = self.gcs_s = 0.0
        t0 = time.monotonic()
        for k in range(frames):
            if rate_hz:
                delay = t0 + k / rate_hz - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            c0 = time.perf_counter()
            fr = self.stepper.frame()
            u = self.ap.update(fr.t, fr.z_true)
            c1 = time.perf_counter()
            sens = self.link.sensor_messages(fr.t, fr.y, fr.mask, fr.static_pressure_pa)
            t_ms, t = int(round(fr.t * 1000)), fr.t
            c2 = time.perf_counter()
            for b in sens:
                self.conn.write(b)
            t_sent = time.perf_counter()
            deadline = time.monotonic() + (1.0 / rate_hz if rate_hz else 2.0)
            got = self.wait_estimate(t_ms, deadline)
            lat.append(np.nan if got is None else got - t_sent)
            c3 = time.perf_counter()
            act = self.link.actuator_messages(t, u)
            c4 = time.perf_counter()
            for b in act:
                self.conn.write(b)
            c5 = time.perf_counter()
            self.stepper.advance(u)
            c6 = time.perf_counter()
            self.sim_s += (c1 - c0) + (c6 - c5)
            self.encode_s += (c2 - c1) + (c4 - c3)
        return np.array(lat), time.monotonic() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--filter", default="RJMRPF")
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--throughput-particles", type=int, default=100)
    ap.add_argument("--seconds", type=float, default=10.0,
                    help="wall seconds per latency run (both runs share one 50 s simulated flight)")
    ap.add_argument("--record", metavar="FILE.mcap", type=Path, default=None,
                    help="let the service record to this file (default: --no-record)")
    args = ap.parse_args()

    svc = Service(args.filter, args.particles, args.record)
    try:
        pilot = Autopilot(svc.port)
        pilot.handshake()
        for rate in (20.0, 100.0):
            n = min(int(args.seconds * rate), pilot.scenario.steps - pilot.stepper.k)  # one 50 s flight
            lat, _ = pilot.run(n, rate)
            ok = lat[np.isfinite(lat)] * 1e3
            print(f"{args.filter} N={args.particles} input {rate:5.0f} Hz: latency last input message -> "
                  f"FDIR_ESTIMATE p50 {np.percentile(ok, 50):.2f} ms, p99 {np.percentile(ok, 99):.2f} ms, "
                  f"max {ok.max():.2f} ms ({len(ok)}/{n} frames answered within the frame period)",
                  flush=True)
    finally:
        err = svc.stop()
    if "stopped after" not in err:
        print(err, file=sys.stderr)

    svc = Service(args.filter, args.throughput_particles, args.record)
    try:
        pilot = Autopilot(svc.port)
        pilot.handshake()
        lat, wall = pilot.run(pilot.scenario.steps, None)
        n_ok = int(np.isfinite(lat).sum())
        rt = np.nanpercentile(lat, 50) * 1e3
        print(f"{args.filter} N={args.throughput_particles} lockstep (--speed 0): {n_ok} frames in "
              f"{wall:.2f} s = {n_ok / wall:.0f} frames/s sustained (p50 round trip {rt:.2f} ms)", flush=True)
        n = len(lat)
        sim_ms, enc_ms = 1e3 * pilot.sim_s / n, 1e3 * pilot.encode_s / n
        gcs_ms = 1e3 * pilot.gcs_s / n
        svc_ms = 1e3 * wall / n - sim_ms - enc_ms - gcs_ms
        print(f"  per frame (mean wall): simulator {sim_ms:.3f} ms (truth, sensors, autopilot) + its MAVLink "
              f"encoding {enc_ms:.3f} ms + decoding the replies {gcs_ms:.3f} ms; the rest {svc_ms:.3f} ms = "
              f"service round trip (UDP both ways, parse, filter, publish, recorder) -> the service alone "
              f"would sustain {1e3 / svc_ms:.0f} frames/s", flush=True)
    finally:
        svc.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
