"""A reachability database opened for queries: IK by query.

Rows are sorted by voxel key; ``unique_keys[i]`` owns rows ``offsets[i]:offsets[i + 1]``. The
tool pose of every row was computed when the database was indexed, so candidates are ranked by
how close their pose is to a target without any kinematics at open. The arrays are memory-mapped
read-only (:mod:`pickstop.store.reach_index`): processes share them through the page cache and a
query reads only the voxels it touches. Finding and opening a database by id reads the catalog:
:func:`pickstop.store.reach_catalog.open_database`.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.errors import QueryError
from pickstop.reach.build import dequantise
from pickstop.reach.voxels import VoxelGrid
from pickstop.robot.model import RobotModel
from pickstop.store.reach_index import OpenStats

#: Length that turns a rotation error into a distance when ranking candidates [m/rad].
RANK_LENGTH = 0.1


@dataclass(frozen=True)
class IKSeeds:
    """Stored configurations whose tool pose is near one target: approximate IK solutions,
    best first, the seeds that refinement turns into exact ones."""

    rows: np.ndarray  # (k,) database rows
    thetas: np.ndarray  # (k, dof) joint values [rad or m]
    pos_err: np.ndarray  # (k,) distance of the stored tool position to the target [m]
    rot_err: np.ndarray  # (k,) rotation angle between stored and target orientation [rad]
    keys: np.ndarray  # (k,) voxel keys


@dataclass(frozen=True)
class IKSeedSet:
    """The seeds of many targets in CSR form: target i owns ``rows[offsets[i]:offsets[i+1]]``."""

    offsets: np.ndarray  # (M + 1,) int64
    rows: np.ndarray  # (total,) int64


def check_poses(ps: Any, qs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Validate target positions ``(M, 3)`` [m] and quaternions ``(M, 4)`` wxyz; normalise q."""
    ps = np.asarray(ps, dtype=np.float64)
    qs = np.asarray(qs, dtype=np.float64)
    if ps.ndim != 2 or ps.shape[1] != 3:
        raise QueryError(f"positions must have shape (M, 3), got {ps.shape}", field="positions")
    if qs.shape != (ps.shape[0], 4):
        raise QueryError(
            f"quaternions must have shape ({ps.shape[0]}, 4) wxyz, got {qs.shape}",
            field="quaternions",
        )
    if not np.isfinite(ps).all():
        raise QueryError("positions contain NaN or infinity", field="positions")
    if not np.isfinite(qs).all():
        raise QueryError("quaternions contain NaN or infinity", field="quaternions")
    norms = np.linalg.norm(qs, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-3)
    if len(bad):
        raise QueryError(
            f"quaternion {bad[0]} has norm {norms[bad[0]]:.6f}; give a unit quaternion wxyz",
            field="quaternions",
        )
    return ps, qs / norms[:, None]


class ReachDatabase:
    """Read-only after construction: safe to share between threads (and forked processes)."""

    def __init__(
        self,
        info: dict[str, Any],
        *,
        unique_keys: np.ndarray,
        offsets: np.ndarray,
        joints: np.ndarray,
        manip: np.ndarray,
        positions: np.ndarray,
        quats: np.ndarray,
        reach_xy: float | None = None,
        stats: OpenStats | None = None,
    ) -> None:
        """Rows sorted by voxel key (arrays in memory or mapped):

        unique_keys: (V,) int64 ascending; offsets: (V + 1,) int64, voxel i owns rows
        ``offsets[i]:offsets[i + 1]``; joints: (N, dof) uint16 quantised; manip: (N,);
        positions: (N, 3) [m] and quats: (N, 4) wxyz float32, the tool pose of each row;
        reach_xy: the largest horizontal tool reach [m] (computed from positions if None).
        """
        n = len(joints)
        assert offsets.shape == (len(unique_keys) + 1,), (offsets.shape, unique_keys.shape)
        assert manip.shape == (n,) and positions.shape == (n, 3) and quats.shape == (n, 4)
        self.info = info
        self.id: str = info["id"]
        self.voxel = VoxelGrid(info["resolution"], info["orientation"])
        self.lower = np.asarray(json.loads(info["joint_lower"]))
        self.upper = np.asarray(json.loads(info["joint_upper"]))
        self.unique_keys = unique_keys
        self.offsets = offsets
        self.joints = joints
        self.manip = manip
        self.positions = positions
        self.quats = quats
        if reach_xy is None:
            reach_xy = float(np.hypot(positions[:, 0], positions[:, 1]).max()) if n else 0.0
        #: The largest horizontal distance of a stored tool position from the base [m].
        self.reach_xy = reach_xy
        #: What opening cost: files hashed because they changed since last verified.
        self.stats = stats or OpenStats()

    @cached_property
    def keys(self) -> np.ndarray:
        """Voxel key ``(N,)`` of every row, expanded on first use (N * 8 bytes in memory)."""
        return np.repeat(np.asarray(self.unique_keys), np.diff(self.offsets))

    def keys_of(self, rows: np.ndarray) -> np.ndarray:
        """Voxel keys ``(k,)`` of database ``rows``, from the voxel index alone."""
        return np.asarray(
            self.unique_keys[np.searchsorted(self.offsets, rows, side="right") - 1], np.int64
        )

    def __len__(self) -> int:
        return len(self.joints)

    @property
    def n_voxels(self) -> int:
        return len(self.unique_keys)

    def thetas(self, rows: np.ndarray) -> np.ndarray:
        """Joint values ``(k, dof)`` [rad or m] of database rows."""
        return dequantise(self.joints[rows], self.lower, self.upper)

    def _rows_of_keys(self, keys: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(self.unique_keys, keys)
        pos = np.minimum(pos, len(self.unique_keys) - 1)
        found = self.unique_keys[pos] == keys
        pos = pos[found]
        if len(pos) == 0:
            return np.empty(0, np.int64)
        return np.concatenate([np.arange(self.offsets[i], self.offsets[i + 1]) for i in pos])

    def _rank(self, rows: np.ndarray, p: np.ndarray, q: np.ndarray, limit: int | None) -> IKSeeds:
        pos_err = np.linalg.norm(self.positions[rows] - p, axis=1)
        dot = np.abs(self.quats[rows] @ q)
        rot_err = 2.0 * np.arccos(np.minimum(dot, 1.0))
        order = np.argsort(pos_err + RANK_LENGTH * rot_err, kind="stable")
        if limit is not None:
            order = order[:limit]
        rows = rows[order]
        return IKSeeds(
            rows=rows,
            thetas=self.thetas(rows),
            pos_err=pos_err[order],
            rot_err=rot_err[order],
            keys=self.keys_of(rows),
        )

    def query(
        self, p: Any, q: Any, *, neighbours: bool = False, limit: int | None = None
    ) -> IKSeeds:
        """The seeds of one target pose ``T_base_tool`` (``p: (3,)`` [m], ``q: (4,)`` wxyz).

        neighbours: also the adjacent voxels (the paper's vicinity of the target).
        """
        ps, qs = check_poses(
            np.reshape(p, (1, -1)) if np.size(p) == 3 else p,
            np.reshape(q, (1, -1)) if np.size(q) == 4 else q,
        )
        pv, qv = ps[0], qs[0]
        if neighbours:
            rows = self._rows_of_keys(self.voxel.neighbour_keys(pv, qv))
        else:
            key = self.voxel.key_one((pv[0], pv[1], pv[2]), (qv[0], qv[1], qv[2], qv[3]))
            i = int(np.searchsorted(self.unique_keys, key))
            if i < len(self.unique_keys) and self.unique_keys[i] == key:
                rows = np.arange(self.offsets[i], self.offsets[i + 1])
            else:
                rows = np.empty(0, np.int64)
        return self._rank(rows, pv, qv, limit)

    def lookup(self, ps: np.ndarray, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row ranges of many targets' own voxels: ``starts, ends: (M,)`` (empty if equal).

        The hot path of region computation; inputs are trusted (use :func:`check_poses`).
        """
        return self.lookup_keys(self.voxel.keys(ps, qs))

    def lookup_keys(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row ranges ``starts, ends`` of voxel ``keys`` (empty where absent or -1)."""
        keys = np.asarray(keys, dtype=np.int64)
        pos = np.searchsorted(self.unique_keys, keys)
        np.minimum(pos, len(self.unique_keys) - 1, out=pos)
        found = (self.unique_keys[pos] == keys) & (keys >= 0)
        return np.where(found, self.offsets[pos], 0), np.where(found, self.offsets[pos + 1], 0)

    def lookup_vicinity(
        self, ps: np.ndarray, qs: np.ndarray, full: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Row ranges of the position voxels next to each target, in its orientation cell.

        The own voxel and its 6 face neighbours (``full``: all 27 around it). Returns
        ``starts, ends: (M, 7 or 27)``: the paper's vicinity of a target pose.
        """
        cells = self.voxel.position_cells(ps)  # (M, 3)
        orient = self.voxel.so3.index(qs)  # (M,)
        offs = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)])
        if not full:
            offs = offs[np.abs(offs).sum(axis=1) <= 1]
        keys = self.voxel.keys_from_cells(cells[:, None, :] + offs, orient[:, None])
        return self.lookup_keys(keys)

    def query_many(self, ps: Any, qs: Any, *, order: bool = True) -> IKSeedSet:
        """The seeds of many targets (own voxel), each target's ranked best first if ``order``."""
        ps, qs = check_poses(ps, qs)
        starts, ends = self.lookup(ps, qs)
        counts = ends - starts
        offsets = np.zeros(len(ps) + 1, np.int64)
        np.cumsum(counts, out=offsets[1:])
        total = int(offsets[-1])
        owner = np.repeat(np.arange(len(ps)), counts)
        rows = np.arange(total) - np.repeat(offsets[:-1], counts) + np.repeat(starts, counts)
        if order and total:
            pos_err = np.linalg.norm(self.positions[rows] - ps[owner], axis=1)
            dot = np.abs(np.einsum("ij,ij->i", self.quats[rows], qs[owner]))
            score = pos_err + RANK_LENGTH * 2.0 * np.arccos(np.minimum(dot, 1.0))
            rows = rows[np.lexsort((score, owner))]
        return IKSeedSet(offsets=offsets, rows=rows.astype(np.int64))


_BUILD_FLAGS = (
    ("--samples", "samples"),
    ("--resolution", "resolution"),
    ("--orientation", "orientation"),
    ("--seed", "seed"),
    ("--chunk-size", "chunk_size"),
    ("--thinning", "thinning"),
)


def robot_arg(robot: RobotModel) -> str:
    """What ``--robot`` takes to load ``robot`` again: the preset name or the config file path
    it was loaded from (its name when it was loaded by name, as the API's robots are)."""
    return robot.source or robot.name


def build_command(
    row: dict[str, Any] | None, robot: RobotModel, data_dir: Path | str | None = None
) -> str:
    """The ``pickstop reach build`` command that builds (or resumes, or indexes) ``row``
    (None: a first database with the default parameters); ``data_dir``: the data folder to
    name with ``--data-dir`` (None: the default one)."""
    args = ["pickstop", *(["--data-dir", str(data_dir)] if data_dir is not None else [])]
    args += ["reach", "build", "--robot", robot_arg(robot)]
    if row is not None:
        for flag, column in _BUILD_FLAGS:
            args += [flag, str(row[column])]
        clearance = row.get("floor_clearance")
        if clearance is not None:
            args += ["--floor-clearance", str(clearance)]
    return shlex.join(args)
