"""IK refinement figures: success rate, iterations and time from nearby seeds, and the baselines.

Targets are FK poses of uniform random configurations (so all reachable); seeds are the true
configurations with every joint moved by 0.1-0.2 rad (then 0.02-0.06 rad), random sign;
prismatic joints move a quarter of that in metres.

    python benchmarks/bench_ik.py [--robot tiago] [--n 300] [--seed 0]
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from pickstop.reach.ik import IKResult, Refiner, solve_from_fixed_seed, solve_multistart
from pickstop.robot.model import RobotModel, load

T = TypeVar("T")


def perturb(
    robot: RobotModel, theta: np.ndarray, rng: np.random.Generator, lo: float, hi: float
) -> np.ndarray:
    """Move each joint by ``lo``-``hi`` rad (prismatic: a quarter of that in m), random sign."""
    scale = np.where([j.kind == "prismatic" for j in robot.joints], 0.25, 1.0)
    return theta + scale * rng.uniform(lo, hi, robot.dof) * rng.choice([-1.0, 1.0], robot.dof)


def seed_offsets(
    solver: Refiner, seeds: list[np.ndarray], targets: list[tuple[np.ndarray, np.ndarray]]
) -> tuple[np.ndarray, np.ndarray]:
    """Tool position [m] and rotation [deg] offsets of each (projected) seed from its target."""
    pos, rot = [], []
    for seed, (R, p) in zip(seeds, targets, strict=True):
        Rs, ps = solver.pose(solver.project(seed))
        pos.append(float(np.linalg.norm(ps - p)))
        cos = np.clip((np.trace(Rs.T @ R) - 1) / 2, -1, 1)
        rot.append(math.degrees(math.acos(cos)))
    return np.array(pos), np.array(rot)


def summary(label: str, results: list[IKResult], times: list[float]) -> None:
    if not results:
        print(f"  {label:<38} n=   0")
        return
    its = np.array([r.iterations for r in results])
    t = np.array(times) * 1e3
    ok = np.mean([r.success for r in results])
    reasons = dict(Counter(r.reason for r in results).most_common())
    print(
        f"  {label:<38} n={len(results):4d}  success {ok:6.1%}  iterations mean {its.mean():5.2f}"
        f" median {np.median(its):3.0f} p95 {np.percentile(its, 95):3.0f} max {its.max():3d}  "
        f"ms/refine mean {t.mean():.3f} median {np.median(t):.3f} p95 {np.percentile(t, 95):.3f}"
        f"  {reasons}"
    )


def timed(fn: Callable[..., T], *args: Any) -> tuple[T, float]:
    """``fn(*args)`` and its wall time [s]."""
    t0 = time.perf_counter()
    r = fn(*args)
    return r, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--robot", default="tiago")
    ap.add_argument("--n", type=int, default=300, help="random targets")
    ap.add_argument("--n-baseline", type=int, default=100, help="targets for the fixed seed")
    ap.add_argument("--n-multi", type=int, default=10, help="targets for the multi-start oracle")
    ap.add_argument("--starts", type=int, default=50, help="random seeds per multi-start target")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    robot = load(args.robot)
    solver = Refiner(robot)
    rng = np.random.default_rng(args.seed)
    thetas = solver.random_thetas(args.n, rng)
    targets = [solver.pose(th) for th in thetas]
    print(f"robot {robot.name}: dof {robot.dof}, {args.n} random reachable targets")

    fixed = [timed(solver.refine, th, R, p)[1] for th, (R, p) in zip(thetas, targets, strict=True)]
    fixed_us = float(np.median(fixed)) * 1e6
    print(
        f"  fixed cost of one refine (seed = solution: input checks, 1 FK + Jacobian, final "
        f"verifying FK): median {fixed_us:.0f} us"
    )

    for lo, hi in ((0.1, 0.2), (0.02, 0.06)):
        seeds = [perturb(robot, th, rng, lo, hi) for th in thetas]
        sp, sr = seed_offsets(solver, seeds, targets)
        print(
            f"  seeds {lo}-{hi} rad/joint: offset from target median {np.median(sp) * 100:.1f} cm"
            f" (p95 {np.percentile(sp, 95) * 100:.1f}), {np.median(sr):.1f} deg"
            f" (p95 {np.percentile(sr, 95):.1f})"
        )
        runs = [timed(solver.refine, s, R, p) for s, (R, p) in zip(seeds, targets, strict=True)]
        results, times = [r for r, _ in runs], [t for _, t in runs]
        summary(f"refine, seeds {lo}-{hi} rad", results, times)
        its = sum(r.iterations for r in results)
        if its:
            per_it = (sum(times) - len(times) * fixed_us * 1e-6) / its * 1e6
            print(f"    marginal time per iteration: {per_it:.0f} us")
        near = (sp <= 0.05) & (sr <= 15.0)
        summary(
            "  of which seed within 5 cm / 15 deg",
            [r for r, k in zip(results, near, strict=True) if k],
            [t for t, k in zip(times, near, strict=True) if k],
        )
        fails = [r for r in results if not r.success]
        if fails:
            worst = max(fails, key=lambda r: r.pos_err)
            print(
                f"    worst failure: pos_err {worst.pos_err:.4f} m, rot_err {worst.rot_err:.4f} rad"
            )

    runs = [timed(solve_from_fixed_seed, robot, R, p) for R, p in targets[: args.n_baseline]]
    summary("baseline: fixed mid-range seed", [r for r, _ in runs], [t for _, t in runs])

    counts, t_multi = [], []
    for R, p in targets[: args.n_multi]:
        sols, t = timed(solve_multistart, robot, R, p, args.starts, rng)
        counts.append(len(sols))
        t_multi.append(t)
    c = np.array(counts)
    print(
        f"  multi-start oracle ({args.starts} starts, {len(c)} targets): distinct solutions mean "
        f"{c.mean():.1f} min {c.min()} max {c.max()}, found for {np.mean(c > 0):.0%} of targets, "
        f"{np.mean(t_multi) * 1e3:.1f} ms per target"
    )

    far = [(np.eye(3), np.array([3.0, 0.0, 1.0])), (np.eye(3), np.array([0.0, -3.0, 0.5]))]
    runs = [timed(solver.refine, solver.mid_range(), R, p) for R, p in far]
    summary("unreachable (3 m away), mid seed", [r for r, _ in runs], [t for _, t in runs])


if __name__ == "__main__":
    main()
