"""Layout suggestions in words and ghosts: pure functions of the planner's request and of the
API's layout document (``pickstop.layout``, the result of a ``POST /layouts`` job)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Ghost:
    """A tray where a suggestion puts it: box centre [m], yaw [rad], dimensions [m]."""

    tray: str
    centre: Vec3
    yaw: float
    size: Vec3


def layout_body(
    doc: dict[str, Any], movable: list[str] | None, options: dict[str, Any], step: float,
    turns: list[int], shortlist: int,
) -> dict[str, Any]:  # fmt: skip
    """The ``POST /layouts`` body: the document as edited, the trays that may move (None:
    every tray an order needs), plan options, slot spacing ``step`` [m], ``turns`` [deg],
    ``shortlist`` (layouts planned exactly); one suggestion, the best."""
    body: dict[str, Any] = {"scene": doc, "options": options, "step": step, "turns": turns,
                            "shortlist": shortlist, "suggestions": 1}  # fmt: skip
    if movable is not None:
        body["movable"] = movable
    return body


def parse_turns(text: str) -> list[int]:
    """'0, 90' -> [0, 90]; ValueError naming the field for anything but 0, 90, 180, 270."""
    try:
        turns = sorted({int(t) for t in text.replace(" ", "").split(",") if t})
    except ValueError:
        raise ValueError(f"turns [°]: {text!r} is not a list of whole degrees") from None
    if not turns or any(t not in (0, 90, 180, 270) for t in turns):
        raise ValueError(f"turns [°]: {text!r}: give some of 0, 90, 180, 270")
    return turns


def best(layout: dict[str, Any]) -> dict[str, Any] | None:
    """The first-ranked suggestion, or None when the search found no better layout."""
    found = sorted(layout.get("suggestions", []), key=lambda s: s["rank"])
    return found[0] if found else None


def _fig(v: float | None, fmt: str) -> str:
    return "—" if v is None else format(v, fmt)


def gain_text(layout: dict[str, Any]) -> str:
    """The panel's words: the best suggestion's moves, time and stops before and after."""
    s = best(layout)
    if s is None:
        notes = " ".join(layout.get("notes", []))
        return f"**No better layout found.** {notes}".strip()
    b, a, g = layout["before"]["totals"], s["after"]["totals"], s["gain"]
    moves = ", ".join(
        f"{m['tray']} → ({m['to']['x']:.2f}, {m['to']['y']:.2f})"
        + (f" turned {m['turn']:.0f}°" if m["turn"] else "")
        for m in s["moves"]
    )
    return "\n".join([
        f"**Suggested layout** (verified): {moves}",
        f"- Time: {_fig(b['time'], '.1f')} s → **{_fig(a['time'], '.1f')} s** "
        f"(gain {_fig(g.get('time'), '+.1f')} s)",
        f"- Stops: {_fig(b['stops'], '.2f')} → **{_fig(a['stops'], '.2f')}** "
        f"(gain {_fig(g.get('stops'), '+.2f')})",
        "*Accept* applies it as one step (Undo takes it back); *Dismiss* keeps the layout.",
    ])  # fmt: skip


def ghosts(suggestion: dict[str, Any]) -> list[Ghost]:
    """A box per moved tray, where the suggestion's moved scene puts it."""
    trays = {t["id"]: t for t in suggestion["scene"]["trays"]}
    out = []
    for m in suggestion["moves"]:
        t = trays[m["tray"]]
        p, wall = t["pose"], float(t.get("wall_thickness", 0.0))
        h = float(t.get("wall_height", 0.05)) + float(t.get("floor_thickness", 0.0))
        lx, ly = (float(v) + 2 * wall for v in t["inner_size"])
        centre = (float(p["x"]), float(p["y"]), float(p.get("z", 0.0)) + h / 2)
        out.append(Ghost(m["tray"], centre, float(p.get("yaw", 0.0)), (lx, ly, h)))
    return out
