"""`fdir`: the onboard service's command-line tools. Each subcommand lives in
`fdir_service/commands/<name>.py` and exposes `add_parser(subparsers)`; its parser's
`func` default runs it and returns the exit status."""

from __future__ import annotations

import argparse
import importlib
import sys

from fdir_service import __version__
from fdir_service.errors import ConfigError

COMMANDS = ("run", "replay", "log", "bench")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fdir",
        description="Onboard fault detection, isolation and estimation for fixed-wing UAVs. "
        "Reads an autopilot's MAVLink stream, estimates sensor and actuator faults with "
        "jump-Markov particle filters, and publishes them back over MAVLink.",
    )
    parser.add_argument("--version", action="version", version=f"fdir {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"fdir_service.commands.{name}")
        except ModuleNotFoundError as exc:  # subcommand not written yet
            if exc.name != f"fdir_service.commands.{name}":
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
        print(f"fdir: configuration error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
