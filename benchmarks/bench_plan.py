"""Plans of the example scenes: stops, time and success against the naive plan, and speed.

    python benchmarks/bench_plan.py [--db ID] [--workers N] [--only estimates]

Prints, per example scene: the plan at sigma = 0.10 m (Gaussian error) under the paper's rule
and under the 95% success rule (stops, predicted time, naive time, per-stop Monte Carlo
success with 1,000 samples); a sweep of sigma from 0 to 0.2 m; then the speed figures:
re-plan after a sigma change with regions cached (no Monte Carlo), the factory cell from
scratch (regions, intersections, selection, route, verification; no Monte Carlo), and the
Monte Carlo of a plan (1,000 samples per stop); then the fast success estimates: their time for
every candidate of the factory cell (regions warm, exact boundary tests from scratch), and at
every stop of the examples' plans (both rules) the estimate beside the Monte Carlo with 1,000
and 10,000 samples, with the gap. ``--only estimates`` prints that part alone. Times: best of
several runs on 2 shared cores.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import statistics
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.pool import PlannerPool
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Scene
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.request import world_key
from pickstop.settings import data_dir
from pickstop.speedups.stop_planner import StopPlanner

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
NAMES = ["paper_experiment", "five_trays", "factory_cell"]


def _stops(plan: Plan) -> str:
    return ", ".join(
        f"{'+'.join(s.trays)} r={s.inscribed_radius:.3f} "
        f"ok={'-' if s.success is None else f'{s.success.rate:.1%}'}"
        for s in plan.stops
    )


def estimates(sp: StopPlanner, scenes: dict[str, Scene]) -> None:
    """The fast estimates' time on the factory cell, and their gap to the Monte Carlo."""
    print("\n== success estimates (density over the cells, exact near the boundaries)")
    factory, best = scenes["factory_cell"], []
    regions = sp.regions.regions(factory)
    sp.plan(factory, PlanOptions(samples=0))  # regions and centre checks warm
    for _ in range(3):
        fresh = StopPlanner(sp.regions)
        p = fresh.plan(factory, PlanOptions(samples=0))
        world = world_key(factory)
        tests = sum(fresh.refinement(world, r).checks for r in regions.values())
        best.append((p.timings.estimates, tests))
    t, tests = min(best)
    print(
        f"factory cell: {len(p.candidates)} candidates estimated in {t * 1e3:.0f} ms (best of 3, "
        f"{tests} exact boundary tests)"
    )
    rack = json.loads((SCENES / "rack_cell.json").read_text())
    for name, scene in {**scenes, "rack_cell": parse_scene(rack)}.items():
        gaps, outside = [], 0
        for rule in ("sigma", "success"):
            for n in (1000, 10_000):
                try:
                    p = sp.plan(scene, PlanOptions(rule=rule, samples=n))
                except InfeasiblePlanError:
                    break
                for s in p.stops:
                    lo, hi = s.success.interval
                    est = s.estimated_success
                    inside = lo <= est <= hi
                    outside += not inside
                    gaps.append(abs(est - s.success.rate))
                    print(
                        f"{name:17s} {rule:7s} {n:6d} {'+'.join(s.trays):28s} est {est:.4f} "
                        f"mc {s.success.rate:.4f} [{lo:.4f}, {hi:.4f}] "
                        f"gap {est - s.success.rate:+.4f}"
                        f"{'' if inside else '  outside'}"
                    )
        if gaps:
            print(
                f"{name:17s} max gap {max(gaps):.4f}; {outside} of {len(gaps)} outside the "
                "95% interval"
            )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--only", choices=["estimates"])
    args = ap.parse_args()
    scenes = {n: parse_scene(json.loads((SCENES / f"{n}.json").read_text())) for n in NAMES}
    slot = PlannerPool(data_dir()).scene_slot(scenes["paper_experiment"], SCENES, args.db)
    regions = slot.regions
    regions.workers = args.workers
    print(f"database: {regions.db.id} ({len(regions.db):,} configurations)")
    sp = slot.planner
    if args.only == "estimates":
        estimates(sp, scenes)
        regions.close()
        return

    print("\n== plans at sigma = 0.10 m, Gaussian error, 1,000 Monte Carlo samples per stop")
    for name, scene in scenes.items():
        for rule in ("sigma", "success"):
            try:
                p = sp.plan(scene, PlanOptions(sigma=0.10, rule=rule, samples=1000))
            except InfeasiblePlanError as e:
                print(f"{name:17s} {rule:7s} infeasible: {e.message}")
                continue
            t = p.totals
            print(
                f"{name:17s} {rule:7s} stops {t.stops} (naive {len(p.naive.stops)}), "
                f"time {t.time.total:.1f} s (naive {p.naive.time.total:.1f} s, saving "
                f"{p.naive.saving_fraction:.1%}), route {t.route_length:.2f} m, plan success "
                f"{t.success:.1%}; min stop {min(s.success.rate for s in p.stops):.1%}"
            )
            print(f"{'':25s} {_stops(p)}")

    print("\n== sigma sweep (paper's rule, Gaussian; 500 samples per stop)")
    for name, scene in scenes.items():
        cells = []
        for k in range(9):
            sigma = 0.025 * k
            try:
                p = sp.plan(scene, PlanOptions(sigma=sigma, samples=500))
            except InfeasiblePlanError:
                cells.append(f"{sigma:.3f}: -")
                continue
            ok = "-" if p.totals.success is None else f"{p.totals.success:.0%}"
            cells.append(f"{sigma:.3f}: {p.totals.stops} stops {p.totals.time.total:.0f} s {ok}")
        print(f"{name:17s} " + " | ".join(cells))

    print("\n== speed")
    paper = scenes["paper_experiment"]
    sp.plan(paper, PlanOptions(samples=0))
    times = []
    for k in range(30):
        sigma = 0.02 + 0.004 * (k % 20)
        t0 = time.perf_counter()
        with contextlib.suppress(InfeasiblePlanError):
            sp.plan(paper, PlanOptions(sigma=sigma, samples=0))
        times.append(time.perf_counter() - t0)
    print(
        f"re-plan after a sigma change, regions cached (paper scene, no Monte Carlo): "
        f"median {statistics.median(times) * 1e3:.0f} ms, max {max(times) * 1e3:.0f} ms"
    )
    factory = scenes["factory_cell"]
    scratch = []
    for _ in range(3):
        regions.forget()
        fresh = StopPlanner(regions)
        t0 = time.perf_counter()
        p = fresh.plan(factory, PlanOptions(samples=0))
        scratch.append(time.perf_counter() - t0)
    tm = p.timings
    print(
        f"factory cell ({len(factory.trays)} trays, {len(p.trays)} in the task) from scratch, no "
        f"Monte Carlo: best {min(scratch):.2f} s (regions {tm.regions:.2f}, intersections "
        f"{tm.intersections:.3f}, routing {tm.routing:.3f}, selection {tm.selection:.3f}, "
        f"verification {tm.verification:.2f}); {len(p.candidates)} candidates, {p.totals.stops} "
        f"stops"
    )
    for name, scene in scenes.items():
        sp.plan(scene, PlanOptions(samples=0))  # regions and checks warm
        best = []
        for seed in range(3):
            p = sp.plan(scene, PlanOptions(samples=1000, seed=100 + seed))
            best.append(p.timings.monte_carlo)
        print(
            f"Monte Carlo, 1,000 samples per stop, {name}: {len(p.stops)} stops in "
            f"{min(best):.2f} s (best of 3)"
        )
    estimates(sp, scenes)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory (this process): {peak:.0f} MB")
    regions.close()


if __name__ == "__main__":
    main()
