"""Self-collision figures: disabled pairs, sphere screen rate, exact rate, false rejections.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_selfcollision.py [--robots tiago pr2]
        [--samples 50000] [--n 5000] [--seed 0]

One core: BLAS is pinned to one thread before numpy loads. Rates are the best of a few
repetitions over uniform random configurations in blocks of ``kinematics.BLOCK``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time
from collections.abc import Callable

import numpy as np

from pickstop.robot.kinematics import BLOCK, Chain, fk_soa
from pickstop.robot.model import load
from pickstop.robot.screen import config_count
from pickstop.robot.selfcollision import (
    ExactSelfCollision,
    SphereModel,
    disabled_pairs,
    false_rejection_rate,
    screen,
)

ROBOTS = {"tiago": "tiago", "pr2": "examples/robots/pr2.yaml"}


def best_rate(n: int, fn: Callable[[], object], repeats: int = 3) -> float:
    """Configurations per second [1/s] of ``fn`` over ``n`` configurations, best of repeats."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return n / best


def bench(name: str, samples: int, n: int, seed: int) -> None:
    robot = load(ROBOTS[name])
    t0 = time.perf_counter()
    pairs = disabled_pairs(robot, samples=samples, seed=seed)
    t_pairs = time.perf_counter() - t0
    counts = pairs.counts()
    what = "read from SRDF" if pairs.source == "srdf" else f"computed, {samples} samples"
    print(f"[{name}] disabled pairs ({what}): {t_pairs:.1f} s, {counts}")

    t0 = time.perf_counter()
    model = SphereModel.from_robot(robot, pairs)
    print(f"[{name}] sphere model build: {time.perf_counter() - t0:.1f} s, {config_count(model)}")

    chain = Chain.from_robot(robot)
    rng = np.random.default_rng(seed)
    N = 5 * BLOCK
    th = rng.uniform(robot.lower, robot.upper, (N, robot.dof))
    blocks = [np.ascontiguousarray(th[s : s + BLOCK].T) for s in range(0, N, BLOCK)]
    frames = [fk_soa(chain, b, frames=True)[2] for b in blocks]

    def run_screen() -> None:
        for f in frames:
            screen(model, f)

    def run_pipeline() -> None:
        for b in blocks:
            screen(model, fk_soa(chain, b, frames=True)[2])

    print(f"[{name}] screen rate: {best_rate(N, run_screen):,.0f} configs/s (one core)")
    print(f"[{name}] FK + screen rate: {best_rate(N, run_pipeline):,.0f} configs/s (one core)")

    exact = ExactSelfCollision(robot, pairs)
    m = 2000
    print(f"[{name}] exact rate: {best_rate(m, lambda: exact.colliding(th[:m]), 1):,.0f} configs/s")

    fig = false_rejection_rate(robot, pairs, model, n=n, seed=seed + 1)
    print(
        f"[{name}] n={n}: colliding {fig['colliding']:.1%}, flagged {fig['flagged']:.1%}, "
        f"false rejection {fig['false_rejection']:.2%} of free configurations, "
        f"false acceptances {fig['false_acceptances']:.0f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=list(ROBOTS))
    ap.add_argument("--samples", type=int, default=50000, help="samples for disabled pairs")
    ap.add_argument("--n", type=int, default=5000, help="configurations for false rejections")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    for name in args.robots:
        bench(name, args.samples, args.n, args.seed)


if __name__ == "__main__":
    main()
