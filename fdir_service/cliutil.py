"""Shared plumbing of the `fdir` and `sim-bridge` command lines: one module per subcommand."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from fdir_service import __version__
from fdir_service.errors import ConfigError


def build_parser(prog: str, description: str, package: str,
                 commands: Sequence[str]) -> argparse.ArgumentParser:
    """A parser whose subcommands are `<package>.<name>` modules, each with `add_parser(subparsers)`."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--version", action="version", version=f"{prog} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in commands:
        importlib.import_module(f"{package}.{name}").add_parser(sub)
    return parser


def run(parser: argparse.ArgumentParser, argv: list[str] | None) -> int:
    """Parse and run; a configuration error prints its message and exits with status 2."""
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"{parser.prog}: configuration error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
