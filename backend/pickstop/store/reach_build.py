"""Run a reachability build, recording it in the catalog: register, resume, shard, index.

The computing is :mod:`pickstop.reach.build` (chunks) and :mod:`pickstop.reach.index` (the
voxel index); this records what they make, so an interrupted build resumes with the chunks
it lacks and a complete one is not built twice.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterable
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any

import pickstop
from pickstop.errors import DatabaseError
from pickstop.progress import Steps, step
from pickstop.reach.build import (
    FORMAT_VERSION,
    BuildParams,
    ChunkResult,
    ChunkRunner,
    database_id,
    make_kernel,
    run_local,
    screen_figures,
    shard_relpath,
)
from pickstop.reach.index import index_database
from pickstop.robot.floor import floor_identity
from pickstop.robot.kinematics import Chain
from pickstop.robot.model import RobotModel
from pickstop.store import reach_catalog as rc
from pickstop.store.catalog import Catalog
from pickstop.store.reach_index import file_sha256


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _register(catalog: Catalog, db_id: str, robot: RobotModel, params: BuildParams) -> dict:
    row = rc.database_row(catalog, db_id)
    if row is not None:
        return row
    row = {
        "id": db_id,
        "robot": robot.name,
        "robot_hash": robot.robot_hash,
        "dof": robot.dof,
        "resolution": params.resolution,
        "orientation": params.orientation,
        "samples": params.samples,
        "seed": params.seed,
        "chunk_size": params.chunk_size,
        "thinning": params.thinning,
        "floor_clearance": params.floor_clearance,
        "code_version": f"{pickstop.__version__}+format{FORMAT_VERSION}",
        "joint_lower": json.dumps(robot.lower.tolist()),
        "joint_upper": json.dumps(robot.upper.tolist()),
        "state": "building",
        "builder": rc.builder_tag(),  # named from the start: no delete comes between
        "created": _now(),
    }
    rc.insert_database(catalog, row)
    return row


def _chunks_done(catalog: Catalog, db_id: str, data_dir: Path) -> set[int]:
    """Chunks whose shard is recorded and present with the recorded size and checksum."""
    done = set()
    for r in rc.shards(catalog, db_id):
        f = data_dir / r["path"]
        if f.is_file() and f.stat().st_size == r["bytes"] and file_sha256(f) == r["sha256"]:
            done.add(r["chunk"])
        else:  # a vanished or altered shard is computed again
            rc.forget_shard(catalog, db_id, r["chunk"])
    return done


def _shard_row(db_id: str, res: ChunkResult) -> dict[str, Any]:
    return {
        "chunk": res.chunk,
        "path": shard_relpath(db_id, res.chunk),
        "sha256": res.sha256,
        "bytes": res.bytes,
        "rows": res.rows,
        "samples": res.samples,
        "rejected_self_collision": res.rejected_self_collision,
        "rejected_thinning": res.rejected_thinning,
        "rejected_floor": res.rejected_floor,
        "seconds": res.seconds,
    }


def build(
    robot: RobotModel,
    params: BuildParams,
    data_dir: Path,
    *,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    max_chunks: int | None = None,
    runner: ChunkRunner | None = None,
    nice: int = 0,
    steps: Steps | None = None,
) -> dict[str, Any]:
    """Build (or resume) the database of ``robot`` with ``params``; return its catalog row.

    progress: called with (samples done, samples total) once the screens are ready, then as
    chunks come in. max_chunks: stop after computing that many chunks (the database stays
    'building' and resumes on the next call). steps: told of what comes before and after the
    chunks (the robot's screen on a first build, the index; :mod:`pickstop.progress`).
    """
    params.validate()
    data_dir = Path(data_dir)
    catalog = Catalog(data_dir)
    db_id = database_id(robot.robot_hash, params, floor_identity(robot))
    row = _register(catalog, db_id, robot, params)
    t0 = time.perf_counter()
    done = _chunks_done(catalog, db_id, data_dir)
    if (
        row["state"] == "complete"
        and len(done) == params.n_chunks
        and rc.index_intact(catalog, row, data_dir)
    ):
        catalog.close()
        return row
    # Building (again): a shard that went missing or was altered is recomputed (the content is
    # deterministic); the row names this process until the build ends, complete or not (made
    # again if a delete came since it was read).
    rc.claim_build(catalog, row)
    todo = [c for c in range(params.n_chunks) if c not in done]
    if max_chunks is not None:
        todo = todo[:max_chunks]
    workers = workers or os.cpu_count() or 1
    run = runner or (
        lambda k, c, d, i: run_local(k, c, d, i, min(workers, max(len(c), 1)), nice=nice)
    )
    try:
        kernel = make_kernel(robot, params, data_dir, steps)
        rc.update_database(catalog, db_id, screen_figures(robot, data_dir))
        step(steps, "")
        chunks = partial(run, kernel, todo, data_dir, db_id)
        _run_chunks(catalog, db_id, params, chunks, done, progress)
        if len(done) == params.n_chunks:
            _index(catalog, db_id, data_dir, kernel.chain, workers, nice, steps)
    finally:
        # Whatever stopped it (Ctrl-C, an error, a chunk limit), an unfinished build is
        # 'interrupted' until the same command resumes it; a killed one is found out by
        # list_databases from its builder tag.
        rc.end_build(catalog, db_id, time.perf_counter() - t0)
    return _finish(catalog, db_id, params, done, max_chunks)


def _run_chunks(
    catalog: Catalog,
    db_id: str,
    params: BuildParams,
    chunks: Callable[[], Iterable[ChunkResult]],
    done: set[int],
    progress: Callable[[int, int], None] | None,
) -> None:
    """Compute the chunks (``chunks()``, after a first ``progress``), recording each one's
    shard as it comes in, adding it to ``done`` and telling ``progress`` (samples done, samples
    total)."""
    samples_done = sum(params.chunk_samples(c) for c in done)
    if progress:
        progress(samples_done, params.samples)
    for res in chunks():
        rc.record_shard(catalog, db_id, _shard_row(db_id, res))
        done.add(res.chunk)
        samples_done += res.samples
        if progress:
            progress(samples_done, params.samples)


def _index(
    catalog: Catalog,
    db_id: str,
    data_dir: Path,
    chain: Chain,
    workers: int,
    nice: int,
    steps: Steps | None,
) -> None:
    """The voxel index of the complete database, built and recorded."""
    current = rc.database_row(catalog, db_id)
    assert current is not None
    step(steps, "indexing the stored configurations")
    files, figures = index_database(
        data_dir, current, rc.shards(catalog, db_id), chain, workers, nice
    )
    rc.record_index(catalog, db_id, files, figures)
    step(steps, "")


def _finish(
    catalog: Catalog, db_id: str, params: BuildParams, done: set[int], max_chunks: int | None
) -> dict[str, Any]:
    """The database marked complete if every chunk is done; its row (the catalog closed).
    Missing chunks without a chunk limit are an error."""
    if len(done) == params.n_chunks:
        fields: dict[str, Any] = {"state": "complete", "completed": _now()}
        rc.update_database(catalog, db_id, {**fields, **rc.shard_totals(catalog, db_id)})
    out = rc.database_row(catalog, db_id)
    assert out is not None
    catalog.close()
    if out["state"] != "complete" and max_chunks is None:
        raise DatabaseError(f"database {db_id}: build ended with missing chunks")
    return out
