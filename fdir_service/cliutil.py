"""Shared plumbing of the `fdir` and `sim-bridge` command lines: one module per subcommand."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

import numpy  # noqa: F401 - loads OpenBLAS before `run` limits its threads (threadpoolctl limits loaded libraries)
from threadpoolctl import threadpool_limits

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
    """Parse and run on one BLAS thread; a configuration error prints its message and exits with
    status 2. One thread, as every campaign worker (`sim_bridge.campaign.run_job`): a filter step's
    products are (n x N) with n <= ~30, too small for a pool to pay, and on a busy 2-core machine
    OpenBLAS's two threads spun against the load: the catalogue's step at N = 1000 took 15-120 ms
    against 7.5 ms on one thread (`fdir bench --estimator aerosonde-catalogue`, a campaign beside
    it). And the service, its replays, the campaigns and the tests then share one floating-point path."""
    args = parser.parse_args(argv)
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"{parser.prog}: configuration error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
