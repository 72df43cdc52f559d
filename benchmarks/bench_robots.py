"""Per robot: `robot check` CPU and wall time with a fresh cache and again, the first and a
cached database build, screen false rejection, stored fraction, and the regions and plan of
the paper-like scene with that robot (stops, predicted success); every shipped robot and a
generated one by default.

    python benchmarks/bench_robots.py [--samples 2000000] [--robots tiago examples/robots/pr2.yaml]
        [--no-dense] [--no-generated] [--triangles 4000]

The generated robot (tests/robot/synthetic.py) is one as vendors ship them: an SRDF, dense
collision meshes on the torso, the seven arm links and the palm, and a parallel gripper whose
tool frame lies between the pads. Every robot's derived data goes to a fresh cache folder.
Also builds a generated robot whose fixed links carry 100,000-triangle meshes (a laser, an
e-stop and a wrist camera) and reports the time to a finished small build.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
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


def _clock() -> tuple[float, float]:
    """(wall, CPU of this process and its finished children) [s]."""
    cpu = sum(
        u.ru_utime + u.ru_stime
        for u in (
            resource.getrusage(resource.RUSAGE_SELF),
            resource.getrusage(resource.RUSAGE_CHILDREN),
        )
    )
    return time.perf_counter(), cpu


def _since(t: tuple[float, float]) -> str:
    now = _clock()
    return f"{now[1] - t[1]:.1f} s CPU / {now[0] - t[0]:.1f} s wall"


def bench(ref: str, samples: int, folder: Path) -> tuple[dict, dict]:
    from pickstop.reach.build import BuildParams
    from pickstop.robot.check import check_robot
    from pickstop.robot.model import load
    from pickstop.settings import cache_dir
    from pickstop.store.reach_build import build

    os.environ["PICKSTOP_CACHE_DIR"] = str(folder / "cache")  # fresh: everything is made
    t = _clock()
    report = check_robot(ref, cache_dir())
    fresh = _since(t)
    t = _clock()
    check_robot(ref, cache_dir())
    again = _since(t)
    robot = load(ref)
    params = BuildParams(samples=samples, chunk_size=250_000)
    t = _clock()
    row = build(robot, params, folder)
    first = _since(t)
    t0 = time.perf_counter()
    build(robot, params, folder)
    cached = time.perf_counter() - t0
    scr = report["screen"]
    print(
        f"{robot.name:10s} check {fresh} fresh, {again} again ({report['seconds']}) | build "
        f"{samples / 1e6:.0f}M after it: {first}, again {cached:.2f} s | screen false "
        f"rejection {100 * row['screen_false_rejection']:.1f}% (flags "
        f"{100 * row['screen_flagged']:.1f}%, {int(scr['rounds'])} tightening rounds, "
        f"{'within' if scr['meets_bound'] else 'OVER'} its bound) | stored "
        f"{row['stored'] / samples:.1%}"
    )
    for warning in report["warnings"]:
        print(f"{'':10s} check warns: {warning}")
    paper(ref, robot, row, folder)
    return report, row


def paper(ref: str, robot, row: dict, folder: Path) -> None:
    """Regions and plan of the paper-like scene with ``robot`` (its database of ``row``)."""
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.cover import InfeasiblePlanError
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.settings import cache_dir
    from pickstop.speedups.region_planner import RegionPlanner
    from pickstop.speedups.stop_planner import StopPlanner
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


def generated(folder: Path, samples: int, triangles: int) -> None:
    """The generated robot as vendors ship it (SRDF, dense meshes, the tool frame between the
    pads): its check, build and plan."""
    sys.path.insert(0, str(ROOT))
    from tests.robot.synthetic import write_manipulator

    os.environ["PICKSTOP_CACHE_DIR"] = str(folder / "srdf-cache")  # its SRDF's computation
    config = write_manipulator(folder / "robot", triangles=triangles)
    print(f"gen_arm: {triangles:,}-triangle meshes on 11 links, an SRDF, 8 arm joints")
    report, row = bench(str(config), samples, folder / "bench")
    # The tool_offset its check suggests (the robot hash leaves the hand out: same database).
    from pickstop.robot.model import load

    position = report["hand"]["suggested_tool_offset"]["position"]
    fixed = config.with_name("gen_arm_offset.yaml")
    fixed.write_text(
        config.read_text().replace(
            "max_opening: 0.08", f"max_opening: 0.08\n  tool_offset: {{position: {position}}}"
        )
    )
    print(f"{'':10s} with the suggested hand.tool_offset {position}:")
    paper(str(fixed), load(str(fixed)), row, folder / "bench")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=2_000_000)
    ap.add_argument("--robots", nargs="*", default=ROBOTS)
    ap.add_argument("--no-dense", action="store_true", help="skip the 100,000-triangle robot")
    ap.add_argument("--no-generated", action="store_true", help="skip the generated robot")
    ap.add_argument("--triangles", type=int, default=4000, help="per mesh of the generated one")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for ref in args.robots:
            bench(
                str(ROOT / ref) if ref.endswith(".yaml") else ref,
                args.samples,
                Path(tmp) / Path(ref).stem,
            )
        if not args.no_generated:
            generated(Path(tmp) / "generated", args.samples, args.triangles)
        if not args.no_dense:
            dense(Path(tmp) / "dense")


if __name__ == "__main__":
    main()
