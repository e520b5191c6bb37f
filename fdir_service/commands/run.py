"""`fdir run`: the onboard fault monitor daemon."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fdir_service.estimation.recipes import FILTER_NAMES

DESCRIPTION = """\
Run the onboard fault monitor next to an autopilot.

It listens to the autopilot's MAVLink 2 stream (sensor messages such as GPS_RAW_INT,
SCALED_PRESSURE, ATTITUDE, ODOMETRY and the actuator outputs), assembles one frame per
filter step from the message timestamps, runs a jump-Markov particle filter that detects,
isolates and estimates additive sensor and actuator faults, and publishes what it finds as
component 191 (onboard computer) of the autopilot's system:

  HEARTBEAT           1 Hz, system status = estimator health
  NAMED_VALUE_FLOAT   f_<id> fault estimate (SI), pf_<id> P(fault),
                      pfa_<id> / pmd_<id> false-alarm / missed-detection probability (adaptive filters)
  STATUSTEXT          when a fault is declared or cleared, e.g. "FDIR gnss fault +50.1 m p=0.98"
  FDIR_ESTIMATE       the whole estimate (message 52500 of the fdir.xml dialect)

Everything goes back on the autopilot link and to each --gcs endpoint, stamped with the
autopilot's time of the frame it describes. Which message fields feed the filter, signing
and the publishing rates are set in the service config file; what the monitor assumes (its
airframe, filter, measurement noise and monitored faults) is set in the estimator file it
names (default config/estimators/aerosonde.toml); the options below override both.
Stop with Ctrl-C or SIGTERM.
"""

EPILOG = """\
examples:
  fdir run                                          # config/service/default.toml: udpin:127.0.0.1:14550
  fdir run --estimator my-aircraft.toml             # another airframe / noise / fault set
  fdir run --autopilot ardupilot --master /dev/ttyAMA0,921600   # next to a stock ArduPlane
  fdir run --master udpin:0.0.0.0:14550 --gcs udpout:192.168.1.10:14550
  fdir run --filter RJMRPF --particles 500 --record flight.mcap
  fdir run --no-record                              # default: records into recordings/
  sim-bridge fly ch4 --to udpout:127.0.0.1:14550    # feed it a simulated Aerosonde

URLs are pymavlink connection strings: udpin:HOST:PORT (listen), udpout:HOST:PORT (send),
tcp:HOST:PORT (connect), tcpin:HOST:PORT (listen), or a serial device (/dev/ttyUSB0,57600).
Exit status: 0 clean stop, 2 bad configuration (the message names the key).
See docs/service.md for the message mapping, the hysteresis and the signing setup.
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "run", help="run the fault monitor on a MAVLink link (the daemon)",
        description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", metavar="FILE", type=Path, default=None,
                   help="service config TOML (default: config/service/default.toml)")
    p.add_argument("--estimator", metavar="NAME|FILE", default=None,
                   help="estimator file, by name in config/estimators/ or path "
                        "(default: service.estimator in the config, else aerosonde)")
    p.add_argument("--autopilot", metavar="NAME", default="none",
                   help="the autopilot's message profile: ardupilot (config/autopilots/ardupilot.toml), "
                        "px4 (config/autopilots/px4.toml), auto (ardupilot or px4 by the autopilot's "
                        "HEARTBEAT: MAV_AUTOPILOT_ARDUPILOTMEGA or MAV_AUTOPILOT_PX4, else none; nothing "
                        "is monitored before that HEARTBEAT), none (the config's own [measurements] and "
                        "[inputs], the default), or a profile file. See docs/autopilots.md")
    p.add_argument("--master", metavar="URL", default=None,
                   help="the autopilot link to listen on (default: link.master in the config)")
    p.add_argument("--gcs", metavar="URL", action="append", default=None,
                   help="also send everything published to this endpoint; repeat for several "
                        "(default: link.gcs in the config)")
    p.add_argument("--filter", metavar="NAME", choices=FILTER_NAMES, default=None,
                   help=f"estimator: {', '.join(FILTER_NAMES)} (default: service.filter in the config)")
    p.add_argument("--particles", metavar="N", type=int, default=None,
                   help="number of particles (default: service.particles in the config)")
    p.add_argument("--seed", metavar="N", type=int, default=None,
                   help="the filter's random seed (default: service.seed in the config)")
    rec = p.add_mutually_exclusive_group()
    rec.add_argument("--record", metavar="FILE.mcap", type=Path, default=None,
                     help="record raw bytes, decoded input, estimates, events and particles to this "
                          "MCAP file (replayable bit for bit with `fdir replay`). Recording is on by "
                          "default: [record] in the config names the directory and the rotation")
    rec.add_argument("--no-record", action="store_true",
                     help="do not record (overrides [record] enabled = true)")
    p.add_argument("--duration", metavar="S", type=float, default=None,
                   help="stop after S seconds of wall time (default: run until stopped)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from fdir_service.autopilot_profile import select_autopilot
    from fdir_service.daemon import Daemon
    from fdir_service.errors import ConfigError
    from fdir_service.pipeline import Pipeline
    from fdir_service.service_config import load_service_config

    config = select_autopilot(load_service_config(args.config, estimator=args.estimator), args.autopilot)
    if args.particles is not None and args.particles <= 0:
        raise ConfigError(f"--particles: expected a positive number, got {args.particles}")
    observers = []
    recorder = None
    record_path = recording_path(config, args.record, args.no_record)
    if record_path is not None:
        from fdir_service.recording.recorder import Recorder

        try:
            record_path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"record.directory: cannot create {record_path.parent}: "
                              f"{exc.strerror}") from None
        rc = config.record
        recorder = Recorder(record_path, rotate_bytes=int(rc.rotate_mb * 1e6) or None,
                            rotate_seconds=rc.rotate_s or None)
        observers.append(recorder)
    try:
        pipeline = Pipeline(config, filter_name=args.filter, particles=args.particles, seed=args.seed,
                            observers=observers)
        warm_kernels(pipeline)
        master = args.master or config.master
        gcs = tuple(args.gcs) if args.gcs is not None else config.gcs
        daemon = Daemon(pipeline, master, gcs)
        status = daemon.run(max_seconds=args.duration)
    finally:
        if recorder is not None:
            recorder.close()
            names = ", ".join(str(p) for p in recorder.paths)
            print(f"fdir: recorded {names}", file=sys.stderr, flush=True)
    return status


def warm_kernels(pipeline) -> None:
    """Compile (or load) the filter's numba kernels on a throwaway copy before the first frame
    (`estimation.warm_up`)."""
    from fdir_service.estimation.warm_up import warm_up

    seconds = warm_up(pipeline.filter_name, pipeline.estimator)
    print(f"fdir: {pipeline.filter_name} ready ({seconds:.1f} s to compile or load its kernels)",
          file=sys.stderr, flush=True)


def recording_path(config, record: Path | None, no_record: bool) -> Path | None:
    """Where `fdir run` records: --record FILE, nothing with --no-record, else a fresh file in
    [record] directory when [record] enabled (the default)."""
    from fdir_service.recording.recorder import default_record_path

    if no_record:
        return None
    if record is not None:
        return record
    if not config.record.enabled:
        return None
    return default_record_path(config.record.directory)
