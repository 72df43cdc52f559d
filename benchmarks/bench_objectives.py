"""Plans that price failure: each objective's stops, success, predicted and expected time.

    python benchmarks/bench_objectives.py [--db ID] [--samples N]

Prints, per example scene (paper, five-tray, factory and rack cells) at sigma = 0.10 m
(Gaussian error) and the scene's failure model: the plan under the paper's rule (fewest
stops), the 95% success rule, and the expected-time objective (under the paper's rule's
candidates): stops, the plan's Monte Carlo success (``--samples`` per stop, 1,000), predicted
time, expected time per run (failed arrivals included) and planning time; then the
expected-time plan's trade-off table (for each number of stops: the least expected time, its
predicted time and success). Times are wall clock on the machine as it is: run it alone.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.pool import PlannerPool
from pickstop.scene.load import parse_scene
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.settings import data_dir

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
NAMES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]
RUNS = (
    ("paper's rule", {"rule": "sigma", "objective": "stops"}),
    ("95% rule", {"rule": "success", "target": 0.95, "objective": "stops"}),
    ("expected time", {"rule": "sigma", "objective": "expected-time"}),
)


def _row(name: str, label: str, p: Plan, seconds: float) -> str:
    t = p.totals
    ok = "-" if t.success is None else f"{t.success:.1%}"
    return (
        f"{name:17s} {label:14s} stops {t.stops}  success {ok:>6s}  predicted "
        f"{t.time.total:6.1f} s  expected {t.time.expected or t.time.total:7.1f} s  "
        f"planned in {seconds:5.2f} s"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--samples", type=int, default=1000)
    args = ap.parse_args()
    scenes = {n: parse_scene(json.loads((SCENES / f"{n}.json").read_text())) for n in NAMES}
    slot = PlannerPool(data_dir()).scene_slot(scenes["paper_experiment"], SCENES, args.db)
    print(f"database: {slot.regions.db.id} ({len(slot.regions.db):,} configurations)")
    sp = slot.planner
    print(f"\n== sigma = 0.10 m, Gaussian error, {args.samples} Monte Carlo samples per stop")
    tables = {}
    for name, scene in scenes.items():
        sp.plan(scene, PlanOptions(sigma=0.10, samples=0))  # regions warm for every objective
        for label, over in RUNS:
            t0 = time.perf_counter()
            try:
                p = sp.plan(scene, PlanOptions(sigma=0.10, samples=args.samples, **over))
            except InfeasiblePlanError as e:
                print(f"{name:17s} {label:14s} infeasible: {e.message[:90]}")
                continue
            print(_row(name, label, p, time.perf_counter() - t0))
            if p.tradeoff:
                tables[name] = p.tradeoff
    print("\n== trade-off of the expected-time plans (success from the fast estimates)")
    for name, rows in tables.items():
        for r in rows:
            print(
                f"{name:17s} {r.stops} stops: expected {r.expected_time:7.1f} s, predicted "
                f"{r.time:6.1f} s, success {r.success:6.1%}{'  (chosen)' if r.chosen else ''}"
                f"{'' if r.optimal else '  (not proven optimal)'}"
            )
    slot.regions.close()


if __name__ == "__main__":
    main()
