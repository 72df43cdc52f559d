"""Values the scene format takes when a document leaves a field out.

Written once: the scene model (:mod:`pickstop.scene.model`) declares its fields with them and
the planner UI reads a document's plain JSON with them, so the two never disagree. Pure
constants: the UI imports this module without pydantic, coal or pinocchio.
"""

from __future__ import annotations

SIGMA = 0.10  # base positioning error [m]
GRID_RESOLUTION = 0.025  # base grid cell edge [m]

TRAY_WALL_HEIGHT = 0.06  # above the inner floor [m]
TRAY_WALL_THICKNESS = 0.01  # [m]
TRAY_FLOOR_THICKNESS = 0.005  # below the inner floor [m]

#: A tray without a ``color`` ("#rrggbb") takes the ``k``-th of these (k: its index in the
#: scene, cycling), RGB 0-255: the planner and the plan report draw it alike.
TRAY_PALETTE: tuple[tuple[int, int, int], ...] = (
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (210, 245, 60),
    (0, 128, 128),
    (170, 110, 40),
    (128, 0, 0),
    (0, 0, 128),
)
