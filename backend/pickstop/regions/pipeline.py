"""The region pipeline: a tray's base region from scratch, step by step.

Cells within the arm's reach of the tray, where the base footprint fits; the grasps of every
part; the cells the database serves; part by part, IK by query and verification
(:mod:`pickstop.regions.solve`); growth into open neighbours from the solved cells' witnesses.
Whatever the computation looks at is marked on the region's envelope, which
:mod:`pickstop.speedups.validity` reads to tell when the region may be reused. Where work done
before may stand in, the pipeline asks a :class:`~pickstop.regions.recall.Recall`, made for the
tray by a :data:`RecallOf`: from scratch (:func:`from_scratch`), it computes everything.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickstop import frames
from pickstop.regions import solve
from pickstop.regions.arm import ArmWorld, nearby
from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.envelope import Envelope
from pickstop.regions.footprint import footprint_check
from pickstop.regions.kit import RegionKit
from pickstop.regions.recall import FROM_SCRATCH, Recall
from pickstop.regions.solve import Targets
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import BoxArrays, Solid


@dataclass(frozen=True)
class BaseCells:
    """The cells a tray's region is solved over: within the arm's reach of the tray and
    where the base footprint fits."""

    ix: np.ndarray  # (M,) int
    iy: np.ndarray  # (M,) int
    centres: np.ndarray  # (M, 2) [m]
    counts: dict[str, int]  # cells "in_reach", and of them "footprint_free" (if checked)
    reason: str | None  # why there is none, if there is none

    @property
    def cells(self) -> np.ndarray:
        """``(M, 2)`` int (iy, ix)."""
        return np.stack([self.iy, self.ix], 1)


#: Makes the recall of one tray's region (:mod:`pickstop.regions.recall`) from the kit, the
#: scene, the tray, the base yaw [rad], its base cells, its parts' grasps and the solids near it.
RecallOf = Callable[[RegionKit, Scene, Tray, float, BaseCells, list[GraspSet], list[Solid]], Recall]


def from_scratch(
    kit: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    base: BaseCells,
    grasp_sets: list[GraspSet],
    solids: list[Solid],
) -> Recall:
    """The :data:`RecallOf` of the pipeline from scratch: nothing is taken from before."""
    return FROM_SCRATCH


def own_key(kit: RegionKit, scene: Scene, tray: Tray, yaw: float) -> str:
    """What the region of ``tray`` depends on apart from the other objects."""
    blob = {
        "tray": tray.model_dump(),
        "yaw": yaw,
        "grid": [scene.grid_extent.model_dump(), scene.base_grid.resolution],
        "floor": scene.floor.model_dump(),
        "floor_clearance": scene.floor_clearance,
        "gripper": scene.gripper.model_dump(),
        "hand": kit.hand.key,
        "robot": kit.robot.robot_hash,
        "db": kit.db.id,
        "algo": solve.VERSION,
    }
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()


def tray_reach(kit: RegionKit, tray: Tray) -> float:
    """[m] How far from the tray's centre a base may stand and still reach into the tray."""
    return kit.reach_xy + 0.5 * math.hypot(*tray.outer_size)


def base_cells(
    kit: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    grid: CellGrid,
    env: Envelope | None = None,
) -> BaseCells:
    """The cells of ``grid`` within reach of ``tray`` (a bounding window, then the disc) where
    the base at ``yaw`` [rad] fits. env: marked with the columns of the base at every cell in
    reach, the owners of overhangs that block one, and the free cells."""
    tc = np.array([tray.pose.x, tray.pose.y])
    reach = tray_reach(kit, tray)
    lo = np.floor((tc - reach - [grid.x0, grid.y0]) / grid.res).astype(int)
    hi = np.ceil((tc + reach - [grid.x0, grid.y0]) / grid.res).astype(int)
    ix = np.arange(max(lo[0], 0), min(hi[0], grid.nx))
    iy = np.arange(max(lo[1], 0), min(hi[1], grid.ny))
    IX2, IY2 = np.meshgrid(ix, iy)
    IX, IY = IX2.ravel(), IY2.ravel()
    cen = grid.centres(IX, IY)
    near = np.hypot(*(cen - tc).T) <= reach
    IX, IY, cen = IX[near], IY[near], cen[near]
    counts = {"in_reach": len(IX)}
    fp = kit.robot.footprint
    if env is not None:
        env.mark_columns(cen, fp.bounding_radius, fp.height)
    if len(IX) == 0:
        return BaseCells(IX, IY, cen, counts, out_of_reach(tray, reach))
    free, overhangs = footprint_check(scene, kit.robot, cen, yaw, kit.solids_of(scene))
    IX, IY, cen = IX[free], IY[free], cen[free]
    counts["footprint_free"] = len(IX)
    if env is not None:
        env.hit_owners |= overhangs
        env.free_xy = cen
    return BaseCells(IX, IY, cen, counts, None if len(IX) else no_room(tray))


def compute_tray_region(
    kit: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    key: str = "",
    recall_of: RecallOf = from_scratch,
) -> TrayRegion:
    """The region of ``tray`` at base ``yaw`` [rad] (see the module); ``key`` is stored with
    it (:func:`own_key`). ``recall_of``: where work done before may stand in (default: none,
    from scratch)."""
    t0 = time.perf_counter()
    robot = kit.robot
    grid = CellGrid.of(scene)
    counts = {"grid": grid.nx * grid.ny}
    part_ids = tuple(p.id for p in tray.parts)
    env = _hand_envelope(kit, scene, tray)

    def empty(reason: str) -> TrayRegion:
        seconds = time.perf_counter() - t0
        return TrayRegion.empty(
            tray.id, yaw, grid, part_ids, robot.dof, counts, reason, seconds, key, env
        )

    if not tray.parts:
        return empty(no_parts(tray))
    base = base_cells(kit, scene, tray, yaw, grid, env)
    counts.update(base.counts)
    if base.reason is not None:
        return empty(base.reason)
    _, solids, boxes, R_base_world = tray_world(kit, scene, tray, yaw)
    grasp_sets = kit.grasps(scene, tray)
    why = ungraspable(kit, scene, tray, grasp_sets)
    if why is not None:
        return empty(why)
    world, targets, alive = _arm_targets(
        kit, scene, tray, yaw, base, grasp_sets, (solids, boxes, R_base_world, env), recall_of
    )
    counts["served"] = len(alive)
    alive, witness, grasp_of, failed = _solve_parts(
        kit, world, targets, base, alive, len(part_ids), counts
    )
    if failed is not None:
        return empty(no_cell_grasps(failed, tray, counts["footprint_free"]))
    kit.checkpoint()
    alive, counts["grown"] = _grown(kit, world, targets, base, alive, witness, grasp_of)
    counts["feasible"] = len(alive)
    cells = np.stack([base.iy[alive], base.ix[alive]], 1)
    return TrayRegion.of_cells(
        tray.id, yaw, grid, cells, part_ids, witness[alive], grasp_of[alive], counts, None,
        time.perf_counter() - t0, key, env,
    )  # fmt: skip


def _hand_envelope(kit: RegionKit, scene: Scene, tray: Tray) -> Envelope:
    """The open hands at every candidate grasp: what reaches in there may change the grasps."""
    env = Envelope.empty(scene.floor.min, scene.floor.max)
    for part in tray.parts:
        env.mark_box(*kit.hand_space(scene, tray, part))
    return env


def _arm_targets(
    kit: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    base: BaseCells,
    grasp_sets: list[GraspSet],
    near: tuple[list[Solid], BoxArrays, np.ndarray, Envelope],
    recall_of: RecallOf = from_scratch,
) -> tuple[ArmWorld, list[Targets], np.ndarray]:
    """The arm's world, each part's targets from the base cells, and the cells the database
    serves for every part (indices into ``base``); the others are left to the growth.
    ``near``: the solids near the tray (exact and as arrays), R_base_world, the hands'
    envelope. ``recall_of``: makes the targets' recall."""
    solids, boxes, R_base_world, env = near
    world = ArmWorld(boxes, solids, yaw, env, scene.floor_clearance)
    recall = recall_of(kit, scene, tray, yaw, base, grasp_sets, solids)
    targets = [Targets.of(gs, base.centres, R_base_world, recall) for gs in grasp_sets]
    served = recall.served(
        len(base.ix), lambda idx: solve.served(kit.db, [t.take(idx) for t in targets])
    )
    return world, targets, np.flatnonzero(served)


def _solve_parts(
    kit: RegionKit,
    world: ArmWorld,
    targets: list[Targets],
    base: BaseCells,
    alive: np.ndarray,
    n_parts: int,
    counts: dict[str, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
    """Each part solved in turn on the cells every earlier part was solved on: (the cells
    solved for all, witnesses ``(cells, parts, dof)`` [rad or m], grasp indices ``(cells,
    parts)``, the part no cell serves or None). ``counts`` gains the cells left per part."""
    shape = (len(base.ix), n_parts)
    witness = np.zeros((*shape, kit.robot.dof))
    grasp_of = np.zeros(shape, int)
    for k, tg in enumerate(targets):
        kit.checkpoint()
        found, th, gi = solve.solve_part(kit, world, tg.take(alive), base.centres[alive])
        alive = alive[found]
        witness[alive, k] = th[found]
        grasp_of[alive, k] = gi[found]
        counts[f"feasible_after_{tg.grasps.part_id}"] = len(alive)
        if len(alive) == 0:
            return alive, witness, grasp_of, tg.grasps.part_id
    return alive, witness, grasp_of, None


def _grown(
    kit: RegionKit,
    world: ArmWorld,
    targets: list[Targets],
    base: BaseCells,
    alive: np.ndarray,
    witness: np.ndarray,
    grasp_of: np.ndarray,
) -> tuple[np.ndarray, int]:
    """The cells solved for every part (``alive``, indices into ``base``) grown into their
    open neighbours (:func:`~pickstop.regions.solve.grow`; ``witness``, ``grasp_of`` in
    place): (the region's cells, how many were grown)."""
    solved = np.zeros(len(base.ix), bool)
    solved[alive] = True
    grown = solve.grow(
        kit, world, targets, base.centres, np.stack([base.iy, base.ix], 1), solved, witness,
        grasp_of,
    )  # fmt: skip
    return np.flatnonzero(solved), grown


def arm_radius(kit: RegionKit, tray: Tray) -> float:
    """[m] How far from the tray's centre, in the floor plane, a solid's bounding box may lie
    and still be met by the arm reaching into the tray from a base within reach: the solids
    its region and its off-grid checks look at (:func:`tray_world`)."""
    return tray_reach(kit, tray) + kit.reach_xy + 0.2


def tray_world(
    kit: RegionKit, scene: Scene, tray: Tray, yaw: float
) -> tuple[float, list[Solid], BoxArrays, np.ndarray]:
    """Reach radius around the tray [m], the solids near it (exact and as arrays), R_base_world."""
    tc = np.array([tray.pose.x, tray.pose.y])
    solids = nearby(kit.solids_of(scene), tc, arm_radius(kit, tray))
    return tray_reach(kit, tray), solids, BoxArrays.of(solids), frames.R_base_world(yaw)


# -- why a region is empty: one wording for the pipeline and the reference solvers -------------
def no_parts(tray: Tray) -> str:
    return f"tray {tray.id!r} has no parts"


def out_of_reach(tray: Tray, reach: float) -> str:
    return f"tray {tray.id!r} is farther than the arm reaches ({reach:.2f} m) from every grid cell"


def no_room(tray: Tray) -> str:
    return f"no cell within reach of tray {tray.id!r} has room for the base footprint"


def ungraspable(kit: RegionKit, scene: Scene, tray: Tray, grasp_sets: list[GraspSet]) -> str | None:
    """Why the first part of ``tray`` without a grasp the open hand fits has none (None if
    every part has one)."""
    for gs in grasp_sets:
        if len(gs.Ts_world_tool) == 0:
            low = _too_low(kit) if gs.too_low else ""
            return (
                f"part {gs.part_id!r} of tray {tray.id!r}: none of its {gs.rejected} grasps "
                "fits the robot's open hand without touching the tray, a neighbour or a table, "
                f"or coming within the floor clearance of {scene.floor_clearance:.3f} m "
                f"({gs.near_floor} of them too close to the floor)" + low
            )
    return None


def _too_low(kit: RegionKit) -> str:
    """Why a part has no top-down grasp, and what in the robot config sets it."""
    import shlex

    from pickstop.reach.database import robot_arg

    check = shlex.join(["pickstop", "robot", "check", robot_arg(kit.robot)])
    return (
        f"; no top-down grasp: the open hand reaches {kit.hand.reach:.3f} m past its grasp "
        "point, which would put it below the tray floor for a part this low; the robot "
        "config's hand.tool_offset places the grasp point (nearer the fingertips, the hand "
        f"reaches less past it): `{check}` shows the hand's reach and suggests an offset"
    )


def no_cell_grasps(part_id: str, tray: Tray, cells: int) -> str:
    """No cell of the ``cells`` reachable free ones tried lets the arm grasp ``part_id``."""
    return (
        f"no base cell lets the arm grasp part {part_id!r} of tray {tray.id!r} without "
        f"collision (of {cells} reachable free cells)"
    )
