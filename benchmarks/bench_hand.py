"""Region and Monte Carlo speed with TIAGo's own Hey5 hand, plus region fingerprints.

    python benchmarks/bench_hand.py [--db ID] [--runs 3] [--factory-runs 1] [--dump FILE]
        [--profile tray|mc|factory]

Prints: one tray region (paper scene tray_3), every factory-cell region from scratch, and a
Monte Carlo of 1,000 samples at the paper plan's first stop, each the best of ``--runs``
(2 shared cores: figures vary by 10-30 %). ``--dump`` writes every example scene's regions
(cells and witnesses) as JSON so two versions can be compared; ``--profile``
prints cProfile's top functions of that figure instead.
"""

from __future__ import annotations

import argparse
import cProfile
import hashlib
import json
import os
import pstats
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.pool import PlannerPool
from pickstop.scene.load import parse_scene
from pickstop.sequence.plan_model import PlanOptions
from pickstop.sequence.request import world_key
from pickstop.settings import data_dir
from pickstop.speedups.stop_planner import StopPlanner

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
NAMES = ["paper_experiment", "five_trays", "factory_cell"]


def best(fn: Callable[[], object], runs: int) -> float:
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--factory-runs", type=int, default=1)
    ap.add_argument("--dump")
    ap.add_argument("--profile", choices=["tray", "mc", "factory"])
    args = ap.parse_args()
    scenes = {n: parse_scene(json.loads((SCENES / f"{n}.json").read_text())) for n in NAMES}
    paper, factory = scenes["paper_experiment"], scenes["factory_cell"]
    planner = PlannerPool(data_dir()).region_planner(paper, SCENES, args.db)
    planner.workers = 1
    print(f"database: {planner.db.id} ({len(planner.db):,} configurations)")
    for scene in scenes.values():
        for tray_id in scene.task_trays:
            planner.grasps(scene, scene.tray(tray_id))  # grasps warm, as in a running service

    tray = paper.tray("tray_3")
    yaw = paper.base_yaw.yaws[0]

    def one_tray() -> None:
        planner.compute_region(paper, tray.id, yaw)

    def all_factory() -> None:
        planner.forget()  # nor reused from the trays as they last stood, or the layout
        planner.regions(factory)

    sp = StopPlanner(planner)
    plan = sp.plan(paper, PlanOptions(samples=0))
    stop = plan.stops[0]
    regions = planner.regions(paper)
    stop_regions = [regions[t, stop.yaw] for t in stop.trays]
    sigma = 0.10  # [m]
    runs_mc = iter(range(10**6))

    def monte_carlo() -> None:
        # a fresh seed each run: nothing comes from the success cache
        sp.success(
            paper, world_key(paper), stop_regions, (stop.x, stop.y), sigma, 1000, next(runs_mc)
        )

    if args.profile:
        fn = {"tray": one_tray, "mc": monte_carlo, "factory": all_factory}[args.profile]
        fn()
        prof = cProfile.Profile()
        prof.runcall(fn)
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)
        return

    print(
        f"one tray region (paper {tray.id}, {len(tray.parts)} parts): "
        f"{best(one_tray, args.runs):.2f} s"
    )
    print(
        f"factory cell, all {len(factory.task_trays)} regions from scratch, 1 process: "
        f"{best(all_factory, args.factory_runs):.2f} s"
    )
    print(
        f"Monte Carlo, 1,000 samples at one stop (paper, trays {'+'.join(stop.trays)}, "
        f"sigma {sigma:.2f} m): {best(monte_carlo, args.runs):.2f} s"
    )
    if args.dump:
        out = {}
        for name, scene in scenes.items():
            planner.forget()
            for r in planner.regions(scene).values():
                out[f"{name}/{r.tray_id}/{r.yaw:.6f}"] = {
                    "cells": r.cells.tolist(),
                    "thetas": hashlib.sha256(r.thetas.round(9).tobytes()).hexdigest(),
                    "grasps": r.grasp_index.tolist(),
                    "counts": r.counts,
                }
        Path(args.dump).write_text(json.dumps(out, indent=1, sort_keys=True))
        print(f"regions of {len(out)} trays written to {args.dump}")
    planner.close()


if __name__ == "__main__":
    main()
