"""A plan's stops as CSV: one row per stop in visiting order, for a spreadsheet or a cell
controller."""

from __future__ import annotations

import csv
import io
import math
from typing import Any

from pickstop.report.drawing import tray_names
from pickstop.sequence.plan_model import Plan, Stop

COLUMNS = (
    "stop", "x_m", "y_m", "yaw_deg", "yaw_rad", "trays", "tray_names", "inscribed_radius_m",
    "success", "success_low", "success_high", "witnesses",
)  # fmt: skip


def stop_row(k: int, s: Stop, names: dict[str, str]) -> dict[str, Any]:
    """Stop ``s`` (the ``k``-th, from 0) as one row of :data:`COLUMNS`: lengths [m] to the
    millimetre's tenth, the yaw in degrees and radians, trays by id and by name."""
    rate = s.success
    return {
        "stop": k + 1,
        "x_m": f"{s.x:.4f}",
        "y_m": f"{s.y:.4f}",
        "yaw_deg": f"{math.degrees(s.yaw):.2f}",
        "yaw_rad": f"{s.yaw:.6f}",
        "trays": ";".join(s.trays),
        "tray_names": ";".join(names.get(t, t) for t in s.trays),
        "inscribed_radius_m": f"{s.inscribed_radius:.4f}",
        "success": "" if rate is None else f"{rate.rate:.4f}",
        "success_low": "" if rate is None else f"{rate.interval[0]:.4f}",
        "success_high": "" if rate is None else f"{rate.interval[1]:.4f}",
        "witnesses": len(s.witnesses),
    }


def stops_csv(plan: Plan, scene: dict[str, Any]) -> str:
    """The header and one row per stop of ``plan`` (``scene``: its document, for names)."""
    names = tray_names(scene)
    out = io.StringIO()
    w = csv.DictWriter(out, fieldnames=COLUMNS, lineterminator="\r\n")
    w.writeheader()
    for k, s in enumerate(plan.stops):
        w.writerow(stop_row(k, s, names))
    return out.getvalue()
