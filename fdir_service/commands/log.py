"""`fdir log`: inspect and repair recorded MCAP logs.

  fdir log info LOG.mcap                    topics, counts, duration, config (reads killed files too)
  fdir log recover BROKEN.mcap FIXED.mcap   rewrite a killed recording into a finalised, indexed file
"""

from __future__ import annotations

import argparse
import json
import sys

from mcap.exceptions import McapError

from fdir_service.recording.logtools import format_info, log_info, recover


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "log", help="inspect or repair a recorded MCAP log",
        description="Inspect or repair an MCAP log written by `fdir run --record`. Both tools read a "
        "file whose writer was killed (no summary) by scanning it linearly; everything up to the last "
        "complete chunk (at most one second before the kill) is kept.")
    sub = p.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    info = sub.add_parser("info", help="topics, message counts, duration, config",
                          description="Print the topics (schema, message count), time span, metadata "
                          "and whether the file was finalised.")
    info.add_argument("log", metavar="LOG.mcap")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.add_argument("--no-config", action="store_true", help="do not list the config metadata values")
    info.set_defaults(func=_info)
    rec = sub.add_parser("recover", help="rewrite a killed recording into a finalised file",
                         description="Copy every complete record of BROKEN into FIXED with a summary and "
                         "indexes, so any MCAP reader opens it.")
    rec.add_argument("broken", metavar="BROKEN.mcap")
    rec.add_argument("fixed", metavar="FIXED.mcap")
    rec.set_defaults(func=_recover)
    return p


def _info(args: argparse.Namespace) -> int:
    try:
        info = log_info(args.log)
    except (OSError, ValueError, McapError) as exc:
        print(f"fdir log info: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_info(info, show_config=not args.no_config))
    return 0


def _recover(args: argparse.Namespace) -> int:
    try:
        r = recover(args.broken, args.fixed)
    except (OSError, ValueError, McapError) as exc:
        print(f"fdir log recover: {exc}", file=sys.stderr)
        return 1
    state = ("was already finalised" if r.was_finalised
             else f"dropped {r.dropped_bytes} unreadable trailing bytes")
    print(f"recovered {r.messages} messages on {r.channels} channels ({r.schemas} schemas, "
          f"{r.metadata} metadata records) into {args.fixed}; source {state}")
    return 0
