"""`sim-bridge`: the simulator's command-line tools, one module per subcommand in
`sim_bridge/commands/`."""

from __future__ import annotations

import argparse
import sys

from fdir_service import cliutil

COMMANDS = ("linearize", "simulate", "fly", "replay", "experiment", "compare", "bench")
DESCRIPTION = (
    "The Aerosonde simulator: trim and linearise the airframe, fly closed-loop scenarios with "
    "sensor and actuator faults, stream them over MAVLink like an autopilot, and run the thesis's "
    "Monte Carlo campaigns."
)


def build_parser() -> argparse.ArgumentParser:
    return cliutil.build_parser("sim-bridge", DESCRIPTION, "sim_bridge.commands", COMMANDS)


def main(argv: list[str] | None = None) -> int:
    return cliutil.run(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
