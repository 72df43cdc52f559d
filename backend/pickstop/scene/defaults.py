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
