"""A quick prediction of an order's stops and time with some trays in other slots.

For the search to weigh thousands of layouts, each tray's region is known once per turn (where
it stands, or at one slot of that turn) and carried with it by whole grid cells, clipped where
the base fits, as placement guidance does (:mod:`pickstop.layout.guidance`). Where a circle of
radius sigma fits is where the regions' erosions meet; an order's stops are the fewest blocks
its trays split into whose erosions meet (every split tried for up to :data:`EXACT_TRAYS`
trays, the largest blocks first beyond), and its time is that of a straight route from the
start through each block's deepest point to the goal, plus the stops' and picks' times. A
prediction ranks layouts; only the exact plans of the best ones are believed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from pickstop.layout.guidance import eroded
from pickstop.layout.slots import Slot
from pickstop.regions.cells import CellGrid
from pickstop.regions.footprint import footprint_free
from pickstop.scene.model import Scene
from pickstop.sequence.timing import leg_time
from pickstop.speedups.region_planner import RegionPlanner

EXACT_TRAYS = 6  # orders up to this many trays: every way of splitting them is tried
INFEASIBLE = (math.inf, math.inf)


@dataclass(frozen=True)
class Reach:
    """A window of a mask on the scene's grid: ``mask`` covers rows ``y0..`` and columns
    ``x0..`` (cells whose centre a circle of radius sigma may have)."""

    y0: int
    x0: int
    mask: np.ndarray

    @classmethod
    def of(cls, mask: np.ndarray) -> Reach | None:
        ys, xs = np.nonzero(mask)
        if len(ys) == 0:
            return None
        y0, x0 = int(ys.min()), int(xs.min())
        return cls(y0, x0, mask[y0 : ys.max() + 1, x0 : xs.max() + 1].copy())

    def shifted(self, dy: int, dx: int) -> Reach:
        return Reach(self.y0 + dy, self.x0 + dx, self.mask)

    def meet(self, other: Reach) -> Reach | None:
        """Where both hold (None if nowhere)."""
        y0, x0 = max(self.y0, other.y0), max(self.x0, other.x0)
        y1 = min(self.y0 + self.mask.shape[0], other.y0 + other.mask.shape[0])
        x1 = min(self.x0 + self.mask.shape[1], other.x0 + other.mask.shape[1])
        if y1 <= y0 or x1 <= x0:
            return None
        a = self.mask[y0 - self.y0 : y1 - self.y0, x0 - self.x0 : x1 - self.x0]
        b = other.mask[y0 - other.y0 : y1 - other.y0, x0 - other.x0 : x1 - other.x0]
        both = a & b
        return Reach(y0, x0, both) if both.any() else None

    def deepest(self, grid: CellGrid) -> tuple[float, float]:
        """The centre [m] of the cell deepest inside the window's cells."""
        depth = ndimage.distance_transform_edt(np.pad(self.mask, 1))[1:-1, 1:-1]
        iy, ix = np.unravel_index(int(np.argmax(depth)), depth.shape)
        c = grid.centres(np.array([ix + self.x0]), np.array([iy + self.y0]))[0]
        return float(c[0]), float(c[1])


@dataclass
class Predictor:
    """Predicted stops and time of orders with trays in slots (see the module), for one scene,
    sigma and set of turned regions; memoised by the slots of an order's trays."""

    scene: Scene
    grid: CellGrid
    sigma: float
    fits: dict[float, Reach | None]  # yaw -> where a circle of radius sigma fits the base
    refs: dict[tuple[str, int, float], tuple[Reach | None, tuple[float, float]]]
    parts: dict[str, int]
    fewest: bool = True  # the plans' objective: fewest stops first (else least time)
    _reach: dict[tuple[Slot, float], Reach | None] = field(default_factory=dict)
    _cost: dict[tuple[Slot, ...], tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def of(
        cls, rp: RegionPlanner, scene: Scene, trays: list[str], refs: dict[tuple[str, int], Slot],
        sigma: float, fewest: bool = True,
    ) -> Predictor:  # fmt: skip
        """The predictor of ``scene`` for ``trays`` (their regions where they stand, and for
        each ``(tray, turn)`` of ``refs`` the region with the tray in that slot, computed by
        ``rp`` if not known)."""
        grid = CellGrid.of(scene)
        yaws = scene.base_yaw.yaws
        regions = rp.regions(scene.model_copy(update={"task": list(trays)}))
        out: dict[tuple[str, int, float], tuple[Reach | None, tuple[float, float]]] = {}
        for t in trays:
            p = scene.tray(t).pose
            for y in yaws:
                out[t, 0, y] = (Reach.of(eroded(regions[t, y].mask, grid.res, sigma)), (p.x, p.y))
        for (t, turn), slot in refs.items():
            there = _with(scene, [slot])
            for y in yaws:
                region = rp.tray_region(there, t, y)
                out[t, turn, y] = (Reach.of(eroded(region.mask, grid.res, sigma)), (slot.x, slot.y))
        fits = {y: Reach.of(eroded(_base_fits(rp, scene, grid, y), grid.res, sigma)) for y in yaws}
        parts = {t.id: len(t.parts) for t in scene.trays}
        return cls(scene, grid, sigma, fits, out, parts, fewest)

    def reach(self, slot: Slot, yaw: float) -> Reach | None:
        """Where a stop serving the tray in ``slot`` may stand at base ``yaw`` (predicted)."""
        key = (slot, yaw)
        if key not in self._reach:
            self._reach[key] = self._carried(slot, yaw)
        return self._reach[key]

    def _carried(self, slot: Slot, yaw: float) -> Reach | None:
        known, (rx, ry) = self.refs[slot.tray, slot.turn, yaw]
        fits = self.fits[yaw]
        if known is None or fits is None:
            return None
        dx = round((slot.x - rx) / self.grid.res)
        dy = round((slot.y - ry) / self.grid.res)
        return known.shifted(dy, dx).meet(fits) if (dx, dy) != (0, 0) else known

    def order_cost(self, slots: tuple[Slot, ...]) -> tuple[float, float]:
        """(stops, time [s]) predicted for an order whose trays stand in ``slots`` (one per
        tray); ``(inf, inf)`` if some tray has no place for a stop."""
        if slots not in self._cost:
            self._cost[slots] = self._order_cost(slots)
        return self._cost[slots]

    def _order_cost(self, slots: tuple[Slot, ...]) -> tuple[float, float]:
        blocks = self._blocks(slots)
        n = len(slots)
        if any(not any(k in b for b in blocks) for k in range(n)):
            return INFEASIBLE
        best = INFEASIBLE
        for split in _splits(n, blocks, self.fewest):
            stops = [blocks[b] for b in split]
            cost = (float(len(split)), self._time(stops, slots))
            best = min(best, cost, key=lambda c: c if self.fewest else (c[1], c[0]))
        return best

    def _blocks(self, slots: tuple[Slot, ...]) -> dict[frozenset[int], Reach]:
        """Every set of the order's trays (by index) whose erosions meet at some base yaw,
        with where they meet (the deepest meeting over the yaws)."""
        out: dict[frozenset[int], Reach] = {}
        for yaw in self.scene.base_yaw.yaws:
            own = [self.reach(s, yaw) for s in slots]
            todo = [(frozenset([k]), r) for k, r in enumerate(own) if r is not None]
            while todo:
                block, common = todo.pop()
                if block in out:
                    continue
                out[block] = common
                top = max(block)
                for k in range(top + 1, len(slots)):
                    r = own[k]
                    more = common.meet(r) if r is not None else None
                    if more is not None:
                        todo.append((block | {k}, more))
        return out

    def _time(self, stops: list[Reach], slots: tuple[Slot, ...]) -> float:
        """Predicted time [s]: the straight route from the start through the stops' deepest
        points to the goal (the best order for up to 6 stops), the stops and the picks."""
        m, sc = self.scene.motion, self.scene
        pts = [s.deepest(self.grid) for s in stops]
        ends = (sc.start.x, sc.start.y), (sc.goal.x, sc.goal.y)
        orders = itertools.permutations(pts) if len(pts) <= 6 else [tuple(pts)]
        travel = min(_route_time(ends, list(o), m.max_speed, m.max_acceleration) for o in orders)
        picks = sum(self.parts[s.tray] for s in slots)
        return travel + len(stops) * m.stop_time + picks * m.pick_time


def _route_time(
    ends: tuple[tuple[float, float], tuple[float, float]],
    pts: list[tuple[float, float]],
    speed: float,
    accel: float,
) -> float:
    path = [ends[0], *pts, ends[1]]
    d = np.array([math.dist(a, b) for a, b in itertools.pairwise(path)])
    return float(np.sum(leg_time(d, speed, accel)))


def _splits(
    n: int, blocks: dict[frozenset[int], Reach], fewest: bool = True
) -> Iterator[list[frozenset[int]]]:
    """Ways of splitting trays ``0..n-1`` into blocks of ``blocks``: up to
    :data:`EXACT_TRAYS` trays all of them (only those of the fewest blocks with ``fewest``),
    else the largest blocks first."""
    if n > EXACT_TRAYS:
        left, split = set(range(n)), []
        while left:
            best = max((b for b in blocks if b <= left), key=lambda b: (len(b), -min(b)))
            split.append(best)
            left -= best
        yield split
        return
    least: int | None = None
    for split in sorted(_partitions(list(range(n))), key=len):
        if least is not None and len(split) > least:
            return
        if all(b in blocks for b in split):
            least = len(split) if fewest else None
            yield split


def _partitions(items: list[int]) -> Iterator[list[frozenset[int]]]:
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for part in _partitions(rest):
        for k in range(len(part)):
            yield [*part[:k], part[k] | {first}, *part[k + 1 :]]
        yield [frozenset([first]), *part]


def _with(scene: Scene, slots: list[Slot]) -> Scene:
    """``scene`` with each slot's tray standing in it."""
    at = {s.tray: s for s in slots}
    trays = [at[t.id].placed(t) if t.id in at else t for t in scene.trays]
    return scene.model_copy(update={"trays": trays})


def _base_fits(rp: RegionPlanner, scene: Scene, grid: CellGrid, yaw: float) -> np.ndarray:
    """``(ny, nx)`` the cells where the base at ``yaw`` fits."""
    gx, gy = np.meshgrid(np.arange(grid.nx), np.arange(grid.ny))
    centres = grid.centres(gx.ravel(), gy.ravel())
    free = footprint_free(scene, rp.robot, centres, yaw, rp.solids_of(scene))
    return free.reshape(grid.ny, grid.nx)
