"""Where a tray may go when a layout is searched: slots on its supports.

A slot is a pose of the tray on a face at its own height (the same table or shelf height: its
region there is a translation of the one known), on a lattice of ``step`` [m] through where it
stands now (so a slot is a whole number of grid cells from it), turned by one of ``turns``,
standing free of every tray that stays and every solid, and within a zone that admits it if the
scene declares zones. The tray's own place comes first, then the rest nearest first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from pickstop.frames import wrap_angle
from pickstop.scene.model import Pose, Scene, Tray
from pickstop.scene.outline import tray_footprint, tray_z_range
from pickstop.scene.supports import SAME_HEIGHT, moved, place_tray, stand_areas

MAX_SLOTS = 400  # slots per tray: the lattice is made coarser until it holds at most this


@dataclass(frozen=True)
class Slot:
    """A pose of a tray [m, rad]: ``turn`` [deg] from its yaw now, on ``support``."""

    tray: str
    x: float
    y: float
    z: float
    yaw: float
    turn: int
    support: str

    @property
    def pose(self) -> Pose:
        return Pose(x=self.x, y=self.y, z=self.z, yaw=self.yaw)

    def placed(self, tray: Tray) -> Tray:
        """``tray`` standing in this slot."""
        return moved(tray, self.x, self.y, self.yaw, self.z)

    def outline(self, tray: Tray) -> BaseGeometry:
        return tray_footprint(self.placed(tray))

    def z_range(self, tray: Tray) -> tuple[float, float]:
        return tray_z_range(self.placed(tray))


def home_slot(scene: Scene, tray_id: str, support: str = "") -> Slot:
    """The slot of the tray where it stands now."""
    p = scene.tray(tray_id).pose
    return Slot(tray_id, p.x, p.y, p.z, p.yaw, 0, support)


def tray_slots(
    scene: Scene,
    tray_id: str,
    movable: list[str],
    step: float,
    turns: tuple[int, ...] = (0, 90, 180, 270),
    max_slots: int = MAX_SLOTS,
) -> list[Slot]:
    """The slots of ``tray_id`` (see the module); the other ``movable`` trays do not count as
    obstacles (they may move: a layout's slots are checked against each other)."""
    tray = scene.tray(tray_id)
    stays = [t for t in scene.trays if t.id == tray_id or t.id not in movable]
    fixed = scene.model_copy(update={"trays": stays})
    areas: list[tuple[int, float, BaseGeometry, str, float]] = []
    for turn in turns:
        yaw = float(wrap_angle(tray.pose.yaw + math.radians(turn)))
        turned = tray.model_copy(update={"pose": tray.pose.model_copy(update={"yaw": yaw})})
        for a in stand_areas(fixed, turned):
            if abs(a.z - tray.pose.z) <= SAME_HEIGHT:
                areas.append((turn, yaw, _admitted(scene, turned, a.area), a.support, a.z))
    p = tray.pose
    home = home_slot(scene, tray_id, place_tray(scene, tray, p.x, p.y, p.yaw, p.z).support or "")
    while True:
        out = [home]
        for turn, yaw, area, support, z in areas:
            for x, y in _lattice(area, tray.pose.x, tray.pose.y, step):
                if turn != 0 or (x, y) != (tray.pose.x, tray.pose.y):
                    out.append(Slot(tray_id, x, y, z, yaw, turn, support))
        if len(out) <= max_slots:
            break
        step *= 2
    far = [math.hypot(s.x - tray.pose.x, s.y - tray.pose.y) + 0.1 * (s.turn != 0) for s in out]
    order = np.argsort(far, kind="stable")
    return [out[k] for k in order]


def _admitted(scene: Scene, tray: Tray, area: BaseGeometry) -> BaseGeometry:
    """The part of ``area`` (centres of ``tray``, turned as it is) inside a zone of the scene
    that admits it (all of it if the scene declares no zones)."""
    if not scene.zones:
        return area
    at0 = tray_footprint(moved(tray, 0.0, 0.0, tray.pose.yaw))
    corners = np.asarray(at0.exterior.coords)[:-1]
    inside = shapely.Polygon()
    for zone in scene.zones:
        if zone.trays is not None and tray.id not in zone.trays:
            continue
        outline = shapely.Polygon(zone.outline)
        held = outline
        for cx, cy in corners:  # the tray's outline lies in a convex zone where its corners do
            held = held.intersection(shapely.affinity.translate(outline, -cx, -cy))
        inside = inside.union(held)
    return area.intersection(inside)


def _lattice(area: BaseGeometry, x0: float, y0: float, step: float) -> list[tuple[float, float]]:
    """The points ``(x0 + i step, y0 + j step)`` [m] inside ``area``."""
    if area.is_empty:
        return []
    bx0, by0, bx1, by1 = area.bounds
    i = np.arange(math.ceil((bx0 - x0) / step - 1e-9), math.floor((bx1 - x0) / step + 1e-9) + 1)
    j = np.arange(math.ceil((by0 - y0) / step - 1e-9), math.floor((by1 - y0) / step + 1e-9) + 1)
    gx, gy = (a.ravel() for a in np.meshgrid(x0 + i * step, y0 + j * step))
    ok = shapely.contains_xy(area, gx, gy)
    return [(float(x), float(y)) for x, y in zip(gx[ok], gy[ok], strict=True)]


def slots_meet(a: Slot, b: Slot, ta: Tray, tb: Tray) -> bool:
    """Whether two trays in these slots would meet (outlines and heights overlapping)."""
    za, zb = a.z_range(ta), b.z_range(tb)
    if min(za[1], zb[1]) - max(za[0], zb[0]) <= 1e-6:
        return False
    oa, ob = a.outline(ta), b.outline(tb)
    return bool(oa.intersects(ob)) and oa.intersection(ob).area > 1e-6
