"""The planner's picture to hand on: a render of the 3D view with a title, the plan's figures
and a legend, as PNG bytes (a pure function of the render and the words).

The render itself comes from the browser (:meth:`viser.ClientHandle.get_render`) from a camera
that frames the whole scene (:mod:`pickstop_ui.views`), with the gizmo and other helpers
hidden; this module only lays the page out around it.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from pickstop.sequence.plan_model import Plan

RGB = tuple[int, int, int]
TITLE_H = 64  # [px] above the render
LEGEND_W = 300  # [px] right of the render
PAD = 14  # [px]


@dataclass(frozen=True)
class LegendEntry:
    """A swatch: its colour and how it is drawn ("patch", "line", "dashed", "dot")."""

    colour: RGB
    style: str
    text: str


#: What the picture's colours mean: the same as the 3D view's (see :mod:`plan_view`).
LEGEND = (
    LegendEntry((245, 130, 48), "patch", "base region (the tray's colour)"),
    LegendEntry((150, 150, 150), "outline", "intersection of regions"),
    LegendEntry((40, 200, 90), "ring", "inscribed circle, kept"),
    LegendEntry((220, 40, 40), "dashed", "inscribed circle, rejected"),
    LegendEntry((255, 200, 0), "line", "route"),
    LegendEntry((30, 30, 30), "dot", "start"),
    LegendEntry((250, 250, 250), "dot", "goal"),
)


def figure_lines(plan: Plan | None) -> list[str]:
    """The plan's figures in a few short lines (stops, route, time, saving, success, rule)."""
    if plan is None:
        return ["No plan."]
    t, n = plan.totals, plan.naive
    lines = [
        f"{t.stops} stops for {len(plan.trays)} trays",
        f"route {t.route_length:.2f} m",
        f"predicted time {t.time.total:.1f} s",
        f"saving {100 * n.saving_fraction:.1f}% against one stop per tray",
    ]
    if t.success is not None:
        lines.append(f"success {100 * t.success:.1f}%")
    lines.append(f"sigma {plan.parameters.sigma:.3f} m, rule {plan.parameters.rule}")
    if not plan.verified:
        lines.append("preview: not verified")
    return lines


def _font(size: int):  # type: ignore[no-untyped-def]
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _swatch(draw, x: int, y: int, e: LegendEntry) -> None:  # type: ignore[no-untyped-def]
    box = (x, y, x + 28, y + 16)
    if e.style == "patch":
        draw.rectangle(box, fill=tuple(int(0.45 * c + 0.55 * 255) for c in e.colour))
    elif e.style == "outline":
        draw.rectangle(box, outline=e.colour, width=2)
    elif e.style in ("ring", "dashed"):
        draw.ellipse((x + 6, y, x + 22, y + 16), outline=e.colour, width=2)
        if e.style == "dashed":
            draw.line((x + 4, y + 8, x + 24, y + 8), fill="white", width=4)
    elif e.style == "line":
        draw.line((x, y + 8, x + 28, y + 8), fill=e.colour, width=4)
    else:
        draw.ellipse((x + 7, y + 1, x + 21, y + 15), fill=e.colour, outline=(90, 90, 90))


def compose_png(
    render: np.ndarray,
    title: str,
    lines: list[str],
    legend: tuple[LegendEntry, ...] = LEGEND,
) -> bytes:
    """The page: ``title`` above ``render`` ``(H, W, 3 or 4)`` uint8, and to its right the
    figures (``lines``) and the legend; PNG bytes of ``(H + TITLE_H, W + LEGEND_W)``."""
    from PIL import Image, ImageDraw

    assert render.ndim == 3 and render.shape[2] in (3, 4), render.shape
    h, w = render.shape[:2]
    page = Image.new("RGB", (w + LEGEND_W, h + TITLE_H), "white")
    img = Image.fromarray(np.ascontiguousarray(render[..., :3]).astype(np.uint8))
    if render.shape[2] == 4:  # transparent background over white
        alpha = Image.fromarray(render[..., 3].astype(np.uint8))
        page.paste(img, (0, TITLE_H), alpha)
    else:
        page.paste(img, (0, TITLE_H))
    draw = ImageDraw.Draw(page)
    draw.text((PAD, 12), title, fill=(20, 20, 20), font=_font(24))
    draw.line((0, TITLE_H - 1, w + LEGEND_W, TITLE_H - 1), fill=(200, 200, 200))
    x, y = w + PAD, TITLE_H + PAD
    for line in lines:
        draw.text((x, y), line, fill=(30, 30, 30), font=_font(15))
        y += 22
    y += 14
    draw.text((x, y), "Legend", fill=(30, 30, 30), font=_font(16))
    y += 26
    for e in legend:
        _swatch(draw, x, y, e)
        draw.text((x + 38, y), e.text, fill=(30, 30, 30), font=_font(14))
        y += 24
    buf = io.BytesIO()
    page.save(buf, format="PNG")
    return buf.getvalue()
