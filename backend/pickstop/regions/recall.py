"""What a region computation may take from earlier ones: one small strategy, from scratch here.

The region pipeline (:mod:`pickstop.regions.pipeline`, :mod:`pickstop.regions.solve`) asks a
:class:`Recall` at the few places where work done before could stand in for work to do: the
cells the database serves, the exact IK refinements, the answers of whole cells, the exact
checks of :func:`~pickstop.regions.solve.verify`, and the witnesses cells were grown with.
:data:`FROM_SCRATCH` answers every question by computing it: the algorithm as it reads. The
speed-ups (:mod:`pickstop.speedups`) implement the same interface over a memo kept across
layouts.

A recall is bound to a sequence of base cells of one tray: the M cells of its targets, or
(:meth:`Recall.take`, indices may repeat) the cell of each row of a batch of refinements or
checks.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from pickstop.reach.batch_ik import BatchSolver, refine_batch
from pickstop.regions.arm import ArmWorld
from pickstop.regions.kit import RegionKit

#: What :func:`~pickstop.regions.solve._rounds` gives K cells: found ``(K,)``, witnesses
#: ``(K, dof)``, grasps ``(K,)``, the database rows screened ``(cells, rows)`` and the refined
#: joint values verified ``(cells, thetas)`` (cells as indices into the K).
Rounds = tuple[
    np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]
]
#: A witness per solved (open cell, part): open-cell indices ``(S,)`` (into the ``open_`` of
#: :meth:`Recall.grown_before`), part indices ``(S,)``, joint values ``(S, dof)``, grasp
#: indices ``(S,)``.
Solved = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class RefineRows:
    """What the B rows of one refinement are, besides their cells (a recall bound to one cell
    per row): the stage (``"db"``: database candidates, ``"grow"``: neighbours' witnesses),
    the part each grasps (one for all, or ``(B,)``), each row's grasp ``(B,)``, and where each
    seed came from: ``(B,)`` database rows, or None (the seed itself)."""

    tag: str
    part: str | np.ndarray
    grasps: np.ndarray
    sources: np.ndarray | None = None


class Aims(Protocol):
    """One part's tool targets from the recall's M cells (a
    :class:`~pickstop.regions.solve.Targets`)."""

    @property
    def part_id(self) -> str:
        """The part's id."""
        ...

    @property
    def Rs_base_tool(self) -> np.ndarray:
        """``(G, 3, 3)`` the grasps' tool orientations in the base frame."""
        ...

    @property
    def ps_base_tool(self) -> np.ndarray:
        """``(M, G, 3)`` [m] the grasps' tool positions from each cell, in the base frame."""
        ...


class Checks(Protocol):
    """The exact arm checks of one :func:`~pickstop.regions.solve.verify` call known before
    (``known``: row -> collided), and the keeping of new ones."""

    known: dict[int, bool]

    def remember(self, j: int, colliding: bool) -> None:
        """Row ``j`` was checked exactly and ``colliding`` is the outcome."""
        ...

    def flush(self) -> None:
        """Keep what :meth:`remember` was told since the last flush."""
        ...


class Recall(Protocol):
    """Where a region computation may take work done before (see the module)."""

    def take(self, idx: np.ndarray) -> Recall:
        """The recall of the cells ``idx: (K,)`` (indices into this recall's cells)."""
        ...

    def served(self, n: int, compute: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """``(n,)`` whether the database serves each of the recall's cells (``n``: their
        count); ``compute(idx)`` gives it for cells ``idx`` (indices into them)."""
        ...

    def refine(
        self,
        solver: BatchSolver,
        rows: RefineRows | None,
        seeds: np.ndarray,
        Rs_target: np.ndarray,
        ps_target: np.ndarray,
        max_iter: int,
        give_up: tuple[tuple[int, float], ...],
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~pickstop.reach.batch_ik.refine_batch` of ``seeds: (B, dof)`` towards
        ``(B, 3, 3)``, ``(B, 3)`` targets, the recall bound to one cell per row (``rows``:
        what the rows are; None: nothing to remember them by): thetas ``(B, dof)`` and
        success ``(B,)``."""
        ...

    def solve_cells(
        self,
        kit: RegionKit,
        world: ArmWorld,
        tag: str,
        part: str,
        cen: np.ndarray,
        compute: Callable[[np.ndarray], Rounds],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Found ``(M,)``, witnesses ``(M, dof)`` and grasps ``(M,)`` of the cells at
        ``cen: (M, 2)`` [m] for ``part`` (``tag``: ``"db"`` or ``"vicinity"``);
        ``compute(idx)`` solves cells ``idx`` (indices), each on its own."""
        ...

    def known_checks(
        self,
        kit: RegionKit,
        world: ArmWorld,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        rows: np.ndarray,
        target_of: Callable[[int], str | None],
    ) -> Checks:
        """The exact checks known of rows ``rows`` of ``thetas: (B, dof)`` on bases
        ``base_xy: (B, 2)`` [m], the recall bound to one cell per row of ``thetas``;
        ``target_of(j)``: the part row ``j`` grasps."""
        ...

    def grown_before(
        self,
        kit: RegionKit,
        world: ArmWorld,
        targets: Sequence[Aims],
        cen: np.ndarray,
        open_: np.ndarray,
    ) -> Solved:
        """The parts of open cells ``open_: (O,)`` (rows; their bases ``cen[open_]`` [m]) solved
        by a witness they were grown with before, verified here now; rows of the result index
        ``open_``, parts ``targets``."""
        ...

    def remember_grown(
        self, parts: list[str], cells: np.ndarray, thetas: np.ndarray, grasps: np.ndarray
    ) -> None:
        """Cells ``cells: (K,)`` (indices into the recall's cells) grew into the region with
        witnesses ``thetas: (K, P, dof)`` and grasps ``(K, P)`` for ``parts: (P,)``."""
        ...


@dataclass
class NoChecks:
    """No exact check is known, and none is kept."""

    known: dict[int, bool] = field(default_factory=dict)

    def remember(self, j: int, colliding: bool) -> None:
        pass

    def flush(self) -> None:
        pass


class FromScratch:
    """Every question computed directly; nothing is read or kept."""

    def take(self, idx: np.ndarray) -> FromScratch:
        return self

    def served(self, n: int, compute: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        return compute(np.arange(n))

    def refine(
        self,
        solver: BatchSolver,
        rows: RefineRows | None,
        seeds: np.ndarray,
        Rs_target: np.ndarray,
        ps_target: np.ndarray,
        max_iter: int,
        give_up: tuple[tuple[int, float], ...],
    ) -> tuple[np.ndarray, np.ndarray]:
        res = refine_batch(solver, seeds, Rs_target, ps_target, max_iter=max_iter, give_up=give_up)
        return res.thetas, res.success

    def solve_cells(
        self,
        kit: RegionKit,
        world: ArmWorld,
        tag: str,
        part: str,
        cen: np.ndarray,
        compute: Callable[[np.ndarray], Rounds],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return compute(np.arange(len(cen)))[:3]

    def known_checks(
        self,
        kit: RegionKit,
        world: ArmWorld,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        rows: np.ndarray,
        target_of: Callable[[int], str | None],
    ) -> Checks:
        return NoChecks()

    def grown_before(
        self,
        kit: RegionKit,
        world: ArmWorld,
        targets: Sequence[Aims],
        cen: np.ndarray,
        open_: np.ndarray,
    ) -> Solved:
        none = np.zeros(0, np.int64)
        return none, none, np.zeros((0, kit.solver.chain.dof)), none

    def remember_grown(
        self, parts: list[str], cells: np.ndarray, thetas: np.ndarray, grasps: np.ndarray
    ) -> None:
        pass


FROM_SCRATCH = FromScratch()
