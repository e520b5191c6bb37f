"""`sim-bridge fly`: stream the simulated Aerosonde over MAVLink 2 like an autopilot."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

DESCRIPTION = """\
Fly a scenario's simulated Aerosonde and stream it over MAVLink 2 as an autopilot would
(system 1, component 1): HEARTBEAT, GPS_RAW_INT, SCALED_PRESSURE, ATTITUDE, ODOMETRY (body-frame
velocities), SERVO_OUTPUT_RAW and ACTUATOR_OUTPUT_STATUS, every message stamped with the
simulation time. The truth never goes on the wire (--record writes it to an MCAP instead).

Per frame k: the sensor messages of frame k are sent; with --nav fdir the autopilot then waits
for the service's FDIR_ESTIMATE of frame k and flies on its state estimate (with --nav truth it
flies on the true state); its output u_k is sent as the actuator messages of frame k.
"""

EPILOG = """\
--speed 0 runs in lockstep: each frame waits for the service's FDIR_ESTIMATE of that frame
(up to --timeout s of wall time). When it does not come, the autopilot coasts: it flies on the
last estimate received, propagated with the linear model and the inputs applied since (and
after 3 misses in a row with --nav truth, the simulator stops waiting and free-runs).

examples:
  fdir run &                                          # listens on udpin:127.0.0.1:14550
  sim-bridge fly ch4 --to udpout:127.0.0.1:14550 --speed 0 --nav fdir --record truth.mcap
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("fly", help="stream a simulated flight over MAVLink like an autopilot",
                              description=DESCRIPTION, epilog=EPILOG,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario id (ch4, ch5a, ...) or path to a scenario TOML")
    p.add_argument("--to", metavar="URL", default="udpout:127.0.0.1:14550",
                   help="where the service listens (pymavlink URL; default udpout:127.0.0.1:14550)")
    p.add_argument("--speed", metavar="X", type=float, default=1.0,
                   help="X times real time; 0 = lockstep, as fast as the service keeps up (default 1)")
    p.add_argument("--seed", metavar="N", type=int, default=0, help="simulation seed (default 0)")
    p.add_argument("--nav", choices=("truth", "fdir"), default="truth",
                   help="what the autopilot flies on: the true state, or the service's estimate")
    p.add_argument("--record", metavar="TRUTH.mcap", type=Path, default=None,
                   help="record the truth (/sim/truth) to this MCAP file")
    p.add_argument("--duration", metavar="S", type=float, default=None,
                   help="simulated seconds to fly (default: the scenario's duration)")
    p.add_argument("--timeout", metavar="S", type=float, default=1.0,
                   help="wall seconds to wait for an estimate in lockstep / fdir nav (default 1)")
    p.add_argument("--wait", metavar="S", type=float, default=10.0,
                   help="wait up to S wall seconds for the service's HEARTBEAT before starting")
    p.add_argument("--key-file", metavar="FILE", type=Path, default=None,
                   help="sign with the 32-byte key in FILE (64 hex characters)")
    p.add_argument("--loss", metavar="P", type=float, default=0.0,
                   help="drop each MAVLink packet sent with probability P (0 <= P < 1), from a stream "
                        "seeded by --seed: a deterministic lossy radio link (default 0). With --speed 0 "
                        "use a short --timeout: a frame whose messages were lost is answered late")
    p.add_argument("--quiet", action="store_true", help="no summary line")
    p.set_defaults(func=run)
    return p


class _Receiver:
    """Reads the service's replies on the link; keeps the latest FDIR_ESTIMATE per frame time."""

    def __init__(self, conn, link) -> None:
        self.conn = conn
        self.link = link
        self.estimates: dict[int, np.ndarray] = {}
        self.latest: tuple[int, np.ndarray] | None = None
        self.service_seen = False

    def poll(self, timeout: float) -> None:
        import select

        fd = self.conn.port.fileno()
        ready, _, _ = select.select([fd], [], [], max(timeout, 0.0))
        if not ready:
            return
        while True:
            data = self.conn.recv(65536)
            if not data:
                return
            if isinstance(data, str):
                data = data.encode("latin-1")
            for msg in self.link.parse(data):
                if msg.get_srcComponent() == 191 or msg.get_type() == "FDIR_ESTIMATE":
                    self.service_seen = True
                if msg.get_type() == "FDIR_ESTIMATE":
                    z = np.asarray(msg.state, dtype=float)
                    self.estimates[msg.time_boot_ms] = z
                    if self.latest is None or msg.time_boot_ms >= self.latest[0]:
                        self.latest = (msg.time_boot_ms, z)
                    if len(self.estimates) > 64:
                        for k in sorted(self.estimates)[:-32]:
                            del self.estimates[k]

    def wait_for(self, t_ms: int, deadline: float) -> np.ndarray | None:
        while True:
            if t_ms in self.estimates:
                return self.estimates[t_ms]
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.poll(left)


def run(args: argparse.Namespace) -> int:
    from fdir_service.daemon import open_link
    from fdir_service.errors import ConfigError
    from sim_bridge.mavlink_bridge import AutopilotLink, LossyLink
    from sim_bridge.scenario import load_scenario
    from sim_bridge.simulate import SimStepper, default_autopilot

    if not 0.0 <= args.loss < 1.0:
        raise ConfigError(f"--loss: expected a probability in [0, 1), got {args.loss}")
    lossy = LossyLink(args.loss, args.seed)
    if args.speed < 0:
        raise ConfigError(f"--speed: expected 0 (lockstep) or a positive factor, got {args.speed}")
    scenario = load_scenario(args.scenario)
    key = None
    if args.key_file is not None:
        try:
            key = bytes.fromhex(args.key_file.read_text().strip())
        except (OSError, ValueError):
            key = b""
        if len(key) != 32:
            raise ConfigError(f"--key-file: {args.key_file} must hold 64 hex characters")
    stepper = SimStepper(scenario, args.seed)
    ap = default_autopilot(scenario, stepper.airframe)
    ap.reset()
    signing_ts = int((time.time() - 1420070400) * 1e5) if key else 0
    link = AutopilotLink(scenario, key=key, signing_timestamp=signing_ts)
    conn = open_link(args.to, source_system=1, source_component=1)
    rx = _Receiver(conn, link)
    truth = None
    if args.record is not None:
        from sim_bridge.truth_log import TruthWriter

        args.record.parent.mkdir(parents=True, exist_ok=True)
        truth = TruthWriter(args.record, [f.id for f in scenario.faults],
                            metadata={"scenario": {"id": scenario.id, "seed": str(args.seed),
                                                   "nav": args.nav, "speed": str(args.speed)}})
    duration = scenario.duration_s if args.duration is None else args.duration
    K = int(round(duration / scenario.dt_s))
    dt = scenario.dt_s

    # Handshake: heartbeats until the service answers (it replies on the link once it hears us).
    if args.wait > 0:
        t_wait = time.monotonic() + args.wait
        while not rx.service_seen and time.monotonic() < t_wait:
            conn.write(link.heartbeat())
            rx.poll(0.2)
        if not rx.service_seen:
            print(f"sim-bridge: no service answered on {args.to} within {args.wait:g} s; flying anyway",
                  file=sys.stderr, flush=True)

    lockstep = args.speed == 0
    wait_estimates = lockstep or args.nav == "fdir"
    misses = consecutive = 0
    max_alt_err = 0.0
    coast: tuple[np.ndarray, int] | None = None  # (state, frame index it describes)
    u_hist: list[np.ndarray] = []
    t_start = time.monotonic()
    try:
        for k in range(K):
            fr = stepper.frame()
            if not lockstep:
                delay = t_start + k * dt / args.speed - time.monotonic()
                if delay > 0:
                    rx.poll(delay)
            t_ms = int(round(fr.t * 1000))
            sent = lossy.filter(link.sensor_messages(fr.t, fr.y, fr.mask, fr.static_pressure_pa))
            if sent:
                conn.write(b"".join(sent))
            z_est = None
            if wait_estimates:
                if lockstep:
                    deadline = time.monotonic() + args.timeout
                else:
                    deadline = min(time.monotonic() + args.timeout, t_start + (k + 1) * dt / args.speed)
                z_est = rx.wait_for(t_ms, deadline)
                if z_est is None:
                    misses += 1
                    consecutive += 1
                    if args.nav == "truth" and lockstep and consecutive >= 3:
                        wait_estimates = False  # nobody publishes estimates: free-run
                else:
                    consecutive = 0
            else:
                rx.poll(0.0)
            if args.nav == "fdir":
                if z_est is not None:
                    coast = (z_est, k)
                    z_nav = z_est
                elif coast is not None:  # coast: last estimate propagated with the model
                    z_nav = coast[0].copy()
                    for j in range(coast[1], k):
                        z_nav = ap.model.step(z_nav, u_hist[j])
                else:
                    z_nav = ap.model.trim.z.copy()
            else:
                z_nav = fr.z_true
            u = ap.update(fr.t, z_nav)
            sent = lossy.filter(link.actuator_messages(fr.t, u))
            if sent:
                conn.write(b"".join(sent))
            u_hist.append(np.asarray(u, dtype=float).copy())
            if truth is not None:
                truth.write(fr.t, fr.z_true, fr.faults, u)
            max_alt_err = max(max_alt_err, abs(-fr.z_true[0] - ap.altitude_command(fr.t)))
            stepper.advance(u)
        rx.poll(0.05)
    except KeyboardInterrupt:
        pass
    finally:
        if truth is not None:
            truth.close()
        conn.close()
    wall = time.monotonic() - t_start
    if not args.quiet:
        print(f"sim-bridge: flew {scenario.id} {K * dt:g} s in {wall:.2f} s wall "
              f"({K / max(wall, 1e-9):.0f} frames/s), nav {args.nav}, {misses} estimates missed, "
              f"max |altitude error| {max_alt_err:.2f} m"
              + (f"; {lossy.dropped} of {lossy.sent + lossy.dropped} packets dropped" if args.loss else "")
              + (f"; truth in {args.record}" if truth else ""),
              file=sys.stderr, flush=True)
    return 0 if math.isfinite(max_alt_err) else 1
