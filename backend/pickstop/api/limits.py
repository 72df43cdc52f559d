"""Sizes that drive the cost of a request, bounded before any super-linear work.

The checks read the raw decoded document (lists and numbers, before the scene model and its
geometry checks), so a 10,000-tray scene is refused in the time it takes to count its trays.
The same limits are published at ``GET /api/v1/limits`` so a client can check before sending.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, Field

from pickstop.settings import Settings


class Limits(BaseModel):
    """What one request may ask for; larger requests are refused (422, or 413 for a body)."""

    max_body_bytes: int = Field(description="request body [bytes]")
    max_yaml_bytes: int = Field(description="YAML request body (robot configs) [bytes]")
    max_trays: int = Field(description="trays per scene")
    max_parts_per_tray: int = Field(description="parts per tray")
    max_parts: int = Field(description="parts per scene")
    max_obstacles: int = Field(description="obstacles per scene")
    max_mesh_triangles: int = Field(description="triangles of all meshes of a scene")
    max_grid_cells: int = Field(description="base grid cells per scene")
    max_mc_samples: int = Field(description="Monte Carlo samples per stop")
    max_batch: int = Field(description="scenes per batch job")
    max_orders: int = Field(default=200, description="orders of a mix per request")
    max_build_samples: int = Field(description="samples per database build")
    request_deadline_s: float = Field(description="computation time of a synchronous request [s]")
    job_deadline_s: float = Field(description="run time of a job [s]")

    @classmethod
    def of(cls, s: Settings) -> Limits:
        return cls(
            max_body_bytes=s.max_body_bytes,
            max_yaml_bytes=s.max_yaml_bytes,
            max_trays=s.max_trays,
            max_parts_per_tray=s.max_parts_per_tray,
            max_parts=s.max_parts,
            max_obstacles=s.max_obstacles,
            max_mesh_triangles=s.max_mesh_triangles,
            max_grid_cells=s.max_grid_cells,
            max_mc_samples=s.max_mc_samples,
            max_batch=s.max_batch,
            max_orders=s.max_orders,
            max_build_samples=s.max_samples,
            request_deadline_s=s.request_deadline,
            job_deadline_s=s.job_deadline,
        )


Problems = list[tuple[str, str]]


def _num(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def grid_cells(doc: dict[str, Any]) -> float | None:
    """Cells of a raw scene's base grid (a float: it may be astronomically large), or None if
    the extent or resolution is malformed (the scene model names that)."""
    grid: dict[str, Any] = doc["base_grid"] if isinstance(doc.get("base_grid"), dict) else {}
    ext = grid["extent"] if isinstance(grid.get("extent"), dict) else doc.get("floor")
    res = _num(grid.get("resolution", 0.025))
    if not isinstance(ext, dict) or res is None or not res > 0:
        return None
    lo, hi = ext.get("min"), ext.get("max")
    if not (isinstance(lo, list) and isinstance(hi, list) and len(lo) == len(hi) == 2):
        return None
    vals = [_num(v) for v in (*lo, *hi)]
    finite = [v for v in vals if v is not None and math.isfinite(v)]
    if len(finite) != 4:
        return None
    x0, y0, x1, y1 = finite
    # Float arithmetic throughout: an extent of 1e308 gives inf, never an OverflowError.
    nx, ny = (x1 - x0) / res, (y1 - y0) / res
    if not (nx > 0 and ny > 0):
        return None
    return math.floor(nx) * math.floor(ny) if nx * ny < 1e15 else nx * ny


def scene_problems(doc: Any, limits: Limits, loc: str = "") -> Problems:
    """Every size limit a raw scene document exceeds, as (field, message); ``loc`` prefixes the
    fields (``scenes.3.scene.``). Malformed parts are left to the scene model."""
    if not isinstance(doc, dict):
        return []
    out: Problems = []
    trays = doc.get("trays")
    if isinstance(trays, list):
        if len(trays) > limits.max_trays:
            out.append(
                (f"{loc}trays", f"{len(trays)} trays exceed the limit of {limits.max_trays}")
            )
            return out  # counting the parts of 10,000 trays is no use
        total = 0
        for i, tray in enumerate(trays):
            parts = tray.get("parts") if isinstance(tray, dict) else None
            if isinstance(parts, list):
                total += len(parts)
                if len(parts) > limits.max_parts_per_tray:
                    out.append((f"{loc}trays.{i}.parts", f"{len(parts)} parts exceed the limit "
                                f"of {limits.max_parts_per_tray} per tray"))  # fmt: skip
        if total > limits.max_parts:
            out.append((f"{loc}trays", f"{total} parts in all exceed the limit of "
                        f"{limits.max_parts} per scene"))  # fmt: skip
    obstacles = doc.get("obstacles")
    if isinstance(obstacles, list) and len(obstacles) > limits.max_obstacles:
        out.append((f"{loc}obstacles", f"{len(obstacles)} obstacles exceed the limit of "
                    f"{limits.max_obstacles}"))  # fmt: skip
    cells = grid_cells(doc)
    if cells is not None and cells > limits.max_grid_cells:
        shown = f"{cells:.3g}" if cells >= 1e9 else f"{int(cells)}"
        out.append((f"{loc}base_grid", f"{shown} cells exceeds the limit of "
                    f"{limits.max_grid_cells}; coarsen the resolution or the extent"))  # fmt: skip
    return out


def mesh_geometries(doc: Any) -> list[tuple[str, dict[str, Any]]]:
    """(field, geometry) of every mesh of a raw scene document."""
    out: list[tuple[str, dict[str, Any]]] = []
    if not isinstance(doc, dict):
        return out
    for i, ob in enumerate(doc.get("obstacles") or []):
        g = ob.get("geometry") if isinstance(ob, dict) else None
        if isinstance(g, dict) and g.get("shape") == "mesh":
            out.append((f"obstacles.{i}.geometry", g))
    for i, tray in enumerate(doc.get("trays") or []):
        parts = tray.get("parts") if isinstance(tray, dict) else None
        for k, part in enumerate(parts if isinstance(parts, list) else []):
            g = part.get("geometry") if isinstance(part, dict) else None
            if isinstance(g, dict) and g.get("shape") == "mesh":
                out.append((f"trays.{i}.parts.{k}.geometry", g))
    return out


def check_body_int(value: Any, field: str, limit: int, what: str) -> Problems:
    if isinstance(value, int) and not isinstance(value, bool) and value > limit:
        return [(field, f"{value} {what} exceed the limit of {limit}")]
    return []
