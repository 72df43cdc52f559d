"""Designing the cell: a product mix on one layout, and layout suggestions with their gap.

    python benchmarks/bench_cell.py [--db ID] [--workers N] [--tiny]

Prints:
1. The factory cell with a mix of ``--orders`` (20) orders of 2 to 5 trays (seeded): the whole
   mix planned with its regions cold (a new planner) and warm (the same layout again), and the
   time per order once the regions are known; with ``--samples`` Monte Carlo samples per stop
   (1,000) and without.
2. Layout suggestions for 1, 2 and 3 movable trays on the paper-like scene (its task) and the
   factory cell (the mix; the trays most orders need): time to the first verified suggestion
   and in all, the gain (weighted time and stops) of the best, its predicted and ranked figures.
3. The gap to the true optimum on a small instance: three movable trays of the paper-like
   scene with ``--slots`` (12) slots each, every layout planned exactly (no Monte Carlo), and
   the search over the same slots: its best against the optimum.

``--tiny`` checks that it runs (3 orders, one movable tray, 3 slots, few samples). Times are
wall clock on the machine as it is (2 shared cores here): run it alone.
"""

from __future__ import annotations

import argparse
import os
import random
import time
from collections import Counter
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.layout.search import SearchSettings, build_space, exhaustive, search, suggest
from pickstop.layout.verify import LocalEvaluator
from pickstop.pool import PlannerPool
from pickstop.scene.load import load_scene
from pickstop.scene.model import Order, Scene
from pickstop.sequence.mix import mix_document, plan_mix
from pickstop.sequence.plan_model import PlanOptions
from pickstop.settings import data_dir
from pickstop.speedups.region_planner import RegionPlanner
from pickstop.speedups.stop_planner import StopPlanner

SCENES = Path(__file__).parents[1] / "examples" / "scenes"


def mix_orders(scene: Scene, n: int, seed: int = 0) -> list[Order]:
    """``n`` orders of 2 to 5 of the scene's trays, weighted 1, 2 or 5 (seeded)."""
    rng = random.Random(seed)
    ids = [t.id for t in scene.trays]
    return [
        Order(id=f"o{k:02d}", trays=rng.sample(ids, rng.randint(2, min(5, len(ids)))),
              weight=rng.choice([1, 2, 5]))
        for k in range(n)
    ]  # fmt: skip


def bench_mix(rp: RegionPlanner, scene: Scene, orders: list[Order], samples: int) -> None:
    print(f"\n== mix: {scene.name}, {len(orders)} orders of 2-5 trays")
    for s in (samples, 0):
        opts = PlanOptions(samples=s)
        fresh = RegionPlanner(rp.robot, rp.db, cache_dir=rp.cache_dir, workers=rp.workers)
        try:
            sp = StopPlanner(fresh)
            for label in ("cold", "warm"):
                t0 = time.perf_counter()
                mix = plan_mix(sp, scene, orders, opts)
                wall = time.perf_counter() - t0
                doc = mix_document(mix)
                t = doc.totals
                print(f"{label:4s} samples {s:5d}: {wall:6.2f} s in all (regions "
                      f"{mix.regions_seconds:5.2f} s, plans {mix.plans_seconds:5.2f} s = "
                      f"{1e3 * mix.plans_seconds / len(orders):6.1f} ms per order); weighted per "
                      f"order: stops {t.stops:.2f} (naive {t.naive_stops:.2f}), time "
                      f"{t.time:.1f} s (naive {t.naive_time:.1f} s), success "
                      f"{'-' if t.success is None else f'{t.success:.1%}'}; {t.planned} of "
                      f"{t.orders} planned")  # fmt: skip
        finally:
            fresh.close()


def most_needed(scene: Scene, orders: list[Order], k: int) -> list[str]:
    count = Counter(t for o in orders for t in scene.order_trays(o))
    return [t for t, _ in count.most_common(k)]


def bench_suggest(
    sp: StopPlanner, scene: Scene, orders: list[Order], movable: list[str], opts: PlanOptions,
    settings: SearchSettings,
) -> None:  # fmt: skip
    ev = LocalEvaluator(sp, orders, opts)
    t0 = time.perf_counter()
    try:
        doc = suggest(sp.regions, ev, scene, orders, movable, opts, settings)
    finally:
        ev.close()
    wall = time.perf_counter() - t0
    sec, b = doc.search.seconds, doc.before.totals
    head = (f"{scene.name:16s} {len(movable)} movable ({','.join(movable)}): first verified "
            f"{sec.get('first', float('nan')):6.1f} s, in all {wall:6.1f} s; "
            f"{doc.search.predicted} predicted, {doc.search.planned} planned, "
            f"{doc.search.verified} verified")  # fmt: skip
    if not doc.suggestions:
        print(f"{head}; no gain found (before: {b.time:.1f} s, {b.stops:.2f} stops)")
        return
    s = doc.suggestions[0]
    a = s.after.totals
    print(f"{head}; best: time {b.time:.1f} -> {a.time:.1f} s (gain {s.gain.time:.1f} s), "
          f"stops {b.stops:.2f} -> {a.stops:.2f}, success "
          f"{'-' if b.success is None else f'{b.success:.1%} -> {a.success:.1%}'}; predicted "
          f"{s.predicted['time']:.1f} s, ranked {s.ranked['time']:.1f} s; moves "
          + "; ".join(f"{m.tray} to ({m.to.x:.2f}, {m.to.y:.2f}) turn {m.turn:.0f}"
                      for m in s.moves))  # fmt: skip


def bench_gap(sp: StopPlanner, scene: Scene, n_slots: int, settings: SearchSettings) -> None:
    orders = [Order(id="task", trays=scene.task_trays)]
    movable = ["tray_4", "tray_1", "tray_2"]
    opts = PlanOptions(samples=0)
    space = build_space(sp.regions, scene, orders, movable, opts, settings)
    for t, slots in space.slots.items():  # the tray's place and slots spread over the rest
        rest = slots[1:]
        pick = [rest[round(k * (len(rest) - 1) / max(n_slots - 2, 1))] for k in range(n_slots - 1)]
        space.slots[t] = [slots[0], *dict.fromkeys(pick)]
    ev = LocalEvaluator(sp, orders, opts)
    t0 = time.perf_counter()
    every = exhaustive(space, ev)
    t_all = time.perf_counter() - t0
    t0 = time.perf_counter()
    found = search(space, ev, opts, settings)
    t_search = time.perf_counter() - t0
    best = every[0][1]
    home = next(v for k, v in every if k == space.home)
    mine = min(((0.0, s.ranked["time"], s.ranked["stops"]) for s in found.suggestions),
               default=home)  # fmt: skip
    sizes = "x".join(str(len(space.slots[t])) for t in movable)
    print(
        f"\n== gap on a small instance: {scene.name}, {sizes} slots, {len(every)} layouts "
        f"without clashes"
    )
    print(f"exhaustive {t_all:.1f} s: optimum {best[1]:.2f} s, {best[2]:.2f} stops (as it is: "
          f"{home[1]:.2f} s, {home[2]:.2f} stops); search {t_search:.1f} s: {mine[1]:.2f} s, "
          f"{mine[2]:.2f} stops; gap {mine[1] - best[1]:.2f} s "
          f"({100 * (mine[1] - best[1]) / best[1]:.1f}%)")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--orders", type=int, default=20)
    ap.add_argument("--samples", type=int, default=1000, help="Monte Carlo samples of the mix")
    ap.add_argument("--layout-samples", type=int, default=200,
                    help="Monte Carlo samples of the verified layouts")  # fmt: skip
    ap.add_argument("--slots", type=int, default=12, help="slots per tray of the gap instance")
    ap.add_argument("--tiny", action="store_true", help="check that it runs, quickly")
    args = ap.parse_args()
    if args.tiny:
        args.orders, args.samples, args.layout_samples, args.slots = 3, 20, 10, 3
    paper = load_scene(SCENES / "paper_experiment.json")
    factory = load_scene(SCENES / "factory_cell.json")
    slot = PlannerPool(data_dir()).scene_slot(paper, SCENES, args.db)
    slot.regions.workers = args.workers
    print(f"database: {slot.regions.db.id} ({len(slot.regions.db):,} configurations)")
    orders = mix_orders(factory, args.orders)
    bench_mix(slot.regions, factory, orders, args.samples)

    print(f"\n== layout suggestions ({args.layout_samples} Monte Carlo samples per stop verified)")
    settings = SearchSettings(step=0.1, suggestions=1 if args.tiny else 3,
                              shortlist=3 if args.tiny else 12)  # fmt: skip
    opts = PlanOptions(samples=args.layout_samples)
    counts = [1] if args.tiny else [1, 2, 3]
    cases = [(paper, [Order(id="task", trays=paper.task_trays)], ["tray_4", "tray_1", "tray_2"]),
             (factory, orders, most_needed(factory, orders, 3))]  # fmt: skip
    for scene, mix, candidates in cases:
        for k in counts:
            bench_suggest(slot.planner, scene, mix, candidates[:k], opts, settings)
    bench_gap(slot.planner, paper, args.slots, SearchSettings(step=0.1, turns=(0,),
              suggestions=3, shortlist=3 if args.tiny else 12))  # fmt: skip
    slot.close()


if __name__ == "__main__":
    main()
