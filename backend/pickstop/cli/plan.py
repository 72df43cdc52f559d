"""``pickstop regions`` and ``pickstop plan``: base regions of a scene's trays, and plans of
one scene, every order of a product mix, or a folder of scenes (locally or on Dask)."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from pickstop.argtypes import finite_float, positive_int
from pickstop.cli.common import emit, plan_options, planner_pool, write_json
from pickstop.errors import InputError, PickStopError

_ROBOT_HELP = (
    "plan with this robot instead of the scene's: a preset name or a robot config file "
    "(YAML or JSON, relative to the working folder)"
)


def _robot_ref(robot: str) -> dict[str, str]:
    """The scene's ``robot`` block naming what ``--robot`` gives: a preset, or a config file
    (by its absolute path, so that it does not depend on the scene's folder)."""
    from pickstop.errors import RobotConfigError
    from pickstop.robot.config import preset_names, robot_config_file

    if robot in preset_names():
        return {"preset": robot}
    path = robot_config_file(robot)  # an unknown name is refused here, naming the presets
    if not path.is_file():
        raise RobotConfigError(f"--robot {robot}: robot config file not found", field="robot")
    return {"config": str(path.resolve())}


def _with_robot(scene: Any, robot: str | None) -> Any:
    """``scene`` planned with the robot ``--robot`` names instead of its own (None: its own)."""
    if robot is None:
        return scene
    from pickstop.scene.model import RobotRef

    ref = _robot_ref(robot)
    block = RobotRef(preset=ref.get("preset"), config=ref.get("config"))
    return scene.model_copy(update={"robot": block})


def cmd_regions(args: argparse.Namespace) -> int:
    from pickstop.pool import PlannerPool
    from pickstop.regions.geojson import regions_geojson
    from pickstop.scene.load import load_scene
    from pickstop.settings import data_dir

    scene = _with_robot(load_scene(args.scene), args.robot)
    trays = args.tray or scene.task_trays
    known = {t.id for t in scene.trays}
    for t in trays:
        if t not in known:
            raise InputError(f"--tray {t!r}: no such tray in {args.scene}", field="tray")
    pool = PlannerPool(data_dir(args.data_dir))
    try:
        planner = pool.region_planner(scene, Path(args.scene).resolve().parent, args.db)
        if not args.tray:  # every task tray: use all cores
            planner.regions(scene, workers=os.cpu_count() or 1)
        regions = [planner.tray_region(scene, t, y) for t in trays for y in scene.base_yaw.yaws]
    finally:
        pool.close()
    doc = regions_geojson(regions, {t.id: t.name for t in scene.trays})
    if args.out:
        Path(args.out).write_text(json.dumps(doc, indent=1) + "\n")
    emit(
        {
            "scene": scene.name,
            "database": planner.db.id,
            "out": args.out,
            "regions": [f["properties"] for f in doc["features"]],
        }
    )
    return 0


def _plan_one(pool: Any, path: Path, args: argparse.Namespace, options: Any) -> Any:
    from pickstop.scene.load import load_scene

    scene = _with_robot(load_scene(path), getattr(args, "robot", None))
    slot = pool.scene_slot(scene, path.resolve().parent, args.db)
    slot.regions.workers = args.workers
    return slot.planner.plan(scene, options)


def _plan_row(plan: Any) -> dict[str, Any]:
    t = plan.totals
    return {
        "trays": len(plan.trays),
        "stops": t.stops,
        "naive_stops": len(plan.naive.stops),
        "length_m": round(t.route_length, 2),
        "time_s": round(t.time.total, 1),
        "expected_s": "-" if t.time.expected is None else round(t.time.expected, 1),
        "naive_time_s": round(plan.naive.time.total, 1),
        "saving": f"{plan.naive.saving_fraction:.1%}",
        "success": "-" if t.success is None else f"{t.success:.1%}",
        "seconds": round(plan.timings.total, 2),
    }


def cmd_plan(args: argparse.Namespace) -> int:
    options = plan_options(args)
    src = Path(args.scene)
    if args.orders is not None:
        return _plan_mix(src, args, options)
    if src.is_dir():
        return _plan_batch(src, args, options)
    pool = planner_pool(args)
    try:
        plan = _plan_one(pool, src, args, options)
    finally:
        pool.close()
    doc = plan.model_dump(mode="json")
    if args.out:
        out = Path(args.out)
        if out.is_dir():
            raise InputError(f"--out {out}: is a folder; give a file for one scene", field="out")
        write_json(out, doc)
        emit({"scene": plan.scene, "out": str(out), **_plan_row(plan)})
    else:
        emit(doc)
    return 0


def _plan_mix(src: Path, args: argparse.Namespace, options: Any) -> int:
    """Every order of a mix on the scene's layout (``--orders``: the scene's, or a file's):
    one plan per order and the mix document in ``--out`` (a folder), the mix on stdout.
    Exit 3 if an order has no plan."""
    from pickstop.scene.load import load_scene
    from pickstop.scene.orders import load_orders, scene_orders
    from pickstop.sequence.mix import mix_document, plan_mix

    if src.is_dir():
        raise InputError(f"--orders: {src} is a folder; give one scene file", field="orders")
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: must be a folder for the orders' plans", field="out")
    scene = load_scene(src)
    orders = scene_orders(scene) if args.orders is True else load_orders(args.orders, scene)
    pool = planner_pool(args)
    try:
        slot = pool.scene_slot(scene, src.resolve().parent, args.db)
        slot.regions.workers = args.workers
        mix = plan_mix(slot.planner, scene, orders, options)
    finally:
        pool.close()
    refs: list[str | None] = [None] * len(mix.orders)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        for k, op in enumerate(mix.orders):
            if op.plan is not None:
                ref = refs[k] = f"{op.order.id}.plan.json"
                write_json(out / ref, op.plan.model_dump(mode="json"))
    doc = mix_document(mix, refs).model_dump(mode="json")
    if out is not None:
        write_json(out / "mix.json", doc)
    emit(doc)
    failed = [op for op in mix.orders if op.plan is None]
    for op in failed:
        print(f"pickstop: order {op.order.id}: {op.error}", file=sys.stderr)
    return 3 if failed else 0


def _plan_batch(folder: Path, args: argparse.Namespace, options: Any) -> int:
    """Plan every scene file of ``folder``; a summary table on stdout, plans in --out."""
    scenes = sorted(p for p in folder.glob("*.json") if not p.name.endswith(".plan.json"))
    if not scenes:
        raise InputError(f"{folder}: no scene files (*.json) in this folder", field="scene")
    out = Path(args.out) if args.out else None
    if out is not None:
        if out.exists() and not out.is_dir():
            raise InputError(f"--out {out}: must be a folder when planning a folder", field="out")
        out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    codes: set[int] = set()
    if args.dask:
        return _plan_batch_dask(scenes, args, options, out)
    pool = planner_pool(args)
    try:
        for path in scenes:
            t0 = time.perf_counter()
            try:
                plan = _plan_one(pool, path, args, options)
            except PickStopError as e:
                codes.add(e.exit_code)
                rows.append({"scene": path.name, "status": "error", "error": e.message,
                             "seconds": round(time.perf_counter() - t0, 2)})  # fmt: skip
                continue
            if out is not None:
                write_json(out / f"{path.stem}.plan.json", plan.model_dump(mode="json"))
            rows.append({"scene": path.name, "status": "ok", **_plan_row(plan)})
    finally:
        pool.close()
    if args.json:
        emit(rows)
    else:
        _print_table(rows)
    return _batch_exit(codes)


def _batch_exit(codes: set[int]) -> int:
    """A folder's exit code: 2 if any scene is invalid, else 5 if a robot has no database,
    else 3 if any is infeasible, else 1 for other failures (0: every scene planned)."""
    return next((c for c in (2, 5, 3) if c in codes), 1 if codes else 0)


def _plan_batch_dask(
    scenes: list[Path], args: argparse.Namespace, options: Any, out: Path | None
) -> int:
    """The folder's scenes as Dask tasks; the same table and files as the local batch."""
    from pickstop.distributed import client_for, plan_batch
    from pickstop.sequence.plan_model import Plan
    from pickstop.settings import data_dir

    rows: list[dict[str, Any] | None] = [None] * len(scenes)
    codes: set[int] = set()
    items = []
    for k, path in enumerate(scenes):
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as e:
            codes.add(2)
            rows[k] = {"scene": path.name, "status": "error", "error": f"not valid JSON: {e}"}
            continue
        if args.robot is not None and isinstance(doc, dict):
            doc["robot"] = _robot_ref(args.robot)
        items.append((k, path, doc))
    client = client_for(args.dask)
    try:
        work = [(p.name, doc, p.resolve().parent) for _, p, doc in items]
        for j, res in plan_batch(client, work, options.model_dump(), data_dir(args.data_dir),
                                 args.db):  # fmt: skip
            k, path, _ = items[j]
            if "error" in res:
                codes.add(int(res["exit_code"]))
                rows[k] = {"scene": path.name, "status": "error", "error": res["error"]}
                continue
            if out is not None:
                write_json(out / f"{path.stem}.plan.json", res)
            rows[k] = {"scene": path.name, "status": "ok", **_plan_row(Plan.model_validate(res))}
    finally:
        client.close()
    done = [r for r in rows if r is not None]
    if args.json:
        emit(done)
    else:
        _print_table(done)
    return _batch_exit(codes)


def _print_table(rows: list[dict[str, Any]]) -> None:
    cols = ["scene", "status", "trays", "stops", "naive_stops", "length_m", "time_s",
            "expected_s", "naive_time_s", "saving", "success", "seconds"]  # fmt: skip
    cells = [[str(r.get(c, "")) for c in cols] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths, strict=True)))
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths, strict=True)))
    errors = [r for r in rows if r["status"] == "error"]
    for r in errors:
        print(f"{r['scene']}: {r['error']}")
    print(f"{len(rows) - len(errors)} of {len(rows)} scenes planned")


def add_parser(sub: Any) -> None:
    """Add the regions and the plan commands to ``sub``."""
    rg = sub.add_parser("regions", help="base regions of a scene's trays, as GeoJSON")
    rg.add_argument("scene", help="scene JSON file")
    rg.add_argument("--out", help="write the GeoJSON FeatureCollection here")
    rg.add_argument("--tray", action="append", help="only this tray (repeatable)")
    rg.add_argument("--db", help="reachability database id (default: newest for the robot)")
    rg.add_argument("--robot", help=_ROBOT_HELP)
    rg.set_defaults(func=cmd_regions)
    _add_plan(sub)


def _add_plan(sub: Any) -> None:
    pl = sub.add_parser("plan", help="plan stops and route for a scene (or a folder of scenes)")
    pl.add_argument("scene", help="scene JSON file, or a folder: plan every *.json in it")
    pl.add_argument(
        "--sigma", type=finite_float, help="base positioning error [m] (default: the scene's)"
    )
    pl.add_argument("--rule", choices=["sigma", "success"], help="candidate rule (default: sigma)")
    pl.add_argument("--target", type=finite_float, help="success rate per stop for --rule success")
    pl.add_argument(
        "--objective",
        choices=["stops", "time", "expected-time"],
        help="default: stops, then route; time: least predicted time; expected-time: least "
        "expected time, failed arrivals included (the scene's failure model)",
    )
    pl.add_argument(
        "--placement",
        choices=["centre", "success"],
        help="default centre: each stop at its intersection's inscribed circle's centre; "
        "success: where its success estimate is highest (the centre's figures reported too)",
    )
    pl.add_argument(
        "--samples", type=int, help="Monte Carlo samples per stop (default 1000; 0: none)"
    )
    pl.add_argument("--seed", type=int, help="Monte Carlo seed")
    pl.add_argument("--time-limit", type=finite_float, help="stop selection time limit [s]")
    pl.add_argument("--out", help="write the plan here (a folder when planning a folder)")
    pl.add_argument(
        "--orders",
        nargs="?",
        const=True,
        metavar="FILE",
        help="plan every order of a product mix on the scene's layout: the scene's orders, or "
        "a JSON list of {id, trays | parts, weight} in FILE; --out: a folder for one plan per "
        "order and mix.json",
    )
    pl.add_argument("--json", action="store_true", help="folder: the summary as JSON, not a table")
    pl.add_argument("--db", help="reachability database id (default: the largest for the robot)")
    pl.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1)
    pl.add_argument("--dask", help="folder: one Dask task per scene ('local' or tcp://host:8786)")
    pl.add_argument("--robot", help=_ROBOT_HELP)
    pl.set_defaults(func=cmd_plan)
