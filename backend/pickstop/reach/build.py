"""Build a reachability database: sample joints, FK, floor and self-collision screens, bin,
shard, index.

The samples are cut into chunks; chunk ``c`` draws from ``default_rng([seed, c])`` and becomes
one shard, so a chunk's content depends on nothing but its index: an interrupted build resumes
with the missing chunks and ends byte-identical to an uninterrupted one, and chunks can run in
any process (or on any cluster worker) in any order. Once every chunk is in, the shards are
indexed (:mod:`pickstop.reach.index`): what opening the database maps.

This module computes; :func:`pickstop.store.reach_build.build` runs a build, recording its
database, shards and index in the catalog as they are made.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.errors import InputError
from pickstop.progress import Steps
from pickstop.reach.so3 import matrices_to_quats
from pickstop.reach.voxels import VoxelGrid
from pickstop.robot.floor import (
    FLOOR_CLEARANCE,
    MAX_CLEARANCE,
    FloorSpheres,
    below_floor,
    floor_identity,
)
from pickstop.robot.kinematics import BLOCK, Chain, fk_soa, manipulability_soa
from pickstop.robot.model import RobotModel
from pickstop.store.shards import ShardData, write_shard

#: Bumped whenever a change alters what a build stores for the same inputs
#: (2: configurations with a moving link below the floor clearance are dropped).
FORMAT_VERSION = 2
QUANT_LEVELS = 65535  # uint16 joint quantisation: theta = lower + u * (upper - lower) / 65535


@dataclass(frozen=True)
class BuildParams:
    """What a build stores; two builds with equal params and robot hash are identical."""

    samples: int
    resolution: float = 0.05  # position voxel edge [m]
    orientation: int = 6  # SO(3) cells per cube-face edge (4 n^3 cells)
    seed: int = 0
    chunk_size: int = 250_000
    thinning: float = 0.0  # manipulability reference w_ref; keep prob. min(1, w / w_ref); 0 = off
    floor_clearance: float = FLOOR_CLEARANCE  # [m] moving links stay this far above the floor

    def validate(self) -> None:
        if not (1_000 <= self.samples <= 2_000_000_000):
            raise InputError(f"samples must be in [1000, 2e9], got {self.samples}", field="samples")
        if not (0.005 <= self.resolution <= 0.5):
            raise InputError(
                f"resolution must be in [0.005, 0.5] m, got {self.resolution}", field="resolution"
            )
        if not (1 <= self.orientation <= 32):
            raise InputError(
                f"orientation must be in [1, 32] cells per face edge, got {self.orientation}",
                field="orientation",
            )
        if not (1_000 <= self.chunk_size <= 5_000_000):
            raise InputError(
                f"chunk_size must be in [1000, 5e6], got {self.chunk_size}", field="chunk_size"
            )
        if not (0 <= self.seed < 2**63):
            raise InputError(f"seed must be in [0, 2^63), got {self.seed}", field="seed")
        if not (0.0 <= self.thinning < 10.0) or not math.isfinite(self.thinning):
            raise InputError(f"thinning must be in [0, 10), got {self.thinning}", field="thinning")
        c = self.floor_clearance
        if not (math.isfinite(c) and 0.0 <= c <= MAX_CLEARANCE):
            raise InputError(
                f"floor_clearance must be in [0, {MAX_CLEARANCE}] m, got {c}",
                field="floor_clearance",
            )

    @property
    def n_chunks(self) -> int:
        return -(-self.samples // self.chunk_size)

    def chunk_samples(self, chunk: int) -> int:
        return min(self.chunk_size, self.samples - chunk * self.chunk_size)


def database_id(robot_hash: str, params: BuildParams, floor: str = "links") -> str:
    """Deterministic id of the database ``params`` builds for the robot with ``robot_hash``.

    floor: :func:`pickstop.robot.floor.floor_identity`, what the floor filter checks beyond
    the robot hash (the stand-in hand boxes, whose config the robot hash leaves out)."""
    doc = {"robot": robot_hash, "format": FORMAT_VERSION, "floor": floor, **params.__dict__}
    blob = json.dumps(doc, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class BuildKernel:
    """Everything a worker needs to compute a chunk: plain arrays, cheap to pickle."""

    chain: Chain
    spheres: Any  # selfcollision.SphereModel, or None for no self-collision filter
    floor: FloorSpheres | None  # covers of the checked links and hand, None: no floor filter
    voxel: VoxelGrid
    lower: np.ndarray  # (dof,) quantisation range [rad or m]
    upper: np.ndarray  # (dof,)
    params: BuildParams

    @property
    def scale(self) -> np.ndarray:
        return (self.upper - self.lower) / QUANT_LEVELS


@dataclass(frozen=True)
class ChunkResult:
    chunk: int
    sha256: str
    bytes: int
    rows: int
    samples: int
    rejected_self_collision: int
    rejected_thinning: int
    seconds: float
    rejected_floor: int = 0


def dequantise(joints: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """uint16 joints ``(m, dof)`` -> joint values ``(m, dof)`` float64 [rad or m]."""
    return lower + joints.astype(np.float64) * ((upper - lower) / QUANT_LEVELS)


def compute_chunk_data(kernel: BuildKernel, chunk: int) -> tuple[ShardData, int, int, int]:
    """Samples of one chunk -> (sorted shard data, rejected by self-collision, by thinning, by
    the floor).

    The floor screen runs first (it is cheap); self-collision counts only what it kept."""
    p = kernel.params
    m = p.chunk_samples(chunk)
    dof = kernel.chain.dof
    rng = np.random.default_rng([p.seed, chunk])
    u = rng.integers(0, QUANT_LEVELS + 1, size=(m, dof), dtype=np.uint16)
    draws = rng.random(m) if p.thinning > 0 else None
    u_t = np.ascontiguousarray(u.T)
    scale = kernel.scale[:, None]
    lower = kernel.lower[:, None]

    keys_parts, idx_parts, manip_parts = [], [], []
    rej_self = rej_thin = rej_floor = 0
    for s in range(0, m, BLOCK):
        th = lower + u_t[:, s : s + BLOCK] * scale
        R, pos, frames = fk_soa(kernel.chain, th, frames=True)
        B = th.shape[1]
        # Both screens see the whole block (one subset copy after them); a configuration
        # below the floor counts as that, not as a self-collision.
        low = np.zeros(B, bool)
        if kernel.floor is not None:
            low = below_floor(kernel.floor, frames, p.floor_clearance)
            rej_floor += int(low.sum())
        hit = np.zeros(B, bool)
        if kernel.spheres is not None:
            from pickstop.robot.selfcollision import screen

            hit = screen(kernel.spheres, frames) & ~low
            rej_self += int(hit.sum())
        sel = np.flatnonzero(~(low | hit))
        if len(sel) < B:
            frames = [(Rj[:, :, sel], pj[:, sel]) for Rj, pj in frames]
            R, pos = R[:, :, sel], pos[:, sel]
        w = manipulability_soa(kernel.chain, frames, pos)
        if draws is not None:
            keep = draws[s + sel] < w / p.thinning
            rej_thin += int(len(sel) - keep.sum())
            sel, R, pos, w = sel[keep], R[:, :, keep], pos[:, keep], w[keep]
        keys = kernel.voxel.keys(pos.T, matrices_to_quats(R.transpose(2, 0, 1)))
        ok = keys >= 0
        keys_parts.append(keys[ok])
        idx_parts.append(s + sel[ok])
        manip_parts.append(w[ok])
    keys = np.concatenate(keys_parts)
    idx = np.concatenate(idx_parts)
    manip = np.concatenate(manip_parts)
    order = np.argsort(keys, kind="stable")
    data = ShardData(joints=u[idx[order]], manip=manip[order].astype(np.float16))
    return data, rej_self, rej_thin, rej_floor


def shard_relpath(db_id: str, chunk: int) -> str:
    return f"reach/{db_id}/chunk-{chunk:06d}.parquet"


def compute_chunk(kernel: BuildKernel, chunk: int, data_dir: Path, db_id: str) -> ChunkResult:
    """Compute chunk ``chunk`` and write its shard atomically; safe to run anywhere, retried."""
    t0 = time.perf_counter()
    data, rej_self, rej_thin, rej_floor = compute_chunk_data(kernel, chunk)
    sha, nbytes = write_shard(data_dir / shard_relpath(db_id, chunk), data)
    return ChunkResult(
        chunk=chunk,
        sha256=sha,
        bytes=nbytes,
        rows=len(data.manip),
        samples=kernel.params.chunk_samples(chunk),
        rejected_self_collision=rej_self,
        rejected_thinning=rej_thin,
        seconds=time.perf_counter() - t0,
        rejected_floor=rej_floor,
    )


_WORKER_KERNEL: BuildKernel | None = None


def _init_worker(kernel: BuildKernel, nice: int = 0) -> None:
    global _WORKER_KERNEL
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    if nice:
        os.nice(nice)
    _WORKER_KERNEL = kernel


def _run_chunk(chunk: int, data_dir: Path, db_id: str) -> ChunkResult:
    assert _WORKER_KERNEL is not None
    return compute_chunk(_WORKER_KERNEL, chunk, data_dir, db_id)


def make_kernel(
    robot: RobotModel, params: BuildParams, data_dir: Path, steps: Steps | None = None
) -> BuildKernel:
    """The build kernel of ``robot``: its chain, floor and self-collision screens, voxel grid
    (``steps``: told how making a screen not yet cached goes)."""
    from pickstop.robot.artifacts import self_collision
    from pickstop.settings import cache_dir

    _, spheres = self_collision(robot, cache_dir(data_dir), steps)
    return BuildKernel(
        chain=Chain.from_robot(robot),
        spheres=spheres,
        floor=floor_spheres(robot, cache_dir(data_dir)),
        voxel=VoxelGrid(params.resolution, params.orientation),
        lower=robot.lower,
        upper=robot.upper,
        params=params,
    )


def floor_spheres(robot: RobotModel, cache_dir: Path | None) -> FloorSpheres:
    """:meth:`FloorSpheres.of` ``robot``, kept in the cache: the links it covers depend on the
    hand's set-up too (stand-in boxes leave the hand links out), which the name holds."""
    from pickstop.robot.cache import derived

    hand = robot.config.hand
    what = json.dumps([floor_identity(robot), hand.geometry, hand.links])
    name = f"floor-spheres-{hashlib.sha256(what.encode()).hexdigest()[:12]}"
    return derived(robot, cache_dir, name, lambda: FloorSpheres.of(robot))


def screen_figures(robot: RobotModel, data_dir: Path) -> dict[str, Any]:
    """The self-collision screen's false rejection for ``robot``, as catalog columns."""
    from pickstop.robot.artifacts import screen_quality
    from pickstop.settings import cache_dir

    q = screen_quality(robot, cache_dir(data_dir))
    return {
        "screen_false_rejection": q["false_rejection"],
        "screen_flagged": q["flagged"],
        "screen_samples": int(q["n"]),
    }


ChunkRunner = Callable[[BuildKernel, list[int], Path, str], Iterable[ChunkResult]]


def run_local(
    kernel: BuildKernel,
    chunks: list[int],
    data_dir: Path,
    db_id: str,
    workers: int,
    nice: int = 0,
) -> Iterable[ChunkResult]:
    """Compute ``chunks`` in this process (``workers == 1``) or a pool of processes.

    nice: lower the workers' priority by this much (a service building in the background)."""
    if workers <= 1:
        for c in chunks:
            yield compute_chunk(kernel, c, data_dir, db_id)
        return
    ctx = get_context("spawn")
    with ProcessPoolExecutor(
        workers, mp_context=ctx, initializer=_init_worker, initargs=(kernel, nice)
    ) as ex:
        pending: set[Future[ChunkResult]] = set()
        todo = list(chunks)
        try:
            while todo or pending:
                while todo and len(pending) < 2 * workers:  # bounded queue: results stream back
                    pending.add(ex.submit(_run_chunk, todo.pop(0), data_dir, db_id))
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    yield f.result()
        finally:
            for f in pending:
                f.cancel()
