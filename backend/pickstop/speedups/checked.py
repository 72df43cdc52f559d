"""What a region's computation checked against the scene, as the memo of reuse keeps it.

The links of checked configurations as boxes per joint group (:class:`CheckedLinks`,
:func:`group_boxes_of`, :class:`CheckedConfigs`), the cell answers of
:func:`~pickstop.regions.solve.solve_part` with what each checked (:func:`cell_answers`), and the
exact checks of one :func:`~pickstop.regions.solve.verify` call the memo remembers
(:class:`KnownChecks`): what :mod:`pickstop.speedups.region_memo` tests against a change of the
scene.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pickstop.regions.arm_kernel import configs_touched, group_boxes
from pickstop.regions.kit import RegionKit
from pickstop.scene.world import AGREE_MARGIN
from pickstop.speedups.region_memo import (
    SAME,
    CellAnswers,
    Change,
    ChangeSet,
    ExactCheck,
    RefineMemo,
)


@dataclass(frozen=True)
class TrayView:
    """Where checks are made from, as the memo places them relative to the tray: the base
    ``yaw`` [rad], the tray's position ``tray_xy`` (x, y) [m], and ``around``, the id of the
    tray's surroundings in the memo."""

    yaw: float
    tray_xy: tuple[float, float]
    around: int


@dataclass(frozen=True)
class CheckedLinks:
    """C configurations on their bases as the sphere screen sees them: per joint, a box
    around the covering spheres of every link it carries (the hand's included), padded by
    :data:`AGREE_MARGIN`. Whatever a screen or an exact check of the arm against the scene
    looks at lies in the spheres."""

    lo: np.ndarray  # (C * J, 3) [m]
    hi: np.ndarray  # (C * J, 3)
    owner: np.ndarray  # (C * J,) the id of the thing each box belongs to
    group: np.ndarray  # (C * J,) which joint's group of spheres

    @classmethod
    def of(
        cls, kit: RegionKit, thetas: np.ndarray, xy: np.ndarray, yaw: float, owner: np.ndarray
    ) -> CheckedLinks:
        """``thetas: (C, dof)`` on bases at ``xy: (C, 2)``; ``owner: (C,)`` per configuration."""
        C, J = len(thetas), len(kit.arm.joint_groups.joints)
        lo, hi = group_boxes_of(kit, thetas, xy, yaw, np.arange(C), C)
        return cls(
            lo.reshape(-1, 3), hi.reshape(-1, 3), np.repeat(owner, J), np.tile(np.arange(J), C)
        )


def group_boxes_of(
    kit: RegionKit, thetas: np.ndarray, xy: np.ndarray, yaw: float, owner: np.ndarray, A: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, J, 3)`` twice: per owner ``a`` (``owner: (C,)`` in 0..A-1) and joint group, the box
    that holds the group's covering spheres, padded by :data:`AGREE_MARGIN`, over every
    configuration ``thetas: (C, dof)`` on its base ``xy: (C, 2)`` at ``yaw`` that ``a`` owns
    (inf and -inf where it owns none), compiled
    (:func:`~pickstop.regions.arm_kernel.group_boxes`)."""
    J = len(kit.arm.joint_groups.joints)
    lo, hi = np.full((A, J, 3), np.inf), np.full((A, J, 3), -np.inf)
    if len(thetas):
        group_boxes(*_placed(kit, thetas, xy, owner, yaw), AGREE_MARGIN, lo, hi)
    return lo, hi


_A = np.ndarray
#: The leading arguments of the kernels over placed configurations (see :func:`_placed`).
Placed = tuple[_A, _A, _A, float, float, _A, _A, _A, _A, _A, _A, _A, _A]


def _placed(
    kit: RegionKit, thetas: np.ndarray, xy: np.ndarray, owner: np.ndarray, yaw: float
) -> Placed:
    """The leading arguments of the kernels over C placed configurations
    (:func:`~pickstop.regions.arm_kernel.group_boxes`,
    :func:`~pickstop.regions.arm_kernel.configs_touched`): ``thetas: (C, dof)``, their bases
    ``xy: (C, 2)`` [m], ``owner: (C,)``, the yaw's cosine and sine, the chain's joint placements,
    axes and kinds, and each joint group's joint and sphere box."""
    chain, groups = kit.solver.chain, kit.arm.joint_groups
    return (
        np.ascontiguousarray(thetas, dtype=float).reshape(len(thetas), -1),
        np.ascontiguousarray(xy, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(owner, dtype=np.int64),
        math.cos(yaw),
        math.sin(yaw),
        chain.R_parent_joint,
        chain.p_parent_joint,
        chain.axis_index.astype(np.int64),
        chain.axes,
        chain.prismatic,
        (groups.joints - 1).astype(np.int64),
        groups.lo,
        groups.hi,
    )


@dataclass(frozen=True)
class CheckedConfigs:
    """What some remembered things checked (:meth:`~pickstop.speedups.region_memo.RefineMemo.held`):
    C configurations ``thetas: (C, dof)`` on bases ``xy: (C, 2)`` (relative to the tray [m])
    at ``yaw``, each owned by the thing ``owner: (C,)`` (an id)."""

    kit: RegionKit
    thetas: np.ndarray
    xy: np.ndarray
    yaw: float
    owner: np.ndarray

    def touched_by(self, changes: list[Change], reached: list[np.ndarray]) -> np.ndarray:
        """The ids of the owners some covering sphere of whose configurations, padded by
        :data:`AGREE_MARGIN`, may see a change: ``changes[h]`` for the owners
        ``reached[h]`` (ids) alone. Tested coarse to fine, compiled
        (:func:`~pickstop.regions.arm_kernel.configs_touched`)."""
        ids, inv = np.unique(self.owner, return_inverse=True)
        reach = np.zeros((len(ids), len(reached)), bool)  # (A, H)
        for h, r in enumerate(reached):
            pos = np.minimum(np.searchsorted(ids, r), len(ids) - 1)
            reach[pos[ids[pos] == r], h] = True
        keep = reach[inv].any(1)
        if not keep.any():
            return ids[:0]
        arm = self.kit.arm
        groups = arm.joint_groups
        touched = np.zeros(len(ids), bool)
        cs = ChangeSet.of(changes)
        configs_touched(
            *_placed(self.kit, self.thetas[keep], self.xy[keep], inv[keep], self.yaw),
            np.cumsum([0] + [len(k) for k in groups.links]).astype(np.int64),
            np.concatenate(groups.links).astype(np.int64),
            *arm.link_boxes,
            arm.leaf_start,
            arm.leaf_count,
            arm.leaf_c,
            arm.leaf_r,
            AGREE_MARGIN,
            cs.c_lo,
            cs.c_hi,
            cs.n_lo,
            cs.n_hi,
            cs.moved,
            reach,
            SAME,
            touched,
        )
        return ids[touched]


def cell_answers(
    kit: RegionKit,
    view: TrayView,
    cen: np.ndarray,
    found: np.ndarray,
    thetas: np.ndarray,
    grasps: np.ndarray,
    screened: tuple[np.ndarray, np.ndarray],
    refined: tuple[np.ndarray, np.ndarray],
) -> CellAnswers:
    """The M cells' answers of :func:`~pickstop.regions.solve.solve_part`'s rounds as the
    memo keeps them: the database rows ``screened`` and the joint values ``refined`` checked
    for it (``(cells, rows)`` and ``(cells, thetas)``) and the relative box that holds all
    their links."""
    M, dof = len(cen), kit.solver.chain.dof
    xy = cen - np.asarray(view.tray_xy)
    s_cell, s_rows = screened
    r_cell, r_th = refined
    th = np.concatenate([kit.db.thetas(s_rows).reshape(-1, dof), r_th.reshape(-1, dof)])
    cell = np.concatenate([s_cell, r_cell]).astype(np.int64)
    g_lo, g_hi = group_boxes_of(kit, th, xy[cell], view.yaw, cell, M)
    lo, hi = g_lo.min(axis=1), g_hi.max(axis=1)
    rows_of = _per_cell(s_rows.astype(np.int32), s_cell, M)
    ref_of = _per_cell(r_th.reshape(-1, dof).astype(np.float32), r_cell, M)
    return CellAnswers(
        found.astype(bool),
        np.array(thetas, float),
        np.asarray(grasps, np.int64),
        lo,
        hi,
        xy,
        g_lo,
        g_hi,
        rows_of,
        ref_of,
    )


def _per_cell(values: np.ndarray, cell: np.ndarray, M: int) -> list[np.ndarray]:
    """``values`` (along the first axis) of each of M cells, ``cell`` telling whose each is:
    views of one array sorted by cell (stable: each cell's in their order)."""
    order = np.argsort(cell, kind="stable")
    ends = np.cumsum(np.bincount(cell, minlength=M)).tolist()
    v = values[order]
    return [v[s:e] for s, e in zip([0, *ends[:-1]], ends, strict=True)]


@dataclass
class KnownChecks:
    """The exact arm checks of one :func:`~pickstop.regions.solve.verify` call that the
    tray's memo remembers (``known``: row -> collided), and the keeping of new ones."""

    kit: RegionKit
    view: TrayView
    thetas: np.ndarray
    base_xy: np.ndarray
    keys: dict[int, tuple[int, str, bytes]]
    known: dict[int, bool]
    memo: RefineMemo
    pending: list[tuple[int, bool]] = field(default_factory=list)

    @classmethod
    def of(
        cls,
        kit: RegionKit,
        view: TrayView,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        rows: np.ndarray,
        target_of: Callable[[int], str | None],
        memo: RefineMemo,
        ck: np.ndarray,
    ) -> KnownChecks:
        """Rows ``rows`` (the screen flagged them against the scene) of ``thetas``;
        ``ck: (B,)`` each row's cell key in ``memo``."""
        out = cls(kit, view, thetas, base_xy, {}, {}, memo)
        if not len(rows):
            return out
        out.keys = {j: (int(ck[j]), str(target_of(j)), thetas[j].tobytes()) for j in rows.tolist()}
        order = list(out.keys)
        xy = base_xy[order] - np.asarray(view.tray_xy)
        dof = thetas.shape[1]
        got = memo.remembered_checks(
            [out.keys[j] for j in order],
            view.around,
            lambda rows, ids: CheckedConfigs(
                kit, thetas[np.array(order)[rows]].reshape(-1, dof), xy[rows], view.yaw, ids
            ),
        )
        out.known = {j: g for j, g in zip(order, got, strict=True) if g is not None}
        return out

    def remember(self, j: int, colliding: bool) -> None:
        """Row ``j`` was checked exactly (kept by :meth:`flush`)."""
        if j in self.keys:
            self.pending.append((j, colliding))

    def flush(self) -> None:
        """Keep the checks made since the last flush in the memo, their links' boxes
        computed at once."""
        memo, around = self.memo, self.view.around
        if not self.pending:
            return
        rows = np.array([j for j, _ in self.pending])
        xy = self.base_xy[rows] - np.asarray(self.view.tray_xy)
        links = CheckedLinks.of(self.kit, self.thetas[rows], xy, self.view.yaw, rows)
        n = len(rows)
        g_lo, g_hi = links.lo.reshape(n, -1, 3), links.hi.reshape(n, -1, 3)
        for i, (j, colliding) in enumerate(self.pending):
            memo.remember_check(
                self.keys[j],
                ExactCheck(
                    colliding, around, g_lo[i].min(0), g_hi[i].max(0), xy[i], g_lo[i], g_hi[i]
                ),
            )
        self.pending = []
