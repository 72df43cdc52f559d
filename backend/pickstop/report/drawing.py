"""The plan seen from above as SVG: floor, obstacles, trays with their names, base regions,
intersections, inscribed circles, stops, the route, a scale bar and a legend.

World frame: x right, y up on the page (SVG's y points down, so y is flipped); lengths in
metres, the drawing's in pixels at a scale chosen to fit ``width`` [px].
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from html import escape
from typing import Any

from pickstop.scene import defaults
from pickstop.sequence.plan_model import Plan

RGB = tuple[int, int, int]
KEPT: RGB = (40, 170, 80)
REJECTED: RGB = (210, 40, 40)
ROUTE: RGB = (230, 150, 0)
STOP: RGB = (30, 60, 150)
OBSTACLE: RGB = (150, 140, 130)
PAD = 16.0  # [px] around the floor
LEGEND_H = 64.0  # [px] below the floor: scale bar and legend
FONT = "font-family='Helvetica, Arial, sans-serif'"


def hex_rgb(c: RGB) -> str:
    return "#{:02x}{:02x}{:02x}".format(*c)


def tray_colour(index: int, tray: dict[str, Any]) -> RGB:
    """The tray's ``color`` ("#rrggbb"), else the format's palette colour ``index``."""
    c = tray.get("color")
    if isinstance(c, str) and c.startswith("#") and len(c) == 7:
        return (int(c[1:3], 16), int(c[3:5], 16), int(c[5:7], 16))
    return defaults.TRAY_PALETTE[index % len(defaults.TRAY_PALETTE)]


def tray_names(scene: dict[str, Any]) -> dict[str, str]:
    """Each tray's display name: its ``name``, else its id."""
    return {t["id"]: str(t.get("name") or t["id"]) for t in scene.get("trays", [])}


@dataclass(frozen=True)
class Frame:
    """World [m] to page [px]: ``x0, y1`` the floor's left and top edge, ``s`` px per m."""

    x0: float
    y1: float
    s: float

    def p(self, x: float, y: float) -> tuple[float, float]:
        return PAD + (x - self.x0) * self.s, PAD + (self.y1 - y) * self.s

    def pts(self, xy: Iterable[tuple[float, float]]) -> str:
        return " ".join("{:.1f},{:.1f}".format(*self.p(x, y)) for x, y in xy)


def _rect(f: Frame, x: float, y: float, yaw: float, sx: float, sy: float) -> str:
    """The points of a ``sx`` by ``sy`` [m] rectangle centred at ``(x, y)`` turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    corners = [(-sx / 2, -sy / 2), (sx / 2, -sy / 2), (sx / 2, sy / 2), (-sx / 2, sy / 2)]
    return f.pts((x + c * a - s * b, y + s * a + c * b) for a, b in corners)


def _obstacles(f: Frame, scene: dict[str, Any]) -> list[str]:
    out = []
    for ob in scene.get("obstacles", []):
        g, p = ob["geometry"], ob.get("pose", {})
        x, y, yaw = float(p.get("x", 0)), float(p.get("y", 0)), float(p.get("yaw", 0))
        tip = f"<title>{escape(ob['id'])} (obstacle)</title>"
        fill = f"fill='{hex_rgb(OBSTACLE)}' fill-opacity='0.55' stroke='#555'"
        if g["shape"] == "box":
            sx, sy = float(g["size"][0]), float(g["size"][1])
            out.append(f"<polygon points='{_rect(f, x, y, yaw, sx, sy)}' {fill}>{tip}</polygon>")
        elif g["shape"] == "cylinder":
            cx, cy = f.p(x, y)
            r = float(g["radius"]) * f.s
            out.append(f"<circle cx='{cx:.1f}' cy='{cy:.1f}' r='{r:.1f}' {fill}>{tip}</circle>")
    return out


def _trays(f: Frame, scene: dict[str, Any]) -> list[str]:
    out = []
    for k, t in enumerate(scene.get("trays", [])):
        p = t.get("pose", {})
        wall = float(t.get("wall_thickness", defaults.TRAY_WALL_THICKNESS))
        sx, sy = (float(v) + 2 * wall for v in t["inner_size"])
        pts = _rect(f, float(p.get("x", 0)), float(p.get("y", 0)), float(p.get("yaw", 0)), sx, sy)
        colour = hex_rgb(tray_colour(k, t))
        out.append(f"<polygon points='{pts}' fill='{colour}' fill-opacity='0.8' stroke='#222' "
                   f"stroke-width='1'><title>{escape(t['id'])}</title></polygon>")  # fmt: skip
    return out


def _tray_labels(f: Frame, scene: dict[str, Any]) -> list[str]:
    """Each tray's name beside it, moved to the first free place (above, below, further up,
    further down) so no two names overlap."""
    taken: list[tuple[float, float, float, float]] = []
    out = []
    names = tray_names(scene)
    for t in scene.get("trays", []):
        p = t.get("pose", {})
        cx, cy = f.p(float(p.get("x", 0)), float(p.get("y", 0)))
        text = names[t["id"]]
        w, h = 6.3 * len(text) + 4, 13.0
        half = max(float(v) for v in t["inner_size"]) / 2 * f.s + 4
        for dy in (-half - 2, half + h, -half - 2 - h, half + 2 * h, -half - 2 - 2 * h,
                   half + 3 * h):  # fmt: skip
            box = (cx - w / 2, cy + dy - h, cx + w / 2, cy + dy)
            if not any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3]
                       for b in taken):  # fmt: skip
                break
        taken.append(box)
        out.append(f"<text x='{cx:.1f}' y='{box[3] - 3:.1f}' text-anchor='middle' font-size='11' "
                   f"{FONT} fill='#111' stroke='white' stroke-width='3' paint-order='stroke'>"
                   f"{escape(text)}</text>")  # fmt: skip
    return out


def _ring_path(f: Frame, rings: list[list[tuple[float, float]]]) -> str:
    return " ".join("M " + f.pts(r) + " Z" for r in rings if len(r) >= 3)


def _regions(f: Frame, plan: Plan, colours: dict[str, RGB]) -> list[str]:
    out = []
    for c in plan.candidates:
        d = _ring_path(f, c.polygon)
        if not d:
            continue
        if len(c.trays) == 1:
            col = hex_rgb(colours.get(c.trays[0], (150, 150, 150)))
            out.append(f"<path d='{d}' fill='{col}' fill-opacity='0.28' fill-rule='evenodd'/>")
        else:
            out.append(f"<path d='{d}' fill='none' stroke='#333' stroke-width='1' "
                       "stroke-opacity='0.7'/>")  # fmt: skip
    return out


def _circles(f: Frame, plan: Plan, names: dict[str, str]) -> list[str]:
    out = []
    for c in plan.candidates:
        x, y = f.p(c.x, c.y)
        bad = c.status == "rejected"
        colour = hex_rgb(REJECTED if bad else KEPT)
        dash = " stroke-dasharray='4 3'" if bad else ""
        why = f": {c.reason}" if bad and c.reason else ""
        tip = f"{c.status} candidate, {', '.join(names.get(t, t) for t in c.trays)}{why}"
        out.append(f"<circle cx='{x:.1f}' cy='{y:.1f}' r='{max(c.inscribed_radius * f.s, 1.5):.1f}'"
                   f" fill='none' stroke='{colour}' stroke-width='1.5'{dash}>"
                   f"<title>{escape(tip)}</title></circle>")  # fmt: skip
    return out


def _route(f: Frame, plan: Plan) -> list[str]:
    if len(plan.route) < 2:
        return []
    col = hex_rgb(ROUTE)
    marks = "marker-mid='url(#arrow)' marker-end='url(#arrow)'"
    return [f"<polyline points='{f.pts(plan.route)}' fill='none' stroke='{col}' "
            f"stroke-width='3' stroke-linejoin='round' {marks}/>"]  # fmt: skip


def _stops(f: Frame, plan: Plan, scene: dict[str, Any]) -> list[str]:
    out = []
    for name in ("start", "goal"):
        p = scene.get(name)
        if isinstance(p, dict):
            x, y = f.p(float(p["x"]), float(p["y"]))
            fill = "#222" if name == "start" else "#fff"
            out.append(f"<rect x='{x - 6:.1f}' y='{y - 6:.1f}' width='12' height='12' fill='{fill}'"
                       f" stroke='#222' stroke-width='1.5'/><text x='{x + 9:.1f}' y='{y + 4:.1f}' "
                       f"font-size='11' {FONT}>{name}</text>")  # fmt: skip
    for k, s in enumerate(plan.stops):
        x, y = f.p(s.x, s.y)
        hx, hy = x + 16 * math.cos(s.yaw), y - 16 * math.sin(s.yaw)
        out.append(f"<line x1='{x:.1f}' y1='{y:.1f}' x2='{hx:.1f}' y2='{hy:.1f}' "
                   f"stroke='{hex_rgb(STOP)}' stroke-width='2.5'/>"
                   f"<circle cx='{x:.1f}' cy='{y:.1f}' r='9' fill='{hex_rgb(STOP)}'/>"
                   f"<text x='{x:.1f}' y='{y + 4:.1f}' text-anchor='middle' font-size='11' "
                   f"font-weight='bold' fill='white' {FONT}>{k + 1}</text>")  # fmt: skip
    return out


def nice_length(span: float) -> float:
    """A round length [m] (1, 2 or 5 times a power of ten) near a fifth of ``span`` [m]."""
    target = max(span / 5, 1e-3)
    p = 10 ** math.floor(math.log10(target))
    return min((m * p for m in (1, 2, 5, 10)), key=lambda v: abs(v - target))


def _scale_and_legend(f: Frame, width: float, top: float, span: float) -> list[str]:
    bar = nice_length(span)
    x, y = PAD, top + 18
    w = bar * f.s
    out = [f"<rect x='{x:.1f}' y='{y:.1f}' width='{w / 2:.1f}' height='5' fill='#222'/>",
           f"<rect x='{x + w / 2:.1f}' y='{y:.1f}' width='{w / 2:.1f}' height='5' fill='#fff' "
           "stroke='#222'/>",
           f"<text x='{x:.1f}' y='{y + 18:.1f}' font-size='11' {FONT}>0</text>",
           f"<text x='{x + w:.1f}' y='{y + 18:.1f}' font-size='11' text-anchor='middle' "
           f"{FONT}>{bar:g} m</text>"]  # fmt: skip
    items = [
        ("<rect width='14' height='10' fill='#e6194b' fill-opacity='0.3'/>", "base region"),
        ("<rect width='14' height='10' fill='none' stroke='#333'/>", "intersection"),
        (f"<circle cx='7' cy='5' r='5' fill='none' stroke='{hex_rgb(KEPT)}' "
         "stroke-width='1.5'/>", "kept circle"),
        (f"<circle cx='7' cy='5' r='5' fill='none' stroke='{hex_rgb(REJECTED)}' "
         "stroke-dasharray='3 2' stroke-width='1.5'/>", "rejected circle"),
        (f"<circle cx='7' cy='5' r='6' fill='{hex_rgb(STOP)}'/>", "stop (heading)"),
        (f"<line x1='0' y1='5' x2='14' y2='5' stroke='{hex_rgb(ROUTE)}' stroke-width='3'/>",
         "route"),
        (f"<rect width='14' height='10' fill='{hex_rgb(OBSTACLE)}' fill-opacity='0.55'/>",
         "obstacle"),
    ]  # fmt: skip
    lx, ly = x + w + 40, top + 10
    for sym, text in items:
        if lx + 120 > width:
            lx, ly = x + w + 40, ly + 20
        out.append(f"<g transform='translate({lx:.1f},{ly:.1f})'>{sym}<text x='19' y='9' "
                   f"font-size='11' {FONT}>{text}</text></g>")  # fmt: skip
        lx += 26 + 6.5 * len(text)
    return out


def top_view_svg(plan: Plan, scene: dict[str, Any], width: float = 900.0) -> str:
    """The plan over its scene seen from above, as an SVG element ``width`` [px] wide."""
    (x0, y0), (x1, y1) = scene["floor"]["min"], scene["floor"]["max"]
    s = (width - 2 * PAD) / max(x1 - x0, 1e-6)
    f = Frame(float(x0), float(y1), s)
    height = 2 * PAD + (y1 - y0) * s + LEGEND_H
    colours = {t["id"]: tray_colour(k, t) for k, t in enumerate(scene.get("trays", []))}
    names = tray_names(scene)
    fx0, fy0 = f.p(x0, y1)
    grid = []
    step = nice_length(max(x1 - x0, y1 - y0)) / 2
    gx = math.ceil(x0 / step) * step
    while gx <= x1:
        a, b = f.p(gx, y0), f.p(gx, y1)
        grid.append(f"<line x1='{a[0]:.1f}' y1='{a[1]:.1f}' x2='{b[0]:.1f}' y2='{b[1]:.1f}'/>")
        gx += step
    gy = math.ceil(y0 / step) * step
    while gy <= y1:
        a, b = f.p(x0, gy), f.p(x1, gy)
        grid.append(f"<line x1='{a[0]:.1f}' y1='{a[1]:.1f}' x2='{b[0]:.1f}' y2='{b[1]:.1f}'/>")
        gy += step
    parts = [
        f"<svg xmlns='http://www.w3.org/2000/svg' width='{width:.0f}' height='{height:.0f}' "
        f"viewBox='0 0 {width:.0f} {height:.0f}' role='img' aria-label='top view of the plan'>",
        "<defs><marker id='arrow' viewBox='0 0 10 10' refX='5' refY='5' markerWidth='5' "
        f"markerHeight='5' orient='auto'><path d='M0,0 L10,5 L0,10 z' fill='{hex_rgb(ROUTE)}'/>"
        "</marker></defs>",
        f"<rect x='{fx0:.1f}' y='{fy0:.1f}' width='{(x1 - x0) * s:.1f}' "
        f"height='{(y1 - y0) * s:.1f}' fill='#fafafa' stroke='#999'/>",
        f"<g stroke='#e3e3e3' stroke-width='1'>{''.join(grid)}</g>",
        *_regions(f, plan, colours), *_obstacles(f, scene), *_trays(f, scene),
        *_circles(f, plan, names), *_route(f, plan), *_stops(f, plan, scene),
        *_tray_labels(f, scene),
        *_scale_and_legend(f, width, 2 * PAD + (y1 - y0) * s, x1 - x0),
        "</svg>",
    ]  # fmt: skip
    return "\n".join(parts)
