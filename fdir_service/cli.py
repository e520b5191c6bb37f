"""`fdir`: the onboard service's command-line tools, one module per subcommand in
`fdir_service/commands/`."""

from __future__ import annotations

import argparse
import sys

from fdir_service import cliutil

COMMANDS = ("run", "replay", "log", "import_log", "bench", "identify")
DESCRIPTION = (
    "Onboard fault detection, isolation and estimation for fixed-wing UAVs. Reads an autopilot's "
    "MAVLink stream, estimates sensor and actuator faults with jump-Markov particle filters, and "
    "publishes them back over MAVLink."
)


def build_parser() -> argparse.ArgumentParser:
    return cliutil.build_parser("fdir", DESCRIPTION, "fdir_service.commands", COMMANDS)


def main(argv: list[str] | None = None) -> int:
    return cliutil.run(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
