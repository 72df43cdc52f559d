"""The ``pickstop`` command. Errors print one line on stderr and exit non-zero (2: bad input)."""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.argtypes import finite_float, positive_int, unit_fraction
from pickstop.errors import CorruptShardError, InputError, PickStopError
from pickstop.robot.floor import FLOOR_CLEARANCE

DEFAULT_SAMPLES = 2_000_000
STRICT_EXIT = 6  # robot check --strict: the check warns
_ROBOT_HELP = (
    "plan with this robot instead of the scene's: a preset name or a robot config file "
    "(YAML or JSON, relative to the working folder)"
)


def _emit(obj: Any) -> None:
    json.dump(obj, sys.stdout, indent=2, default=_json_default)
    sys.stdout.write("\n")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.integer | np.floating):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)


class _Progress:
    """tqdm bar over samples, with rate and ETA, on stderr."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.bar: Any = None
        self.closed = False

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or self.closed:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total,
                initial=done,
                unit="sample",
                unit_scale=True,
                file=sys.stderr,
                desc="reach build",
                smoothing=0.1,
            )
        else:
            self.bar.update(done - self.bar.n)
        if done >= total:  # what follows (indexing) draws its own line
            self.close()

    def close(self) -> None:
        if self.bar is not None and not self.closed:
            self.bar.close()
            self.closed = True


def _db_summary(row: dict[str, Any]) -> dict[str, Any]:
    keep = [
        "id",
        "robot",
        "robot_hash",
        "state",
        "samples",
        "stored",
        "resolution",
        "orientation",
        "seed",
        "chunk_size",
        "thinning",
        "floor_clearance",
        "code_version",
        "created",
        "completed",
        "build_seconds",
        "rejected_self_collision",
        "rejected_thinning",
        "rejected_floor",
        "screen_false_rejection",
        "screen_flagged",
        "screen_samples",
        "voxels",
        "index_seconds",
    ]
    out = {k: row.get(k) for k in keep}
    if row.get("screen_false_rejection") is not None:
        from pickstop.robot.artifacts import FALSE_REJECTION_BOUND

        out["screen_bound"] = FALSE_REJECTION_BOUND
        out["screen_meets_bound"] = row["screen_false_rejection"] <= FALSE_REJECTION_BOUND
    if row.get("samples") and row.get("state") == "complete":
        out["stored_fraction"] = round((row.get("stored") or 0) / row["samples"], 4)
    shards = row.get("shards")
    if shards is not None:
        out["shards"] = len(shards)
        out["bytes"] = sum(s["bytes"] for s in shards)
    index = row.get("index")
    if index is not None:
        from pickstop.store.reach_index import INDEX_FORMAT

        # Opened only once indexed: a database built before indices says so here.
        out["indexed"] = bool(index) and row.get("index_format") == INDEX_FORMAT
        out["index_bytes"] = sum(f["bytes"] for f in index)
    return out


def cmd_reach_build(args: argparse.Namespace) -> int:
    from pickstop.progress import StepLines
    from pickstop.reach.build import BuildParams
    from pickstop.robot.model import load
    from pickstop.settings import data_dir
    from pickstop.store.reach_build import build
    from pickstop.store.reach_catalog import list_databases

    params = BuildParams(
        samples=args.samples,
        resolution=args.resolution,
        orientation=args.orientation,
        seed=args.seed,
        chunk_size=args.chunk_size,
        thinning=args.thinning,
        floor_clearance=args.floor_clearance,
    )
    params.validate()
    robot = load(args.robot)
    folder = data_dir(args.data_dir)
    bar = _Progress(not args.quiet)
    steps = None if args.quiet else StepLines("reach build")
    t0 = time.perf_counter()
    client = None
    runner = None
    if args.dask:
        from pickstop.distributed import client_for, dask_runner

        client = client_for(args.dask)
        runner = dask_runner(client)
    try:
        row = build(robot, params, folder, workers=args.workers, progress=bar, runner=runner,
                    steps=steps)  # fmt: skip
    finally:
        bar.close()
        if steps is not None:
            steps.close()
        if client is not None:
            client.close()
    elapsed = time.perf_counter() - t0
    info = next(r for r in list_databases(folder) if r["id"] == row["id"])
    out = _db_summary(info)
    out["seconds_this_run"] = round(elapsed, 2)
    if not args.quiet and info.get("screen_false_rejection") is not None:
        print(
            f"self-collision screen: drops {100 * info['screen_false_rejection']:.1f}% of valid "
            f"configurations, flags {100 * info['screen_flagged']:.1f}% "
            f"({info['screen_samples']:,} random configurations checked exactly with coal)",
            file=sys.stderr,
        )
    if out.get("screen_meets_bound") is False:  # said even with --quiet
        from pickstop.robot.artifacts import bound_missed

        missed = bound_missed({"false_rejection": info["screen_false_rejection"]})
        print(f"pickstop: warning: {missed}", file=sys.stderr)
    _emit(out)
    return 0


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
        _emit(report)
    else:
        print(format_report(report))
    for warning in report["warnings"]:
        print(f"pickstop: warning: {warning}", file=sys.stderr)
    return STRICT_EXIT if args.strict and report["warnings"] else 0


def cmd_reach_info(args: argparse.Namespace) -> int:
    from pickstop.settings import data_dir
    from pickstop.store.reach_catalog import list_databases

    rows = list_databases(data_dir(args.data_dir), args.robot)
    if args.id:
        rows = [r for r in rows if r["id"].startswith(args.id)]
        if not rows:
            raise PickStopError(f"no reachability database with id {args.id!r}")
    _emit([r if args.shards else _db_summary(r) for r in rows])
    return 0


def cmd_reach_verify(args: argparse.Namespace) -> int:
    from pickstop.settings import data_dir
    from pickstop.store.reach_catalog import verify_databases

    reports = verify_databases(data_dir(args.data_dir), args.id)
    _emit(reports)
    bad = [f["path"] for r in reports for f in r["files"] if not f["ok"]]
    if bad:
        from pickstop.store.reach_catalog import folder_flag

        flag = folder_flag(data_dir(args.data_dir))
        info = ["pickstop", *(["--data-dir", str(flag)] if flag else []), "reach", "info", "--id"]
        ids = [r["id"] for r in reports if not r["ok"]]
        print(
            f"pickstop: error: {len(bad)} file(s) failed verification ({', '.join(bad)}); "
            "the `pickstop reach build` command of each database repairs it: "
            + "; ".join(f"`{shlex.join([*info, i])}` shows its parameters" for i in ids),
            file=sys.stderr,
        )
        return CorruptShardError.exit_code
    return 0


def cmd_reach_query(args: argparse.Namespace) -> int:
    from pickstop.reach.database import check_poses
    from pickstop.robot.model import load
    from pickstop.settings import data_dir
    from pickstop.store.reach_catalog import open_database

    x, y, z, qw, qx, qy, qz = args.pose
    ps, qs = check_poses([[x, y, z]], [[qw, qx, qy, qz]])
    robot = load(args.robot)
    db = open_database(data_dir(args.data_dir), robot, args.id)
    t0 = time.perf_counter()
    cands = db.query(ps[0], qs[0], neighbours=args.neighbours)
    query_ms = (time.perf_counter() - t0) * 1e3
    cells, orient = db.voxel.decode(np.array([db.voxel.key_one(tuple(ps[0]), tuple(qs[0]))]))
    out: dict[str, Any] = {
        "database": db.id,
        "robot": robot.name,
        "pose": {"position": ps[0], "quaternion_wxyz": qs[0]},
        "voxel": {
            "key": int(db.voxel.key_one(tuple(ps[0]), tuple(qs[0]))),
            "position_cell": cells[0],
            "orientation_cell": int(orient[0]),
            "resolution_m": db.voxel.resolution,
            "orientation_cell_deg": float(np.degrees(db.voxel.so3.cell_angle)),
        },
        "neighbours": args.neighbours,
        "query_ms": round(query_ms, 3),
        "count": len(cands.rows),
        "joints": [j.name for j in robot.joints],
        "candidates": [
            {
                "theta": t,
                "pos_err_m": round(float(pe), 5),
                "rot_err_deg": round(float(np.degrees(re)), 3),
            }
            for t, pe, re in zip(
                cands.thetas[: args.limit], cands.pos_err, cands.rot_err, strict=False
            )
        ],
    }
    if args.refine:
        from pickstop.reach.ik import refine_many
        from pickstop.reach.so3 import quats_to_matrices

        R = quats_to_matrices(qs[0])
        if len(cands.rows):
            res = refine_many(robot, cands.thetas[: args.refine_seeds], R, ps[0])
            out["refined"] = {
                "success": res.success,
                "theta": res.theta,
                "pos_err_m": res.pos_err,
                "rot_err_deg": float(np.degrees(res.rot_err)),
                "iterations": res.iterations,
                "reason": res.reason,
            }
        else:
            out["refined"] = {"success": False, "reason": "no candidates in the voxel"}
    _emit(out)
    return 0


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
    _emit(
        {
            "scene": scene.name,
            "database": planner.db.id,
            "out": args.out,
            "regions": [f["properties"] for f in doc["features"]],
        }
    )
    return 0


def _plan_options(args: argparse.Namespace) -> Any:
    from pydantic import ValidationError

    from pickstop.sequence.plan_model import PlanOptions

    fields = {
        "sigma": args.sigma,
        "rule": args.rule,
        "target": args.target,
        "objective": args.objective,
        "placement": getattr(args, "placement", None),
        "samples": args.samples,
        "seed": args.seed,
        "time_limit": args.time_limit,
    }
    try:
        return PlanOptions(**{k: v for k, v in fields.items() if v is not None})
    except ValidationError as e:
        err = e.errors()[0]
        name = str(err["loc"][0]).replace("_", "-")
        raise InputError(f"--{name}: {err['msg']}", field=name) from None


def _pool(args: argparse.Namespace) -> Any:
    """The planner pool of this command (scenes of one robot share its planners)."""
    from pickstop.pool import PlannerPool
    from pickstop.settings import data_dir

    return PlannerPool(data_dir(args.data_dir))


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
    options = _plan_options(args)
    src = Path(args.scene)
    if args.orders is not None:
        return _plan_mix(src, args, options)
    if src.is_dir():
        return _plan_batch(src, args, options)
    pool = _pool(args)
    try:
        plan = _plan_one(pool, src, args, options)
    finally:
        pool.close()
    doc = plan.model_dump(mode="json")
    if args.out:
        out = Path(args.out)
        if out.is_dir():
            raise InputError(f"--out {out}: is a folder; give a file for one scene", field="out")
        _write_json(out, doc)
        _emit({"scene": plan.scene, "out": str(out), **_plan_row(plan)})
    else:
        _emit(doc)
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
    pool = _pool(args)
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
                refs[k] = f"{op.order.id}.plan.json"
                _write_json(out / refs[k], op.plan.model_dump(mode="json"))
    doc = mix_document(mix, refs).model_dump(mode="json")
    if out is not None:
        _write_json(out / "mix.json", doc)
    _emit(doc)
    failed = [op for op in mix.orders if op.plan is None]
    for op in failed:
        print(f"pickstop: order {op.order.id}: {op.error}", file=sys.stderr)
    return 3 if failed else 0


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

    options, settings = _plan_options(args), _layout_settings(args)
    src = Path(args.scene)
    scene = load_scene(src)
    orders = _mix_orders(scene, args.orders)
    movable = args.movable.split(",") if args.movable else mix_trays(scene, orders)
    check_request(scene, orders, movable)
    pool = _pool(args)
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
        _write_json(Path(args.out), out)
        _emit(_layout_summary(out) | {"out": args.out})
    else:
        _emit(out)
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


def _write_json(path: Path, doc: Any) -> None:
    """Write atomically: a reader never sees half a file, a failure leaves the old one."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=1, default=_json_default) + "\n")
    tmp.replace(path)


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
    pool = _pool(args)
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
                _write_json(out / f"{path.stem}.plan.json", plan.model_dump(mode="json"))
            rows.append({"scene": path.name, "status": "ok", **_plan_row(plan)})
    finally:
        pool.close()
    if args.json:
        _emit(rows)
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
                _write_json(out / f"{path.stem}.plan.json", res)
            rows[k] = {"scene": path.name, "status": "ok", **_plan_row(Plan.model_validate(res))}
    finally:
        client.close()
    done = [r for r in rows if r is not None]
    if args.json:
        _emit(done)
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


def cmd_serve(args: argparse.Namespace) -> int:
    """The REST API under uvicorn and, unless --no-ui, the 3D planner beside it."""
    from pickstop import stack
    from pickstop.settings import Settings

    overrides: dict[str, Any] = {}
    if args.data_dir:
        overrides["data_dir"] = Path(args.data_dir)
    for name in ("host", "port", "ui_port", "workers"):
        if getattr(args, name) is not None:
            overrides[name] = getattr(args, name)
    settings = Settings(**overrides)
    if not settings.api_keys:
        print("pickstop: no API keys configured (PICKSTOP_API_KEYS): the API refuses writes; "
              "make one with `pickstop api-key`", file=sys.stderr)  # fmt: skip
    if args.scene_file:
        from pickstop.scene.load import load_scene

        load_scene(args.scene_file)  # a bad file fails here, naming its field
    run = stack.start(
        settings,
        ui=not args.no_ui,
        scene_id=args.scene,
        scene_file=Path(args.scene_file) if args.scene_file else None,
        log_level=args.log_level,
    )
    print(f"PickStop API on {run.api_url}/api/v1 (docs: {run.api_url}/api/v1/docs)",
          file=sys.stderr, flush=True)  # fmt: skip
    if run.ui_url:
        print(f"PickStop 3D planner on {run.ui_url} (scene {run.scene_id})", file=sys.stderr,
              flush=True)  # fmt: skip
    run.wait()
    return 0


def cmd_ui(args: argparse.Namespace) -> int:
    """The 3D planner, a client of a running API."""
    from pickstop_ui.app import run
    from pickstop_ui.client import ApiProblem, PickStopClient

    key = args.key or os.environ.get("PICKSTOP_UI_KEY")
    scene_id = args.scene
    if args.scene_file:
        from pickstop.scene.load import load_scene

        load_scene(args.scene_file)  # a bad file fails here, with its field
        doc = json.loads(Path(args.scene_file).read_text(encoding="utf-8"))
        try:
            client = PickStopClient(args.api, key)
            if args.robot is not None:
                doc["robot"] = {"preset": _api_robot(client, args.robot)}
            scene_id = client.create_scene(doc).id
        except ApiProblem as e:
            raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    elif scene_id and args.robot is not None:  # a copy of the stored scene with that robot
        try:
            client = PickStopClient(args.api, key)
            doc = {
                **client.scene(scene_id).doc,
                "robot": {"preset": _api_robot(client, args.robot)},
            }
            scene_id = client.create_scene(doc).id
        except ApiProblem as e:
            raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    if not scene_id:
        raise InputError("give --scene SCENE_ID or --scene-file FILE", field="scene")
    try:
        app = run(args.api, scene_id, key, args.host, args.port, args.lighting == "flat",
                  args.draft_scale)  # fmt: skip
    except ApiProblem as e:
        raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    print(f"PickStop 3D planner on http://{args.host}:{app.port}/ (scene {scene_id})",
          file=sys.stderr, flush=True)  # fmt: skip
    try:
        while True:
            time.sleep(3600)
    finally:
        app.close()


def _api_robot(client: Any, robot: str) -> str:
    """The name the API knows the robot ``--robot`` names by: a preset or a registered
    robot's name as it is; a config file is registered first under its ``name`` (the API
    accepts it when its files lie in the API's ``<data>/robots/`` folder)."""
    from pickstop.robot.config import load_config, preset_names
    from pickstop_ui.client import API, ApiProblem

    path = Path(robot)
    if robot in preset_names() or not path.is_file():
        return robot  # a name: the API refuses one it does not know, listing those it does
    config, _ = load_config(path)  # a bad config fails here, naming its field
    r = client.http.get(f"{API}/robots")
    if r.status_code < 400 and config.name in {x.get("name") for x in r.json()}:
        return config.name
    yaml = path.suffix.lower() in {".yaml", ".yml"}
    r = client.http.post(
        f"{API}/robots",
        content=path.read_bytes(),
        headers={"Content-Type": "application/yaml" if yaml else "application/json"},
    )
    if r.status_code >= 400:
        body = r.json() if r.headers.get("content-type", "").endswith("json") else {}
        raise ApiProblem(r.status_code, body.get("title", "Error"), body.get("detail", r.text))
    return config.name


def cmd_api_key(args: argparse.Namespace) -> int:
    """A new random API key and the hash to configure (the service stores only hashes)."""
    import secrets

    from pickstop.settings import hash_key

    key = secrets.token_urlsafe(32)
    _emit({"key": key, "hash": hash_key(key),
           "configure": f"PICKSTOP_API_KEYS='[\"{hash_key(key)}\"]'"})  # fmt: skip
    return 0


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
    bar = _Progress(True)
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pickstop", description="Plan where a mobile manipulator stops to pick every part."
    )
    parser.add_argument(
        "--data-dir", help="data folder (default: $PICKSTOP_DATA_DIR or database/data)"
    )
    sub = parser.add_subparsers(dest="command", required=True)

    _add_demo_and_regions(sub)
    _add_plan(sub)
    _add_layout(sub)
    _add_service(sub)
    _add_robot(sub)
    _add_reach(sub)

    from pickstop.fleet.cli import add_commands as add_fleet_commands

    add_fleet_commands(sub)
    return parser


def _add_demo_and_regions(sub: Any) -> None:
    """Add the demo and the regions commands to ``sub``."""
    demo = sub.add_parser("demo", help="the embedded default: bundled TIAGo and example scene")
    demo.add_argument("--samples", type=positive_int, default=DEFAULT_SAMPLES)
    demo.add_argument("--port", type=positive_int, help="API port (default 8000, or a free one)")
    demo.add_argument("--ui-port", type=positive_int, default=8080, help="3D planner port")
    demo.set_defaults(func=cmd_demo)

    rg = sub.add_parser("regions", help="base regions of a scene's trays, as GeoJSON")
    rg.add_argument("scene", help="scene JSON file")
    rg.add_argument("--out", help="write the GeoJSON FeatureCollection here")
    rg.add_argument("--tray", action="append", help="only this tray (repeatable)")
    rg.add_argument("--db", help="reachability database id (default: newest for the robot)")
    rg.add_argument("--robot", help=_ROBOT_HELP)
    rg.set_defaults(func=cmd_regions)


def _add_plan(sub: Any) -> None:
    """Add the plan command to ``sub``."""
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


def _add_layout(sub: Any) -> None:
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


def _add_service(sub: Any) -> None:
    """Add the serve, ui and api-key commands to ``sub``."""
    sv = sub.add_parser("serve", help="run the REST API (uvicorn)")
    sv.add_argument("--host", help="listen address (default: $PICKSTOP_HOST or 127.0.0.1)")
    sv.add_argument("--port", type=positive_int, help="port (default: $PICKSTOP_PORT or 8000)")
    sv.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    sv.add_argument("--ui-port", type=positive_int, help="3D planner port (default 8080)")
    sv.add_argument("--no-ui", action="store_true", help="the API alone")
    sv.add_argument("--workers", type=positive_int,
                    help="API processes on the port (default: $PICKSTOP_WORKERS or 1)")  # fmt: skip
    sv.add_argument("--scene", help="scene the planner opens (default: the first stored one)")
    sv.add_argument("--scene-file", help="or a scene file, stored first")
    sv.set_defaults(func=cmd_serve)

    ui = sub.add_parser("ui", help="run the 3D planner against a running API")
    ui.add_argument("--api", default="http://127.0.0.1:8000", help="the API's base URL")
    ui.add_argument("--scene", help="id of a stored scene")
    ui.add_argument("--scene-file", help="or a scene file: stored through the API first")
    ui.add_argument("--key", help="API key for saving (default: $PICKSTOP_UI_KEY)")
    ui.add_argument("--host", default="127.0.0.1")
    ui.add_argument("--port", type=positive_int, default=8080)
    ui.add_argument(
        "--lighting",
        choices=("flat", "environment"),
        default="flat",
        help="flat: one hemisphere light (default; about twice the frame rate of the other in "
        "a browser without a GPU); environment: an environment map, shinier colours",
    )
    ui.add_argument(  # the default since --lighting; kept for scripts that still pass it
        "--flat-lighting", dest="lighting", action="store_const", const="flat",
        help=argparse.SUPPRESS,
    )  # fmt: skip
    ui.add_argument(
        "--draft-scale",
        type=unit_fraction,
        help="pixel ratio, as a fraction of the device's, at which a browser without a GPU "
        "draws the previews that follow a drag (default 0.35, about an eighth of the pixels; "
        "1: full resolution throughout)",
    )
    ui.add_argument(
        "--robot",
        help="plan with this robot instead of the scene's: a preset, a robot the API has "
        "registered, or a config file (registered with the API first; its files must lie in "
        "the API's <data>/robots/ folder); with --scene, a copy of the scene is stored",
    )
    ui.set_defaults(func=cmd_ui)

    ak = sub.add_parser("api-key", help="make a new API key and print its hash for the settings")
    ak.set_defaults(func=cmd_api_key)


def _add_robot(sub: Any) -> None:
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


def _add_reach(sub: Any) -> None:
    """Add the reach commands to ``sub``."""
    reach = sub.add_parser("reach", help="reachability databases").add_subparsers(
        dest="reach_command", required=True
    )
    b = reach.add_parser("build", help="build (or resume) a reachability database")
    b.add_argument("--robot", default="tiago", help="preset name or robot config file")
    b.add_argument("--samples", type=positive_int, default=DEFAULT_SAMPLES)
    b.add_argument("--resolution", type=finite_float, default=0.05, help="position voxel [m]")
    b.add_argument("--orientation", type=positive_int, default=6, help="SO(3) cells per face edge")
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--chunk-size", type=positive_int, default=250_000)
    b.add_argument(
        "--thinning",
        type=finite_float,
        default=0.0,
        help="manipulability reference w_ref: keep prob. min(1, w/w_ref); 0 = off",
    )
    b.add_argument(
        "--floor-clearance",
        type=finite_float,
        default=FLOOR_CLEARANCE,
        help="drop configurations with a moving link this close to the floor or below [m]",
    )
    b.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1)
    b.add_argument("--quiet", action="store_true", help="no progress bar")
    b.add_argument("--dask", help="run chunks on Dask: 'local' or a scheduler tcp://host:8786")
    b.set_defaults(func=cmd_reach_build)

    i = reach.add_parser("info", help="list databases as JSON")
    i.add_argument("--robot", help="only this robot's")
    i.add_argument("--id", help="only this database (id or prefix)")
    i.add_argument("--shards", action="store_true", help="include every shard")
    i.set_defaults(func=cmd_reach_info)

    v = reach.add_parser(
        "verify", help="check every file of the databases against its checksum (JSON report)"
    )
    v.add_argument("--id", help="only this database (id or prefix)")
    v.set_defaults(func=cmd_reach_verify)

    q = reach.add_parser("query", help="approximate IK solutions of a tool pose, as JSON")
    q.add_argument("--robot", default="tiago")
    q.add_argument("--id", help="database id (default: newest complete one for the robot)")
    q.add_argument(
        "--pose",
        nargs=7,
        type=finite_float,
        required=True,
        metavar=("X", "Y", "Z", "QW", "QX", "QY", "QZ"),
        help="T_base_tool: position [m] and unit quaternion wxyz",
    )
    q.add_argument("--neighbours", action="store_true", help="include adjacent voxels")
    q.add_argument("--limit", type=positive_int, default=10, help="candidates to print")
    q.add_argument("--refine", action="store_true", help="refine to an exact IK solution")
    q.add_argument("--refine-seeds", type=positive_int, default=20)
    q.set_defaults(func=cmd_reach_query)


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


if __name__ == "__main__":
    sys.exit(main())
