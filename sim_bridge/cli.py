"""`sim-bridge`: the simulator's command-line tools. Each subcommand lives in
`sim_bridge.commands/<name>.py` and exposes `add_parser(subparsers)`; its parser's
`func` default runs it and returns the exit status."""

from __future__ import annotations

import argparse
import importlib
import sys

from fdir_service import __version__
from fdir_service.errors import ConfigError

COMMANDS = ("linearize", "simulate", "fly", "experiment", "bench")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sim-bridge",
        description="The Aerosonde simulator: trim and linearise the airframe, fly closed-loop "
        "scenarios with sensor and actuator faults, stream them over MAVLink like an autopilot, "
        "and run the thesis's Monte Carlo campaigns.",
    )
    parser.add_argument("--version", action="version", version=f"sim-bridge {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"sim_bridge.commands.{name}")
        except ModuleNotFoundError as exc:  # subcommand not written yet
            if exc.name != f"sim_bridge.commands.{name}":
                raise
            continue
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"sim-bridge: configuration error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
