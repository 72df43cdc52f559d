"""All k-th order intersections of base regions, as candidate stops with inscribed circles.

A candidate is one connected component of the intersection of the regions of a set of trays
(k = 1: a region's own components). Its robust stop is the centre of its largest inscribed
circle; the paper keeps it only if that radius is at least sigma, the base positioning error.
Shapely may return lines and points where regions merely touch: only polygon parts count.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

MIN_AREA = 1e-8  # [m^2] slivers below this are numerical leftovers


@dataclass(frozen=True)
class Intersection:
    """One connected component of the intersection of the regions of ``trays``, with its
    largest inscribed circle: a candidate stop, serving those trays from its centre."""

    trays: frozenset[str]
    yaw: float  # [rad]
    polygon: Polygon
    centre: tuple[float, float]  # of the largest inscribed circle [m]
    radius: float  # of that circle [m]

    @property
    def order(self) -> int:
        return len(self.trays)

    @cached_property
    def rings(self) -> list[list[tuple[float, float]]]:
        """The polygon's exterior ring, then its holes, as plans report them: coordinates [m]
        rounded to 0.1 mm (computed once: candidates are kept while their regions are)."""
        rings = [self.polygon.exterior, *self.polygon.interiors]
        return [
            [(x, y) for x, y in np.round(shapely.get_coordinates(r), 4).tolist()] for r in rings
        ]


def polygon_parts(geom: BaseGeometry) -> list[Polygon]:
    """The polygons of any geometry (collections, multipolygons), slivers dropped."""
    if geom.is_empty:
        return []
    if isinstance(geom, Polygon):
        return [geom] if geom.area > MIN_AREA else []
    if isinstance(geom, MultiPolygon) or hasattr(geom, "geoms"):
        out: list[Polygon] = []
        for g in geom.geoms:
            out += polygon_parts(g)
        return out
    return []  # lines and points


def inscribed_circle(poly: Polygon, tolerance: float = 1e-3) -> tuple[tuple[float, float], float]:
    """Centre and radius [m] of the largest circle inside ``poly`` (holes respected)."""
    line = shapely.maximum_inscribed_circle(poly, tolerance)
    (cx, cy), _ = line.coords
    return (float(cx), float(cy)), float(line.length)


def intersections(
    regions: dict[str, BaseGeometry],
    yaw: float = 0.0,
    max_order: int | None = None,
    circle: Callable[[Polygon], tuple[tuple[float, float], float]] = inscribed_circle,
) -> list[Intersection]:
    """Every connected component of every non-empty intersection of ``regions``.

    regions: tray id -> region geometry at one yaw. Subsets grow one tray at a time and stop
    as soon as they are empty (an empty intersection has no non-empty superset), so the work
    follows the number of non-empty intersections, not 2^n. ``circle``: the
    :func:`inscribed_circle` of a component (a memo of it, say).
    """
    ids = sorted(t for t, g in regions.items() if polygon_parts(g))
    cleaned = {t: shapely.union_all(polygon_parts(regions[t])) for t in ids}
    out: list[Intersection] = []
    # Level k: subsets as (sorted tray tuple, their intersection geometry).
    level: list[tuple[tuple[str, ...], BaseGeometry]] = [((t,), cleaned[t]) for t in ids]
    k = 1
    while level:
        for trays, geom in level:
            for part in polygon_parts(geom):
                centre, radius = circle(part)
                out.append(Intersection(frozenset(trays), yaw, part, centre, radius))
        if max_order is not None and k >= max_order:
            break
        nxt = []
        for trays, geom in level:
            last = ids.index(trays[-1])
            for t in ids[last + 1 :]:
                if not geom.intersects(cleaned[t]):
                    continue
                inter = shapely.union_all(polygon_parts(geom.intersection(cleaned[t])))
                if not inter.is_empty:
                    nxt.append(((*trays, t), inter))
        level = nxt
        k += 1
    return out
