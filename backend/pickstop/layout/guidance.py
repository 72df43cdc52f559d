"""Placement guidance: where a tray could go and what that does to its order's stops.

On every face at the tray's height where it may stand (:func:`~pickstop.scene.supports.
stand_areas`), the positions of its centre are sorted into zones: where it shares a stop with
some of its order partners (their regions and its own, moved with it, meet in a circle of radius
>= sigma), where it needs a stop of its own (its region alone holds such a circle), and where it
cannot be reached (not even that). Faces at other heights are marked unknown: the tray's region
there has not been computed.

Computed from known regions, in a fraction of a second: the tray's region where it stands is
carried with it by whole grid cells (the reach of the arm goes with the tray) and clipped to
where the base fits; the partners' regions stay as they are. That is a prediction, as a preview
is: nothing in it is verified, and the tray's exact plan replaces it when it is dropped.
On the grid, "a circle of radius sigma fits" is "a cell whose centre is at least sigma from the
region's edge" (:func:`eroded`); where two regions share such a circle is where their erosions
meet, and the offsets at which the moved tray's erosion meets a partner's come from one
correlation of the two masks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry.base import BaseGeometry

from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.footprint import footprint_free
from pickstop.scene.model import Scene
from pickstop.scene.supports import SAME_HEIGHT, StandArea, stand_areas
from pickstop.speedups.region_planner import RegionPlanner

Kind = Literal["shares", "own", "unreachable", "unknown"]
MAX_SHARED = 4  # trays but the moved one that one stop is tried for


@dataclass(frozen=True)
class Zone:
    """Positions of the tray's centre on one support: ``kind``, and for ``shares`` the
    partners (``trays``) it shares one stop with there."""

    kind: Kind
    support: str
    area: BaseGeometry
    trays: tuple[str, ...] = ()


@dataclass(frozen=True)
class Guidance:
    """The zones of one tray (its yaw as it is) for a set of partner groups (one per order
    shown), the sigma they were judged at, and the zone the tray is in now."""

    tray: str
    sigma: float
    groups: tuple[tuple[str, ...], ...]
    zones: list[Zone]
    here: Kind
    seconds: float


def partner_groups(
    scene: Scene, tray_id: str, order: str | None = None, mix: bool = False
) -> list[list[str]]:
    """The trays ``tray_id`` is planned with: of the order ``order`` (of the scene's orders),
    of every order that needs it (``mix``), or of the scene's task; each group without it."""
    if mix or order is not None:
        chosen = [o for o in scene.orders or [] if mix or o.id == order]
        trays = [scene.order_trays(o) for o in chosen]
    else:
        trays = [scene.task_trays]
    return [[t for t in g if t != tray_id] for g in trays if tray_id in g]


def eroded(mask: np.ndarray, res: float, sigma: float) -> np.ndarray:
    """``(ny, nx)`` the cells of ``mask`` whose centre is at least ``sigma`` [m] from the
    edge of the mask's cells (the centres of circles of radius sigma inside them)."""
    if not mask.any():
        return mask
    inside = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
    return mask & ((inside - 0.5) * res >= sigma - 1e-9)


def meeting_offsets(
    moving: np.ndarray, fixed: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """``(hi - lo + 1)`` bool over whole-cell offsets ``d`` (``(iy, ix)``, from ``lo`` to
    ``hi``): whether ``moving``, shifted by ``d``, meets ``fixed`` (both ``(ny, nx)`` masks)."""
    out = np.zeros(tuple(hi - lo + 1), bool)
    ys, xs = np.nonzero(moving)
    if len(ys) == 0 or not fixed.any():
        return out
    k0 = np.array([ys.min(), xs.min()])
    kernel = moving[k0[0] : ys.max() + 1, k0[1] : xs.max() + 1].astype(float)
    # fixed is read over rows lo + k0 .. hi + k0 + kernel rows (zero beyond the grid)
    a0, a1 = lo + k0, hi + k0 + np.array(kernel.shape) - 1
    window = np.zeros(tuple(a1 - a0 + 1))
    s0, s1 = np.maximum(a0, 0), np.minimum(a1, np.array(fixed.shape) - 1)
    if np.any(s1 < s0):
        return out
    window[s0[0] - a0[0] : s1[0] - a0[0] + 1, s0[1] - a0[1] : s1[1] - a0[1] + 1] = fixed[
        s0[0] : s1[0] + 1, s0[1] : s1[1] + 1
    ]
    from scipy import signal  # on use: it adds 0.7 s to the API's start

    return signal.correlate(window, kernel, mode="valid", method="auto") > 0.5


@dataclass(frozen=True)
class _Offsets:
    """Whole-cell offsets of the tray from where it stands, covering the areas: ``lo``,
    ``hi`` (``(iy, ix)``) and the grid whose cell ``(iy, ix) - lo`` is centred on the tray
    moved by that offset."""

    lo: np.ndarray
    hi: np.ndarray
    grid: CellGrid

    @classmethod
    def of(cls, grid: CellGrid, x: float, y: float, areas: list[StandArea]) -> _Offsets:
        b = np.array([a.area.bounds for a in areas])
        lo = np.floor((b[:, :2].min(0) - (x, y)) / grid.res).astype(int)[::-1]
        hi = np.ceil((b[:, 2:].max(0) - (x, y)) / grid.res).astype(int)[::-1]
        shape = hi - lo + 1
        x0 = x + (lo[1] - 0.5) * grid.res
        y0 = y + (lo[0] - 0.5) * grid.res
        return cls(lo, hi, CellGrid(x0, y0, grid.res, int(shape[1]), int(shape[0])))

    def polygon(self, mask: np.ndarray) -> BaseGeometry:
        iy, ix = np.nonzero(mask)
        return self.grid.cells_polygon(iy, ix)


def guidance(
    rp: RegionPlanner,
    scene: Scene,
    tray_id: str,
    groups: list[list[str]],
    sigma: float | None = None,
) -> Guidance:
    """The zones of ``tray_id`` for its partner ``groups`` (:func:`partner_groups`) at
    ``sigma`` [m] (default: the scene's). The regions of the tray and its partners come from
    ``rp`` (computed if never planned)."""
    t0 = time.perf_counter()
    sigma = scene.sigma if sigma is None else sigma
    tray = scene.tray(tray_id)
    areas = stand_areas(scene, tray)
    here_z = tray.pose.z
    known = [a for a in areas if abs(a.z - here_z) <= SAME_HEIGHT]
    zones = [Zone("unknown", a.support, a.area) for a in areas if a not in known]
    masks = _reach_masks(rp, scene, tray_id, groups, sigma, known)
    for a in known:
        zones += _face_zones(a, masks)
    here = _kind_at(zones, tray.pose.x, tray.pose.y)
    return Guidance(tray_id, sigma, tuple(tuple(g) for g in groups), zones, here,
                    time.perf_counter() - t0)  # fmt: skip


@dataclass(frozen=True)
class _Masks:
    """Over the offsets: where the moved tray reaches alone (``own``) and where it shares a
    stop with each set of partners (``shares``), with the offsets' grid."""

    offsets: _Offsets
    own: np.ndarray
    shares: dict[tuple[str, ...], np.ndarray]


def _reach_masks(
    rp: RegionPlanner,
    scene: Scene,
    tray_id: str,
    groups: list[list[str]],
    sigma: float,
    known: list[StandArea],
) -> _Masks | None:
    """The masks of :class:`_Masks`, OR-ed over the base yaws (None without a known face)."""
    if not known:
        return None
    tray = scene.tray(tray_id)
    grid = CellGrid.of(scene)
    offsets = _Offsets.of(grid, tray.pose.x, tray.pose.y, known)
    needed = list(dict.fromkeys([tray_id, *(t for g in groups for t in g)]))
    regions = rp.regions(scene.model_copy(update={"task": needed}))
    own = np.zeros(tuple(offsets.hi - offsets.lo + 1), bool)
    shares: dict[tuple[str, ...], np.ndarray] = {}
    for yaw in scene.base_yaw.yaws:
        mine = eroded(regions[tray_id, yaw].mask, grid.res, sigma)
        fits = eroded(_free_cells(rp, scene, grid, yaw, offsets, mine), grid.res, sigma)
        own |= meeting_offsets(mine, fits, offsets.lo, offsets.hi)
        for subset, common in _partner_sets(regions, groups, yaw, grid.res, sigma):
            hit = meeting_offsets(mine, common, offsets.lo, offsets.hi)
            shares[subset] = shares.get(subset, np.zeros_like(own)) | hit
    return _Masks(offsets, own, {k: v for k, v in shares.items() if v.any()})


def _partner_sets(
    regions: dict[tuple[str, float], TrayRegion],
    groups: list[list[str]],
    yaw: float,
    res: float,
    sigma: float,
) -> list[tuple[tuple[str, ...], np.ndarray]]:
    """Every set of up to :data:`MAX_SHARED` partners of one group whose regions share a
    circle of radius sigma, with the mask of those circles' centres (a set grows only from
    one that shares: its supersets cannot share what it does not)."""
    out: dict[tuple[str, ...], np.ndarray] = {}
    for group in groups:
        own = {t: eroded(regions[t, yaw].mask, res, sigma) for t in sorted(group)}
        todo = [((t,), m) for t, m in own.items() if m.any()]
        while todo:
            subset, common = todo.pop()
            if subset in out:
                continue
            out[subset] = common
            if len(subset) == MAX_SHARED:
                continue
            for t in own:
                if t > subset[-1] and (more := common & own[t]).any():
                    todo.append(((*subset, t), more))
    return list(out.items())


def _free_cells(
    rp: RegionPlanner,
    scene: Scene,
    grid: CellGrid,
    yaw: float,
    offsets: _Offsets,
    mine: np.ndarray,
) -> np.ndarray:
    """``(ny, nx)`` the cells of ``grid`` the moved region can reach where the base fits."""
    out = np.zeros((grid.ny, grid.nx), bool)
    ys, xs = np.nonzero(mine)
    if len(ys) == 0:
        return out
    y0, x0 = max(ys.min() + offsets.lo[0], 0), max(xs.min() + offsets.lo[1], 0)
    y1, x1 = min(ys.max() + offsets.hi[0], grid.ny - 1), min(xs.max() + offsets.hi[1], grid.nx - 1)
    if y1 < y0 or x1 < x0:
        return out
    gx, gy = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
    ok = footprint_free(scene, rp.robot, grid.centres(gx.ravel(), gy.ravel()), yaw,
                        rp.solids_of(scene))  # fmt: skip
    out[y0 : y1 + 1, x0 : x1 + 1] = ok.reshape(gx.shape)
    return out


def _face_zones(a: StandArea, masks: _Masks | None) -> list[Zone]:
    """The zones of one known face: its stand area cut by the masks, each place in one zone
    only: sharing with the most partners first (ties by their ids), then alone, then not."""
    if masks is None:
        return []
    cut = masks.offsets.polygon
    zones = []
    taken = shapely.Polygon()
    for subset, mask in sorted(masks.shares.items(), key=lambda kv: (-len(kv[0]), kv[0])):
        area = a.area.intersection(cut(mask)).difference(taken)
        if area.area > 1e-9:
            zones.append(Zone("shares", a.support, area, subset))
            taken = taken.union(area)
    own = a.area.intersection(cut(masks.own)).difference(taken)
    if not own.is_empty:
        zones.append(Zone("own", a.support, own))
    rest = a.area.difference(taken).difference(own)
    if not rest.is_empty:
        zones.append(Zone("unreachable", a.support, rest))
    return zones


def _kind_at(zones: list[Zone], x: float, y: float) -> Kind:
    """The kind of the first zone holding ``(x, y)``: shares before own before unreachable."""
    p = shapely.Point(x, y)
    for kind in ("shares", "own", "unreachable", "unknown"):
        if any(z.kind == kind and z.area.buffer(1e-6).contains(p) for z in zones):
            return kind  # type: ignore[return-value]
    return "unreachable"


def guidance_geojson(g: Guidance) -> dict[str, object]:
    """The zones as a GeoJSON FeatureCollection (positions of the tray's centre, world
    x, y [m]), each with its kind, support and partners; the collection's own properties say
    for which tray, groups and sigma, and where the tray is now."""
    import json

    return {
        "type": "FeatureCollection",
        "properties": {
            "tray": g.tray,
            "sigma": g.sigma,
            "groups": [list(x) for x in g.groups],
            "here": g.here,
            "seconds": g.seconds,
        },
        "features": [
            {
                "type": "Feature",
                "geometry": json.loads(shapely.to_geojson(z.area)),
                "properties": {
                    "kind": z.kind,
                    "support": z.support,
                    "trays": list(z.trays),
                    "area_m2": z.area.area,
                },
            }
            for z in g.zones
        ],
    }
