"""Index a built database once: the tool pose of every stored row, rows merged by voxel key.

The shards hold quantised joints in build order; queries need rows grouped by voxel and the
tool pose of each row to rank candidates. Both follow from the joints by FK, so they are
computed here, once, when a build completes (or for a database built before indices existed),
and written as the memory-mapped index of :mod:`pickstop.store.reach_index` (the build records
it in the catalog).

Memory is bounded: each shard is posed and sorted on its own (pass 1, to temporary files),
then the shards are merged one key range at a time (pass 2) straight into the mapped output.
Rows of equal key keep shard order, then build order: the same order as a stable sort of all
shards concatenated, so candidates and their ranking do not depend on how the merge was cut.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import shutil
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.errors import DatabaseError
from pickstop.reach.build import dequantise
from pickstop.reach.so3 import matrices_to_quats
from pickstop.reach.voxels import VoxelGrid
from pickstop.robot.kinematics import Chain, fk
from pickstop.store.reach_index import (
    ARRAYS,
    ArrayFile,
    create_array,
    index_relpath,
    seal_array,
)
from pickstop.store.shards import read_shard

#: Rows merged at once in pass 2 (each costs about 100 bytes of memory while merged).
MERGE_ROWS = 1 << 20
_STEP = 1 << 18  # rows posed at once


def tool_poses(
    chain: Chain, voxel: VoxelGrid, thetas_of: Any, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tool poses and voxel keys of ``n`` rows: ``positions (n, 3)``, ``quats (n, 4)`` float32,
    ``keys (n,)`` int64. ``thetas_of(s, e)`` gives the joint values of rows ``s:e`` [rad or m].
    """
    positions = np.empty((n, 3), np.float32)
    quats = np.empty((n, 4), np.float32)
    keys = np.empty(n, np.int64)
    for s in range(0, n, _STEP):
        e = min(s + _STEP, n)
        R, p = fk(chain, thetas_of(s, e))
        q = matrices_to_quats(R)
        positions[s:e] = p
        quats[s:e] = q
        keys[s:e] = voxel.keys(p, q)
    return positions, quats, keys


def index_database(
    data_dir: Path,
    row: dict[str, Any],
    shards: list[dict[str, Any]],
    chain: Chain,
    workers: int = 1,
    nice: int = 0,
) -> tuple[list[ArrayFile], dict[str, Any]]:
    """Build the voxel index of the complete database ``row`` from its ``shards`` (catalog
    rows ``chunk, path, sha256``, in chunk order; each is verified as it is read).

    workers: processes posing the shards (pass 1), their priority lowered by ``nice`` (a
    service building in the background). Written to a temporary folder, then moved in
    place; returns the files written and the figures (voxels, reach_xy, seconds) for the
    catalog to record.
    """
    t0 = time.perf_counter()
    data_dir = Path(data_dir)
    db_id, dof = row["id"], row["dof"]
    voxel = VoxelGrid(row["resolution"], row["orientation"])
    lower, upper = _joint_range(row)
    if len(shards) != math.ceil(row["samples"] / row["chunk_size"]):
        raise DatabaseError(f"database {db_id}: catalog lists {len(shards)} shards, expected more")
    final = data_dir / index_relpath(db_id)
    work = final.with_name(f"index.tmp{os.getpid()}")
    shutil.rmtree(work, ignore_errors=True)
    try:
        # Pass 1: pose each shard's rows and sort them by key, one shard at a time.
        jobs = [
            _PoseJob(data_dir / s["path"], s["sha256"], dof, work / f"chunk-{s['chunk']:06d}",
                     chain, voxel, lower, upper)
            for s in shards
        ]  # fmt: skip
        _pose_all(jobs, workers, nice)
        # Pass 2: merge key range by key range into the index's arrays.
        out_dir = work / "index"
        all_keys, reach_xy = _merge(jobs, dof, out_dir)
        rel = index_relpath(db_id)
        files: list[ArrayFile] = [
            seal_array(name, out_dir / f"{name}.npy", f"{rel}/{name}.npy") for name in ARRAYS
        ]
        # In place: a process still mapping the old index keeps reading its (unlinked) files.
        old = final.with_name(f"index.old{os.getpid()}")
        if final.exists():
            final.rename(old)
        (out_dir).rename(final)
        shutil.rmtree(old, ignore_errors=True)
        figures = {"voxels": len(all_keys), "reach_xy": reach_xy,
                   "seconds": time.perf_counter() - t0}  # fmt: skip
        return files, figures
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _pose_all(jobs: list[_PoseJob], workers: int, nice: int) -> None:
    """Pass 1 over every shard, on up to ``workers`` processes lowered by ``nice``."""
    workers = max(1, min(workers, len(jobs)))
    if workers == 1:
        for job in jobs:
            _pose_shard(job)
        return
    ctx = get_context("spawn")
    with ProcessPoolExecutor(
        workers, mp_context=ctx, initializer=_init_worker, initargs=(nice,)
    ) as ex:
        list(ex.map(_pose_shard, jobs))


def _merge(jobs: list[_PoseJob], dof: int, out_dir: Path) -> tuple[np.ndarray, float]:
    """Pass 2: the shards' sorted rows merged key range by key range, appended to the output
    arrays in ``out_dir``; then the voxel keys and starts saved. Inputs are mapped afresh for
    each range and written with plain writes, so what this process holds stays about one
    range, not the database. Returns the voxel keys and the farthest reach in xy [m]."""
    n = sum(_open(job.out, "keys").shape[0] for job in jobs)
    bounds = _merge_bounds([_open(job.out, "keys") for job in jobs], n)
    shapes = {"joints": (n, dof), "manip": (n,), "positions": (n, 3), "quats": (n, 4)}
    offsets = {}
    for name, shape in shapes.items():
        arr = create_array(out_dir / f"{name}.npy", ARRAYS[name], shape)
        offsets[name] = arr.offset
        del arr
    voxel_keys, voxel_counts = [], []
    reach_xy = 0.0
    at = 0
    for lo, hi in itertools.pairwise(bounds):
        m, reach = _merge_range(jobs, lo, hi, out_dir, offsets, at, voxel_keys, voxel_counts)
        reach_xy = max(reach_xy, reach)
        at += m
    assert at == n, (at, n)
    all_keys = np.concatenate(voxel_keys) if voxel_keys else np.empty(0, np.int64)
    counts = np.concatenate(voxel_counts) if voxel_counts else np.empty(0, np.int64)
    np.save(out_dir / "keys.npy", all_keys.astype(ARRAYS["keys"]))
    np.save(out_dir / "starts.npy", np.r_[0, np.cumsum(counts)].astype(ARRAYS["starts"]))
    return all_keys, reach_xy


def _merge_range(
    jobs: list[_PoseJob],
    lo: int,
    hi: int,
    out_dir: Path,
    offsets: dict[str, int],
    at: int,
    voxel_keys: list[np.ndarray],
    voxel_counts: list[np.ndarray],
) -> tuple[int, float]:
    """The rows of keys in ``[lo, hi)`` merged and written at row ``at``; their voxels' keys
    and counts appended. Returns the rows written and their farthest reach in xy [m]."""
    parts = [{name: _open(job.out, name) for name in _PASS1} for job in jobs]
    cuts = [
        (int(np.searchsorted(p["keys"], lo)), int(np.searchsorted(p["keys"], hi))) for p in parts
    ]
    keys = np.concatenate([p["keys"][a:b] for p, (a, b) in zip(parts, cuts, strict=True)])
    m = len(keys)
    reach_xy = 0.0
    if m == 0:
        return 0, reach_xy
    order = np.argsort(keys, kind="stable")
    for name in offsets:
        merged = np.concatenate([p[name][a:b] for p, (a, b) in zip(parts, cuts, strict=True)])
        merged = merged[order]
        with open(out_dir / f"{name}.npy", "r+b") as f:
            f.seek(offsets[name] + at * merged[:1].nbytes)
            merged.tofile(f)
        if name == "positions":
            reach_xy = float(np.hypot(merged[:, 0], merged[:, 1]).max())
    keys = keys[order]
    first = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    voxel_keys.append(keys[first])
    voxel_counts.append(np.diff(np.r_[first, m]))
    return m, reach_xy


_PASS1 = ("keys", "joints", "manip", "positions", "quats")


@dataclass(frozen=True)
class _PoseJob:
    """Pass 1 of one shard: read it (checked), pose and sort its rows into ``out``."""

    shard: Path
    sha256: str
    dof: int
    out: Path
    chain: Chain
    voxel: VoxelGrid
    lower: np.ndarray
    upper: np.ndarray


def _open(folder: Path, name: str) -> np.ndarray:
    return np.load(folder / f"{name}.npy", mmap_mode="r")


def _init_worker(nice: int) -> None:
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    if nice:
        os.nice(nice)


def _pose_shard(job: _PoseJob) -> None:
    data = read_shard(job.shard, job.sha256, job.dof)
    j = data.joints
    pos, quat, keys = tool_poses(
        job.chain, job.voxel, lambda a, b: dequantise(j[a:b], job.lower, job.upper), len(j)
    )
    order = np.argsort(keys, kind="stable")
    job.out.mkdir(parents=True)
    cols = {"keys": keys, "joints": j, "manip": data.manip, "positions": pos, "quats": quat}
    for name in _PASS1:
        np.save(job.out / f"{name}.npy", cols[name][order])


def _joint_range(row: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(json.loads(row["joint_lower"])), np.asarray(json.loads(row["joint_upper"]))


def _merge_bounds(keys: list[np.ndarray], n: int) -> list[int]:
    """Key boundaries ``b_0 < ... < b_P`` cutting ``n`` sorted rows into ranges of about
    :data:`MERGE_ROWS` (a voxel never straddles two), chosen from a sample of the keys."""
    lowest, highest = np.iinfo(np.int64).min, np.iinfo(np.int64).max
    n_ranges = max(1, math.ceil(n / MERGE_ROWS))
    if n_ranges == 1:
        return [lowest, highest]
    step = max(1, n // (64 * n_ranges))
    sample = np.sort(np.concatenate([k[::step] for k in keys]))
    cuts = sample[np.linspace(0, len(sample), n_ranges, endpoint=False).astype(int)[1:]]
    return [lowest, *np.unique(cuts).tolist(), highest]
