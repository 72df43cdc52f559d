"""One part from many base cells: IK by query, verification, and growth from solved cells.

For a fixed base yaw the tool targets of a part's grasps, seen from a base cell, differ only by
a translation, so all cells x grasps are looked up in the reachability database at once (the
paper's IK by query). Per (cell, part) the candidates are ranked by pose distance and screened
in windows against the scene with conservative spheres; the best free one is refined to an
exact IK solution (batched damped least squares) and checked again: screen-free is guaranteed,
anything the screen flags goes to coal. Where a cell's window holds no screen-free candidate,
its best flagged ones are refined and checked exactly instead: the spheres hold the robot with
a margin, so next to a tray wall or with a bulky hand they flag many free configurations, and
dropping those left whole trays without a region.

Where the database's voxels hold no usable candidate (the edge of the sampled set), the
witnesses of solved neighbouring cells, 2.5 cm away, seed the refinement instead: the region
grows cell by cell until no neighbour can be solved. Every answer is verified the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from pickstop.reach.database import RANK_LENGTH, ReachDatabase
from pickstop.reach.so3 import matrices_to_quats
from pickstop.regions.arm import ArmWorld, screen_arm
from pickstop.regions.kit import RegionKit
from pickstop.regions.recall import FROM_SCRATCH, Recall, RefineRows, Rounds
from pickstop.robot.kinematics import fk_soa
from pickstop.robot.selfcollision import screen as screen_self
from pickstop.scene.grasps import GraspSet

WINDOW = 4  # candidates screened per (cell, part) at a time
MAX_ROUNDS = 2  # refinement rounds per part (1, then 2 candidates per open cell)
VICINITY_ROUNDS = 1  # the vicinity pass: the best free candidate per open cell
VICINITY_DISTANCE = 0.05  # [m] open cells this close to solved ones also query the vicinity
REFINE_ITERATIONS = 6  # database candidates are close: 2-4 steps; a slow one yields its turn
GROW_SEEDS = 3  # solved neighbours whose witnesses seed an open cell, per wave
GROW_ITERATIONS = 20  # a seed for another grasp turns the wrist: 0.3 rad per step at most
REFINE_GIVE_UP = ((3, 0.01),)  # after 3 iterations, candidates still 1 cm off stop
GROW_GIVE_UP = ((5, 0.02), (10, 0.003))
GROW_WAVES = 12  # rings of cells grown at most
VERIFY_CHUNK = 16_384  # configurations screened at once (bounds the joint frames' memory)


@dataclass(frozen=True)
class Targets:
    """Tool targets of one part's grasps from M base cells, in the base frame, and what the
    computation may take from earlier ones for those cells (:mod:`pickstop.regions.recall`)."""

    grasps: GraspSet
    Rs_base_tool: np.ndarray  # (G, 3, 3) the same from every cell (fixed yaw)
    qs_base_tool: np.ndarray  # (G, 4) wxyz
    ps_base_tool: np.ndarray  # (M, G, 3) [m]
    recall: Recall = FROM_SCRATCH

    @classmethod
    def of(
        cls, gs: GraspSet, cen: np.ndarray, R_base_world: np.ndarray, recall: Recall = FROM_SCRATCH
    ) -> Targets:
        """``cen: (M, 2)`` base positions [m]; ``R_base_world: (3, 3)`` R_base_world of the yaw."""
        Rs_base_tool = np.einsum("ij,gjk->gik", R_base_world, gs.Ts_world_tool[:, :3, :3])
        base = np.concatenate([cen, np.zeros((len(cen), 1))], 1)
        ps_base_tool = (gs.Ts_world_tool[None, :, :3, 3] - base[:, None]) @ R_base_world.T
        return cls(gs, Rs_base_tool, matrices_to_quats(Rs_base_tool), ps_base_tool, recall)

    @property
    def part_id(self) -> str:
        return self.grasps.part_id

    def take(self, idx: np.ndarray) -> Targets:
        """The targets of cells ``idx: (K,)`` (indices)."""
        return Targets(
            self.grasps,
            self.Rs_base_tool,
            self.qs_base_tool,
            self.ps_base_tool[idx],
            self.recall.take(idx),
        )


def served(db: ReachDatabase, targets: list[Targets]) -> np.ndarray:
    """``(M,)`` True where every part has a grasp whose voxel or vicinity holds candidates.

    Only such cells can be solved from the database; the rest can only be grown into.
    """
    M = targets[0].ps_base_tool.shape[0]
    ok = np.ones(M, bool)
    for tg in targets:
        G = tg.ps_base_tool.shape[1]
        idx = np.flatnonzero(ok)
        s, e = db.lookup(
            tg.ps_base_tool[idx].reshape(-1, 3), np.tile(tg.qs_base_tool, (len(idx), 1))
        )
        own = ((e - s).reshape(-1, G) > 0).any(1)
        rest = idx[~own]
        if len(rest):
            s, e = db.lookup_vicinity(
                tg.ps_base_tool[rest].reshape(-1, 3), np.tile(tg.qs_base_tool, (len(rest), 1))
            )
            ok[rest] = ((e - s).reshape(len(rest), -1) > 0).any(1)
    return ok


def solve_part(
    kit: RegionKit, world: ArmWorld, tg: Targets, cen: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For M cells: (found (M,), witness thetas (M, dof), grasp index (M,)).

    First the candidates of each target's own voxel; then, for cells still open next to
    solved ones, the target's vicinity (the 27 surrounding position voxels), as the paper
    queries it: an empty own voxel at the edge of the sampled set is the usual miss.
    """
    found, th_out, g_out = _solve_cells(kit, world, tg, cen, False, MAX_ROUNDS)
    open_ = np.flatnonzero(~found)
    if found.any() and len(open_):
        sub = open_[_near_found(cen, found, VICINITY_DISTANCE)[open_]]
        if len(sub):
            f2, th2, g2 = _solve_cells(kit, world, tg.take(sub), cen[sub], True, VICINITY_ROUNDS)
            found[sub[f2]] = True
            th_out[sub[f2]] = th2[f2]
            g_out[sub[f2]] = g2[f2]
    return found, th_out, g_out


def _solve_cells(
    kit: RegionKit, world: ArmWorld, tg: Targets, cen: np.ndarray, vicinity: bool, rounds: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_rounds` over the database's candidates (the own voxels, or the vicinity) of M
    cells, each solved on its own (through the targets' recall)."""

    def compute(idx: np.ndarray) -> Rounds:
        sub = tg.take(idx)
        return _rounds(kit, world, sub, cen[idx], _gather(kit.db, sub, vicinity), rounds)

    tag = "vicinity" if vicinity else "db"
    return tg.recall.solve_cells(kit, world, tag, tg.part_id, cen, compute)


def _near_found(cen: np.ndarray, found: np.ndarray, dist: float) -> np.ndarray:
    """``(M,)`` True for points within about ``dist`` [m] of a found one: in the same or a
    neighbouring bucket of a grid of ``dist`` squares (the points are one tray's cells in
    the arm's reach, so the buckets are a few thousand)."""
    out = np.zeros(len(cen), bool)
    if not found.any():
        return out
    key = np.floor(cen / dist).astype(np.int64)
    key -= key.min(0) - 1  # a border of one bucket on each side
    marked = np.zeros(tuple(key.max(0) + 2), bool)
    marked[key[found, 0], key[found, 1]] = True
    near = marked.copy()
    for da in (-1, 0, 1):
        for db in (-1, 0, 1):
            if da or db:
                near[1:-1, 1:-1] |= marked[1 + da : marked.shape[0] - 1 + da,
                                           1 + db : marked.shape[1] - 1 + db]  # fmt: skip
    return near[key[:, 0], key[:, 1]]


@dataclass(frozen=True)
class Candidates:
    """The database's candidates of M cells' targets, sorted by cell then score."""

    rows: np.ndarray  # (R,) database rows
    cell: np.ndarray  # (R,) the cell of each (index into the targets' cells)
    grasp: np.ndarray  # (R,) its grasp
    target: np.ndarray  # (R,) cell * G + grasp
    rank: np.ndarray  # (R,) rank within its cell
    ps: np.ndarray  # (M * G, 3) the target positions [m]


def _gather(db: ReachDatabase, tg: Targets, vicinity: bool) -> Candidates:
    """Candidates of the targets: their own voxels' or (``vicinity``) the 27 around them."""
    M, G = tg.ps_base_tool.shape[:2]
    ps, qs = tg.ps_base_tool.reshape(-1, 3), np.tile(tg.qs_base_tool, (M, 1))
    if vicinity:
        starts, ends = db.lookup_vicinity(ps, qs)  # (M * G, 27)
        n = (ends - starts).ravel()
        target = np.repeat(np.repeat(np.arange(M * G), starts.shape[1]), n)
        starts = starts.ravel()
    else:
        starts, ends = db.lookup(ps, qs)
        n = ends - starts
        target = np.repeat(np.arange(M * G), n)
    off = np.repeat(np.cumsum(n) - n, n)
    rows = np.arange(len(target)) - off + np.repeat(starts, n)
    cell = target // G
    g = target % G
    pos_err = np.linalg.norm(db.positions[rows] - ps[target], axis=1)
    dot = np.abs(np.einsum("ij,ij->i", db.quats[rows], tg.qs_base_tool[g]))
    score = pos_err + RANK_LENGTH * 2 * np.arccos(np.minimum(dot, 1.0))
    order = np.lexsort((score, cell))
    rows, cell, g, target = rows[order], cell[order], g[order], target[order]
    first = np.searchsorted(cell, np.arange(M))
    rank = np.arange(len(cell)) - first[cell]
    return Candidates(rows, cell, g, target, rank, ps)


@dataclass(frozen=True)
class _Search:
    """Where :func:`_rounds` stands over M cells and R candidates (changed in place): each
    candidate's state, how far each cell's candidates were screened, the answers so far, and
    what was checked against the scene (per screen and refinement, the cells and the rows or
    joint values)."""

    state: np.ndarray  # (R,) int8: 0 unscreened, 1 free untried, 2 done, 3 flagged
    screened: np.ndarray  # (M,) candidates screened per cell (by rank)
    found: np.ndarray  # (M,) bool
    thetas: np.ndarray  # (M, dof) witnesses
    grasps: np.ndarray  # (M,) grasp indices
    s_cells: list[np.ndarray] = field(default_factory=list)
    s_rows: list[np.ndarray] = field(default_factory=list)
    r_cells: list[np.ndarray] = field(default_factory=list)
    r_ths: list[np.ndarray] = field(default_factory=list)

    @classmethod
    def start(cls, M: int, R: int, dof: int) -> _Search:
        return cls(
            np.zeros(R, np.int8),
            np.zeros(M, np.int64),
            np.zeros(M, bool),
            np.zeros((M, dof)),
            np.zeros(M, int),
        )

    def checked(
        self, dof: int
    ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """The database rows screened ``(cells, rows)`` and the refined joint values verified
        ``(cells, thetas)``."""
        rows = (
            np.concatenate([np.zeros(0, int), *self.s_cells]),
            np.concatenate([np.zeros(0, int), *self.s_rows]),
        )
        refined = (
            np.concatenate([np.zeros(0, int), *self.r_cells]),
            np.concatenate([np.zeros((0, dof)), *self.r_ths]),
        )
        return rows, refined


def _rounds(
    kit: RegionKit,
    world: ArmWorld,
    tg: Targets,
    cen: np.ndarray,
    cands: Candidates,
    rounds: int,
) -> Rounds:
    """Screen, refine and verify candidates per cell in widening rounds; each cell's answer
    depends on its own candidates alone.

    Returns found ``(M,)``, witnesses ``(M, dof)``, grasps ``(M,)`` and what was checked
    against the scene: the database rows screened ``(cells, rows)`` and the refined joint
    values verified ``(cells, thetas)``."""
    M, dof = len(cen), kit.solver.chain.dof
    search = _Search.start(M, len(cands.rows), dof)
    per_cell = np.bincount(cands.cell, minlength=M)
    for attempt in range(rounds):
        kit.checkpoint()
        _screen_window(kit, world, tg, cen, cands, per_cell, search)
        e = _to_refine(cands.cell, search, attempt)
        if len(e) == 0:
            continue
        search.state[e] = 2
        _refine_and_verify(kit, world, tg, cen, cands, e, search)
    return search.found, search.thetas, search.grasps, *search.checked(dof)


def _screen_window(
    kit: RegionKit,
    world: ArmWorld,
    tg: Targets,
    cen: np.ndarray,
    cands: Candidates,
    per_cell: np.ndarray,
    search: _Search,
) -> None:
    """Screen the next :data:`WINDOW` candidates (by rank) of each open cell with no
    screen-free candidate left to try, against the scene with the spheres; ``per_cell``:
    ``(M,)`` each cell's candidates."""
    cell, rank = cands.cell, cands.rank
    found, state, screened = search.found, search.state, search.screened
    open_cells = np.flatnonzero(~found & (screened < per_cell))
    pending = ~found[cell] & (state == 1)
    ready = np.zeros(len(found), bool)
    ready[cell[pending]] = True
    need = open_cells[~ready[open_cells]]
    if not len(need):
        return
    sel = np.flatnonzero(
        np.isin(cell, need) & (rank >= screened[cell]) & (rank < screened[cell] + WINDOW)
    )
    screened[need] += WINDOW
    if not len(sel):
        return
    th = kit.db.thetas(cands.rows[sel])
    _, _, frames = fk_soa(kit.solver.chain, np.ascontiguousarray(th.T), frames=True)
    search.s_cells.append(cell[sel])
    search.s_rows.append(cands.rows[sel])
    hit = screen_arm(
        kit.arm, world.boxes, frames, cen[cell[sel]], world.yaw, world.env, tg.grasps.part_id,
        world.floor,
    )  # fmt: skip
    state[sel] = np.where(hit, 3, 1)


def _to_refine(cell: np.ndarray, search: _Search, attempt: int) -> np.ndarray:
    """The candidates to refine in round ``attempt`` (indices, by cell then score).

    Screen-free candidates first; a cell whose screened candidates are all flagged tries its
    best flagged ones (exactly checked by verify). The best untried per cell: one in the
    first round, then more at once, so few rounds settle the hard cells."""
    found, state = search.found, search.state
    free = (state == 1) & ~found[cell]
    has_free = np.zeros(len(found), bool)
    has_free[cell[free]] = True
    cand = np.flatnonzero(free | ((state == 3) & ~found[cell] & ~has_free[cell]))
    if len(cand) == 0:
        return cand
    width = min(1 << attempt, 4)
    _, first, count = np.unique(cell[cand], return_index=True, return_counts=True)
    pos = np.arange(len(cand)) - np.repeat(first, count)
    return cand[pos < width]


def _refine_and_verify(
    kit: RegionKit,
    world: ArmWorld,
    tg: Targets,
    cen: np.ndarray,
    cands: Candidates,
    e: np.ndarray,
    search: _Search,
) -> None:
    """Refine candidates ``e`` (indices) to exact IK solutions, verify those that converge,
    and take each cell's best-ranked verified one as its witness."""
    cell, g, rows = cands.cell, cands.grasp, cands.rows
    recall = tg.recall.take(cell[e])  # a cell per row
    thetas, success = recall.refine(
        kit.solver, RefineRows("db", tg.part_id, g[e], rows[e]), kit.db.thetas(rows[e]),
        tg.Rs_base_tool[g[e]], cands.ps[cands.target[e]], REFINE_ITERATIONS, REFINE_GIVE_UP,
    )  # fmt: skip
    ok = np.flatnonzero(success)
    if len(ok) == 0:
        return
    search.r_cells.append(cell[e[ok]])
    search.r_ths.append(thetas[ok])
    good = verify(
        kit, world, thetas[ok], cen[cell[e[ok]]], cell[e[ok]], tg.part_id, recall=recall.take(ok)
    )
    acc, ths = e[ok[good]], thetas[ok[good]]
    # Several may succeed for a cell: keep its best-ranked (first) one.
    _, keep = np.unique(cell[acc], return_index=True)
    acc, ths = acc[keep], ths[keep]
    search.found[cell[acc]] = True
    search.thetas[cell[acc]] = ths
    search.grasps[cell[acc]] = g[acc]


def verify(
    kit: RegionKit,
    world: ArmWorld,
    thetas: np.ndarray,
    base_xy: np.ndarray,
    owner: np.ndarray | None = None,
    targets: np.ndarray | str | None = None,
    counts: dict[str, int] | None = None,
    recall: Recall = FROM_SCRATCH,
) -> np.ndarray:
    """``(B,)`` True where ``thetas: (B, dof)`` on a base at ``base_xy: (B, 2)`` is free of the
    scene, of the floor and of itself, the robot's whole collision geometry (hand included)
    checked: the sphere screens first, coal for whatever they flag.

    owner: ``(B,)`` the problem each row solves; once one row of a problem is verified, the
    coal checks of its other flagged rows are skipped (they count as not verified).
    targets: the part each row grasps (one for all, or per row): no obstacle for the hand.
    counts: if given, its ``"exact_checks"`` counts the rows checked by coal.
    recall: where exact checks known before are taken from and new ones kept, bound to one
    cell per row (:meth:`~pickstop.regions.recall.Recall.known_checks`).
    """
    env_hit, self_hit = _screens(kit, world, thetas, base_xy, targets)
    flagged = env_hit | self_hit
    good = ~flagged
    done = set() if owner is None else set(owner[good].tolist())
    rows = np.flatnonzero(flagged)
    env_rows = rows[env_hit[rows]]
    checks = recall.known_checks(
        kit, world, thetas, base_xy, env_rows, partial(_target_of, targets)
    )
    env_targets = targets if targets is None or isinstance(targets, str) else targets[env_rows]
    arm_checks = kit.exact_arm.checks(
        thetas[env_rows], base_xy[env_rows], world.yaw, world.solids, env_targets, world.floor,
        world.boxes,
    )  # fmt: skip
    env_index = dict(zip(env_rows.tolist(), range(len(env_rows)), strict=True))
    for j in rows.tolist():
        o = None if owner is None else int(owner[j])
        if o in done:
            continue
        if counts is not None:
            counts["exact_checks"] = counts.get("exact_checks", 0) + 1
        bad = bool(self_hit[j] and kit.exact_self.colliding(thetas[j][None])[0])
        if not bad and env_hit[j]:
            bad = checks.known.get(j)  # type: ignore[assignment]
            if bad is None:
                bad = arm_checks.colliding(env_index[j])
                checks.remember(j, bad)
        good[j] = not bad
        if not bad and o is not None:
            done.add(o)
    checks.flush()
    return good


def _screens(
    kit: RegionKit,
    world: ArmWorld,
    thetas: np.ndarray,
    base_xy: np.ndarray,
    targets: np.ndarray | str | None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`verify`'s sphere screens, :data:`VERIFY_CHUNK` rows at a time: ``(B,)`` flagged
    against the scene and the floor, ``(B,)`` flagged against itself."""
    B = len(thetas)
    env_hit = np.zeros(B, bool)
    self_hit = np.zeros(B, bool)
    for s in range(0, B, VERIFY_CHUNK):
        sl = slice(s, s + VERIFY_CHUNK)
        th = np.ascontiguousarray(thetas[sl].T)
        _, _, frames = fk_soa(kit.solver.chain, th, frames=True)
        tg = targets if targets is None or isinstance(targets, str) else targets[sl]
        env_hit[sl] = screen_arm(
            kit.arm, world.boxes, frames, base_xy[sl], world.yaw, world.env, tg, world.floor
        )
        self_hit[sl] = screen_self(kit.self_spheres, frames)
    return env_hit, self_hit


def _target_of(targets: np.ndarray | str | None, j: int) -> str | None:
    """The part row ``j`` grasps (``targets``: one for all, or per row)."""
    return targets if targets is None or isinstance(targets, str) else str(targets[j])


def seeded(
    kit: RegionKit,
    world: ArmWorld,
    seeds: np.ndarray,
    Rs_target: np.ndarray,
    ps_target: np.ndarray,
    base_xy: np.ndarray,
    problem: np.ndarray,
    n_problems: int,
    max_iter: int,
    give_up: tuple[tuple[int, float], ...] = (),
    targets: np.ndarray | str | None = None,
    recall: Recall = FROM_SCRATCH,
    rows: RefineRows | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Refine ``seeds: (B, dof)`` towards ``T_base_tool`` targets ``(B, 3, 3)``, ``(B, 3)`` on
    bases at ``base_xy: (B, 2)``, and verify them; rows solve ``problem: (B,)`` ids.

    Returns the winning row of each problem ``(n_problems,)`` (-1 where none verified; the
    first verified row wins) and the refined configurations ``(B, dof)``. targets: the part
    each row grasps (one for all, or per row). recall: where refinements and checks may be
    taken from, bound to one cell per row (:mod:`pickstop.regions.recall`); rows: what each
    row is, for a recall that remembers refinements to key them by (without it, they are
    refined as from scratch).
    """
    win = np.full(n_problems, -1)
    if not len(seeds):
        return win, seeds
    thetas, success = recall.refine(
        kit.solver, rows, seeds, Rs_target, ps_target, max_iter, give_up
    )
    ok = np.flatnonzero(success)
    if len(ok):
        sub = targets if targets is None or isinstance(targets, str) else targets[ok]
        good = ok[
            verify(kit, world, thetas[ok], base_xy[ok], problem[ok], sub, recall=recall.take(ok))
        ]
        _, first = np.unique(problem[good], return_index=True)
        win[problem[good[first]]] = good[first]
    return win, thetas


_NEIGHBOURS = np.array([[0, 1], [1, 0], [0, -1], [-1, 0], [1, 1], [1, -1], [-1, 1], [-1, -1]])


def grow(
    kit: RegionKit,
    world: ArmWorld,
    targets: list[Targets],
    cen: np.ndarray,
    ij: np.ndarray,
    found: np.ndarray,
    thetas: np.ndarray,
    grasp: np.ndarray,
) -> int:
    """Grow the solved cells into their open neighbours, in place; returns how many were added.

    ``cen: (M, 2)`` base positions [m] of grid cells ``ij: (M, 2)`` (iy, ix); ``found: (M,)``,
    ``thetas: (M, P, dof)`` and ``grasp: (M, P)`` hold the solved cells. An open cell next to
    a solved one is refined, every part at once, from the solved neighbours' witnesses
    (4-neighbours first); it joins when every part verifies. Each wave retries only cells
    next to cells the previous wave added. Every part's targets share the tray's one recall
    (``targets[0].recall``).
    """
    if not found.any():
        return 0
    recall = targets[0].recall
    nb = _neighbour_rows(ij)
    fresh = found.copy()
    added = 0
    for _ in range(GROW_WAVES):
        kit.checkpoint()
        wave = _Wave.next(nb, found, fresh, thetas, grasp)
        if wave is None:
            break
        # parts a cell was grown with before, where the recall knows them
        wave.solve(*recall.grown_before(kit, world, targets, cen, wave.open_))
        # The neighbours' own grasps first; then, where a part is still open, every other
        # grasp from the same seeds: a witness for one grasp often reaches another here (the
        # wrist turns) where its own grasp runs into a joint limit.
        for other in (False, True):
            _seed_from_neighbours(kit, world, targets, cen, wave, other)
        new = _join(targets, wave, found, thetas, grasp)
        fresh = np.zeros_like(found)
        fresh[new] = True
        added += len(new)
    return added


def _neighbour_rows(ij: np.ndarray) -> np.ndarray:
    """``(M, 8)`` the row of each of the 8 neighbours of grid cells ``ij: (M, 2)`` (iy, ix)
    among them, -1 where it is not one of them (4-neighbours first)."""
    lo = ij.min(0)
    shape = ij.max(0) - lo + 3
    index = np.full(tuple(shape), -1)
    index[ij[:, 0] - lo[0] + 1, ij[:, 1] - lo[1] + 1] = np.arange(len(ij))
    return index[
        ij[:, None, 0] - lo[0] + 1 + _NEIGHBOURS[None, :, 0],
        ij[:, None, 1] - lo[1] + 1 + _NEIGHBOURS[None, :, 1],
    ]


@dataclass(frozen=True)
class _Wave:
    """One wave of :func:`grow`: the O open cells next to cells the last wave added, the S
    seeding pairs (an open cell and one of its first :data:`GROW_SEEDS` solved neighbours,
    whose witnesses seed it), and what is solved of each open cell's P parts so far (changed
    in place)."""

    open_: np.ndarray  # (O,) rows of the open cells
    o_loc: np.ndarray  # (S,) each pair's open cell (index into open_)
    seed_th: np.ndarray  # (S, P, dof) each pair's neighbour's witnesses
    seed_g: np.ndarray  # (S, P) and their grasps
    got: np.ndarray  # (O, P) bool: the part is solved
    th_new: np.ndarray  # (O, P, dof) its witness
    g_new: np.ndarray  # (O, P) its grasp

    @classmethod
    def next(
        cls,
        nb: np.ndarray,
        found: np.ndarray,
        fresh: np.ndarray,
        thetas: np.ndarray,
        grasp: np.ndarray,
    ) -> _Wave | None:
        """The wave after the one that added ``fresh: (M,)`` (None: no open cell is next to
        them); ``nb: (M, 8)`` the neighbours' rows, ``thetas: (M, P, dof)`` and
        ``grasp: (M, P)`` the solved cells' witnesses."""
        has_fresh = ((nb >= 0) & fresh[np.maximum(nb, 0)]).any(1)
        open_ = np.flatnonzero(~found & has_fresh)
        if not len(open_):
            return None
        sol = (nb[open_] >= 0) & found[np.maximum(nb[open_], 0)]  # (O, 8) solved neighbours
        o_loc, k = np.nonzero(sol & (np.cumsum(sol, 1) <= GROW_SEEDS))
        src = nb[open_[o_loc], k]  # the seeding neighbour of each pair
        n_open, P, dof = len(open_), *thetas.shape[1:]
        return cls(
            open_,
            o_loc,
            thetas[src],
            grasp[src],
            np.zeros((n_open, P), bool),
            np.zeros((n_open, P, dof)),
            np.zeros((n_open, P), int),
        )

    def solve(self, o: np.ndarray, p: np.ndarray, thetas: np.ndarray, grasps: np.ndarray) -> None:
        """Parts ``p: (S,)`` of open cells ``o: (S,)`` (indices into ``open_``) are solved
        by witnesses ``thetas: (S, dof)`` with grasps ``(S,)``."""
        self.got[o, p] = True
        self.th_new[o, p] = thetas
        self.g_new[o, p] = grasps


def _seed_from_neighbours(
    kit: RegionKit,
    world: ArmWorld,
    targets: list[Targets],
    cen: np.ndarray,
    wave: _Wave,
    other: bool,
) -> None:
    """Refine the ``wave``'s parts still open from the seeding neighbours' witnesses towards
    the neighbour's own grasp, or (``other``) every other grasp of the part, and verify them;
    the first verified row of each (cell, part) solves it, in place."""
    P = len(targets)
    rows = _seed_rows(targets, wave, other)
    if rows is None:
        return
    pair, part, g = rows
    cell = wave.open_[wave.o_loc[pair]]
    R_t = np.empty((len(pair), 3, 3))
    p_t = np.empty((len(pair), 3))
    for p in range(P):
        m = part == p
        R_t[m] = targets[p].Rs_base_tool[g[m]]
        p_t[m] = targets[p].ps_base_tool[cell[m], g[m]]
    problem = wave.o_loc[pair] * P + part
    part_ids = np.array([tg.grasps.part_id for tg in targets], dtype=object)
    win, ths = seeded(
        kit, world, wave.seed_th[pair, part], R_t, p_t, cen[cell], problem, len(wave.open_) * P,
        GROW_ITERATIONS, GROW_GIVE_UP, part_ids[part], targets[0].recall.take(cell),
        RefineRows("grow", part_ids[part], g),
    )  # fmt: skip
    solved = np.flatnonzero(win >= 0)
    o, p_ = np.divmod(solved, P)
    wave.solve(o, p_, ths[win[solved]], g[win[solved]])


def _seed_rows(
    targets: list[Targets], wave: _Wave, other: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The rows to refine, grouped by problem (open cell, part): the seeding pair, the part
    and the grasp of each (None: no part is open). A pair seeds each open part with its
    neighbour's grasp, or (``other``) every other grasp of the part."""
    P = len(targets)
    G = np.array([len(tg.Rs_base_tool) for tg in targets])
    rows_pair, rows_part, rows_grasp = [], [], []
    for p in range(P):
        pair = np.flatnonzero(~wave.got[wave.o_loc, p])
        shift = np.arange(1, G[p]) if other else np.zeros(1, int)
        if not len(pair) or not len(shift):
            continue
        rows_pair.append(np.repeat(pair, len(shift)))
        rows_part.append(np.full(len(pair) * len(shift), p))
        rows_grasp.append(((wave.seed_g[pair, p][:, None] + shift) % G[p]).ravel())
    if not rows_pair:
        return None
    pair, part, g = map(np.concatenate, (rows_pair, rows_part, rows_grasp))
    order = np.argsort(wave.o_loc[pair] * P + part, kind="stable")  # rows grouped by problem
    return pair[order], part[order], g[order]


def _join(
    targets: list[Targets],
    wave: _Wave,
    found: np.ndarray,
    thetas: np.ndarray,
    grasp: np.ndarray,
) -> np.ndarray:
    """The ``wave``'s cells solved for every part join the region (``found``, ``thetas``,
    ``grasp``, in place) and the targets' recall; returns their rows."""
    alive = wave.got.all(1)
    new = wave.open_[alive]
    found[new] = True
    thetas[new] = wave.th_new[alive]
    grasp[new] = wave.g_new[alive]
    targets[0].recall.remember_grown(
        [tg.part_id for tg in targets], new, wave.th_new[alive], wave.g_new[alive]
    )
    return new


#: Changes whenever the algorithm's answer may change (part of a cached region's key).
VERSION = [WINDOW, MAX_ROUNDS, REFINE_ITERATIONS, VICINITY_ROUNDS, GROW_SEEDS, GROW_WAVES, 10]
