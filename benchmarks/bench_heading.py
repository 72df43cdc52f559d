"""Heading as a decision: a fixed base yaw against a set the plan chooses from.

    python benchmarks/bench_heading.py [--db ID] [--samples N]

The paper-like scene with its tables against the floor's far edge (the floor ends at
y = 2.0 m, 10 cm behind them), so that every tray is reached only from the near side. Plans,
each with a fresh planner (regions cold) and again warm: the base fixed at +90 deg (facing the
tables: the paper's); fixed at -90 deg (facing away: refused, the refusal naming the headings
that reach each tray, and the time the answer takes); the set {-90, +90} deg; and eight
headings every 45 deg. Prints stops, their headings, success (Monte Carlo, ``--samples`` a
stop), predicted and expected time and the planning time; the cost of a set is its cold time
over the fixed yaw's. Run it alone.
"""

from __future__ import annotations

import argparse
import json
import math
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
POLICIES = (
    ("fixed +90 deg", {"fixed": math.pi / 2}),
    ("fixed -90 deg", {"fixed": -math.pi / 2}),
    ("{-90, +90} deg", {"candidates": [-math.pi / 2, math.pi / 2]}),
    ("8 headings", {"candidates": [-math.pi + k * math.pi / 4 for k in range(8)]}),
)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--db")
    ap.add_argument("--samples", type=int, default=1000)
    args = ap.parse_args()
    doc = json.loads((SCENES / "paper_experiment.json").read_text())
    doc["floor"]["max"][1] = 2.0
    base = None
    for label, policy in POLICIES:
        scene = parse_scene({**doc, "base_yaw": policy})
        times = []
        for _ in ("cold", "warm"):
            if not times:  # a fresh planner: regions cold
                slot = PlannerPool(data_dir()).scene_slot(scene, SCENES, args.db)
            t0 = time.perf_counter()
            try:
                plan = slot.planner.plan(scene, PlanOptions(samples=args.samples))
                err = None
            except InfeasiblePlanError as e:
                plan, err = None, str(e)
            times.append(time.perf_counter() - t0)
        base = times[0] if base is None else base
        head = (f"{label:15s} cold {times[0]:6.2f} s ({times[0] / base:4.1f}x the fixed yaw's), "
                f"warm {times[1]:5.2f} s")  # fmt: skip
        if plan is None:
            print(f"{head}: refused: {err}")
            continue
        t = plan.totals
        yaws = ", ".join(f"{math.degrees(s.yaw):.0f}" for s in plan.stops)
        print(f"{head}: {t.stops} stops at {yaws} deg, success {t.success:.1%}, predicted "
              f"{t.time.total:.1f} s, expected {t.time.expected:.1f} s")  # fmt: skip


if __name__ == "__main__":
    main()
