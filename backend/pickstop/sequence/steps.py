"""The steps a plan is made of, as one small interface.

A planning request (:class:`pickstop.sequence.request.PlanRequest`) runs the pipeline's steps
in order and asks these for each answer; it knows nothing of caches. Two implementations:
:class:`pickstop.sequence.pure.PureSteps` computes every answer from its inputs (the
algorithm), :class:`pickstop.speedups.stop_planner.StopPlanner` the same answers remembered, reused
across edits and prepared in the background (the speed-ups).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
from shapely.geometry import Polygon

from pickstop.reach.database import ReachDatabase
from pickstop.regions.cells import TrayRegion
from pickstop.regions.footprint import BodyPieces, FloorSolids, sweep_blocked
from pickstop.robot.model import RobotModel
from pickstop.scene.model import Scene
from pickstop.scene.positioning import ErrorDist
from pickstop.sequence import plan_model as pm
from pickstop.sequence.cover import Selection
from pickstop.sequence.intersections import Intersection
from pickstop.sequence.route import Docking, FloorMap, Paths
from pickstop.sequence.success import Kind, Rate

#: The regions of a scene by (tray id, base yaw [rad]).
Regions = dict[tuple[str, float], TrayRegion]


@dataclass(frozen=True)
class Floor:
    """Where the base may drive, and how it docks where its bounding circle does not fit."""

    fmap: FloorMap
    outlines: list[tuple[str, Polygon]]  # obstacle id -> floor outline
    world: FloorSolids  # every solid reaching below the body's top, for docking legs
    body: BodyPieces
    reach: float  # [m] longest docking leg
    omnidirectional: bool  # the base may dock sideways (else only along its heading)
    key: str  # what the floor is (bounds, body reach, blocking solids, drive), by value

    def docking(self) -> Docking:
        return Docking(lambda a, b, yaw: sweep_blocked(self.body, self.world, a, b, yaw),
                       self.reach, self.omnidirectional)  # fmt: skip


class RegionSteps(Protocol):
    """The base regions a plan reads, of one robot and database."""

    @property
    def robot(self) -> RobotModel: ...

    @property
    def db(self) -> ReachDatabase: ...

    def regions(self, scene: Scene) -> Regions:
        """Every task tray's region at every yaw of the scene's policy."""
        ...

    def tray_region(self, scene: Scene, tray_id: str, yaw: float | None = None) -> TrayRegion:
        """One tray's region at ``yaw`` [rad] (default: the policy's first)."""
        ...

    def known_regions(self, scene: Scene, pairs: list[tuple[str, float]]) -> Regions:
        """For a preview: the regions of ``pairs`` known without computing (may be none)."""
        ...


class PlanSteps(Protocol):
    """Every answer a planning request asks for, beside the regions (see the module)."""

    @property
    def regions(self) -> RegionSteps: ...

    def candidates(self, regions: Regions) -> list[Intersection]:
        """All intersection components of the regions, per yaw, duplicates dropped."""
        ...

    def floor(self, scene: Scene, world: str | None = None) -> Floor:
        """Where the base may drive (``world``: the scene's world key, if known)."""
        ...

    def paths(self, floor: Floor, points: np.ndarray, yaws: np.ndarray) -> Paths:
        """Shortest paths between ``points: (Q, 2)`` [m] held at ``yaws: (Q,)`` [rad]."""
        ...

    def witnesses(
        self, scene: Scene, region: TrayRegion, xy: tuple[float, float], world: str | None = None
    ) -> list[pm.Witness] | None:
        """The exact check of ``region`` at ``xy``: a witness per part, or None if it fails."""
        ...

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
        """Monte Carlo success rate of a stop at ``xy`` picking the regions' trays."""
        ...

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
        """Fast success estimates of a stop at ``xy`` for each set of the regions' trays."""
        ...

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
        """Exact boundary checks the estimates of ``stops`` will need, made ahead (a batch);
        returns the tests run. Changes no answer."""
        ...

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
        """Where in ``cand`` a stop succeeds most, if enough better than its centre."""
        ...

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
        """:func:`~pickstop.sequence.cover.select_stops` (``unlock``: a lock the caller
        holds, which may be let go of while the solver runs)."""
        ...
