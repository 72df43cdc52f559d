"""``pickstop layout``: where to move trays so the product mix runs faster."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from pickstop.argtypes import finite_float, positive_int
from pickstop.cli.common import emit, plan_options, planner_pool, write_json
from pickstop.errors import InputError


def _mix_orders(scene: Any, path: str | None) -> Any:
    """The orders of a layout search: a file's, else the scene's, else its task as one."""
    from pickstop.scene.model import Order
    from pickstop.scene.orders import load_orders

    if path is not None:
        return load_orders(path, scene)
    return list(scene.orders) if scene.orders else [Order(id="task", trays=scene.task_trays)]


def _layout_settings(args: argparse.Namespace) -> Any:
    from pickstop.layout.search import SearchSettings

    try:
        turns = tuple(int(t) for t in args.turns.split(","))
    except ValueError:
        raise InputError(f"--turns {args.turns!r}: give degrees like 0,90,180,270",
                         field="turns") from None  # fmt: skip
    if any(t % 90 for t in turns) or 0 not in turns:
        raise InputError("--turns: multiples of 90 degrees, 0 among them", field="turns")
    if not 0.01 <= args.step <= 1.0:
        raise InputError("--step: between 0.01 and 1 m", field="step")
    return SearchSettings(step=args.step, turns=tuple(dict.fromkeys(t % 360 for t in turns)),
                          suggestions=args.suggestions, shortlist=args.shortlist)  # fmt: skip


def cmd_layout(args: argparse.Namespace) -> int:
    """Suggested layouts: moves of the movable trays, each with its moved scene and the
    before/after figures of exact verified plans of every order."""
    from pickstop.layout.search import check_request, suggest
    from pickstop.layout.verify import LocalEvaluator
    from pickstop.scene.load import load_scene
    from pickstop.sequence.mix import mix_trays

    options, settings = plan_options(args), _layout_settings(args)
    src = Path(args.scene)
    scene = load_scene(src)
    orders = _mix_orders(scene, args.orders)
    movable = args.movable.split(",") if args.movable else mix_trays(scene, orders)
    check_request(scene, orders, movable)
    pool = planner_pool(args)
    client = None
    try:
        slot = pool.scene_slot(scene, src.resolve().parent, args.db)
        slot.regions.workers = args.workers
        if args.dask:
            from pickstop.distributed import DaskEvaluator, client_for

            client = client_for(args.dask)
            evaluator: Any = DaskEvaluator(client, src.resolve().parent, pool.data_dir,
                                           slot.regions.db.id, orders, options)  # fmt: skip
        else:
            evaluator = LocalEvaluator(slot.planner, orders, options)
        bar = _StageBar(not args.quiet)
        try:
            doc = suggest(slot.regions, evaluator, scene, orders, movable, options, settings, bar)
        finally:
            bar.close()
            evaluator.close()
    finally:
        if client is not None:
            client.close()
        pool.close()
    out = doc.model_dump(mode="json")
    if args.out:
        write_json(Path(args.out), out)
        emit(_layout_summary(out) | {"out": args.out})
    else:
        emit(out)
    return 0


def _layout_summary(doc: dict[str, Any]) -> dict[str, Any]:
    """The layout document without the moved scenes and per-order figures."""
    return {
        "scene": doc["scene"],
        "movable": doc["movable"],
        "before": doc["before"]["totals"],
        "suggestions": [
            {"rank": s["rank"], "moves": s["moves"], "gain": s["gain"],
             "after": s["after"]["totals"]}
            for s in doc["suggestions"]
        ],
        "notes": doc["notes"],
        "search": doc["search"],
    }  # fmt: skip


class _StageBar:
    """The search's progress on stderr: fraction done and what it is doing."""

    def __init__(self, enabled: bool) -> None:
        self.enabled, self.last = enabled, ""

    def __call__(self, fraction: float, message: str) -> None:
        if self.enabled and message != self.last:
            print(f"layout: {fraction:4.0%} {message}", file=sys.stderr, flush=True)
            self.last = message

    def close(self) -> None:
        pass


def add_parser(sub: Any) -> None:
    """Add the layout command to ``sub``."""
    ly = sub.add_parser("layout", help="suggest where to move trays so the mix runs faster")
    ly.add_argument("scene", help="scene JSON file")
    ly.add_argument("--orders", metavar="FILE",
                    help="the mix (a JSON list of {id, trays | parts, weight}); default: the "
                    "scene's orders, else its task")  # fmt: skip
    ly.add_argument("--movable", help="trays that may move, comma-separated (default: every "
                    "tray an order needs)")  # fmt: skip
    ly.add_argument("--out", help="write the layout document here (the moved scenes in it)")
    ly.add_argument("--dask", help="plan the candidate layouts on Dask ('local' or an address)")
    ly.add_argument("--step", type=finite_float, default=0.1, help="slot spacing [m]")
    ly.add_argument("--turns", default="0,90,180,270", help="turns to try [deg]")
    ly.add_argument("--suggestions", type=positive_int, default=3)
    ly.add_argument("--shortlist", type=positive_int, default=12,
                    help="best predicted layouts planned exactly")  # fmt: skip
    for flag in ("--sigma", "--target", "--time-limit"):
        ly.add_argument(flag, type=finite_float)
    ly.add_argument("--rule", choices=["sigma", "success"])
    ly.add_argument("--objective", choices=["stops", "time"])
    ly.add_argument("--samples", type=int, help="Monte Carlo samples per stop of the verified "
                    "plans (default 1000)")  # fmt: skip
    ly.add_argument("--seed", type=int)
    ly.add_argument("--db", help="reachability database id")
    ly.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1)
    ly.add_argument("--quiet", action="store_true", help="no progress on stderr")
    ly.set_defaults(func=cmd_layout)
