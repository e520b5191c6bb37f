"""`fdir import`: a ground station's MAVLink telemetry log (.tlog) -> a recording `fdir replay` runs."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

DESCRIPTION = """\
Import a MAVLink telemetry log (.tlog, as Mission Planner, MAVProxy or QGroundControl record it
next to a real autopilot) into an MCAP recording, as if `fdir run --autopilot ...` had been running
on that link: the autopilot's messages (the system whose component 1 sends a HEARTBEAT naming an
autopilot; the ground station's own messages are ignored) go through the service's processing
core with their tlog times, and the raw bytes, decoded messages, estimates, events and the config
(service file, estimator, autopilot profile) are recorded. `fdir replay OUT.mcap` then reproduces
the estimates; `fdir replay OUT.mcap --filter NAME` compares another filter on the real log.

A damaged tlog (cut short, bytes overwritten) is read up to and around the damage; what could not
be read is counted in the summary. MAVLink 1 packets are re-framed as MAVLink 2.

A PX4 ULog (.ulg, read with pyulog) or an ArduPilot DataFlash log (.bin, pymavlink's DFReader) is
first translated into the MAVLink messages the autopilot's profile reads (one per logged sample,
times = the log's boot time; a 1 Hz HEARTBEAT; the logged parameters as PARAM_VALUE), then
imported the same way: `fdir replay` reads the result like any recording.
"""

EPILOG = """\
examples:
  fdir import flight.tlog --out flight.mcap                  # ArduPilot profile (the default)
  fdir import flight.tlog --out flight.mcap --autopilot auto # profile picked by the HEARTBEAT
  fdir import flight.ulg --out flight.mcap                   # PX4 ULog, px4 profile
  fdir import 00000042.BIN --out flight.mcap                # ArduPilot DataFlash log
  fdir replay flight.mcap --filter JMRPF                     # another filter on the same log
Exit status: 0 imported, 1 unreadable file or no autopilot in it, 2 bad configuration.
See docs/autopilots.md ("Logs").
"""


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "import", help="import a telemetry log (.tlog) or an autopilot log (.ulg, .bin) into a replayable "
                       "recording",
        description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("tlog", metavar="FILE", type=Path,
                   help="a MAVLink telemetry log (.tlog), PX4 ULog (.ulg) or ArduPilot DataFlash log (.bin)")
    p.add_argument("--out", metavar="OUT.mcap", type=Path, required=True, help="the recording to write")
    p.add_argument("--autopilot", metavar="NAME", default=None,
                   help="message profile, as `fdir run --autopilot`: ardupilot (default; px4 for a .ulg), "
                        "auto, or a profile file")
    p.add_argument("--estimator", metavar="NAME|FILE", default=None,
                   help="estimator file (default: service.estimator in the service config)")
    p.add_argument("--config", metavar="FILE", type=Path, default=None,
                   help="service config TOML (default: config/service/default.toml)")
    p.add_argument("--particles", metavar="N", type=int, default=None,
                   help="particle count (default: the estimator's)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


def _progress_bar(total: int, enabled: bool):
    """(callback(bytes read), close()) of a tqdm bar on stderr; a no-op when disabled."""
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, unit="B", unit_scale=True, desc="importing", file=sys.stderr, leave=False)

    def update(done: int) -> None:
        bar.update(max(done - bar.n, 0))

    return update, bar.close


def run(args: argparse.Namespace) -> int:
    from fdir_service.errors import ConfigError
    from fdir_service.log_import import default_autopilot, import_tlog, result_json, summary_lines

    if args.particles is not None and args.particles <= 0:
        raise ConfigError(f"--particles: expected a positive number, got {args.particles}")
    try:
        size = args.tlog.stat().st_size
    except OSError as exc:
        print(f"fdir import: {args.tlog}: {exc.strerror}", file=sys.stderr)
        return 1
    update, close = _progress_bar(size, not args.no_progress and sys.stderr.isatty())
    try:
        autopilot = args.autopilot or default_autopilot(args.tlog)
        r = import_tlog(args.tlog, args.out, autopilot=autopilot, estimator=args.estimator,
                        service_config=args.config, particles=args.particles, progress=update)
    except OSError as exc:
        print(f"fdir import: {exc}", file=sys.stderr)
        return 1
    finally:
        close()
    if args.json:
        print(json.dumps(result_json(r), indent=2))
    else:
        print("\n".join(summary_lines(r)))
    return 0 if r.autopilot is not None else 1
