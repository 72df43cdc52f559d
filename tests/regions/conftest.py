from __future__ import annotations

from pathlib import Path

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def add_high_shelf_tray(doc: dict) -> str:
    """Put tray 'high' (one part, 'hp') on top of a 2 m shelf: the cells in front of the shelf
    are free, but the arm cannot reach its top. Returns the tray's id."""
    doc["obstacles"].append(
        {
            "id": "shelf",
            "geometry": {"shape": "box", "size": [0.6, 0.4, 2.0]},
            "pose": {"x": 3.6, "y": 2.6, "z": 0.0, "yaw": 0.0},
        }
    )
    doc["trays"].append(
        {
            "id": "high",
            "pose": {"x": 3.6, "y": 2.6, "z": 2.005, "yaw": 0.0},
            "inner_size": [0.3, 0.2],
            "parts": [{"id": "hp", "geometry": {"shape": "box", "size": [0.04, 0.04, 0.03]}}],
        }
    )
    return "high"
