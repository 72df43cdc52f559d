"""The floor as an obstacle: what it removes at build, how tight its screen is, the rack cell.

    python benchmarks/bench_floor.py [--db ID] [--build SAMPLES] [--exact 3000] [--samples 1000]

Prints: the database's build figures (samples the floor removed next to self-collision, at
its clearance); the floor screen against the exact coal check on uniform random
configurations (false acceptances must be 0; false rejections are what the covers' 1 cm
excess costs) and both rates; the rack cell's region per tray (area, cells, seconds from
scratch, or why it is empty), the floor bin's at three clearances; and the rack cell's plan
(stops, inscribed radii, Monte Carlo success). ``--build N`` first builds (or resumes) an
N-sample TIAGo database in the data folder. Times are best of two on 2 shared cores.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from pickstop.pool import PlannerPool
from pickstop.reach.build import BuildParams
from pickstop.regions.arm import screen_arm
from pickstop.robot.floor import FLOOR_CLEARANCE, ExactFloor, FloorSpheres, below_floor
from pickstop.robot.kinematics import BLOCK, Chain, fk_soa
from pickstop.scene.load import parse_scene
from pickstop.scene.world import BoxArrays
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import PlanOptions
from pickstop.settings import data_dir
from pickstop.speedups.stop_planner import StopPlanner
from pickstop.store.reach_build import build
from pickstop.store.reach_catalog import list_databases

SCENES = Path(__file__).parents[1] / "examples" / "scenes"


def _database(folder: Path, db_id: str) -> None:
    row = next(d for d in list_databases(folder) if d["id"] == db_id)
    n = row["samples"]
    floor, own = row.get("rejected_floor"), row.get("rejected_self_collision") or 0
    print(f"database {db_id}: {n:,} samples, {row['stored']:,} stored ({row['stored'] / n:.1%})")
    if floor is None or row.get("floor_clearance") is None:
        print("  built before the floor filter (format 1): the floor is checked at query time")
        return
    print(
        f"  floor removed {floor:,} ({floor / n:.2%}) at clearance "
        f"{row['floor_clearance']:.3f} m; self-collision removed {own:,} ({own / n:.2%}) of "
        f"the rest; build {row['build_seconds']:.0f} s"
    )


def _screen_vs_exact(planner, n: int) -> None:
    robot = planner.robot
    th = np.random.default_rng(0).uniform(robot.lower, robot.upper, (n, robot.dof))
    frames = fk_soa(Chain.from_robot(robot), np.ascontiguousarray(th.T), frames=True)[2]
    spheres = FloorSpheres.of(robot)
    exact = ExactFloor(robot)
    print(f"\n== floor screen against coal on {n:,} uniform random configurations")
    for clearance in (0.0, FLOOR_CLEARANCE, 0.05):
        below = exact.colliding(th, clearance)
        build_flag = below_floor(spheres, frames, clearance)
        region_flag = screen_arm(
            planner.arm, BoxArrays.of([]), frames, np.zeros((n, 2)), 0.0, floor=clearance
        )
        for name, flag in (("build", build_flag), ("regions", region_flag)):
            free = ~below
            print(
                f"  clearance {clearance:.3f} m, {name:7s} screen: exact below {below.mean():.2%}, "
                f"flagged {flag.mean():.2%}, false rejection "
                f"{(flag & free).sum() / max(free.sum(), 1):.2%}, false acceptances "
                f"{int((below & ~flag).sum())}"
            )
    big = np.random.default_rng(1).uniform(robot.lower, robot.upper, (50_000, robot.dof))
    chain = Chain.from_robot(robot)
    blocks = [
        fk_soa(chain, np.ascontiguousarray(big[s : s + BLOCK].T), frames=True)[2]
        for s in range(0, len(big), BLOCK)
    ]
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for fr in blocks:
            below_floor(spheres, fr, FLOOR_CLEARANCE)
        best = min(best, time.perf_counter() - t0)
    t0 = time.perf_counter()
    exact.colliding(th[:500], FLOOR_CLEARANCE)
    ex = (time.perf_counter() - t0) / 500
    print(f"  screen {len(big) / best:,.0f} configurations/s (FK apart); exact {1 / ex:,.0f}/s")


def _regions(planner, doc: dict) -> None:
    scene = parse_scene(doc)
    print(f"\n== rack cell regions (yaw {scene.base_yaw.yaws[0]:.3f} rad, from scratch)")
    for tray in scene.trays:
        best, region = np.inf, None
        for _ in range(2):
            planner.cache.clear()
            planner.grasp_memo.clear()
            t0 = time.perf_counter()
            region = planner.tray_region(scene, tray.id)
            best = min(best, time.perf_counter() - t0)
        assert region is not None
        tilt = f", tilted {np.degrees(tray.tilt.angle):.0f} deg" if tray.tilt else ""
        what = f"area {region.area:.3f} m^2 ({len(region.cells)} cells)"
        print(f"  {tray.id:11s} z {tray.pose.z:.3f} m{tilt:18s} {what:28s} {best:5.2f} s")
        if region.reason:
            print(f"  {'':11s} {region.reason}")
    print("  floor bin by clearance:")
    for clearance in (0.0, 0.01, 0.03):
        d = json.loads(json.dumps(doc))
        d["floor_clearance"] = clearance
        r = planner.tray_region(parse_scene(d), "floor_bin")
        why = f"; {r.reason}" if r.reason else ""
        print(f"    {clearance:.3f} m: area {r.area:.3f} m^2{why}")


def _plan(planner, doc: dict, samples: int) -> None:
    scene = parse_scene(doc)
    planner.forget()
    sp = StopPlanner(planner)
    t0 = time.perf_counter()
    try:
        plan = sp.plan(scene, PlanOptions(sigma=0.10, samples=samples))
    except InfeasiblePlanError as e:
        print(f"\n== rack cell plan: infeasible: {e.message}")
        return
    seconds = time.perf_counter() - t0
    t = plan.totals
    print(
        f"\n== rack cell plan at sigma 0.10 m ({samples} Monte Carlo samples per stop): "
        f"{t.stops} stops for {len(scene.task_trays)} trays (naive {len(plan.naive.stops)}), "
        f"time {t.time.total:.1f} s, route {t.route_length:.2f} m, plan success {t.success:.1%}, "
        f"{seconds:.1f} s to plan"
    )
    for s in plan.stops:
        rate = "-" if s.success is None else f"{s.success.rate:.1%}"
        print(
            f"  ({s.x:.2f}, {s.y:.2f}) {'+'.join(s.trays):36s} "
            f"inscribed {s.inscribed_radius:.3f} m, success {rate}"
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--build", type=int, help="build (or resume) this many samples first")
    ap.add_argument("--exact", type=int, default=3000, help="configurations checked by coal")
    ap.add_argument("--samples", type=int, default=1000, help="Monte Carlo samples per stop")
    args = ap.parse_args()
    folder = data_dir()
    doc = json.loads((SCENES / "rack_cell.json").read_text())
    db_id = args.db
    if args.build:
        from pickstop.robot.model import load

        row = build(load("tiago"), BuildParams(samples=args.build), folder)
        db_id = row["id"]
    planner = PlannerPool(folder).region_planner(parse_scene(doc), SCENES, db_id)
    _database(folder, planner.db.id)
    _screen_vs_exact(planner, args.exact)
    _regions(planner, doc)
    _plan(planner, doc, args.samples)


if __name__ == "__main__":
    main()
