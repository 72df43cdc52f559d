"""Camera presets that frame the whole scene beside the panel: pure functions of its bounds.

The panel floats over the right of the 3D view, so a view centred on the scene would hide
part of it (in the example scenes, the goal). Every preset here looks from its own direction
and then places the camera so that the scene's bounding box (floor, items and their heights)
fills the free part of the view, left of the panel, with a margin: the projected box's
extent sets the distance and its centre the sideways shift, iterated until both settle
(perspective makes them depend on each other a little).

*Top* looks straight down through a narrow field of view from far above: close to an
orthographic plan (viser's camera is perspective only), so pillars stay circles and lengths
read alike across the floor. The other presets use the usual field of view.

Frames: world z up; a camera pose is its position, the point it looks at, its up vector
and its vertical field of view [rad]; the view's pixels are CSS pixels, x right, y down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pickstop_ui.picking import item_box
from pickstop_ui.scene_view import MARKER_RADIUS, scene_drawing

Vec3 = tuple[float, float, float]
FOV = math.radians(50.0)  # the presets' field of view [rad], vertical
TOP_FOV = math.radians(8.0)  # the top view's: far and narrow, nearly orthographic
TOP_TILT = 0.01  # [rad] from straight down: keeps "up" on screen along +y, orbit well-defined
MARGIN = 24.0  # [px] kept free around the scene
PANEL_PX = 400.0  # the panel's width and padding when the page has not said [px]
#: name -> (azimuth [rad] of the camera seen from the scene, elevation [rad] above the floor)
DIRECTIONS = {
    "top": (-math.pi / 2, math.pi / 2 - TOP_TILT),
    "front": (-math.pi / 2, math.radians(18.0)),
    "iso": (-math.radians(60.0), math.radians(35.0)),
}
PRESETS = ("top", "front", "iso", "fit")


@dataclass(frozen=True)
class Viewport:
    """The 3D view on the page [CSS px]: its size and where the panel starts (the scene is
    framed in ``[0, free_right] x [0, height]``)."""

    width: float
    height: float
    free_right: float

    @classmethod
    def default(cls, width: float = 1280.0, height: float = 800.0) -> Viewport:
        return cls(width, height, max(width - PANEL_PX, 0.5 * width))


@dataclass(frozen=True)
class CameraPose:
    position: Vec3
    look_at: Vec3
    up: Vec3
    fov: float  # vertical [rad]


def scene_bounds(doc: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The box ``(lo (3,), hi (3,))`` [m] around the floor, every item and the markers."""
    d = scene_drawing(doc)
    fx, fy = d.floor_size
    cx, cy, _ = d.floor_centre
    pts = [np.array([cx - fx / 2, cy - fy / 2, 0.0]), np.array([cx + fx / 2, cy + fy / 2, 0.0])]
    for item in d.items:
        b = item_box(item)
        if b is None:
            continue
        r = math.hypot(b.half[0], b.half[1])
        c = np.asarray(b.centre)
        ext = np.array([r, r, b.half[2]])
        pts += [c - ext, c + ext]
    for m in d.markers:
        pts.append(np.asarray(m.position) + 2 * MARKER_RADIUS)
    allp = np.array(pts)
    return allp.min(axis=0), allp.max(axis=0)


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])  # fmt: skip


def project(pose: CameraPose, vp: Viewport, pts: np.ndarray) -> np.ndarray:
    """Pixels ``(N, 2)`` of world points ``pts (N, 3)`` seen from ``pose`` in ``vp``."""
    return project_depth(pose, vp, pts)[0]


def project_depth(pose: CameraPose, vp: Viewport, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`project`, and each point's depth along the view ``(N,)`` [m] (> 0: in front)."""
    f = np.asarray(pose.look_at, float) - np.asarray(pose.position, float)
    f /= np.linalg.norm(f)
    r = np.cross(f, pose.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    rel = np.asarray(pts, float).reshape(-1, 3) - np.asarray(pose.position)
    depth = rel @ f
    F = (vp.height / 2) / math.tan(pose.fov / 2)
    safe = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
    px = np.column_stack([vp.width / 2 + F * (rel @ r) / safe,
                          vp.height / 2 - F * (rel @ u) / safe])  # fmt: skip
    return px, depth


def frame(
    direction: np.ndarray, bounds: tuple[np.ndarray, np.ndarray], vp: Viewport,
    fov: float = FOV, margin: float = MARGIN,
) -> CameraPose:  # fmt: skip
    """The camera looking along ``direction`` (3,) that fits ``bounds`` into the free part of
    ``vp`` with ``margin`` [px] to spare, centred there.

    With the orientation fixed, "this corner projects inside the margins" is linear in the
    camera's position ``p``: for a pixel bound ``X`` on x, ``F (c - p).r >= (X - W/2) (c - p).f``
    (likewise on y). So the closest camera that fits is a small linear program (maximise
    ``p.f``), exact for any window: the box then touches the margins along one side; the
    other side's slack is split evenly (the midpoint of the feasible shift at that depth).
    """
    f = np.asarray(direction, float) / np.linalg.norm(direction)
    up = np.array([0.0, 0.0, 1.0])
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    lo, hi = bounds
    pts = _corners(lo, hi)
    F = (vp.height / 2) / math.tan(fov / 2)
    x_lo, x_hi = margin, max(vp.free_right - margin, margin + 10.0)
    y_lo, y_hi = margin, max(vp.height - margin, margin + 10.0)
    # Coordinates of the camera in its own frame: q = (p.r, p.u, p.f); rows A q <= b.
    rows, rhs = [], []
    for c in pts:
        cr, cu, cf = c @ r, c @ u, c @ f
        for ax, bound, sign in ((0, x_lo, -1), (0, x_hi, 1), (1, y_lo, 1), (1, y_hi, -1)):
            # x: W/2 + F (cr - qr)/(cf - qf); y: H/2 - F (cu - qu)/(cf - qf).
            k = (bound - vp.width / 2) if ax == 0 else (vp.height / 2 - bound)
            g = np.zeros(3)  # F (c_ax - q_ax) - k (cf - qf), signed so that g.q <= h
            g[ax], g[2] = -F, k
            h = -(F * (cr if ax == 0 else cu) - k * cf)
            rows.append(sign * g)
            rhs.append(sign * h)
        rows.append(np.array([0.0, 0.0, 1.0]))  # in front of every corner, by a little
        rhs.append(cf - 1e-3)
    A, b = np.array(rows), np.array(rhs)
    q = _lp(np.array([0.0, 0.0, -1.0]), A, b)
    depth_row = np.array([[0.0, 0.0, -1.0]])
    A2 = np.vstack([A, depth_row])
    b2 = np.append(b, -q[2] + 1e-9 * max(1.0, abs(q[2])))
    mid = q.copy()
    for ax in (0, 1):  # centre the slack side: the midpoint of its shift at that depth
        e = np.zeros(3)
        e[ax] = 1.0
        mid[ax] = 0.5 * (_lp(e, A2, b2)[ax] + _lp(-e, A2, b2)[ax])
    pos = mid[0] * r + mid[1] * u + mid[2] * f
    target = (lo + hi) / 2
    look = pos + f * max(float((target - pos) @ f), 1e-3)
    return CameraPose(tuple(map(float, pos)), tuple(map(float, look)), (0.0, 0.0, 1.0), fov)


def _lp(cost: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``argmin cost.q`` subject to ``A q <= b``, ``q`` free (3,)."""
    from scipy.optimize import linprog

    res = linprog(cost, A_ub=A, b_ub=b, bounds=[(None, None)] * 3, method="highs")
    if res.status != 0:  # cannot happen for a finite box: backing off always fits
        raise RuntimeError(f"view framing failed: {res.message}")
    return np.asarray(res.x, float)


def view_direction(azimuth: float, elevation: float) -> np.ndarray:
    """The unit direction a camera looks along, placed at ``azimuth`` [rad] (from +x about
    z) and ``elevation`` [rad] above the floor as seen from what it looks at."""
    c = math.cos(elevation)
    return -np.array([c * math.cos(azimuth), c * math.sin(azimuth), math.sin(elevation)])


def preset(
    name: str, doc: dict[str, Any], vp: Viewport, current: np.ndarray | None = None
) -> CameraPose:
    """Preset ``name`` ("top", "front", "iso", or "fit": the ``current`` viewing direction
    (3,), refitted) framing the scene of ``doc`` in ``vp``."""
    bounds = scene_bounds(doc)
    if name == "fit":
        d = np.asarray(current, float) if current is not None else view_direction(
            *DIRECTIONS["iso"])  # fmt: skip
        return frame(d, bounds, vp)
    if name not in DIRECTIONS:
        raise ValueError(f"no view preset {name!r}; presets: {', '.join(PRESETS)}")
    return frame(view_direction(*DIRECTIONS[name]), bounds, vp,
                 TOP_FOV if name == "top" else FOV)  # fmt: skip
