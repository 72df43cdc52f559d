"""Stops placed for success against stops at the inscribed circle's centre, per stop.

    python benchmarks/bench_placement.py [--db ID] [--samples N]

Prints, per example scene at its own sigma and error model, under the paper's rule and under
the 95% success rule: each stop's trays, where it stands placed for success and where the
circle's centre is, the fast estimate at both, the Monte Carlo at both (``--samples`` per
stop, 4,000 by default: the placed point's gain is often a point or less, so the intervals
must be narrow to tell), the clearance against the inscribed radius, and the planning time
with placement 'centre' and 'success'. Times are wall clock on the machine as it is: run it
alone.
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
from pickstop.sequence.plan_model import PlanOptions
from pickstop.settings import data_dir

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
NAMES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--samples", type=int, default=4000)
    args = ap.parse_args()
    scenes = {n: parse_scene(json.loads((SCENES / f"{n}.json").read_text())) for n in NAMES}
    slot = PlannerPool(data_dir()).scene_slot(scenes["paper_experiment"], SCENES, args.db)
    print(f"database: {slot.regions.db.id} ({len(slot.regions.db):,} configurations)")
    sp = slot.planner
    for name, scene in scenes.items():
        sp.plan(scene, PlanOptions(samples=0))  # regions and floor warm for both timings
        for rule in ("sigma", "success"):
            times, plans = {}, {}
            for placement in ("centre", "success"):
                t0 = time.perf_counter()
                try:
                    opts = PlanOptions(rule=rule, samples=args.samples, placement=placement)
                    plans[placement] = sp.plan(scene, opts)
                except InfeasiblePlanError as e:
                    plans[placement] = None
                    print(f"{name} rule {rule} placement {placement}: infeasible ({e})"[:160])
                times[placement] = time.perf_counter() - t0
            p = plans["success"]
            if p is None:
                continue
            c = plans["centre"]
            print(f"\n{name}, rule {rule}, sigma {p.parameters.sigma:.2f} m "
                  f"{p.parameters.error_model}: planned in {times['centre']:.2f} s (centre), "
                  f"{times['success']:.2f} s (success); plan success "
                  f"{'-' if c is None else f'{c.totals.success:.1%}'} -> "
                  f"{p.totals.success:.1%}, stops "
                  f"{'-' if c is None else c.totals.stops} -> {p.totals.stops}")  # fmt: skip
            for s in p.stops:
                trays = ",".join(s.trays)
                if s.circle_centre is None:
                    est, mc = s.estimated_success, s.success.rate
                    print(f"  {trays:34s} at the centre ({s.x:.3f}, {s.y:.3f}): estimate "
                          f"{est:.2%}, Monte Carlo {mc:.2%}")  # fmt: skip
                    continue
                cx, cy = s.circle_centre
                d = ((s.x - cx) ** 2 + (s.y - cy) ** 2) ** 0.5
                print(f"  {trays:34s} placed {d * 100:4.1f} cm off the centre: estimate "
                      f"{s.circle_estimated_success:.2%} -> {s.estimated_success:.2%}, Monte "
                      f"Carlo {s.circle_success.rate:.2%} -> {s.success.rate:.2%} "
                      f"(interval {s.success.interval[0]:.1%}-{s.success.interval[1]:.1%}); "
                      f"clearance {s.clearance:.3f} m of r {s.inscribed_radius:.3f} m")  # fmt: skip


if __name__ == "__main__":
    main()
