"""`sim-bridge fly` into `fdir run` through loopback UDP, a pymavlink ground station listening: the
end-to-end tests' shared harness."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from sim_bridge.demo import GroundStation, free_udp_port

ROOT = Path(__file__).resolve().parents[2]
ROBUST_SPEED = "5"
"""`sim-bridge fly --speed` (x real time) beside the robust monitor: 100 frames/s against its ~2 ms
step at N = 1000, with room for a test on the other worker (`make test` runs two). At 20x (400
frames/s) a busy CI core fell behind, its UDP buffer overflowed and frames lost rows."""
CATALOGUE_SPEED = "3"
"""... and beside the catalogue (aerosonde-catalogue, ~4 ms a step under load): at 5x, beside the
other worker's test, it lost a quarter of the messages and a barometer that missed frames was
called stuck."""
FLIGHT_LOCK = Path(tempfile.gettempdir()) / "fdir-service-loopback-flight.lock"
"""Held through each flight: `make test`'s two workers never fly two of them at once."""


@contextmanager
def one_flight_at_a_time() -> Iterator[None]:
    """An exclusive lock on FLIGHT_LOCK (blocks while another process holds it)."""
    with open(FLIGHT_LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@dataclass
class Flight:
    """What one loopback flight left: the ground station's view and both programs' exit and stderr."""

    gs: GroundStation
    service_rc: int
    service_err: str
    sim_rc: int
    sim_err: str


def fly_into_service(service_args: list[str], sim_args: list[str], tail_s: float = 1.0) -> Flight:
    """Run `fdir run --master udpin:... --gcs udpout:... SERVICE_ARGS` and `sim-bridge fly SIM_ARGS
    --to udpout:...` (SIM_ARGS start with the scenario), listen as the ground station until the
    simulator ends and tail_s (s) more, then stop the service with SIGINT. One flight at a time
    across processes (`one_flight_at_a_time`); both programs run on one BLAS thread (`cliutil.run`)."""
    with one_flight_at_a_time():
        return _fly(service_args, sim_args, tail_s)


def _fly(service_args: list[str], sim_args: list[str], tail_s: float) -> Flight:
    p_ap, p_gcs = free_udp_port(), free_udp_port()
    gs = GroundStation(p_gcs)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    service = subprocess.Popen(
        [sys.executable, "-m", "fdir_service.cli", "run", "--master", f"udpin:127.0.0.1:{p_ap}",
         "--gcs", f"udpout:127.0.0.1:{p_gcs}", *service_args],
        cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True)
    sim = subprocess.Popen(
        [sys.executable, "-m", "sim_bridge.cli", "fly", *sim_args, "--to", f"udpout:127.0.0.1:{p_ap}"],
        cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True)
    try:
        while sim.poll() is None:
            gs.poll(0.05)
        end = time.monotonic() + tail_s
        while time.monotonic() < end:
            gs.poll(0.05)
    finally:
        service.send_signal(signal.SIGINT)
        _, err_service = service.communicate(timeout=30)
        _, err_sim = sim.communicate(timeout=30)
        gs.close()
    return Flight(gs, service.returncode, err_service, sim.returncode, err_sim)
