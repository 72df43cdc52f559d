"""Base regions: production (IK by query) against the fixed-seed IK baseline and a dense
multi-start IK oracle, then the planner's everyday timings and peak memory.

    python benchmarks/bench_regions.py [--db ID] [--scenes paper_experiment five_trays]
        [--trays tray_1 tray_2] [--seeds 4 16 64 256] [--band 2] [--sample 200] [--no-oracle]

Per task tray: production, baseline and their area ratio; the oracle is run on every
production cell, every footprint-free cell within ``--band`` cells outside the production
region, and ``--sample`` random other footprint-free cells within reach. Precision: production
cells the oracle confirms (every production witness is also re-checked: numpy FK within 1 mm
and 0.5 deg, joint limits, coal). Recall: oracle-feasible evaluated cells production also has;
each missed cell is put down to the first part whose database lookup explains it.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import traceback
from collections import Counter
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from pickstop.frames import R_base_world
from pickstop.reach.batch_ik import refine_batch
from pickstop.reach.database import RANK_LENGTH
from pickstop.regions.arm import nearby, screen_arm
from pickstop.regions.cells import CellGrid
from pickstop.regions.reference import (
    ORACLE_SEEDS,
    baseline_region,
    comparison_cells,
    oracle_region,
    verify_witnesses,
)
from pickstop.regions.solve import MAX_ROUNDS, REFINE_ITERATIONS, WINDOW, Targets
from pickstop.robot.kinematics import fk_soa
from pickstop.robot.model import load
from pickstop.scene.load import load_scene, parse_scene
from pickstop.scene.model import Scene
from pickstop.scene.world import BoxArrays, scene_solids
from pickstop.settings import cache_dir, data_dir
from pickstop.speedups.region_planner import RegionPlanner
from pickstop.store.reach_catalog import open_database

SCENES = Path(__file__).resolve().parents[1] / "examples" / "scenes"


def _fresh(planner: RegionPlanner) -> None:
    """Forget cached regions and grasps, so the next call computes everything."""
    planner.forget()
    planner.grasp_memo.clear()


def _cells_of(mask: np.ndarray, cells: np.ndarray) -> np.ndarray:
    return mask[cells[:, 0], cells[:, 1]]


def explain_misses(
    planner: RegionPlanner, scene: Scene, tray_id: str, yaw: float, missed: np.ndarray
) -> Counter[str]:
    """Why production lacks ``missed: (N, 2)`` (iy, ix) cells, judged part by part on what
    its database lookup returns there: nothing, only candidates the sphere screen flags, free
    candidates ranked beyond its screening budget, or free candidates its refinement fails
    (with 100 iterations from the best of them as the tie-breaker)."""
    db, solver = planner.db, planner.solver
    tray = scene.tray(tray_id)
    grid = CellGrid.of(scene)
    cen = grid.centres(missed[:, 1], missed[:, 0])
    solids = nearby(scene_solids(scene), (tray.pose.x, tray.pose.y), 3 * planner.reach_xy)
    boxes = BoxArrays.of(solids)
    why: Counter[str] = Counter()
    budget = WINDOW * MAX_ROUNDS  # candidates production screens at most per (cell, part)
    refined = sum(min(1 << a, 4) for a in range(MAX_ROUNDS))  # and refines: 1, 2, 4, 4, ...
    for i in range(len(missed)):
        cause = "free candidates refine for every part: refined pose flagged or colliding"
        for gs in planner.grasps(scene, tray):
            tg = Targets.of(gs, cen[i : i + 1], R_base_world(yaw))
            R, p, q = tg.Rs_base_tool, tg.ps_base_tool, tg.qs_base_tool
            starts, ends = db.lookup(p[0], q)
            rows = np.concatenate([np.arange(s, e) for s, e in zip(starts, ends, strict=True)])
            g = np.repeat(np.arange(len(q)), ends - starts)
            if len(rows) == 0:
                near = sum(
                    len(db.query(p[0, j], q[j], neighbours=True).rows) for j in range(len(q))
                )
                cause = "every grasp's own voxel empty; " + (
                    "adjacent voxels hold candidates" if near else "adjacent voxels empty too"
                )
                break
            pos_err = np.linalg.norm(db.positions[rows] - p[0, g], axis=1)
            dot = np.abs(np.einsum("ij,ij->i", db.quats[rows], q[g]))
            order = np.argsort(pos_err + RANK_LENGTH * 2 * np.arccos(np.minimum(dot, 1.0)))
            rows, g = rows[order], g[order]
            th = db.thetas(rows)
            _, _, frames = fk_soa(solver.chain, np.ascontiguousarray(th.T), frames=True)
            free = np.flatnonzero(
                ~screen_arm(
                    planner.arm,
                    boxes,
                    frames,
                    np.repeat(cen[i : i + 1], len(rows), 0),
                    yaw,
                    floor=scene.floor_clearance,
                )
            )
            if len(free) == 0:
                cause = "every candidate flagged by the sphere screen"
                break
            if free[0] >= budget:
                cause = f"first free candidate ranked beyond the {budget} screened"
                break
            tried = free[free < budget][:refined]
            short = refine_batch(
                solver, th[tried], R[g[tried]], p[0, g[tried]], max_iter=REFINE_ITERATIONS
            )
            if not short.success.any():
                long = refine_batch(solver, th[tried], R[g[tried]], p[0, g[tried]], max_iter=100)
                cause = (
                    f"refinement converges only after more than {REFINE_ITERATIONS} iterations"
                    if long.success.any()
                    else f"refinement stalls from all (up to {refined}) free candidates, "
                    "even with 100 iterations"
                )
                break
        why[cause] += 1
    return why


def compare_tray(
    planner: RegionPlanner, scene: Scene, tray_id: str, args: argparse.Namespace
) -> None:
    _fresh(planner)
    prod = planner.tray_region(scene, tray_id)
    _fresh(planner)
    base = baseline_region(planner, scene, tray_id)
    tray = scene.tray(tray_id)
    grasps = "+".join(str(len(g.Ts_world_tool)) for g in planner.grasps(scene, tray))
    ratio = f"{prod.area / base.area:5.2f}" if base.area else "  n/a"
    print(
        f"{tray_id:<8} {len(tray.parts):>2} {grasps:>7} | {len(prod.cells):5d} {prod.area:6.3f} "
        f"{prod.seconds:5.2f} | {len(base.cells):5d} {base.area:6.3f} {base.seconds:5.2f} | {ratio}"
    )
    for name, r in (("production", prod), ("baseline", base)):
        if r.reason:
            print(f"    {name} empty: {r.reason}")
    check = verify_witnesses(planner, scene, prod)
    print(
        f"    production witnesses re-checked: {check.witnesses}, failures {check.failures} "
        f"(pose {check.pose_failures}, arm {check.arm_collisions}, self {check.self_collisions})"
    )
    if args.no_oracle:
        return
    cmp = comparison_cells(planner, scene, prod, width=args.band, sample=args.sample)
    orc = oracle_region(planner, scene, tray_id, seeds=args.seeds, cells=cmp.all)
    ev = cmp.all
    o, p_, b = (_cells_of(r.mask, ev) for r in (orc, prod, base))
    n_o, hit = int(o.sum()), int((o & p_).sum())
    precision = (o & p_).sum() / max(p_.sum(), 1)
    recall = hit / n_o if n_o else float("nan")
    in_sample = _cells_of(orc.mask, cmp.sample)
    print(
        f"    oracle on {len(ev)} cells ({len(cmp.region)} production + {len(cmp.band)} within "
        f"{args.band} outside + {len(cmp.sample)} sampled), seeds {','.join(map(str, args.seeds))}"
        f": {n_o} feasible, {orc.seconds:.1f} s, {orc.counts.get('ik_problems', 0)} IK solves"
    )
    print(
        f"    precision {precision:6.1%} ({int((o & p_).sum())}/{int(p_.sum())})   recall "
        f"{recall:6.1%} ({hit}/{n_o})   oracle-feasible in the sample: {int(in_sample.sum())}"
        f"   baseline cells the oracle lacks: {int((b & ~o).sum())}"
    )
    missed = ev[o & ~p_]
    if len(missed):
        why = explain_misses(planner, scene, tray_id, prod.yaw, missed)
        for cause, n in why.most_common():
            print(f"      missed {n:4d}: {cause}")


def timings(planner: RegionPlanner) -> None:
    paper = load_scene(SCENES / "paper_experiment.json")
    first = paper.task_trays[0]
    _fresh(planner)
    t = time.perf_counter()
    planner.tray_region(paper, first)
    print(f"  one tray (paper_experiment {first}): {time.perf_counter() - t:.2f} s")
    _fresh(planner)
    pruned = baseline_region(planner, paper, first)
    _fresh(planner)
    full = baseline_region(planner, paper, first, prune=False)
    same = "same" if np.array_equal(full.mask, pruned.mask) else "DIFFERENT"
    print(
        f"  baseline of that tray, every target tried: {full.seconds:.2f} s "
        f"({full.counts['ik_problems']} IK solves; {same} cells as with the reach bound: "
        f"{pruned.seconds:.2f} s, {pruned.counts['ik_problems']} solves)"
    )
    five = load_scene(SCENES / "five_trays.json")
    _fresh(planner)
    t = time.perf_counter()
    before = planner.regions(five)
    print(f"  all {len(before)} regions of five_trays: {time.perf_counter() - t:.2f} s")
    data = five.model_dump(mode="json")
    moved = data["trays"][2]
    moved["pose"]["y"] += 0.3
    after_scene = parse_scene(data, "five_trays (moved)")
    t = time.perf_counter()
    after = planner.regions(after_scene)
    redone = sum(after[k] is not before[k] for k in after)
    print(
        f"  recompute after moving {moved['id']} by 0.3 m (+y): {time.perf_counter() - t:.2f} s "
        f"({redone} of {len(after)} regions recomputed)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", help="database id (default: the newest complete one)")
    ap.add_argument(
        "--scenes", nargs="+", default=["paper_experiment", "five_trays", "factory_cell"]
    )
    ap.add_argument("--trays", nargs="+", help="only these tray ids")
    ap.add_argument("--seeds", nargs="+", type=int, default=list(ORACLE_SEEDS))
    ap.add_argument("--band", type=int, default=2, help="cells outside the region to check")
    ap.add_argument("--sample", type=int, default=200, help="random other cells to check")
    ap.add_argument("--no-oracle", action="store_true")
    ap.add_argument("--no-timings", action="store_true")
    args = ap.parse_args()

    t0 = time.perf_counter()
    robot = load("tiago")
    d = data_dir()
    db = open_database(d, robot, args.db)
    info = db.info
    print(
        f"database {db.id}: {info['samples']:,} samples, {len(db):,} stored, "
        f"{db.n_voxels:,} voxels ({info['resolution']} m, {info['orientation']}), "
        f"loaded in {time.perf_counter() - t0:.1f} s"
    )
    planner = RegionPlanner(robot, db, cache_dir=cache_dir(d))
    for name in args.scenes:
        scene = load_scene(SCENES / f"{name}.json")
        trays = [t for t in scene.task_trays if not args.trays or t in args.trays]
        print(
            f"\n== {name}: yaw {np.degrees(scene.base_yaw.yaws[0]):.0f} deg, cell "
            f"{scene.base_grid.resolution} m; areas in m^2, times in s"
        )
        print(
            "tray     parts grasps |  production cells, area, s |  baseline cells, area, s "
            "| prod/base area"
        )
        for tray_id in trays:
            try:
                compare_tray(planner, scene, tray_id, args)
            except Exception:  # one broken tray should not lose the others' figures
                print(f"{tray_id:<8} FAILED\n{traceback.format_exc()}")
        if name == "factory_cell":
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(f"peak memory after factory_cell (ru_maxrss, database included): {rss:.0f} MB")
    if not args.no_timings:
        print("\n== timings (region and grasp caches emptied first)")
        timings(planner)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak memory {rss:.0f} MB; total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
