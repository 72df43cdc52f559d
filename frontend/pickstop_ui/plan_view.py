"""What a plan looks like on the floor: pure functions from a plan to the drawing's arrays.

A verified plan, a preview (drawn while a tray is dragged, nothing verified) and a stale plan
(the last valid one while the current request has none) differ only in their :class:`Style`.
:func:`plan_drawing` returns arrays only; :mod:`pickstop_ui.plan_layer` puts them into the
scene's existing nodes.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np
from shapely.geometry import Polygon

from pickstop.sequence.plan_model import Plan, Stop
from pickstop_ui.geometry import (
    circle_segments,
    patch_mesh,
    polyline_at,
    ring_segments,
    route_segments,
)

RGB = tuple[int, int, int]
GREY: RGB = (150, 150, 150)
MAX_LABELS = 32  # stop labels kept as nodes


@dataclass(frozen=True)
class Style:
    """Colours [0-255] and opacities of one kind of plan."""

    name: str  # "verified", "preview" or "stale"
    kept: RGB
    rejected: RGB
    route: RGB
    outline: RGB
    region_opacity: float
    region_colour: RGB | None  # None: each tray's own colour
    dashed_route: bool
    ghosts: bool  # robots at the stops in their witness configurations


VERIFIED = Style(
    "verified",
    (40, 200, 90),
    (220, 40, 40),
    (255, 200, 0),
    (255, 255, 255),
    0.35,
    None,
    False,
    True,
)
# A preview: the same layout of things, drawn lighter, its route dashed violet, its circles
# in one unsaturated colour: never mistaken for a verified plan.
PREVIEW = Style(
    "preview", (120, 90, 220), (170, 150, 230), (150, 60, 255), (200, 190, 255), 0.2, None, True,
    False,
)  # fmt: skip
STALE = Style(
    "stale", (140, 140, 175), (140, 140, 175), (140, 140, 175), (255, 255, 255), 0.35,
    (140, 140, 175), False, False,
)  # fmt: skip


def style_of(plan: Plan, stale: bool = False) -> Style:
    if stale:
        return STALE
    return VERIFIED if plan.verified else PREVIEW


@dataclass(frozen=True)
class Ghost:
    """A robot at a stop: base pose [m, rad] and the URDF's actuated joint values."""

    x: float
    y: float
    yaw: float
    cfg: np.ndarray | None  # (n_actuated,), None: the witness is unknown (a preview)


@dataclass(frozen=True)
class PlanDrawing:
    """Everything a plan puts in the scene, as arrays (float32 positions [m], uint8 colours)."""

    style: Style
    regions: dict[str, tuple[np.ndarray, np.ndarray, RGB]]  # tray -> vertices, faces, colour
    outlines: np.ndarray  # (N, 2, 3) intersection outlines (order >= 2)
    circles_kept: np.ndarray  # (N, 2, 3)
    circles_rejected: np.ndarray  # (N, 2, 3)
    centres: np.ndarray  # (C, 3)
    centre_colours: np.ndarray  # (C, 3)
    route: np.ndarray  # (N, 2, 3)
    labels: list[tuple[str, tuple[float, float, float]]]
    ghosts: list[Ghost]


def polygon(rings: list[list[tuple[float, float]]]) -> Polygon:
    return Polygon(rings[0], rings[1:]) if rings else Polygon()


def _stack(parts: list[np.ndarray]) -> np.ndarray:
    parts = [p for p in parts if len(p)]
    if not parts:
        return np.zeros((0, 2, 3), np.float32)
    return np.concatenate(parts).astype(np.float32).reshape(-1, 2, 3)


def _dashes(segments: np.ndarray, dash: float = 0.08) -> np.ndarray:
    """Segments ``(N, 2, 3)`` cut into pieces of about ``dash`` [m], every other one kept."""
    out = []
    for a, b in segments:
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / dash)))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        pts = a + t * (b - a)
        out.append(np.stack([pts[:-1], pts[1:]], axis=1)[::2])
    return _stack(out)


def plan_drawing(
    plan: Plan,
    colours: dict[str, RGB],
    style: Style,
    urdf_joints: list[str] | None = None,
    locked: dict[str, float] | None = None,
    names: dict[str, str] | None = None,
) -> PlanDrawing:
    """The drawing of ``plan`` in ``style``; ``colours``: each tray's colour; ``names``: each
    tray's display name for the stop labels (else its id).

    urdf_joints: the URDF's actuated joint names, to turn witnesses into ghost configurations
    (``locked``: the robot's locked and pre-grasp values).
    """
    regions = {}
    for k, tid in enumerate(plan.trays):
        polys = [polygon(c.polygon) for c in plan.candidates if c.trays == [tid]]
        v, f = patch_mesh(polys, 0.004 + 0.001 * k)
        regions[tid] = (v, f, style.region_colour or colours.get(tid, GREY))
    outlines: list[np.ndarray] = []
    kept: list[np.ndarray] = []
    rejected: list[np.ndarray] = []
    for c in plan.candidates:
        if len(c.trays) >= 2:
            outlines.append(ring_segments(np.asarray(polygon(c.polygon).exterior.coords), 0.02))
        bad = c.status == "rejected"
        ring = circle_segments((c.x, c.y), c.inscribed_radius, 0.025, dashed=bad)
        (rejected if bad else kept).append(ring)
    route = _stack([route_segments(plan.route, 0.05)])
    if style.dashed_route:
        route = _dashes(route)
    labels = []
    for k, s in enumerate(plan.stops[:MAX_LABELS]):
        ok = "" if s.success is None else f", {s.success.rate:.0%} success"
        tag = " (preview)" if not plan.verified else ""
        trays = ", ".join((names or {}).get(t, t) for t in s.trays)
        labels.append((f"stop {k + 1}: {trays}{ok}{tag}", (s.x, s.y, 1.3)))
    ghosts = []
    for s in plan.stops:
        cfg = None
        if s.witnesses and urdf_joints is not None:
            w = s.witnesses[0]
            cfg = joint_cfg(urdf_joints, plan.joints, w.theta, w.hand, locked or {})
        ghosts.append(Ghost(s.x, s.y, s.yaw, cfg))
    return PlanDrawing(
        style=style,
        regions=regions,
        outlines=_stack(outlines),
        circles_kept=_stack(kept),
        circles_rejected=_stack(rejected),
        centres=np.array([[c.x, c.y, 0.03] for c in plan.candidates], np.float32).reshape(-1, 3),
        centre_colours=np.array(
            [style.rejected if c.status == "rejected" else style.kept for c in plan.candidates],
            np.uint8,
        ).reshape(-1, 3),
        route=route,
        labels=labels,
        ghosts=ghosts,
    )


def joint_cfg(
    urdf_joints: list[str],
    joints: list[str],
    theta: list[float],
    hand: dict[str, float] | None,
    locked: dict[str, float],
) -> np.ndarray:
    """The URDF's actuated joint values ``(len(urdf_joints),)``: the arm's ``theta`` (for
    ``joints``), then the hand's values, then the robot's locked (and pre-grasp) values."""
    values = dict(zip(joints, theta, strict=True))
    for name, value in (hand or {}).items():
        values.setdefault(name, value)
    for name, value in locked.items():
        values.setdefault(name, value)
    return np.array([values.get(n, 0.0) for n in urdf_joints])


@dataclass(frozen=True)
class PlaybackStep:
    """One moment of the route's playback: the base pose [m, rad], the arm's joints in the
    plan's joint order [rad or m] (None: as it was), how long to hold it [s] and what the
    robot does: ``drive``, ``reach`` (travel posture to a witness), ``pick`` (at the witness),
    ``fold`` (back to the travel posture) or ``travel`` (in the travel posture, standing)."""

    x: float
    y: float
    yaw: float
    theta: list[float] | None
    hold: float
    what: Literal["drive", "reach", "pick", "fold", "travel"]


def _between(a: np.ndarray, b: np.ndarray, n: int) -> list[list[float]]:
    """The ``n`` joint-space points from just past ``a`` to ``b`` (``b`` included)."""
    return [list(map(float, a + (b - a) * k / n)) for k in range(1, n + 1)]


def _picks(
    stop: Stop, travel: np.ndarray, dt: float, reach_time: float, moves: int
) -> Iterator[PlaybackStep]:
    """At ``stop``: for each witness, the arm from ``travel`` to it in ``moves`` steps, held
    there ``reach_time`` [s], then back to ``travel`` in ``moves`` steps."""
    at = (stop.x, stop.y, stop.yaw)
    for w in stop.witnesses:
        theta = np.asarray(w.theta, float)
        for t in _between(travel, theta, moves)[:-1]:
            yield PlaybackStep(*at, t, dt, "reach")
        yield PlaybackStep(*at, list(map(float, theta)), reach_time, "pick")
        for t in _between(theta, travel, moves):
            yield PlaybackStep(*at, t, dt, "fold")


def playback(
    plan: Plan,
    travel: list[float],
    speed: float = 1.5,
    dt: float = 1 / 30,
    reach_time: float = 0.6,
    moves: int = 8,
) -> Iterator[PlaybackStep]:
    """The robot in its ``travel`` posture (the plan's joint order [rad or m]) driving each leg
    at ``speed`` [m/s] in steps of ``dt`` [s]; at each stop, for each witness, reaching it in
    ``moves`` joint-space steps, holding it ``reach_time`` [s] and folding back to travel in
    ``moves`` steps; in the travel posture at the goal at the end."""
    home = np.asarray(travel, float)
    assert home.shape == (len(plan.joints),), (home.shape, plan.joints)
    folded = list(map(float, home))
    for k, leg in enumerate(plan.legs):
        line = np.asarray(leg.polyline, float)
        length = float(np.sum(np.hypot(*np.diff(line, axis=0).T))) if len(line) > 1 else 0.0
        s = 0.0
        while s <= length:
            p, heading = polyline_at(line, s)
            # The travel posture set as each leg starts; the arm keeps it while driving.
            theta = folded if s == 0.0 else None
            yield PlaybackStep(float(p[0]), float(p[1]), heading, theta, dt, "drive")
            s += speed * dt
        if k < len(plan.stops):
            yield from _picks(plan.stops[k], home, dt, reach_time, moves)
    if plan.legs and len(plan.legs[-1].polyline):
        end = np.asarray(plan.legs[-1].polyline, float)
        _, heading = polyline_at(end, float("inf"))
        yield PlaybackStep(float(end[-1][0]), float(end[-1][1]), heading, folded, 0.0, "travel")
