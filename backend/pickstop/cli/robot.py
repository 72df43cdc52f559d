"""``pickstop robot check``: validate a robot config and show what PickStop makes of it."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from pickstop.cli.common import emit

STRICT_EXIT = 6  # robot check --strict: the check warns


def cmd_robot_check(args: argparse.Namespace) -> int:
    from pickstop.progress import StepLines
    from pickstop.robot.check import check_robot, format_report
    from pickstop.settings import cache_dir

    steps = None if args.quiet else StepLines("robot check")
    try:
        report = check_robot(args.config, cache_dir(), steps)
    finally:
        if steps is not None:
            steps.close()
    if args.json:
        emit(report)
    else:
        print(format_report(report))
    for warning in report["warnings"]:
        print(f"pickstop: warning: {warning}", file=sys.stderr)
    return STRICT_EXIT if args.strict and report["warnings"] else 0


def add_parser(sub: Any) -> None:
    """Add the robot commands to ``sub``."""
    robot = sub.add_parser("robot", help="robot configs").add_subparsers(
        dest="robot_command", required=True
    )
    rc = robot.add_parser(
        "check", help="validate a robot config and show what PickStop makes of it"
    )
    rc.add_argument("config", help="preset name or robot config file (YAML or JSON)")
    rc.add_argument("--json", action="store_true", help="the report as JSON")
    rc.add_argument("--quiet", action="store_true", help="no progress lines")
    rc.add_argument(
        "--strict",
        action="store_true",
        help=f"exit {STRICT_EXIT} if the check warns (a screen over its false-rejection bound, "
        "a hand that rules out grasps)",
    )
    rc.set_defaults(func=cmd_robot_check)
