"""Placement guidance as drawings: the API's GeoJSON zones of a tray's centre -> floor patches.

Pure functions of the guidance document (``POST /guidance``): one triangle mesh per kind of
zone (``shares``, ``own``, ``unreachable``), drawn just above the supports the tray stands on,
and the panel's legend line. Zones of kind ``unknown`` lie on supports at another height (no
region known there): they are counted in the legend, not drawn.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from shapely.geometry import shape
from shapely.geometry.base import BaseGeometry

from pickstop_ui.geometry import patch_mesh

KINDS = ("shares", "own", "unreachable")  # the kinds drawn, in the legend's order
COLOURS = {"shares": (40, 170, 80), "own": (235, 160, 30), "unreachable": (200, 50, 50)}
SWATCH = {"shares": "🟩", "own": "🟧", "unreachable": "🟥"}
LIFT = 0.004  # [m] above the support's top, so a patch never fights with the table's face
OPACITY = 0.45


@dataclass(frozen=True)
class GuidanceDrawing:
    """The meshes of one tray's zones: ``meshes[kind]`` is (vertices ``(3T, 3)`` float32 [m],
    faces ``(T, 3)`` uint32), empty where the tray has no zone of that kind."""

    tray: str
    meshes: dict[str, tuple[np.ndarray, np.ndarray]]
    here: str
    unknown: int  # zones on supports at another height (not drawn)


def _polygons(geom: BaseGeometry) -> list[Any]:
    if geom.is_empty:
        return []
    return list(getattr(geom, "geoms", [geom]))


def guidance_drawing(doc: dict[str, Any], z: float) -> GuidanceDrawing:
    """The zones of guidance document ``doc`` as meshes at height ``z`` [m] (the top of the
    supports at the tray's height, where every zone but ``unknown`` lies) plus :data:`LIFT`."""
    polys: dict[str, list[Any]] = {k: [] for k in KINDS}
    unknown = 0
    for f in doc.get("features", []):
        kind = f["properties"]["kind"]
        if kind in polys and f.get("geometry"):
            polys[kind] += _polygons(shape(f["geometry"]))
        elif kind == "unknown":
            unknown += 1
    info = doc.get("properties", {})
    meshes = {k: patch_mesh(polys[k], z + LIFT) for k in KINDS}
    return GuidanceDrawing(str(info.get("tray", "")), meshes, str(info.get("here", "")), unknown)


def legend(doc: dict[str, Any]) -> str:
    """The panel's line: the three colours, the partners, where the tray stands now."""
    info = doc.get("properties", {})
    partners = sorted({t for g in info.get("groups", []) for t in g} - {info.get("tray")})
    with_ = ", ".join(partners) if partners else "no other tray"
    unknown = sum(f["properties"]["kind"] == "unknown" for f in doc.get("features", []))
    other = f" · {unknown} zone(s) at another height not drawn" if unknown else ""
    return (
        f"**Guidance for {info.get('tray', '?')}** (σ = {float(info.get('sigma', 0)):.3f} m, "
        f"predicted): {SWATCH['shares']} shares a stop with {with_} · {SWATCH['own']} needs a "
        f"stop of its own · {SWATCH['unreachable']} cannot be reached · now: "
        f"*{info.get('here', '?')}*{other}"
    )
