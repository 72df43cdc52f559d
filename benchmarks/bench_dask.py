"""Dask scale-out on this machine: batch planning and a database build, Dask vs local.

    python benchmarks/bench_dask.py [--scenes 100] [--db ID] [--build-samples 4000000]

Generates ``scenes`` variants of the paper-like scene (trays shifted along their table, sigma
varied), plans them in one process and on a 2-worker local Dask cluster, and prints both
throughputs and their ratio; then builds a database (new seed) with 2 local processes and on
the cluster. Workers load the database once each (included in the Dask time).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pickstop.distributed import client_for, dask_runner, plan_batch, plan_task
from pickstop.reach.build import BuildParams
from pickstop.robot.model import load
from pickstop.settings import data_dir
from pickstop.store.reach_build import build

SCENE = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"


def scenes(n: int, seed: int = 0) -> list[tuple[str, dict, Path]]:
    rng = np.random.default_rng(seed)
    base = json.loads(SCENE.read_text())
    out = []
    for k in range(n):
        doc = copy.deepcopy(base)
        doc["name"] = f"variant-{k:03d}"
        doc["sigma"] = float(rng.uniform(0.03, 0.12))
        for t in doc["trays"]:
            t["pose"]["x"] += float(rng.uniform(-0.03, 0.03))
        out.append((doc["name"], doc, SCENE.parent))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", type=int, default=100)
    ap.add_argument("--db", default="82741eced49c0018", help="default: the 2M demo database")
    ap.add_argument("--build-samples", type=int, default=4_000_000)
    args = ap.parse_args()
    folder = data_dir()
    items = scenes(args.scenes)
    opts = {"samples": 0}

    t0 = time.perf_counter()
    ok = sum("error" not in plan_task(d, opts, str(r), str(folder), args.db) for _, d, r in items)
    local = time.perf_counter() - t0
    print(f"batch, one process: {len(items)} scenes ({ok} planned) in {local:.1f} s, "
          f"{len(items) / local:.2f} scenes/s (database load included)")  # fmt: skip

    client = client_for("local")
    t0 = time.perf_counter()
    res = dict(plan_batch(client, items, opts, folder, args.db))
    dask = time.perf_counter() - t0
    ok = sum("error" not in r for r in res.values())
    print(f"batch, local Dask cluster of 2 workers: {len(res)} scenes ({ok} planned) in "
          f"{dask:.1f} s, {len(res) / dask:.2f} scenes/s; throughput ratio "
          f"{local / dask:.2f}x")  # fmt: skip

    robot = load("tiago")
    params = BuildParams(samples=args.build_samples, seed=4242)
    with tempfile.TemporaryDirectory() as tmp:
        for name, runner in (("2 local processes", None), ("local Dask, 2 workers",
                                                           dask_runner(client))):  # fmt: skip
            target = Path(tmp) / name.replace(" ", "_").replace(",", "")
            shutil.copytree(folder / "cache", target / "cache", dirs_exist_ok=True)
            os.environ["PICKSTOP_CACHE_DIR"] = str(target / "cache")
            t0 = time.perf_counter()
            row = build(robot, params, target, workers=2, runner=runner)
            dt = time.perf_counter() - t0
            print(f"build {args.build_samples:,} samples, {name}: {dt:.1f} s, "
                  f"{args.build_samples / dt:,.0f} samples/s ({row['state']})")  # fmt: skip
    client.close()


if __name__ == "__main__":
    main()
