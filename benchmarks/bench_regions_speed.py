"""Base region speed on the example scenes with a warm database.

    python benchmarks/bench_regions_speed.py [--db ID]

Prints: one 4-part tray (paper scene tray_3), all regions of the five-tray scene, the
recompute after moving one tray, the 12-tray factory cell from scratch, and peak memory.
Times are the best of several runs (2 shared cores), regions computed afresh each run.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.pool import PlannerPool
from pickstop.scene.load import parse_scene
from pickstop.settings import data_dir

SCENES = Path(__file__).parents[1] / "examples" / "scenes"


#: [m] tray_5 moved along the row: the farthest it stays on its bench (it ends 0.04 m short of
#: the bench's end; a tray must stand on something).
MOVE = 0.2


def best(fn, runs: int = 5) -> float:
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    args = ap.parse_args()
    paper = parse_scene(json.loads((SCENES / "paper_experiment.json").read_text()))
    planner = PlannerPool(data_dir()).region_planner(paper, SCENES, args.db)
    print(f"database: {planner.db.id} ({len(planner.db):,} configurations)")
    tray = paper.tray("tray_3")
    planner.grasps(paper, tray)
    yaw = paper.base_yaw.yaws[0]
    r = planner.compute_region(paper, tray.id, yaw)
    g = r.grid
    print(
        f"one tray, {len(tray.parts)} parts, grid {g.res} m, {r.counts['in_reach']} cells in "
        f"reach ({r.counts['footprint_free']} free): "
        f"{best(lambda: planner.compute_region(paper, tray.id, yaw)):.3f} s, "
        f"{len(r.cells)} feasible"
    )

    five_doc = json.loads((SCENES / "five_trays.json").read_text())
    five = parse_scene(five_doc)

    def all_five() -> None:
        planner.forget()
        planner.regions(five)

    planner.regions(five)  # grasps cached, as in a running service
    print(
        f"five-tray scene, all {len(five.task_trays)} regions, one process: {best(all_five):.3f} s"
    )

    def all_five_parallel() -> None:
        planner.forget()
        planner.regions(five, workers=2)

    all_five_parallel()  # start the workers and warm their grasp caches
    print(f"five-tray scene, all regions, 2 processes: {best(all_five_parallel):.3f} s")

    def move_one(workers: int) -> None:
        planner.forget()
        before = planner.regions(five, workers=workers)
        doc = json.loads(json.dumps(five_doc))
        doc["trays"][4]["pose"]["x"] += MOVE
        moved = parse_scene(doc)
        planner.grasps(moved, moved.tray("tray_5"))
        t = time.perf_counter()
        regs = planner.regions(moved, workers=workers)
        times.append(time.perf_counter() - t)
        recomputed.append(sum(1 for k, v in regs.items() if v is not before[k]))

    for workers in (1, 2):
        times: list[float] = []
        recomputed: list[int] = []
        for _ in range(3):
            move_one(workers)
        print(
            f"five-tray scene, recompute after moving tray_5 by {MOVE} m, {workers} process(es): "
            f"{min(times):.3f} s ({recomputed[0]} of {len(five.task_trays)} regions recomputed)"
        )
    planner.close()

    cell = parse_scene(json.loads((SCENES / "factory_cell.json").read_text()))
    planner.forget()
    planner.grasp_memo.clear()
    t = time.perf_counter()
    regs = planner.regions(cell)
    dt = time.perf_counter() - t
    empty = [k[0] for k, v in regs.items() if not len(v.cells)]
    print(
        f"factory cell, {len(regs)} task regions from scratch (grasps included): {dt:.2f} s; "
        f"empty: {empty or 'none'}"
    )
    print(
        f"peak memory (database, planner, factory cell): "
        f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB"
    )


if __name__ == "__main__":
    main()
