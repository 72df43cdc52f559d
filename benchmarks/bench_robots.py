"""Per robot: `robot check` time, first and cached database build, screen false rejection.

    python benchmarks/bench_robots.py [--samples 2000000] [--robots tiago examples/robots/pr2.yaml]

Also builds a generated robot whose fixed links carry 100,000-triangle meshes (a laser, an
e-stop and a wrist camera) and reports the time to a finished small build.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def bench(ref: str, samples: int, folder: Path) -> None:
    from pickstop.reach.build import BuildParams, build
    from pickstop.robot.artifacts import _MEMO, _QUALITY
    from pickstop.robot.check import check_robot
    from pickstop.robot.model import load
    from pickstop.settings import cache_dir

    _MEMO.clear()
    _QUALITY.clear()
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


def dense(folder: Path) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "robot"))
    from synthetic import write_dense_robot

    from pickstop.reach.build import BuildParams, build
    from pickstop.robot.model import load

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
    ap.add_argument("--robots", nargs="*", default=["tiago", "examples/robots/pr2.yaml"])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for ref in args.robots:
            bench(ref, args.samples, Path(tmp) / Path(ref).stem)
        dense(Path(tmp) / "dense")


if __name__ == "__main__":
    main()
