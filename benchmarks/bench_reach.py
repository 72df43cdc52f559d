"""Reachability database figures: FK rate, build rate, disk, peak memory, open, query speed.

    python benchmarks/bench_reach.py --samples 10000000

Builds into a fresh temporary data folder (or --data-dir) with all cores, then loads the
database and times queries. Prints one figure per line.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from pickstop.reach.build import BuildParams
from pickstop.robot.kinematics import Chain, fk, manipulability
from pickstop.robot.model import load
from pickstop.store.reach_build import build
from pickstop.store.reach_catalog import list_databases, open_database


def _rss_mb(who: int) -> float:
    return resource.getrusage(who).ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robot", default="tiago")
    ap.add_argument("--samples", type=int, default=10_000_000)
    ap.add_argument("--resolution", type=float, default=0.05)
    ap.add_argument("--orientation", type=int, default=6)
    ap.add_argument("--workers", type=int, default=os.cpu_count())
    ap.add_argument("--data-dir", type=Path)
    ap.add_argument("--queries", type=int, default=1_000_000)
    args = ap.parse_args()

    robot = load(args.robot)
    chain = Chain.from_robot(robot)
    rng = np.random.default_rng(0)
    th = rng.uniform(robot.lower, robot.upper, (200_000, robot.dof))
    fk(chain, th[:1000])
    t = time.perf_counter()
    for _ in range(5):
        fk(chain, th)
    print(f"fk_float64_one_core: {5 * len(th) / (time.perf_counter() - t) / 1e6:.2f} M configs/s")
    t = time.perf_counter()
    manipulability(chain, th)
    print(
        f"fk+manipulability_one_core: {len(th) / (time.perf_counter() - t) / 1e6:.2f} M configs/s"
    )

    tmp = None
    data_dir = args.data_dir
    if data_dir is None:
        tmp = tempfile.mkdtemp(prefix="pickstop-bench-")
        data_dir = Path(tmp)
    try:
        params = BuildParams(
            samples=args.samples, resolution=args.resolution, orientation=args.orientation
        )
        # Self-collision pairs are computed (and cached) once per robot; time them apart.
        t = time.perf_counter()
        build(robot, BuildParams(samples=1000, chunk_size=1000), data_dir, workers=1)
        print(f"first_use_setup (disabled pairs, spheres): {time.perf_counter() - t:.1f} s")
        t = time.perf_counter()
        row = build(robot, params, data_dir, workers=args.workers)
        dt = time.perf_counter() - t
        info = next(r for r in list_databases(data_dir) if r["id"] == row["id"])
        nbytes = sum(s["bytes"] for s in info["shards"])
        index_bytes = sum(f["bytes"] for f in info.get("index", []))
        print(f"build_samples: {args.samples}  workers: {args.workers}")
        print(f"build_seconds: {dt:.1f}")
        print(f"build_rate: {args.samples / dt:,.0f} samples/s (incl. self-collision screen)")
        print(
            f"stored: {row['stored']:,} ({row['stored'] / args.samples:.1%}); "
            f"rejected_self_collision: {row['rejected_self_collision']:,}"
        )
        print(f"disk: {nbytes / 1e6:.1f} MB = {nbytes / row['stored']:.2f} MB per million stored")
        if index_bytes:
            total = nbytes + index_bytes
            print(
                f"disk_index: {index_bytes / 1e6:.1f} MB (mapped, uncompressed); shards + index "
                f"{total / 1e6:.1f} MB = {total / row['stored']:.2f} MB per million stored; "
                f"indexing took {row['index_seconds']:.1f} s of the build"
            )
        print(
            f"peak_rss_main: {_rss_mb(resource.RUSAGE_SELF):.0f} MB  "
            f"peak_rss_largest_worker: {_rss_mb(resource.RUSAGE_CHILDREN):.0f} MB"
        )

        t = time.perf_counter()
        db = open_database(data_dir, robot, row["id"])
        print(f"load_seconds: {time.perf_counter() - t:.3f}")
        print(f"voxels: {db.n_voxels:,}  mean configs/voxel: {len(db) / db.n_voxels:.1f}")
        print(f"peak_rss_after_load: {_rss_mb(resource.RUSAGE_SELF):.0f} MB")

        # Targets: tool poses of random collision-free-ish configurations (reachable).
        rows = rng.integers(0, len(db), args.queries)
        ps = db.positions[rows].astype(np.float64) + rng.normal(0, 0.01, (args.queries, 3))
        qs = db.quats[rows].astype(np.float64)
        qs /= np.linalg.norm(qs, axis=1, keepdims=True)
        lat = []
        found = 0
        for i in range(20_000):
            t = time.perf_counter()
            c = db.query(ps[i], qs[i])
            lat.append(time.perf_counter() - t)
            found += len(c.rows) > 0
        lat_us = np.array(lat) * 1e6
        print(
            f"query_one_pose: p50 {np.percentile(lat_us, 50):.0f} us  p99 "
            f"{np.percentile(lat_us, 99):.0f} us  mean {lat_us.mean():.0f} us  "
            f"(hit rate {found / len(lat):.0%})"
        )
        t = time.perf_counter()
        c = db.query(ps[0], qs[0], neighbours=True)
        print(
            f"query_one_pose_with_neighbours: {(time.perf_counter() - t) * 1e3:.2f} ms "
            f"({len(c.rows)} candidates)"
        )
        t = time.perf_counter()
        starts, ends = db.lookup(ps, qs)
        dt = time.perf_counter() - t
        print(
            f"batch_lookup: {args.queries / dt / 1e6:.2f} M poses/s "
            f"({(ends > starts).mean():.0%} hit, {(ends - starts).sum():,} candidates)"
        )
        t = time.perf_counter()
        cs = db.query_many(ps, qs, order=True)
        dt = time.perf_counter() - t
        print(
            f"batch_query_ranked: {args.queries / dt / 1e6:.2f} M poses/s "
            f"({len(cs.rows):,} candidates ranked per target)"
        )
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
