"""The ``pickstop`` command. Errors print one line on stderr and exit non-zero (2: bad input).

One module per command group, each with its commands and their ``add_parser``: ``reach``,
``robot``, ``plan`` (regions and plan), ``layout``, ``service`` (serve, ui, api-key), ``demo``,
``errors`` (errors fit), ``fleet`` (export, dispatch, sim-vehicle, execute-sim); ``common``
holds what several share.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from pickstop.cli import demo, errors, fleet, layout, plan, reach, robot, service
from pickstop.errors import PickStopError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pickstop", description="Plan where a mobile manipulator stops to pick every part."
    )
    parser.add_argument(
        "--data-dir", help="data folder (default: $PICKSTOP_DATA_DIR or database/data)"
    )
    sub = parser.add_subparsers(dest="command", required=True)

    demo.add_parser(sub)
    plan.add_parser(sub)
    layout.add_parser(sub)
    service.add_parser(sub)
    robot.add_parser(sub)
    reach.add_parser(sub)
    errors.add_parser(sub)
    fleet.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except PickStopError as e:
        print(f"pickstop: error: {e.message}", file=sys.stderr)
        return e.exit_code
    except BrokenPipeError:  # output piped into a reader that closed early (head, less)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("pickstop: interrupted (a build resumes where it stopped)", file=sys.stderr)
        return 130
