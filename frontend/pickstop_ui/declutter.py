"""Labels that never overlap: which of the 3D view's labels to show from where it is seen.

Viser draws a label at a constant size on screen, anchored at a world point; seen from afar,
labels of neighbouring trays run into each other ("tray_0tray_02tray_04"). Each label's box on
screen is estimated from its text (the viewer's font: 12 px high at an 800 px tall view,
about 0.6 of that per character, a little padding) and its anchor (bottom-centre); labels
are then taken in order of priority and a label whose box meets one already shown is
hidden. A hidden tray's name still shows on hover (:mod:`pickstop_ui.overlay`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EM_PX = 12.0  # the labels' font size on an 800 px tall view [px]
CHAR_EM = 0.62  # average width of a character [em]
PAD_PX = 6.0  # a label's padding, both sides together [px]
GAP_PX = 2.0  # labels closer than this count as touching [px]


@dataclass(frozen=True)
class Label:
    """A label to place: its text, its anchor (3,) [m] and its priority (higher first)."""

    key: str
    text: str
    anchor: tuple[float, float, float]
    priority: float = 0.0


def quat_matrix(wxyz: object) -> np.ndarray:
    """The rotation matrix (3, 3) of a unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = (float(v) for v in np.asarray(wxyz, float).reshape(4))
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def screen_points(
    position: object, wxyz: object, fov: float, size: tuple[float, float], pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``(N, 2)`` (x right, y down) of world points ``pts (N, 3)`` [m] seen by a
    camera at ``position`` turned by ``wxyz`` (OpenCV frame: z forward, y down) with vertical
    field of view ``fov`` [rad] in a view of ``size`` (width, height) [px]; and whether each
    lies in front of it ``(N,)``."""
    rel = np.asarray(pts, float).reshape(-1, 3) - np.asarray(position, float)
    pc = rel @ quat_matrix(wxyz)  # R^T p, row-wise
    w, h = size
    f = (h / 2) / np.tan(fov / 2)
    z = np.where(np.abs(pc[:, 2]) < 1e-9, 1e-9, pc[:, 2])
    px = np.column_stack([w / 2 + f * pc[:, 0] / z, h / 2 + f * pc[:, 1] / z])
    return px, pc[:, 2] > 1e-6


def label_box(px: tuple[float, float], text: str, view_height: float) -> np.ndarray:
    """The screen box ``(x0, y0, x1, y1)`` [px] of a bottom-centre anchored label at pixel
    ``px`` (x right, y down)."""
    em = EM_PX * view_height / 800.0
    w = len(text) * CHAR_EM * em + PAD_PX
    h = em * 1.3 + PAD_PX
    return np.array([px[0] - w / 2, px[1] - h, px[0] + w / 2, px[1]])


def visible(labels: list[Label], pixels: np.ndarray, in_front: np.ndarray,
            view_height: float) -> dict[str, bool]:  # fmt: skip
    """Which labels to show: ``pixels (N, 2)`` are their anchors on screen and ``in_front
    (N,)`` whether each lies before the camera. Greedy by priority, then by order."""
    assert pixels.shape == (len(labels), 2), pixels.shape
    order = sorted(range(len(labels)), key=lambda k: (-labels[k].priority, k))
    shown: list[np.ndarray] = []
    out = {lab.key: False for lab in labels}
    for k in order:
        if not in_front[k]:
            continue
        b = label_box((float(pixels[k, 0]), float(pixels[k, 1])), labels[k].text, view_height)
        if any(b[0] < s[2] + GAP_PX and s[0] < b[2] + GAP_PX and b[1] < s[3] + GAP_PX
               and s[1] < b[3] + GAP_PX for s in shown):  # fmt: skip
            continue
        shown.append(b)
        out[labels[k].key] = True
    return out
