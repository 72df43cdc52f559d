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

A cell's whole answer from the database (which candidate verifies, or none) is remembered too
(:meth:`RefineMemo.recall`), with the box that holds every configuration its computation
checked against the scene (the links' bounding spheres) and the tray's surroundings then
(:class:`Surroundings`, relative to the tray). Solved per cell, the answer depends on the scene
only through what lies inside that box; where the surroundings, seen from the tray, are the
same inside it (:func:`changes`), the answer is the same and is taken as it was. A table the
tray slides along is the same inside the box unless the box reaches one of its ends.

A cell whose remembered witness was verified in other surroundings keeps it where it is free of
what is new since (:meth:`RefineMemo.newcomers`: solids not where one of the same shape stood):
against everything else, the floor and itself it was checked exactly then, at the same place
relative to the tray. Such a cell is feasible however its answer from scratch would go, so a
region after a move holds every cell the database solves from scratch, and perhaps more, each
with a verified witness. Growth from solved cells seeds the open ones with their witnesses: a
cell that kept another witness than scratch would pick may grow other neighbours, so at the
region's edge a grown cell may differ either way (every one verified all the same). A cell
grown before tries the witness it was grown with first (:attr:`RefineMemo.grown`): where it
still reaches the target (the same, relative to the cell) and verifies exactly in the new
surroundings, no seed is refined for it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from pickstop.caching import Cache
from pickstop.reach.batch_ik import BatchSolver, _errors, refine_batch
from pickstop.reach.ik import POS_TOL, ROT_TOL
from pickstop.regions.arm_kernel import boxes_hit
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Tray
from pickstop.scene.world import Solid

MAX_ENTRIES = 150_000  # refinements kept per memo (about 25 MB for an 8-joint arm)
MAX_MEMOS = 48  # trays x yaws x grid phases kept
MAX_ANSWERS = 20_000  # cell answers kept per memo
MAX_CHECKS = 20_000  # exact checks kept per memo
MAX_BYTES = 384 << 20  # about what all memos together may hold
# about what one entry holds [bytes] (arrays and their Python objects, an 8-joint arm)
BYTES_PER = (
    ("results", 200), ("served_cells", 60), ("answers", 1100), ("checks", 900), ("grown", 320)
)  # fmt: skip
MAX_SURROUNDINGS = 8  # surroundings a memo's cell answers may refer to
SAME = 1e-9  # [m] bounds this close are the same
# Of this many remembered things a change reaches, every SAMPLE_STEP-th is tested first; if
# fewer than WORTH_TESTING of those still hold, the rest are taken as changed untested.
SAMPLE_FROM = 400
SAMPLE_STEP = 8
WORTH_TESTING = 0.25
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


@dataclass(frozen=True)
class Surroundings:
    """The solids around a tray, seen from the tray: bounds relative to its position (x, y)."""

    solids: tuple[Solid, ...]  # kept alive: a mesh's geometry is compared by identity
    lo: np.ndarray  # (S, 3) relative bounds [m]
    hi: np.ndarray  # (S, 3)
    shape: tuple[tuple[Any, ...], ...]  # (S,) owner, kind, size, rotation, geometry: all but where
    boxes: np.ndarray  # (S,) bool: a box whose bounds are the box (an axis-aligned box)
    at: np.ndarray  # (3,) the tray's position (x, y, 0) they were seen from [m]

    @classmethod
    def of(cls, solids: list[Solid], tray: Tray) -> Surroundings:
        at = np.array([tray.pose.x, tray.pose.y, 0.0])
        bounds = [s.aabb() for s in solids]
        lo = np.array([b[0] - at for b in bounds]).reshape(-1, 3)
        hi = np.array([b[1] - at for b in bounds]).reshape(-1, 3)
        shape = tuple(
            (
                s.owner,
                s.kind,
                tuple(np.round(s.half, 12)),
                s.radius,
                np.round(s.T_world_solid[:3, :3], 12).tobytes(),
                id(s.geometry) if s.kind == "mesh" else None,
            )
            for s in solids
        )
        boxes = np.array([s.aligned_box for s in solids], bool)
        return cls(tuple(solids), lo, hi, shape, boxes, at)

    def relative(self, k: int) -> Solid:
        """Solid ``k`` placed relative to the tray (the tray's position at the origin)."""
        s = self.solids[k]
        T = s.T_world_solid.copy()
        T[:3, 3] -= self.at
        return dataclasses.replace(s, T_world_solid=T)

    def owners_within(self, lo: np.ndarray, hi: np.ndarray) -> set[str]:
        """Owners of the solids whose bounds meet any of the boxes ``lo, hi: (K, 3)``."""
        if not len(lo) or not len(self.lo):
            return set()
        meet = ChangeSet.boxes(self.lo, self.hi).hit(lo, hi).any(1)
        return {self.solids[k].owner for k in np.flatnonzero(meet)}


def _meets(alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray) -> np.ndarray:
    """Do boxes ``a`` and ``b`` (broadcast, bounds on the last axis) touch or overlap?"""
    return np.all((alo <= bhi + SAME) & (blo <= ahi + SAME), axis=-1)


@dataclass(frozen=True)
class Change:
    """One way two surroundings differ: a box a solid filled before or fills now (``new_lo``
    None), or an axis-aligned box that moved (``lo, hi`` to ``new_lo, new_hi``)."""

    lo: np.ndarray  # (3,) [m]
    hi: np.ndarray
    new_lo: np.ndarray | None = None
    new_hi: np.ndarray | None = None

    def hits(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """``(K,)`` True where the boxes ``lo, hi: (K, 3)`` may see the change; False: inside
        the box the solid is as it was (or was and is nowhere)."""
        if self.new_lo is None or self.new_hi is None:
            return _meets(lo, hi, self.lo, self.hi)
        out = _meets(lo, hi, self.lo, self.hi) | _meets(lo, hi, self.new_lo, self.new_hi)
        k = np.flatnonzero(out)
        if not len(k):
            return out
        # Both clip the box to the same bounds, or both miss it: the same inside it.
        return self._clipped_alike(lo, hi, out, k)

    def _clipped_alike(
        self, lo: np.ndarray, hi: np.ndarray, out: np.ndarray, k: np.ndarray
    ) -> np.ndarray:
        assert self.new_lo is not None and self.new_hi is not None
        q_lo, q_hi = lo[k], hi[k]
        a_lo, a_hi = np.maximum(q_lo, self.lo), np.minimum(q_hi, self.hi)
        b_lo, b_hi = np.maximum(q_lo, self.new_lo), np.minimum(q_hi, self.new_hi)
        a_empty = np.any(a_lo > a_hi + SAME, axis=1)
        b_empty = np.any(b_lo > b_hi + SAME, axis=1)
        with np.errstate(invalid="ignore"):  # an empty box (inf bounds) clips to nothing
            same = np.all(np.abs(a_lo - b_lo) <= SAME, axis=1) & np.all(
                np.abs(a_hi - b_hi) <= SAME, axis=1
            )
        out[k] = ~((a_empty & b_empty) | (~a_empty & ~b_empty & same))
        return out


@dataclass(frozen=True)
class ChangeSet:
    """Changes as the compiled kernels take them: ``c_lo, c_hi: (H, 3)`` the boxes, and
    where ``moved[h]``, the box it moved to ``n_lo, n_hi`` (NaN elsewhere)."""

    changes: tuple[Change, ...]
    c_lo: np.ndarray
    c_hi: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    moved: np.ndarray

    @classmethod
    def of(cls, changes: list[Change] | tuple[Change, ...]) -> ChangeSet:
        nan = np.full(3, np.nan)
        return cls(
            tuple(changes),
            np.array([c.lo for c in changes], float).reshape(-1, 3),
            np.array([c.hi for c in changes], float).reshape(-1, 3),
            np.array([nan if c.new_lo is None else c.new_lo for c in changes]).reshape(-1, 3),
            np.array([nan if c.new_hi is None else c.new_hi for c in changes]).reshape(-1, 3),
            np.array([c.new_lo is not None for c in changes], bool),
        )

    @classmethod
    def boxes(cls, lo: np.ndarray, hi: np.ndarray) -> ChangeSet:
        """Boxes ``lo, hi: (H, 3)`` that fill a place (a :class:`Change` each)."""
        lo = np.ascontiguousarray(lo, float).reshape(-1, 3)
        hi = np.ascontiguousarray(hi, float).reshape(-1, 3)
        nan = np.full_like(lo, np.nan)
        return cls((), lo, hi, nan, nan, np.zeros(len(lo), bool))

    def hit(
        self,
        lo: np.ndarray,
        hi: np.ndarray,
        groups: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """``(H, n)`` where change ``h`` may see the box ``lo[i], hi[i]`` (``(n, 3)``), as
        :meth:`Change.hits` says, and (with ``groups``: finer boxes ``(n, J, 3)`` inside each)
        one of the finer boxes of box ``i`` too; compiled
        (:func:`~pickstop.regions.arm_kernel.boxes_hit`)."""
        n = len(lo)
        out = np.zeros((len(self.c_lo), n), bool)
        if not n or not len(self.c_lo):
            return out
        g_lo, g_hi = (np.zeros((n, 0, 3)),) * 2 if groups is None else groups
        boxes_hit(
            np.ascontiguousarray(lo, float), np.ascontiguousarray(hi, float),
            np.ascontiguousarray(g_lo, float), np.ascontiguousarray(g_hi, float),
            self.c_lo, self.c_hi, self.n_lo, self.n_hi, self.moved, SAME, out,
        )  # fmt: skip
        return out


def changes(old: Surroundings, new: Surroundings) -> list[Change]:
    """How ``new`` differs from ``old``, seen from the tray.

    Solids of the same shape and owner are paired in order. A pair where it was is no change;
    an axis-aligned box that moved, the one solid of its owner that did, is one
    :class:`Change` that tells where they look alike (a table the tray slides along); any
    other pair that moved (the walls and floor of another tray), and any solid without a
    partner, changes the box it was or is in (those of one owner merged into one box: a
    handful of changes to test, not one per wall).
    """
    partners: dict[tuple[Any, ...], list[int]] = {}
    for k, key in enumerate(new.shape):
        partners.setdefault(key, []).append(k)
    seen: dict[tuple[Any, ...], int] = {}
    used = np.zeros(len(new.shape), bool)
    out: list[Change] = []
    # per side (before, now) and owner: the union of the boxes
    filled: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}

    def fill(owner: tuple[str, str], lo: np.ndarray, hi: np.ndarray) -> None:
        was = filled.get(owner)
        filled[owner] = (
            (lo, hi) if was is None else (np.minimum(was[0], lo), np.maximum(was[1], hi))
        )

    slid: dict[str, list[tuple[int, int]]] = {}  # per owner, the boxes that moved
    for j, key in enumerate(old.shape):
        n = seen.get(key, 0)
        seen[key] = n + 1
        mine = partners.get(key, [])
        if n >= len(mine):
            fill(("old", key[0]), old.lo[j], old.hi[j])
            continue
        k = mine[n]
        used[k] = True
        if np.all(np.abs(old.lo[j] - new.lo[k]) <= SAME) and np.all(
            np.abs(old.hi[j] - new.hi[k]) <= SAME
        ):
            continue  # the same solid where it was
        if old.boxes[j] and new.boxes[k]:
            slid.setdefault(key[0], []).append((j, k))
        else:
            fill(("old", key[0]), old.lo[j], old.hi[j])
            fill(("new", key[0]), new.lo[k], new.hi[k])
    for u in np.flatnonzero(~used).tolist():
        fill(("new", new.shape[u][0]), new.lo[u], new.hi[u])
    for owner, pairs in slid.items():
        if len(pairs) == 1 and ("old", owner) not in filled and ("new", owner) not in filled:
            ((j, k),) = pairs
            out.append(Change(old.lo[j], old.hi[j], new.lo[k], new.hi[k]))
            continue
        for j, k in pairs:
            fill(("old", owner), old.lo[j], old.hi[j])
            fill(("new", owner), new.lo[k], new.hi[k])
    return out + [Change(lo, hi) for lo, hi in filled.values()]


def _newcomers(was: Surroundings, new: Surroundings) -> tuple[Solid, ...]:
    """:meth:`RefineMemo.newcomers` of ``new`` since ``was``."""
    out: list[Solid] = []
    by_shape: dict[tuple[Any, ...], list[int]] = {}
    for j, key in enumerate(was.shape):
        by_shape.setdefault(key, []).append(j)
    for k, key in enumerate(new.shape):
        alike = by_shape.get(key, [])
        if alike and bool(
            (
                np.all(np.abs(was.lo[alike] - new.lo[k]) <= SAME, axis=1)
                & np.all(np.abs(was.hi[alike] - new.hi[k]) <= SAME, axis=1)
            ).any()
        ):
            continue
        boxes = [j for j in alike if was.boxes[j]] if new.boxes[k] else []
        if not boxes:
            out.append(new.relative(k))
            continue
        mid = (new.lo[k] + new.hi[k]) / 2
        j = min(boxes, key=lambda j: float(np.linalg.norm((was.lo[j] + was.hi[j]) / 2 - mid)))
        for lo, hi in box_minus(new.lo[k], new.hi[k], was.lo[j], was.hi[j]):
            T = np.eye(4)
            T[:3, 3] = (lo + hi) / 2
            out.append(Solid.box(T, hi - lo, key[0]))
    return tuple(out)


def box_minus(
    lo: np.ndarray, hi: np.ndarray, cut_lo: np.ndarray, cut_hi: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed boxes (at most six, none thinner than :data:`SAME`) that cover the box
    ``lo, hi`` wherever it sticks out of the box ``cut_lo, cut_hi`` (bounds (3,) [m])."""
    out = []
    lo, hi = np.array(lo, float), np.array(hi, float)
    for a in range(3):
        if cut_lo[a] > lo[a] + SAME:
            top = hi.copy()
            top[a] = min(cut_lo[a], hi[a])
            out.append((lo.copy(), top))
            lo[a] = top[a]
        if cut_hi[a] < hi[a] - SAME:
            bottom = lo.copy()
            bottom[a] = max(cut_hi[a], lo[a])
            out.append((bottom, hi.copy()))
            hi[a] = bottom[a]
        if hi[a] - lo[a] <= SAME:
            break  # nothing is left inside the cut
    return [(a, b) for a, b in out if np.all(b - a > SAME)]


class Checked(Protocol):
    """What some remembered things checked (configurations of the arm, each owned by the id of
    the thing it belongs to), tested finely against changes on demand."""

    def touched_by(self, changes: list[Change], reached: list[np.ndarray]) -> np.ndarray:
        """The ids of the owners whose checks may see a change: ``changes[h]`` for the ids
        ``reached[h]`` alone."""
        ...


#: What was checked for some cell answers, given one id per answer.
CheckedOf = Callable[["CellAnswers", np.ndarray], Checked]


@dataclass
class CellAnswers:
    """What the database gave M cells for one part, column by column: per cell whether a
    witness verified, the witness and its grasp, the relative box ``lo, hi`` [m] that holds
    every configuration checked for it, and those configurations: database rows and refined
    joint values."""

    found: np.ndarray  # (M,) bool
    theta: np.ndarray  # (M, dof)
    grasp: np.ndarray  # (M,) int
    lo: np.ndarray  # (M, 3)
    hi: np.ndarray  # (M, 3)
    xy: np.ndarray  # (M, 2) the cells' centres relative to the tray [m]
    groups_lo: np.ndarray  # (M, J, 3) per joint, the box of its links over the configurations
    groups_hi: np.ndarray
    rows: list[np.ndarray]  # (M,) of (r,) int32: database candidates screened
    refined: list[np.ndarray]  # (M,) of (k, dof) float32: refinements verified

    def __len__(self) -> int:
        return len(self.found)

    def take(self, idx: np.ndarray) -> CellAnswers:
        """The answers ``idx: (K,)`` (indices)."""
        il = idx.tolist()
        return CellAnswers(
            self.found[idx], self.theta[idx], self.grasp[idx], self.lo[idx], self.hi[idx],
            self.xy[idx], self.groups_lo[idx], self.groups_hi[idx],
            [self.rows[i] for i in il], [self.refined[i] for i in il],
        )  # fmt: skip


_COLUMNS = ("found", "theta", "grasp", "lo", "hi", "xy", "groups_lo", "groups_hi")


class AnswerTable:
    """The remembered answers of one tag and part, by cell key (:class:`CellAnswers`' columns
    and ``around``: which of the memo's surroundings each was computed in, the one column
    that changes, :meth:`RefineMemo.recall`). A cell answered again takes its row anew."""

    def __init__(self) -> None:
        self.row_of: dict[int, int] = {}
        self.cols: CellAnswers | None = None
        self.around = np.zeros(0, np.int64)

    def __len__(self) -> int:
        return len(self.row_of)

    def find(self, cell_keys: np.ndarray) -> np.ndarray:
        """``(M,)`` the row of each cell key, -1 where none is kept."""
        get = self.row_of.get
        return np.fromiter((get(k, -1) for k in cell_keys.tolist()), np.int64, len(cell_keys))

    def put(self, cell_keys: np.ndarray, answers: CellAnswers, around: int) -> None:
        keys = cell_keys.tolist()
        rows = np.empty(len(keys), np.int64)
        for i, k in enumerate(keys):  # a cell key given twice keeps its last answer
            rows[i] = self.row_of.setdefault(k, len(self.row_of))
        n = len(self.row_of)
        if self.cols is None:
            self.cols = dataclasses.replace(
                answers.take(np.zeros(0, np.int64)), rows=[], refined=[]
            )
        cols = self.cols
        if n > len(cols):
            cap = max(n, 2 * len(cols), 64)
            for name in _COLUMNS:
                old = getattr(cols, name)
                new = np.zeros((cap, *old.shape[1:]), old.dtype)
                new[: len(old)] = old
                setattr(cols, name, new)
            self.around = np.concatenate([self.around, np.zeros(cap - len(self.around), np.int64)])
            cols.rows += [np.zeros(0, np.int32)] * (cap - len(cols.rows))
            cols.refined += [np.zeros((0, answers.theta.shape[1]), np.float32)] * (
                cap - len(cols.refined)
            )
        for name in _COLUMNS:
            getattr(cols, name)[rows] = getattr(answers, name)
        self.around[rows] = around
        for r, a, b in zip(rows.tolist(), answers.rows, answers.refined, strict=True):
            cols.rows[r], cols.refined[r] = a, b


@dataclass
class Answers:
    """A memo's remembered cell answers: an :class:`AnswerTable` per tag and part."""

    tables: dict[tuple[str, str], AnswerTable] = field(default_factory=dict)

    def __len__(self) -> int:
        return sum(len(t) for t in self.tables.values())

    def clear(self) -> None:
        self.tables.clear()


@dataclass
class ExactCheck:
    """One exact check of the arm against the scene, remembered: whether it collided, in
    which of the memo's surroundings, and the relative box [m] of its links and its base.
    Only ``around`` ever changes (:meth:`RefineMemo.remembered_checks`)."""

    colliding: bool
    around: int
    lo: np.ndarray  # (3,)
    hi: np.ndarray  # (3,)
    xy: np.ndarray  # (2,)
    groups_lo: np.ndarray  # (J, 3) per joint, the box of its links
    groups_hi: np.ndarray


@dataclass
class RefineMemo:
    """Refinements of one tray's grasps from cells anchored to it (see the module)."""

    results: dict[MemoKey, np.ndarray | None] = field(default_factory=dict)
    served_cells: dict[int, bool] = field(default_factory=dict)
    answers: Answers = field(default_factory=Answers)
    surroundings: OrderedDict[int, Surroundings] = field(default_factory=OrderedDict)
    hits: int = 0
    misses: int = 0
    recalled: int = 0  # cell answers taken as they were
    carried: int = 0  # of those, witnesses kept after a check against the newcomers alone
    # exact checks of the arm against the scene: (cell key, part, joint values) -> whether it
    # collided, the surroundings then, the box of its links and its base (relative [m])
    checks: dict[tuple[int, str, bytes], ExactCheck] = field(default_factory=dict)
    checks_reused: int = 0
    regrown: int = 0  # parts of grown cells solved by the witness they were grown with before
    # the witness (joint values, grasp) of each (part, cell key) last grown into the region
    grown: dict[tuple[str, int], tuple[np.ndarray, int]] = field(default_factory=dict)
    _next: int = 0
    _change_memo: Cache[tuple[int, int], ChangeSet] = field(
        default_factory=lambda: Cache("refine_memo.changes", max_items=4 * MAX_SURROUNDINGS)
    )
    _newcomer_memo: Cache[tuple[int, int], tuple[Solid, ...]] = field(
        default_factory=lambda: Cache("refine_memo.newcomers", max_items=4 * MAX_SURROUNDINGS)
    )
    _newcomer_box_memo: Cache[tuple[int, int], ChangeSet] = field(
        default_factory=lambda: Cache("refine_memo.newcomer_boxes", max_items=4 * MAX_SURROUNDINGS)
    )

    def approx_bytes(self) -> int:
        """About how much memory the memo holds [bytes] (:data:`BYTES_PER` entry)."""
        return sum(n * len(getattr(self, name)) for name, n in BYTES_PER)

    def around(self, now: Surroundings) -> int:
        """The id of the surroundings ``now`` among the memo's (added if new)."""
        for k, s in self.surroundings.items():
            if (
                s.shape == now.shape
                and np.array_equal(s.lo, now.lo)
                and np.array_equal(s.hi, now.hi)
            ):
                self.surroundings.move_to_end(k)
                return k
        k, self._next = self._next, self._next + 1
        self.surroundings[k] = now
        while len(self.surroundings) > MAX_SURROUNDINGS:
            self.surroundings.popitem(last=False)
        return k

    def held(
        self,
        arounds: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        now: int,
        checked: Callable[[np.ndarray], Checked],
        groups: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """``(n,)`` whether each of n things remembered still holds in the surroundings
        ``now``: one computed in surroundings ``arounds[i]`` (``(n,)`` ids) whose checks all
        lay in the box ``lo[i], hi[i]`` (relative [m]) holds where no change since reaches
        the box, or where the finer boxes of what it checked (``checked(indices)``, tested
        coarse to fine) stay clear of every change that does. ``groups``: finer boxes
        ``(n, J, 3)`` each, tested before the configurations are."""
        arounds = np.asarray(arounds, np.int64)
        out = np.zeros(len(arounds), bool)
        for k in np.unique(arounds).tolist():
            if k not in self.surroundings:
                continue
            ix = np.flatnonzero(arounds == k)
            if k == now:
                out[ix] = True
                continue
            held = np.ones(len(ix), bool)
            cs = self._changes(k, now)
            hit = cs.hit(lo[ix], hi[ix], None if groups is None else (groups[0][ix], groups[1][ix]))
            fine = [(c, np.flatnonzero(h)) for c, h in zip(cs.changes, hit, strict=True) if h.any()]
            if fine:
                near = np.unique(np.concatenate([h for _, h in fine]))
                if len(near) >= SAMPLE_FROM:
                    # A sample first: where nearly everything near a change did change, the
                    # rest is computed anew without testing it (that costs as much).
                    sample = near[::SAMPLE_STEP]
                    self._finely(ix, sample, fine, held, checked)
                    if held[sample].mean() < WORTH_TESTING:
                        held[near] = False
                        near = near[:0]
                    else:
                        near = np.setdiff1d(near, sample)
                if len(near):
                    self._finely(ix, near, fine, held, checked)
            out[ix] = held
        return out

    @staticmethod
    def _finely(
        ix: np.ndarray,
        part: np.ndarray,
        fine: list[tuple[Change, np.ndarray]],
        held: np.ndarray,
        checked: Callable[[np.ndarray], Checked],
    ) -> None:
        """:meth:`held`'s fine stage for ``part`` (indices into ``ix``), in place: each
        change against the finer boxes of the things it reached."""
        reached = [ix[np.intersect1d(hit, part)] for _, hit in fine]
        bad = checked(ix[part]).touched_by([c for c, _ in fine], reached)
        held[np.searchsorted(ix, bad)] = False

    def remembered_checks(
        self,
        keys: list[tuple[int, str, bytes]],
        now: int,
        checked: Callable[[np.ndarray, np.ndarray], Checked],
    ) -> list[bool | None]:
        """The remembered outcome of each exact check ``keys`` that still holds in the
        surroundings ``now`` (:meth:`held`), else None. ``checked(rows, ids)``: the links of
        the checks ``rows`` (indices into ``keys``), owned by ``ids``."""
        got = [self.checks.get(k) for k in keys]
        idx = [i for i, g in enumerate(got) if g is not None]
        out: list[bool | None] = [None] * len(keys)
        if not idx:
            return out
        mine = [g for g in got if g is not None]
        ok = self.held(
            np.array([g.around for g in mine], np.int64),
            np.array([g.lo for g in mine]),
            np.array([g.hi for g in mine]),
            now,
            lambda sel: checked(np.array(idx)[sel], sel),
            (np.array([g.groups_lo for g in mine]), np.array([g.groups_hi for g in mine])),
        )
        for i, g, o in zip(idx, mine, ok.tolist(), strict=True):
            if o:
                out[i] = g.colliding
                g.around = now  # it holds there: a check in ``now`` has the same outcome
        self.checks_reused += int(ok.sum())
        return out

    def remember_grown(
        self, parts: list[str], cell_keys: np.ndarray, thetas: np.ndarray, grasps: np.ndarray
    ) -> None:
        """Keep the witnesses ``thetas: (M, P, dof)`` and grasps ``(M, P)`` of cells
        ``cell_keys: (M,)`` grown into a region, per part ``parts: (P,)``."""
        if len(self.grown) + len(cell_keys) * len(parts) > MAX_ENTRIES:
            self.grown.clear()
        for i, k in enumerate(cell_keys.tolist()):
            for p, part in enumerate(parts):
                self.grown[(part, k)] = (thetas[i, p].copy(), int(grasps[i, p]))

    def remember_check(self, key: tuple[int, str, bytes], check: ExactCheck) -> None:
        if len(self.checks) >= MAX_CHECKS:
            self.checks.clear()
        self.checks[key] = check

    def _changes(self, old: int, now: int) -> ChangeSet:
        key = (old, now)
        return self._change_memo.get_or_make(
            key, lambda: ChangeSet.of(changes(self.surroundings[old], self.surroundings[now]))
        )

    def newcomers(self, old: int, now: int) -> tuple[Solid, ...]:
        """What of the surroundings ``now`` lies where nothing of ``old`` did, seen from the
        tray and placed relative to it: all that a configuration free in ``old`` may meet.

        A solid where one of the same shape stood is nothing new; an axis-aligned box that
        moved is new only outside the box it was (at most six slabs: a table the tray slides
        along); any other solid is new whole."""
        key = (old, now)
        return self._newcomer_memo.get_or_make(
            key, lambda: _newcomers(self.surroundings[old], self.surroundings[now])
        )

    def newcomer_boxes(self, old: int, now: int) -> ChangeSet:
        """The bounds of :meth:`newcomers` ``(old, now)``, each a box that fills a place."""
        key = (old, now)

        def make() -> ChangeSet:
            bounds = [s.aabb() for s in self.newcomers(old, now)]
            return ChangeSet.boxes(
                np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
            )

        return self._newcomer_box_memo.get_or_make(key, make)

    def recall(
        self,
        tag: str,
        part: str,
        cell_keys: np.ndarray,
        now: int,
        checked: CheckedOf,
        free_of: Callable[[np.ndarray, np.ndarray, tuple[Solid, ...]], np.ndarray] | None = None,
    ) -> tuple[np.ndarray, CellAnswers | None]:
        """The remembered answers of cells ``cell_keys: (M,)`` that stand in the surroundings
        ``now`` (an id from :meth:`around`): ``(M,)`` whether each does, and the answers of
        those that do (in order; None if none does).

        A found answer from other surroundings stands where its links' boxes stay clear of the
        :meth:`newcomers`' bounds, or ``free_of(idx, thetas, solids)`` says its witness
        (``thetas`` of cells ``idx``, indices into ``cell_keys``) is free of them;
        any other answer where it still holds (:meth:`held`; ``checked(answers, ids)``: the
        links of the answers' checked configurations). Without ``free_of``, every answer
        needs :meth:`held`.

        An answer that stands is kept as an answer in ``now``, so that it outlives the
        surroundings it was computed in (the memo keeps :data:`MAX_SURROUNDINGS`). Sound for
        both kinds: an answer that held would be computed the same in ``now`` (every check it
        made has the same outcome there), and a witness carried is free of all of ``now``
        (of the old surroundings when it was verified, of the newcomers since when it was
        carried).
        """
        ok = np.zeros(len(cell_keys), bool)
        table = self.answers.tables.get((tag, part))
        if table is None or table.cols is None or not len(cell_keys):
            return ok, None
        cols = table.cols
        row = table.find(cell_keys)
        kept = np.flatnonzero(row >= 0)
        r = row[kept]
        around = table.around[r]
        live = np.isin(around, np.fromiter(self.surroundings, np.int64, len(self.surroundings)))
        carry = np.zeros(len(kept), bool)
        if free_of is not None:
            carry = cols.found[r] & (around != now) & live
        for k in np.unique(around[carry]).tolist():
            at = np.flatnonzero(carry & (around == k))  # into kept
            assert free_of is not None
            ok[kept[at]] = self._carried(cols, r[at], kept[at], k, now, free_of)
            self.carried += int(ok[kept[at]].sum())
        rest = np.flatnonzero(~carry)
        if len(rest):
            rr = r[rest]
            ok[kept[rest]] = self.held(
                around[rest],
                cols.lo[rr],
                cols.hi[rr],
                now,
                lambda sel: checked(cols.take(rr[sel]), sel),
                (cols.groups_lo[rr], cols.groups_hi[rr]),
            )
        good = row[ok]
        table.around[good] = now
        self.recalled += len(good)
        return ok, cols.take(good) if len(good) else None

    def _carried(
        self,
        cols: CellAnswers,
        ra: np.ndarray,
        idx: np.ndarray,
        old: int,
        now: int,
        free_of: Callable[[np.ndarray, np.ndarray, tuple[Solid, ...]], np.ndarray],
    ) -> np.ndarray:
        """:meth:`recall`'s found answers ``ra`` (rows of ``cols``; cells ``idx``, indices
        into its cell keys) from the surroundings ``old``: ``(len(ra),)`` whether each
        witness is free of the :meth:`newcomers` since."""
        out = np.ones(len(ra), bool)
        new = self.newcomers(old, now)
        if new:
            # Only a witness whose links' boxes meet a newcomer's bounds can touch it
            # (the answer's box holds its links' boxes: tested first).
            near = np.flatnonzero(
                self.newcomer_boxes(old, now)
                .hit(cols.lo[ra], cols.hi[ra], (cols.groups_lo[ra], cols.groups_hi[ra]))
                .any(0)
            )
            if len(near):
                out[near] = free_of(idx[near], cols.theta[ra[near]], new)
        return out

    def remember(
        self,
        tag: str,
        part: str,
        cell_keys: np.ndarray,
        answers: CellAnswers,
        around: int,
    ) -> None:
        """Keep the ``answers`` of cells ``cell_keys: (M,)``, computed in the surroundings
        ``around``."""
        if len(self.answers) + len(cell_keys) > MAX_ANSWERS:
            self.answers.clear()
        table = self.answers.tables.get((tag, part))
        if table is None:
            table = self.answers.tables[(tag, part)] = AnswerTable()
        table.put(cell_keys, answers, around)

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
                good = reaches(solver, thetas[idx], Rs_target[idx], ps_target[idx])
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


def reaches(
    solver: BatchSolver, thetas: np.ndarray, Rs_target: np.ndarray, ps_target: np.ndarray
) -> np.ndarray:
    """``(B,)`` True where ``thetas`` reach their targets within the IK tolerances."""
    R, p = fk_soa(solver.chain, np.ascontiguousarray(thetas.T))[:2]
    _, ang = _errors(
        R, p, np.ascontiguousarray(Rs_target.transpose(1, 2, 0)), np.ascontiguousarray(ps_target.T)
    )
    pos = np.linalg.norm(p - ps_target.T, axis=0)
    return (pos <= POS_TOL) & (ang <= ROT_TOL)


class ReuseCache(Cache[str, RefineMemo]):
    """The memos of the last trays x yaws x grid phases planned: least recently used go first
    while more than :data:`MAX_MEMOS` are kept or they hold more than :data:`MAX_BYTES`. The
    memos grow in place as regions are computed, so each use weighs them again."""

    def __init__(self) -> None:
        super().__init__(
            "speedups.region_memo",
            max_items=MAX_MEMOS,
            max_weight=MAX_BYTES,
            weigh=RefineMemo.approx_bytes,
        )

    def memo(self, key: str) -> RefineMemo:
        """The memo of ``key`` (a new one if none is kept), the most recently used."""
        hit = self.get(key)
        if hit is None:
            hit = self.put(key, RefineMemo())
        self.reweigh()
        return hit
