"""The plan's steps from scratch: each answer a function of its inputs, nothing remembered.

The functions here are the pipeline's steps (:mod:`pickstop.sequence.request` lists them);
:class:`PureSteps` runs them as they are, and :class:`~pickstop.speedups.stop_planner.StopPlanner`
runs the same functions behind its caches. :func:`~pickstop.sequence.request.plan_from_scratch`
plans a scene over :class:`PureSteps`.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import shapely
from shapely.geometry import Polygon

from pickstop.regions.cells import TrayRegion
from pickstop.regions.footprint import (
    FloorSolids,
    UpperBody,
    body_pieces,
    floor_outline,
    upper_body,
)
from pickstop.regions.kit import RegionKit
from pickstop.regions.offgrid import feasible_near
from pickstop.regions.pure import PureRegions
from pickstop.scene.model import Scene
from pickstop.scene.positioning import ErrorDist, of_scene
from pickstop.scene.world import Solid
from pickstop.sequence import expected
from pickstop.sequence import plan_model as pm
from pickstop.sequence.cover import Selection, select_stops
from pickstop.sequence.estimate import feasible_subcells, kernel, subset_estimates
from pickstop.sequence.intersections import Intersection, inscribed_circle, intersections
from pickstop.sequence.placement import MIN_GAIN, best_point
from pickstop.sequence.refine import Refinement
from pickstop.sequence.route import FloorMap, Paths, shortest_paths
from pickstop.sequence.steps import Floor, Regions
from pickstop.sequence.success import Kind, Rate, monte_carlo_at

DUPLICATE = 1e-3  # [m] candidates of the same trays this close are one
DOCK_REACH = 3.0  # longest docking leg searched, in bounding radii of the base body

#: The largest inscribed circle of a polygon: its centre [m] and radius [m].
Circle = Callable[[Polygon], tuple[tuple[float, float], float]]
#: A region's exact boundary outcomes so far (:class:`Refinement`), by region.
Refinements = Callable[[TrayRegion], Refinement]


def digest(obj: Any) -> str:
    """A short stable digest of ``repr(obj)``."""
    return hashlib.sha256(repr(obj).encode()).hexdigest()[:20]


def candidates(regions: Regions, circle: Circle = inscribed_circle) -> list[Intersection]:
    """All intersection components of the regions, per yaw, duplicates dropped."""
    out: list[Intersection] = []
    for yaw in sorted({y for _, y in regions}):
        polys = {t: r.polygon for (t, y), r in regions.items() if y == yaw}
        for c in intersections(polys, yaw, circle=circle):
            if not any(
                o.trays == c.trays and o.yaw == c.yaw and math.dist(o.centre, c.centre) < DUPLICATE
                for o in out
            ):
                out.append(c)
    return out


@dataclass(frozen=True)
class FloorSpec:
    """What a scene's floor is made of: the body, the solids that block the base, and the
    keys of its map (``key``) and of the whole floor (``full``), by value."""

    body: UpperBody
    every: list[Solid]  # every solid reaching below the body's top (docking legs see them)
    outlines: list[tuple[str, Polygon]]  # those not within another's outline, by owner
    key: tuple[Any, ...]
    full: tuple[Any, ...]


def floor_spec(kit: RegionKit, scene: Scene) -> FloorSpec:
    """Driving, the base turns: whatever reaches below the top of the base body (footprint
    and base-fixed links) blocks it, grown by the body's farthest horizontal reach."""
    body = upper_body(kit.robot)
    every = [s for s in kit.solids_of(scene) if s.aabb()[0][2] < body.top]
    outlines = [(s.owner, Polygon(floor_outline(s))) for s in every]
    # An outline within another's (a tray on its table) blocks nothing more: moving it
    # leaves the floor map as it was.
    polys = [o for _, o in outlines]
    inner, outer = shapely.STRtree(polys).query(polys, predicate="within")
    covered = {
        int(i)
        for i, j in zip(inner.tolist(), outer.tolist(), strict=True)
        if i != j and (j < i or not polys[i].equals(polys[j]))
    }
    keep = [k for k in range(len(every)) if k not in covered]

    def solids_key(ss: list[Solid]) -> tuple[Any, ...]:
        return tuple((s.owner, s.T_world_solid.tobytes(), s.half.tobytes()) for s in ss)

    key = (scene.floor.model_dump_json(), kit.robot.robot_hash, body.radius,
           solids_key([every[k] for k in keep]))  # fmt: skip
    # Docking legs sweep the body's pieces at their own heights: an outline inside another
    # may still meet a piece the outer solid's heights miss, so they see every solid.
    return FloorSpec(body, every, [outlines[k] for k in keep], key, (key, solids_key(every)))


def floor_map(scene: Scene, spec: FloorSpec) -> FloorMap:
    """The floor minus the spec's outlines inflated by the body's radius."""
    bounds = (*scene.floor.min, *scene.floor.max)
    return FloorMap.build(bounds, [o for _, o in spec.outlines], spec.body.radius)


def floor(kit: RegionKit, scene: Scene, spec: FloorSpec, fmap: FloorMap) -> Floor:
    """The floor of ``spec`` over its map ``fmap`` (:func:`floor_map`)."""
    omni = kit.robot.config.footprint.drive == "omnidirectional"
    return Floor(fmap, spec.outlines, FloorSolids.of(scene, spec.every), body_pieces(kit.robot),
                 DOCK_REACH * spec.body.radius, omni, digest((spec.full, omni)))  # fmt: skip


def paths(floor: Floor, points: np.ndarray, yaws: np.ndarray) -> Paths:
    """Shortest paths between ``points: (Q, 2)`` [m] held at ``yaws: (Q,)`` [rad]."""
    return shortest_paths(floor.fmap, points, yaws, floor.docking())


def check(
    kit: RegionKit, scene: Scene, region: TrayRegion, xy: tuple[float, float]
) -> tuple[bool, np.ndarray, np.ndarray]:
    """The exact region test for one tray at one base pose ``xy`` [m]: whether it passes, the
    witnesses ``(P, dof)`` and grasp indices ``(P,)``."""
    ok, th, g = feasible_near(kit, scene, region, np.array([xy]), region.yaw, seeds_first=True)
    return bool(ok[0]), th[0], g[0]


def witnesses(
    kit: RegionKit, scene: Scene, region: TrayRegion, checked: tuple[bool, np.ndarray, np.ndarray]
) -> list[pm.Witness] | None:
    """The arm configurations that pick every part of the region's tray, one per part, from
    the outcome of :func:`check`; None if the check failed."""
    ok, th, g = checked
    if not ok:
        return None
    tray = scene.tray(region.tray_id)
    grasps = kit.grasps(scene, tray)
    return [
        pm.Witness(
            tray_id=tray.id,
            part_id=p.id,
            grasp_index=int(g[k]),
            theta=th[k].tolist(),
            hand=kit.hand.joints,
            T_part_tcp=grasps[k].Ts_part_tcp[int(g[k])].round(9).tolist(),
        )
        for k, p in enumerate(tray.parts)
    ]


def success(
    kit: RegionKit,
    scene: Scene,
    regions: list[TrayRegion],
    xy: tuple[float, float],
    sigma: float,
    samples: int,
    seed: int,
) -> Rate:
    """Monte Carlo success rate of stopping at ``xy`` [m] to pick the regions' trays, under
    the error model of the stop's station (:mod:`pickstop.scene.positioning`); ``samples``
    landings drawn from ``seed`` and the stop."""
    trays = tuple(r.tray_id for r in regions)
    dist = of_scene(scene, sigma).at(xy, trays)

    def evaluate(pts: np.ndarray, yaw_: float) -> np.ndarray:
        ok = np.ones(len(pts), bool)
        for r in regions:
            idx = np.flatnonzero(ok)
            if not len(idx):
                break
            ok[idx] = feasible_near(kit, scene, r, pts[idx], yaw_)[0]
        return ok

    rng = np.random.default_rng([seed, int.from_bytes(digest((trays, xy)).encode()[:4])])
    return monte_carlo_at(evaluate, xy, regions[0].yaw, dist, samples, rng)


def refine(
    kit: RegionKit,
    scene: Scene,
    stops: list[tuple[list[TrayRegion], tuple[float, float]]],
    sigma: float,
    kind: Kind,
    dist: ErrorDist | None,
    yaw: float,
    refinement: Refinements,
) -> int:
    """Check exactly, a region at a time, the boundary cells where the landings of any of
    ``stops`` (each: its trays' regions and its position; landing by ``kind`` and ``sigma``,
    or by ``dist`` at heading ``yaw``) need it (:mod:`~pickstop.sequence.refine`), into each
    region's ``refinement``; returns the tests run."""
    if sigma <= 0 and (dist is None or dist.legacy):
        return 0
    todo: dict[str, Refinement] = {}
    for regions, xy in stops:
        k = kernel(kind, sigma, regions[0].grid, xy, dist, yaw)
        for r in regions:
            todo.setdefault(r.digest, refinement(r)).want(k)

    def evaluate(region: TrayRegion, pts: np.ndarray) -> np.ndarray:
        return feasible_near(kit, scene, region, pts, region.yaw, seeds_first=True)[0]

    return sum(ref.run(evaluate) for ref in todo.values())


def estimates(
    kit: RegionKit,
    scene: Scene,
    regions: list[TrayRegion],
    xy: tuple[float, float],
    spread: tuple[float, Kind, ErrorDist | None, float],
    exact: bool,
    refinement: Refinements,
) -> dict[frozenset[str], float]:
    """Fast success estimates (:mod:`~pickstop.sequence.estimate`) of a stop at ``xy`` [m]
    serving each set of the regions' trays, landing by ``spread`` (sigma [m], the isotropic
    kind, the stop's own model or None, heading [rad]); refined exactly near the regions'
    boundaries into ``refinement`` (:func:`refine`) unless ``exact`` is false."""
    sigma, kind, dist, yaw = spread
    sets = expected.tray_sets(tuple(r.tray_id for r in regions))
    if sigma <= 0 and (dist is None or dist.legacy):  # it lands where it aims
        return dict.fromkeys(sets, 1.0)
    k = kernel(kind, sigma, regions[0].grid, xy, dist, yaw)
    known: dict[str, np.ndarray] = {}
    if exact:
        refine(kit, scene, [(regions, xy)], sigma, kind, dist, yaw, refinement)
        known = {r.tray_id: refinement(r).exact for r in regions}
    feasible = {r.tray_id: feasible_subcells(r, k, known.get(r.tray_id)) for r in regions}
    return subset_estimates(k, feasible, sets)


def placement(
    regions: list[TrayRegion],
    cand: Intersection,
    sigma: float,
    kind: Kind,
    dist: ErrorDist | None,
    estimate: Callable[[tuple[float, float]], float],
) -> tuple[float, float] | None:
    """Where in ``cand`` a stop serving the regions' trays succeeds most
    (:mod:`~pickstop.sequence.placement`), when its ``estimate`` there (for every tray, refined
    exactly) beats the circle's centre's by :data:`~pickstop.sequence.placement.MIN_GAIN`;
    None: the centre is as good."""
    grid, yaw = regions[0].grid, cand.yaw
    found = best_point(regions, cand.polygon, cand.centre,
                       lambda xy: kernel(kind, sigma, grid, xy, dist, yaw))  # fmt: skip
    if found is None or math.dist(found[0], cand.centre) <= 1e-9:
        return None
    at_centre = estimate(cand.centre)
    return found[0] if estimate(found[0]) >= at_centre + MIN_GAIN else None


def _fresh() -> Refinements:
    """Refinements that start empty (one call's scratch: nothing outlives it)."""
    made: dict[str, Refinement] = {}
    return lambda r: made.setdefault(r.digest, Refinement.of(r))


class PureSteps:
    """:class:`~pickstop.sequence.steps.PlanSteps` from scratch over a scratch kit (see the
    module): every answer computed from its arguments, nothing kept between calls."""

    def __init__(self, kit: RegionKit) -> None:
        """kit: the robot and database's kit; its memos are not used (a scratch copy is)."""
        self.kit = kit.scratch()
        self.regions = PureRegions(self.kit)

    def candidates(self, regions: Regions) -> list[Intersection]:
        return candidates(regions)

    def floor(self, scene: Scene, world: str | None = None) -> Floor:
        spec = floor_spec(self.kit, scene)
        return floor(self.kit, scene, spec, floor_map(scene, spec))

    def paths(self, floor: Floor, points: np.ndarray, yaws: np.ndarray) -> Paths:
        return paths(floor, points, yaws)

    def witnesses(
        self, scene: Scene, region: TrayRegion, xy: tuple[float, float], world: str | None = None
    ) -> list[pm.Witness] | None:
        return witnesses(self.kit, scene, region, check(self.kit, scene, region, xy))

    def success(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        xy: tuple[float, float],
        sigma: float,
        samples: int,
        seed: int,
    ) -> Rate:
        return success(self.kit, scene, regions, xy, sigma, samples, seed)

    def estimates(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        xy: tuple[float, float],
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
        yaw: float = 0.0,
        exact: bool = True,
    ) -> dict[frozenset[str], float]:
        return estimates(self.kit, scene, regions, xy, (sigma, kind, dist, yaw), exact, _fresh())

    def refine(
        self,
        scene: Scene,
        world_key: str,
        stops: list[tuple[list[TrayRegion], tuple[float, float]]],
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
        yaw: float = 0.0,
    ) -> int:
        """Nothing made ahead: each estimate refines what it needs itself."""
        return 0

    def placement(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        cand: Intersection,
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
    ) -> tuple[float, float] | None:
        every = frozenset(r.tray_id for r in regions)

        def estimate(xy: tuple[float, float]) -> float:
            return self.estimates(scene, world_key, regions, xy, sigma, kind, dist, cand.yaw)[every]

        return placement(regions, cand, sigma, kind, dist, estimate)

    def selection(
        self,
        trays_of: list[frozenset[str]],
        required: list[str],
        cost: np.ndarray,
        objective: Literal["stops", "time"],
        stop_cost: float,
        time_limit: float,
        unlock: Any = None,
        n_stops: int | None = None,
        groups: tuple[int, ...] | None = None,
    ) -> Selection:
        return select_stops(trays_of, required, cost, objective=objective, stop_cost=stop_cost,
                            time_limit=time_limit, n_stops=n_stops, groups=groups)  # fmt: skip
