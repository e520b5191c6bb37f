"""`fdir identify`: fit the longitudinal airframe to a fault-free flight recorded by `fdir run`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcap.exceptions import McapError

from fdir_service.airframe.params import load_airframe
from fdir_service.errors import ConfigError
from fdir_service.identification import airframe_toml, flight_frames, identify
from fdir_service.replay import ReplayError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "identify", help="fit the airframe's lift and pitch balance to a fault-free recorded flight",
        description="Read a recording of `fdir run` (LOG.mcap) made with an estimator whose rows include "
        "w, q, az and airspeed (config/estimators/aerosonde-robust.toml), assemble its frames as the "
        "service did, and fit the lift curve and the pitching-moment balance of the starting airframe "
        "by equation-error least squares over each frame interval, with instrumental variables against "
        "the accelerometer's noise and the file's values as a prior; a slope fitted with the wrong sign "
        "keeps the file's value. Elevator doublets help (`sim-bridge fly --doublet 3`). Prints the fit "
        "quality, what the autopilot's airspeed hold lets through and how soon it is gone (for a "
        "pitot-watching estimator's [parts] held_airspeed_sigma and held_airspeed_tau_s), and "
        "writes an airframe file for `fdir run --estimator` (via the estimator's `airframe` key) or an "
        "experiment's [estimator] airframe. The flight must be fault-free: a fault is fitted as airframe.")
    p.add_argument("log", metavar="LOG.mcap", help="a recording of `fdir run` of a fault-free flight")
    p.add_argument("--out", metavar="AIRFRAME.toml", required=True, help="the identified airframe file")
    p.add_argument("--airframe", default="aerosonde", metavar="NAME|FILE",
                   help="starting airframe (prior and fixed parameters; default aerosonde)")
    p.add_argument("--estimator", default="aerosonde-robust", metavar="NAME|FILE",
                   help="the estimator whose rows assemble the frames (default aerosonde-robust)")
    p.set_defaults(func=_run)
    return p


def _run(args: argparse.Namespace) -> int:
    try:
        base = load_airframe(args.airframe)
        frames = flight_frames(args.log, args.estimator)
        ident = identify(frames, base)
    except (ReplayError, McapError, OSError, ConfigError, ValueError) as exc:
        print(f"fdir identify: {exc}", file=sys.stderr)
        return 1
    print(ident.report())
    out = Path(args.out)
    out.write_text(airframe_toml(ident, str(args.airframe), Path(args.log).name))
    print(f"wrote {out}")
    return 0
