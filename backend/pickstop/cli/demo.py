"""``pickstop demo``: the embedded default, the bundled TIAGo's database, the example scene, the
API and the 3D planner in one command."""

from __future__ import annotations

import argparse
import time
from typing import Any

from pickstop.argtypes import positive_int
from pickstop.cli.common import Progress
from pickstop.cli.reach import DEFAULT_SAMPLES


def cmd_demo(args: argparse.Namespace) -> int:
    """The embedded default: the bundled TIAGo's database (built once), the paper-like scene,
    the API and the 3D planner; prints the URLs and a first plan."""
    from pickstop import stack
    from pickstop.reach.build import BuildParams
    from pickstop.robot.model import load
    from pickstop.settings import Settings, data_dir
    from pickstop.store.reach_build import build

    t0 = time.perf_counter()
    folder = data_dir(args.data_dir)
    robot = load("tiago")
    bar = Progress(True)
    from pickstop.progress import StepLines

    steps = StepLines("demo")
    try:
        build(robot, BuildParams(samples=args.samples), folder, progress=bar, steps=steps)
    finally:
        bar.close()
        steps.close()
    overrides: dict[str, Any] = {"data_dir": folder, "ui_port": args.ui_port}
    if args.port is not None:
        overrides["port"] = args.port
    run = stack.start(Settings(**overrides), ui=True, move_if_busy=True)
    client = run.ui.api  # the planner's own client, with this run's key
    doc = client.scene(run.scene_id or "").doc
    from pickstop_ui.client import ApiProblem

    try:
        p = client.plan(doc, {"samples": 300}).plan
        first = (
            f"{p.totals.stops} stops (naive {len(p.naive.stops)}), {p.totals.time.total:.1f} s "
            f"predicted (naive {p.naive.time.total:.1f} s), success {p.totals.success or 0:.1%}"
        )
    except ApiProblem as e:
        first = f"{e.title}: {e.detail}"
    print(
        f"\nPickStop demo ({time.perf_counter() - t0:.1f} s to the first plan)\n"
        f"  3D planner: {run.ui_url}\n"
        f"  REST API:   {run.api_url}/api/v1/docs\n"
        f"  scene {run.scene_id} '{doc.get('name', '')}': {first}\n"
        "Press Ctrl-C to stop.",
        flush=True,
    )
    run.wait()
    return 0


def add_parser(sub: Any) -> None:
    """Add the demo command to ``sub``."""
    demo = sub.add_parser("demo", help="the embedded default: bundled TIAGo and example scene")
    demo.add_argument("--samples", type=positive_int, default=DEFAULT_SAMPLES)
    demo.add_argument("--port", type=positive_int, help="API port (default 8000, or a free one)")
    demo.add_argument("--ui-port", type=positive_int, default=8080, help="3D planner port")
    demo.set_defaults(func=cmd_demo)
