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
--profile ardupilot sends ArduPlane's stock messages instead (HEARTBEAT autopilot 3, ATTITUDE,
GLOBAL_POSITION_INT, GPS_RAW_INT, SCALED_PRESSURE, RAW_IMU, VFR_HUD, SERVO_OUTPUT_RAW PWM) and
answers PARAM_REQUEST_READ / PARAM_REQUEST_LIST for its SERVOn_* parameters: what
`fdir run --autopilot ardupilot|auto` reads; --param NAME=VALUE changes one of them (its outputs
follow: e.g. the elevator on another output, reversed). --profile px4 sends PX4's Onboard-mode messages
(HEARTBEAT autopilot 12, ATTITUDE, LOCAL_POSITION_NED, HIGHRES_IMU, GPS_RAW_INT, VFR_HUD,
SERVO_OUTPUT_RAW PWM on the MAIN outputs) and answers for its CA_SV_* / PWM_MAIN_* parameters
(integers bytewise): what `fdir run --autopilot px4|auto` reads.

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
  fdir run --autopilot auto &
  sim-bridge fly real-calm-faultfree --profile ardupilot --duration 30
  sim-bridge fly real-calm-faultfree --profile px4 --duration 30
  sim-bridge fly real-calm-faultfree --profile ardupilot --param SERVO2_FUNCTION=0 \
      --param SERVO5_FUNCTION=19 --param SERVO5_REVERSED=1     # elevator on output 5, reversed
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
    p.add_argument("--profile", choices=("native", "ardupilot", "px4"), default="native",
                   help="the message set on the wire: the simulator's own (native, default), "
                        "ArduPlane's stock messages (ardupilot) or PX4's Onboard-mode ones (px4)")
    p.add_argument("--param", metavar="NAME=VALUE", action="append", default=[],
                   help="--profile ardupilot: a parameter value other than ArduPlane's default, used for "
                        "its outputs and its PARAM_VALUE answers (e.g. --param SERVO2_FUNCTION=0 --param "
                        "SERVO5_FUNCTION=19 --param SERVO5_REVERSED=1: the elevator on output 5, reversed); "
                        "repeatable")
    p.add_argument("--doublet", metavar="DEG", type=float, default=0.0,
                   help="add an elevator doublet of DEG degrees (+DEG for 0.5 s, then -DEG for 0.5 s, "
                   "every 10 s from 5 s) to the autopilot's output: excitation for `fdir identify` "
                   "(default 0: none)")
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
        """Wait up to `timeout` s for data, then read everything available."""
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
                self._take(msg)

    def _take(self, msg) -> None:
        """Note the service's presence; answer requests (the profile's replies, e.g. PARAM_VALUE);
        keep an FDIR_ESTIMATE's state (the last 32-64 frames)."""
        replies = self.link.answer(msg)
        if replies:
            self.conn.write(b"".join(replies))
        is_estimate = msg.get_type() == "FDIR_ESTIMATE"
        if msg.get_srcComponent() == 191 or is_estimate:
            self.service_seen = True
        if not is_estimate:
            return
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


def _params(pairs: list[str]) -> dict[str, float]:
    """--param NAME=VALUE pairs -> {NAME: VALUE}; ConfigError for a malformed one."""
    from fdir_service.errors import ConfigError

    out: dict[str, float] = {}
    for pair in pairs:
        name, _, value = pair.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--param: expected NAME=VALUE (a number), got {pair!r}") from None
    return out


def _check_args(args: argparse.Namespace) -> bytes | None:
    """ConfigError for a bad --loss, --speed or --key-file; the signing key (None: unsigned)."""
    from fdir_service.errors import ConfigError

    args.params = _params(args.param)
    if not 0.0 <= args.loss < 1.0:
        raise ConfigError(f"--loss: expected a probability in [0, 1), got {args.loss}")
    if args.speed < 0:
        raise ConfigError(f"--speed: expected 0 (lockstep) or a positive factor, got {args.speed}")
    if args.key_file is None:
        return None
    try:
        key = bytes.fromhex(args.key_file.read_text().strip())
    except (OSError, ValueError):
        key = b""
    if len(key) != 32:
        raise ConfigError(f"--key-file: {args.key_file} must hold 64 hex characters")
    return key


def _truth_writer(args: argparse.Namespace, scenario):
    """The --record TruthWriter, or None."""
    if args.record is None:
        return None
    from sim_bridge.truth_log import TruthWriter

    args.record.parent.mkdir(parents=True, exist_ok=True)
    return TruthWriter(args.record, [f.id for f in scenario.faults],
                       metadata={"scenario": {"id": scenario.id, "seed": str(args.seed),
                                              "nav": args.nav, "speed": str(args.speed)}})


class _Flight:
    """One simulated flight on the wire: per frame, sensors out, the estimate in (lockstep / fdir
    nav), the autopilot's output out, the truth recorded."""

    def __init__(self, args: argparse.Namespace, scenario, key: bytes | None) -> None:
        from fdir_service.daemon import open_link
        from sim_bridge.autopilot import ElevatorDoublet, ExcitedAutopilot
        from sim_bridge.mavlink_bridge import AutopilotLink, LossyLink
        from sim_bridge.simulate import SimStepper, default_autopilot

        self.args, self.scenario, self.dt = args, scenario, scenario.dt_s
        self.lossy = LossyLink(args.loss, args.seed)
        self.stepper = SimStepper(scenario, args.seed)
        doublet = ElevatorDoublet(math.radians(getattr(args, "doublet", 0.0)))
        self.ap = ExcitedAutopilot(default_autopilot(scenario, self.stepper.airframe), doublet)
        self.ap.reset()
        signing_ts = int((time.time() - 1420070400) * 1e5) if key else 0
        self.link = AutopilotLink(scenario, key=key, signing_timestamp=signing_ts,
                                  profile=getattr(args, "profile", "native"),
                                  params=getattr(args, "params", None))
        self.conn = open_link(args.to, source_system=1, source_component=1)
        self.rx = _Receiver(self.conn, self.link)
        self.truth = _truth_writer(args, scenario)
        self.lockstep = args.speed == 0
        self.wait_estimates = self.lockstep or args.nav == "fdir"
        self.misses = self.consecutive = 0
        self.max_alt_err = 0.0
        self.coast: tuple[np.ndarray, int] | None = None   # (state, frame index it describes)
        self.u_hist: list[np.ndarray] = []
        self.t_start = time.monotonic()

    def handshake(self) -> None:
        """Heartbeats until the service answers (it replies on the link once it hears us)."""
        args, rx = self.args, self.rx
        if args.wait <= 0:
            return
        t_wait = time.monotonic() + args.wait
        while not rx.service_seen and time.monotonic() < t_wait:
            self.conn.write(self.link.heartbeat())
            rx.poll(0.2)
        if not rx.service_seen:
            print(f"sim-bridge: no service answered on {args.to} within {args.wait:g} s; flying anyway",
                  file=sys.stderr, flush=True)

    def _send(self, packets: list[bytes]) -> None:
        sent = self.lossy.filter(packets)
        if sent:
            self.conn.write(b"".join(sent))

    def _estimate(self, k: int, t_ms: int) -> np.ndarray | None:
        """The service's estimate of frame k when the flight waits for it (None: missed / not asked)."""
        if not self.wait_estimates:
            self.rx.poll(0.0)
            return None
        deadline = time.monotonic() + self.args.timeout
        if not self.lockstep:
            deadline = min(deadline, self.t_start + (k + 1) * self.dt / self.args.speed)
        z_est = self.rx.wait_for(t_ms, deadline)
        if z_est is not None:
            self.consecutive = 0
            return z_est
        self.misses += 1
        self.consecutive += 1
        if self.args.nav == "truth" and self.lockstep and self.consecutive >= 3:
            self.wait_estimates = False  # nobody publishes estimates: free-run
        return None

    def _nav_state(self, k: int, z_true: np.ndarray, z_est: np.ndarray | None) -> np.ndarray:
        """What the autopilot flies on: the truth, the estimate, or the last estimate coasted."""
        if self.args.nav != "fdir":
            return z_true
        if z_est is not None:
            self.coast = (z_est, k)
            return z_est
        if self.coast is None:
            return self.ap.model.trim.z.copy()
        z_nav = self.coast[0].copy()        # coast: the last estimate propagated with the model
        for j in range(self.coast[1], k):
            z_nav = self.ap.model.step(z_nav, self.u_hist[j])
        return z_nav

    def frame(self, k: int) -> None:
        fr = self.stepper.frame()
        if not self.lockstep:
            delay = self.t_start + k * self.dt / self.args.speed - time.monotonic()
            if delay > 0:
                self.rx.poll(delay)
        self._send(self.link.sensor_messages(fr.t, fr.y, fr.mask, fr.static_pressure_pa))
        z_est = self._estimate(k, int(round(fr.t * 1000)))
        u = self.ap.update(fr.t, fr.autopilot_view(self._nav_state(k, fr.z_true, z_est)))
        self._send(self.link.actuator_messages(fr.t, u))
        self.u_hist.append(np.asarray(u, dtype=float).copy())
        if self.truth is not None:
            self.truth.write(fr.t, fr.z_true, self.stepper.fault_truth(u), u, active=fr.active)
        self.max_alt_err = max(self.max_alt_err, abs(-fr.z_true[0] - self.ap.altitude_command(fr.t)))
        self.stepper.advance(u)

    def fly(self, K: int) -> None:
        try:
            for k in range(K):
                self.frame(k)
            self.rx.poll(0.05)
        except KeyboardInterrupt:
            pass
        finally:
            if self.truth is not None:
                self.truth.close()
            self.conn.close()

    def summary(self, K: int) -> str:
        wall = time.monotonic() - self.t_start
        args, lossy = self.args, self.lossy
        return (f"sim-bridge: flew {self.scenario.id} {K * self.dt:g} s in {wall:.2f} s wall "
                f"({K / max(wall, 1e-9):.0f} frames/s), "
                + ("" if self.link.profile == "native" else f"profile {self.link.profile}, ")
                + f"nav {args.nav}, {self.misses} estimates missed, "
                f"max |altitude error| {self.max_alt_err:.2f} m"
                + (f"; {lossy.dropped} of {lossy.sent + lossy.dropped} packets dropped" if args.loss else "")
                + (f"; truth in {args.record}" if self.truth else ""))


def run(args: argparse.Namespace) -> int:
    from sim_bridge.scenario import load_scenario

    key = _check_args(args)
    scenario = load_scenario(args.scenario)
    try:
        flight = _Flight(args, scenario, key)
    except ValueError as exc:   # a --param the profile does not have
        from fdir_service.errors import ConfigError

        raise ConfigError(str(exc)) from None
    duration = scenario.duration_s if args.duration is None else args.duration
    K = int(round(duration / scenario.dt_s))
    flight.handshake()
    flight.t_start = time.monotonic()
    flight.fly(K)
    if not args.quiet:
        print(flight.summary(K), file=sys.stderr, flush=True)
    return 0 if math.isfinite(flight.max_alt_err) else 1
