"""The stops as CSV: one row per stop, the plan's numbers, trays by id and by name."""

from __future__ import annotations

import copy
import csv
import io
import math

from pickstop.report.stops_csv import COLUMNS, stops_csv


def test_one_row_per_stop_with_the_plans_numbers(paper_plan, paper_scene):
    scene = copy.deepcopy(paper_scene)
    scene["trays"][0]["name"] = "bolts, M6"  # a comma: quoted, not split
    rows = list(csv.DictReader(io.StringIO(stops_csv(paper_plan, scene))))
    assert len(rows) == len(paper_plan.stops) >= 2
    assert tuple(rows[0]) == COLUMNS
    for k, (row, s) in enumerate(zip(rows, paper_plan.stops, strict=True)):
        assert int(row["stop"]) == k + 1
        assert math.isclose(float(row["x_m"]), s.x, abs_tol=5e-5)
        assert math.isclose(float(row["y_m"]), s.y, abs_tol=5e-5)
        assert math.isclose(float(row["yaw_rad"]), s.yaw, abs_tol=5e-7)
        assert math.isclose(float(row["yaw_deg"]), math.degrees(s.yaw), abs_tol=5e-3)
        assert row["trays"].split(";") == s.trays
        assert math.isclose(float(row["inscribed_radius_m"]), s.inscribed_radius, abs_tol=5e-5)
        assert math.isclose(float(row["success"]), s.success.rate, abs_tol=5e-5)
        assert float(row["success_low"]) <= float(row["success"]) <= float(row["success_high"])
        assert int(row["witnesses"]) == len(s.witnesses)
    named = [r for r in rows if "tray_1" in r["trays"].split(";")]
    assert named and all("bolts, M6" in r["tray_names"] for r in named)
