"""Work reused across tray positions: exact IK refinements per base cell anchored to the tray.

A tray's grasps are fixed in the tray's frame. For a fixed base yaw, a base cell at the same
offset from the tray (in whole grid cells) sees the same tool targets in the base frame
wherever the tray stands, so the database candidates of that cell and the configurations
their refinement reaches are the same too. Only what the arm and base meet (the environment)
differs. :class:`RefineMemo` keeps the refinements of one tray (its grasps, the grid phase of
its position, the base yaw), keyed by the cell's offset from the tray, the grasp and the seed;
the region pipeline then runs exactly as from scratch, every environment check included, with
the refinements taken from the memo. A remembered configuration is used only after forward
kinematics confirms, within the IK tolerances, that it reaches the target of the new position.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pickstop.reach.batch_ik import BatchSolver, _errors, refine_batch
from pickstop.reach.ik import POS_TOL, ROT_TOL
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Tray

MAX_ENTRIES = 150_000  # refinements kept per memo (about 25 MB for an 8-joint arm)
MAX_MEMOS = 48  # trays x yaws x grid phases kept
_OFFSET = 1 << 20  # cell offsets are packed as (dx + _OFFSET) << 21 | (dy + _OFFSET)

#: One refinement: where it came from and which grasp of which part, from which cell offset.
MemoKey = tuple[Any, ...]


@dataclass(frozen=True)
class TrayAnchor:
    """Where a tray stands on a base grid: the cell ``(iu, iv)`` its centre falls in and the
    position within that cell, ``phase`` (fractions of a cell, rounded to 1e-6)."""

    iu: int
    iv: int
    phase: tuple[float, float]

    @classmethod
    def of(cls, x0: float, y0: float, res: float, tray: Tray) -> TrayAnchor:
        u, v = (tray.pose.x - x0) / res, (tray.pose.y - y0) / res
        iu, iv = math.floor(u + 1e-6), math.floor(v + 1e-6)
        return cls(iu, iv, (round(u - iu, 6) % 1.0, round(v - iv, 6) % 1.0))

    def cell_keys(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """``(M,)`` int64 keys of grid cells ``(ix, iy)`` by their offset from the tray."""
        dx = np.asarray(ix, np.int64) - self.iu + _OFFSET
        dy = np.asarray(iy, np.int64) - self.iv + _OFFSET
        return (dx << 21) | dy


def grasps_digest(tray: Tray, grasp_sets: list[GraspSet]) -> str:
    """The grasps' tool poses relative to the tray's position (the same after a translation)."""
    h = hashlib.sha256()
    t = np.array([tray.pose.x, tray.pose.y, tray.pose.z])
    for gs in grasp_sets:
        T = gs.Ts_world_tool.copy()
        T[:, :3, 3] -= t
        h.update(gs.part_id.encode())
        h.update(np.round(T, 9).tobytes())
    return h.hexdigest()


@dataclass
class RefineMemo:
    """Refinements of one tray's grasps from cells anchored to it (see the module)."""

    results: dict[MemoKey, np.ndarray | None] = field(default_factory=dict)
    served_cells: dict[int, bool] = field(default_factory=dict)
    hits: int = 0
    misses: int = 0

    def served(
        self, cell_keys: np.ndarray, compute: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """``(M,)`` whether the database serves each cell (``compute(idx)`` for the cells
        not yet known, by index into ``cell_keys``): a lookup of the targets alone."""
        keys = cell_keys.tolist()
        out = np.zeros(len(keys), bool)
        todo = []
        for i, k in enumerate(keys):
            v = self.served_cells.get(k)
            if v is None:
                todo.append(i)
            else:
                out[i] = v
        if todo:
            idx = np.array(todo)
            got = compute(idx)
            out[idx] = got
            if len(self.served_cells) + len(idx) > MAX_ENTRIES:
                self.served_cells.clear()
            self.served_cells.update(zip(cell_keys[idx].tolist(), got.tolist(), strict=True))
        return out

    def refine(
        self,
        solver: BatchSolver,
        keys: list[MemoKey],
        seeds: np.ndarray,
        Rs_target: np.ndarray,
        ps_target: np.ndarray,
        max_iter: int,
        give_up: tuple[tuple[int, float], ...],
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~pickstop.reach.batch_ik.refine_batch` of ``seeds: (B, n)`` towards
        ``(B, 3, 3)``, ``(B, 3)`` targets, remembered by ``keys`` (one per row).

        Returns ``thetas: (B, n)`` and ``success: (B,)``. A remembered failure stays one (the
        same seed towards the same target); a remembered success is re-checked by FK.
        """
        B = len(keys)
        assert seeds.shape[0] == B and Rs_target.shape == (B, 3, 3) and ps_target.shape == (B, 3)
        thetas = np.array(seeds, dtype=np.float64)
        success = np.zeros(B, bool)
        todo: list[int] = []
        known: list[int] = []
        for i, k in enumerate(keys):
            if k in self.results:
                known.append(i)
            else:
                todo.append(i)
        if known:
            got = [self.results[keys[i]] for i in known]
            ok = np.array([g is not None for g in got])
            idx = np.array(known)[ok]
            if len(idx):
                thetas[idx] = np.stack([g for g in got if g is not None])
                good = _reaches(solver, thetas[idx], Rs_target[idx], ps_target[idx])
                success[idx[good]] = True
                todo += idx[~good].tolist()  # the target moved more than noise: refine anew
            self.hits += len(known)
        if todo:
            t = np.array(sorted(todo))
            res = refine_batch(
                solver, seeds[t], Rs_target[t], ps_target[t], max_iter=max_iter, give_up=give_up
            )
            thetas[t] = res.thetas
            success[t] = res.success
            if len(self.results) + len(t) > MAX_ENTRIES:
                self.results.clear()
            for j, i in enumerate(t.tolist()):
                self.results[keys[i]] = res.thetas[j].copy() if res.success[j] else None
            self.misses += len(t)
        return thetas, success


def _reaches(
    solver: BatchSolver, thetas: np.ndarray, Rs_target: np.ndarray, ps_target: np.ndarray
) -> np.ndarray:
    """``(B,)`` True where ``thetas`` reach their targets within the IK tolerances."""
    R, p = fk_soa(solver.chain, np.ascontiguousarray(thetas.T))[:2]
    _, ang = _errors(
        R, p, np.ascontiguousarray(Rs_target.transpose(1, 2, 0)), np.ascontiguousarray(ps_target.T)
    )
    pos = np.linalg.norm(p - ps_target.T, axis=0)
    return (pos <= POS_TOL) & (ang <= ROT_TOL)


class ReuseCache(OrderedDict[str, RefineMemo]):
    """The memos of the last trays x yaws x grid phases planned (least recently used go)."""

    def memo(self, key: str) -> RefineMemo:
        hit = self.get(key)
        if hit is None:
            hit = self[key] = RefineMemo()
            while len(self) > MAX_MEMOS:
                self.popitem(last=False)
        self.move_to_end(key)
        return hit
