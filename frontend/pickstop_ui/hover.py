"""What the 3D view tells on hover or click: a pure function from a plan and its scene to the
shapes the page tests the pointer against, each with its text.

The page (:mod:`pickstop_ui.overlay`) casts the pointer's ray onto the floor (and onto each
item's top) and shows the text of what it meets first: an item (tray or obstacle), a stop, an
inscribed circle (the nearest centre among those around the pointer), then a region or an
intersection (the smallest holding the pointer). Regions are simplified to a few millimetres
for the page; the plan keeps them exact.
"""

from __future__ import annotations

import math
from typing import Any

import shapely
from shapely.geometry import Polygon

from pickstop.sequence.plan_model import Plan
from pickstop_ui.picking import item_box
from pickstop_ui.scene_view import scene_drawing

STOP_RADIUS = 0.12  # [m] around a stop's centre that names the stop
SIMPLIFY = 0.004  # [m] a region's outline may move this much for the page
ROUND = 4  # decimals kept of a coordinate [m]


def names_of(doc: dict[str, Any]) -> dict[str, str]:
    """Each tray's display name (its ``name``, else its id)."""
    return {t["id"]: str(t.get("name") or t["id"]) for t in doc["trays"]}


def trays_text(trays: list[str], names: dict[str, str]) -> str:
    return ", ".join(names.get(t, t) for t in trays)


def pct(x: float) -> str:
    return f"{100 * x:.1f}%"


def stop_text(plan: Plan, k: int, names: dict[str, str]) -> str:
    s = plan.stops[k]
    lines = [
        f"Stop {k + 1} at ({s.x:.2f}, {s.y:.2f}) m, yaw {math.degrees(s.yaw):.0f}°",
        f"Picks from: {trays_text(s.trays, names)}",
        f"Inscribed circle r = {s.inscribed_radius:.3f} m (sigma {plan.parameters.sigma:.3f} m)",
    ]
    if s.success is not None:
        lo, hi = s.success.interval
        lines.append(f"Success {pct(s.success.rate)} (95% interval {pct(lo)} to {pct(hi)})")
    if s.circle_centre is not None:
        cx, cy = s.circle_centre
        rates = [f"estimate {pct(e)}" for e in (s.circle_estimated_success,) if e is not None]
        if s.circle_success is not None:
            rates.append(f"Monte Carlo {pct(s.circle_success.rate)}")
        at = ", ".join(rates) or "not estimated"
        lines.append(f"Placed for success, {s.clearance or 0:.3f} m clear; at the circle's "
                     f"centre ({cx:.2f}, {cy:.2f}): {at}")  # fmt: skip
    if s.success is None and not plan.verified:
        lines.append("Preview: not verified")
    return "\n".join(lines)


def candidate_text(plan: Plan, i: int, names: dict[str, str]) -> str:
    c = plan.candidates[i]
    head = {"chosen": "Chosen stop", "kept": "Candidate stop (kept)",
            "rejected": "Rejected candidate"}[c.status]  # fmt: skip
    lines = [
        f"{head}: serves {trays_text(c.trays, names)}",
        f"Inscribed circle r = {c.inscribed_radius:.3f} m at ({c.x:.2f}, {c.y:.2f}), "
        f"yaw {math.degrees(c.yaw):.0f}°",
    ]
    if c.predicted_success is not None:
        lines.append(f"Predicted success {pct(c.predicted_success)}")
    if c.status == "rejected":
        lines.append(f"Why rejected: {c.reason or 'rejected'}")
    return "\n".join(lines)


def _rings(rings: list[list[tuple[float, float]]]) -> tuple[list[list[list[float]]], float]:
    """A candidate's polygon simplified for the page, and its exact area [m^2]."""
    poly = Polygon(rings[0], rings[1:]) if rings else Polygon()
    simple = shapely.simplify(poly, SIMPLIFY, preserve_topology=True)
    out = []
    for ring in [simple.exterior, *simple.interiors] if not simple.is_empty else []:
        out.append([[round(x, ROUND), round(y, ROUND)] for x, y in ring.coords])
    return out, float(poly.area)


def hover_data(plan: Plan | None, doc: dict[str, Any]) -> dict[str, Any]:
    """Items, stops, circles and regions with their texts, as JSON for the page."""
    names = names_of(doc)
    items = []
    for it in scene_drawing(doc).items:
        b = item_box(it)
        if b is None:
            continue
        x, y, z = b.centre
        kind = "tray" if it.kind == "trays" else "obstacle"
        name = names.get(it.id, it.id)
        title = f"{name} ({kind} {it.id})" if name != it.id else f"{it.id} ({kind})"
        pose = next(o for o in doc[it.kind] if o["id"] == it.id)["pose"]
        px, py, pz, yaw = (float(pose.get(k, 0.0)) for k in ("x", "y", "z", "yaw"))
        text = (f"{title}\nAt ({px:.3f}, {py:.3f}) m, yaw {math.degrees(yaw):.1f}°, z {pz:.3f} m"
                "\nClick to select it")  # fmt: skip
        items.append({"cx": x, "cy": y, "top": z + b.half[2], "hx": b.half[0], "hy": b.half[1],
                      "yaw": b.yaw, "text": text})  # fmt: skip
    if plan is None:
        return {"items": items, "stops": [], "circles": [], "regions": []}
    stops = [{"x": s.x, "y": s.y, "r": STOP_RADIUS, "text": stop_text(plan, k, names)}
             for k, s in enumerate(plan.stops)]  # fmt: skip
    circles, regions = [], []
    for i, c in enumerate(plan.candidates):
        circles.append({"x": c.x, "y": c.y, "r": c.inscribed_radius,
                        "text": candidate_text(plan, i, names)})  # fmt: skip
        rings, area = _rings(c.polygon)
        what = (f"Base region of {trays_text(c.trays, names)}" if len(c.trays) == 1
                else f"Intersection of {trays_text(c.trays, names)}")  # fmt: skip
        text = f"{what} (base yaw {math.degrees(c.yaw):.0f}°)\nArea {area:.3f} m²"
        regions.append({"rings": rings, "area": area, "text": text})
    return {"items": items, "stops": stops, "circles": circles, "regions": regions}
