"""Error models learned from arrivals: a known anisotropic, biased model fitted back.

    python benchmarks/bench_fit.py [--trials 200] [--seed 0]

Draws ``n`` arrivals (50, 200, 1,000) of one station from a known model in the base frame
(mean (0.04, -0.02) m, standard deviations 0.06 and 0.02 m at 30 degrees, yaw bias 0.02 rad
with yaw sigma 0.03 rad), at stops of random headings, fits them with ``pickstop errors fit``'s
estimator, and prints the recovered mean, axes and yaw against the truth, and over
``--trials`` repetitions how often each 95% interval holds the truth (the mean's two
coordinates, the variances, the covariance). Pure numpy: seconds.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from pickstop.fleet.arrivals import Arrival, Pose
from pickstop.fleet.fit import fit_station
from pickstop.scene.positioning import rot

MEAN = np.array([0.04, -0.02])
SD, ANGLE = (0.06, 0.02), math.radians(30.0)
YAW_MEAN, YAW_SIGMA = 0.02, 0.03


def _truth_cov() -> np.ndarray:
    R = rot(ANGLE)
    return R @ np.diag(np.square(SD)) @ R.T


def _arrivals(n: int, rng: np.random.Generator) -> list[Arrival]:
    C = _truth_cov()
    e = rng.multivariate_normal(MEAN, C, n)
    out = []
    for k in range(n):
        th = float(rng.uniform(-math.pi, math.pi))
        x, y = rng.uniform(0, 5, 2)
        dx, dy = rot(th) @ e[k]  # base frame -> map frame at this stop's heading
        yaw = th + YAW_MEAN + float(rng.normal(0, YAW_SIGMA))
        out.append(Arrival(
            order_id=f"o{k}", node_id="stop0", sequence_id=0, stop=0, trays=["t"],
            manufacturer="sim", serial_number="1", planned=Pose(x=x, y=y, theta=th),
            reported=Pose(x=x + dx, y=y + dy, theta=yaw), time="2026-01-01T00:00:00Z",
            picks=[], ok=True,
        ))  # fmt: skip
    return out


def _inside(v: float, iv: tuple[float, float]) -> bool:
    return iv[0] <= v <= iv[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    C = _truth_cov()
    print(
        f"truth: mean ({MEAN[0]:.3f}, {MEAN[1]:.3f}) m, axes {SD[0]:.3f} x {SD[1]:.3f} m at "
        f"{math.degrees(ANGLE):.0f} deg, yaw bias {YAW_MEAN:.3f} rad, yaw sigma {YAW_SIGMA:.3f}"
    )
    for n in (50, 200, 1000):
        rng = np.random.default_rng([args.seed, n])
        f = fit_station("stop0", ("t",), _arrivals(n, rng))
        print(
            f"n = {n:4d}: mean ({f.mean[0]:+.4f}, {f.mean[1]:+.4f}) m, axes {f.axes[0]:.4f} x "
            f"{f.axes[1]:.4f} m at {math.degrees(f.axes[2]):5.1f} deg, yaw bias "
            f"{f.yaw_mean:+.4f}, yaw sigma {f.yaw_sigma:.4f}"
        )
        hits = np.zeros(5)
        for _ in range(args.trials):
            g = fit_station("stop0", ("t",), _arrivals(n, rng))
            hits += [
                _inside(MEAN[0], g.mean_interval[0]), _inside(MEAN[1], g.mean_interval[1]),
                _inside(C[0, 0], g.variance_interval[0]), _inside(C[1, 1], g.variance_interval[1]),
                _inside(C[0, 1], g.covariance_interval),
            ]  # fmt: skip
        cover = ", ".join(f"{h / args.trials:.0%}" for h in hits)
        print(f"          95% intervals holding the truth over {args.trials} fits "
              f"(mean x, mean y, var x, var y, cov xy): {cover}")  # fmt: skip


if __name__ == "__main__":
    main()
