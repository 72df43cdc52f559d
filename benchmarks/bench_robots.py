"""Per robot: `robot check` time, first and cached database build, screen false rejection,
stored fraction, and the regions and plan of the paper-like scene with that robot (stops,
predicted success); every shipped robot by default.

    python benchmarks/bench_robots.py [--samples 2000000] [--robots tiago examples/robots/pr2.yaml]
        [--no-dense]

Also builds a generated robot whose fixed links carry 100,000-triangle meshes (a laser, an
e-stop and a wrist camera) and reports the time to a finished small build.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
ROOT = Path(__file__).resolve().parents[1]
ROBOTS = [
    "tiago",
    *(f"examples/robots/{n}.yaml" for n in ("pr2", "ur5_amr", "tiago_dual", "tiago_pro")),
]


def bench(ref: str, samples: int, folder: Path) -> None:
    from pickstop.reach.build import BuildParams
    from pickstop.robot.check import check_robot
    from pickstop.robot.model import load
    from pickstop.settings import cache_dir
    from pickstop.store.reach_build import build

    t0 = time.perf_counter()
    report = check_robot(ref, cache_dir(folder))
    t_check = time.perf_counter() - t0
    robot = load(ref)
    params = BuildParams(samples=samples, chunk_size=250_000)
    t0 = time.perf_counter()
    row = build(robot, params, folder)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    build(robot, params, folder)
    cached = time.perf_counter() - t0
    print(
        f"{robot.name:10s} check {t_check:5.1f} s (first; {report['seconds']}) | build "
        f"{samples / 1e6:.0f}M: {first:5.1f} s ({samples / first:,.0f} samples/s), again "
        f"{cached:.2f} s | screen false rejection {100 * row['screen_false_rejection']:.1f}% "
        f"(flags {100 * row['screen_flagged']:.1f}%) | stored {row['stored'] / samples:.1%}"
    )
    paper(ref, robot, row, folder)


def paper(ref: str, robot, row: dict, folder: Path) -> None:
    """Regions and plan of the paper-like scene with ``robot`` (its database of ``row``)."""
    from pickstop.regions.planner import RegionPlanner
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.cover import InfeasiblePlanError
    from pickstop.sequence.plan import StopPlanner
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.settings import cache_dir
    from pickstop.store.reach_catalog import open_database

    doc = json.loads((ROOT / "examples/scenes/paper_experiment.json").read_text())
    doc["robot"] = {"preset": ref} if ref == "tiago" else {"config": str(Path(ref).resolve())}
    scene = parse_scene(doc)
    planner = RegionPlanner(
        robot, open_database(folder, robot, row["id"]), cache_dir=cache_dir(folder)
    )
    t0 = time.perf_counter()
    areas = []
    for tray_id in scene.task_trays:
        region = planner.tray_region(scene, tray_id)
        areas.append(
            f"{tray_id} {region.area * 1e4:.0f} cm2"
            + (f" ({region.reason})" if region.reason else "")
        )
    t_regions = time.perf_counter() - t0
    try:
        plan = StopPlanner(planner).plan(scene, PlanOptions(samples=1000))
        stops = ", ".join(f"{'+'.join(s.trays)} ok={s.success.rate:.1%}" for s in plan.stops)
        docking = sum(y is not None for leg in plan.legs for y in leg.segment_yaws or [])
        result = (
            f"plan {plan.totals.stops} stops (naive {len(plan.naive.stops)}), "
            f"{plan.totals.time.total:.1f} s, success {plan.totals.success:.1%}: {stops}; "
            f"route {plan.totals.route_length:.2f} m, {docking} docking segment(s)"
        )
    except InfeasiblePlanError as e:
        result = f"plan infeasible: {e.message}"
    print(f"{'':10s} paper scene: regions {t_regions:.1f} s: {'; '.join(areas)} | {result}")


def dense(folder: Path) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "robot"))
    from synthetic import write_dense_robot

    from pickstop.reach.build import BuildParams
    from pickstop.robot.model import load
    from pickstop.store.reach_build import build

    t0 = time.perf_counter()
    config = write_dense_robot(folder / "robot", triangles=100_000)
    robot = load(str(config))
    tris = sum(getattr(o.geometry, "num_tris", 0) for o in robot.geom_model.geometryObjects)
    row = build(robot, BuildParams(samples=200_000, chunk_size=100_000), folder / "data")
    print(
        f"dense_amr  {tris:,} triangles on 3 links: load + screen + 200k-sample build "
        f"{time.perf_counter() - t0:.1f} s, screen false rejection "
        f"{100 * row['screen_false_rejection']:.1f}%"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=2_000_000)
    ap.add_argument("--robots", nargs="*", default=ROBOTS)
    ap.add_argument("--no-dense", action="store_true", help="skip the 100,000-triangle robot")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for ref in args.robots:
            bench(
                str(ROOT / ref) if ref.endswith(".yaml") else ref,
                args.samples,
                Path(tmp) / Path(ref).stem,
            )
        if not args.no_dense:
            dense(Path(tmp) / "dense")


if __name__ == "__main__":
    main()
