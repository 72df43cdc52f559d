"""``pickstop reach``: build, list, verify and query reachability databases."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from typing import Any

import numpy as np

from pickstop.argtypes import finite_float, positive_int
from pickstop.cli.common import Progress, emit
from pickstop.errors import CorruptShardError, PickStopError
from pickstop.robot.floor import FLOOR_CLEARANCE

DEFAULT_SAMPLES = 2_000_000


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
    bar = Progress(not args.quiet)
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
    emit(out)
    return 0


def cmd_reach_info(args: argparse.Namespace) -> int:
    from pickstop.settings import data_dir
    from pickstop.store.reach_catalog import list_databases

    rows = list_databases(data_dir(args.data_dir), args.robot)
    if args.id:
        rows = [r for r in rows if r["id"].startswith(args.id)]
        if not rows:
            raise PickStopError(f"no reachability database with id {args.id!r}")
    emit([r if args.shards else _db_summary(r) for r in rows])
    return 0


def cmd_reach_verify(args: argparse.Namespace) -> int:
    from pickstop.settings import data_dir
    from pickstop.store.reach_catalog import verify_databases

    reports = verify_databases(data_dir(args.data_dir), args.id)
    emit(reports)
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
        out["refined"] = _refined(robot, cands, ps[0], qs[0], args.refine_seeds)
    emit(out)
    return 0


def _refined(robot: Any, cands: Any, p: Any, q: Any, seeds: int) -> dict[str, Any]:
    """The exact IK solution refined from the first ``seeds`` candidates of the tool pose
    ``p`` (3,) [m], ``q`` (4,) wxyz."""
    from pickstop.reach.ik import refine_many
    from pickstop.reach.so3 import quats_to_matrices

    R = quats_to_matrices(q)
    if not len(cands.rows):
        return {"success": False, "reason": "no candidates in the voxel"}
    res = refine_many(robot, cands.thetas[:seeds], R, p)
    return {
        "success": res.success,
        "theta": res.theta,
        "pos_err_m": res.pos_err,
        "rot_err_deg": float(np.degrees(res.rot_err)),
        "iterations": res.iterations,
        "reason": res.reason,
    }


def add_parser(sub: Any) -> None:
    """Add the reach commands to ``sub``."""
    reach = sub.add_parser("reach", help="reachability databases").add_subparsers(
        dest="reach_command", required=True
    )
    _add_build(reach)

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

    _add_query(reach)


def _add_build(reach: Any) -> None:
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


def _add_query(reach: Any) -> None:
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
