"""What the view tells on hover: every stop, circle and region of a plan with its words; a
rejected circle names its trays (by name) and its reason."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

from shapely.geometry import Point, Polygon

from pickstop_ui.hover import SIMPLIFY, hover_data
from pickstop_ui.overlay import hover_element, parse_layout

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


def test_every_stop_circle_region_and_item_has_its_words(plans):
    exact, _ = plans
    doc = json.loads(SCENE.read_text())
    doc["trays"][0]["name"] = "bolts M6"
    d = hover_data(exact, doc)
    assert len(d["stops"]) == len(exact.stops) and len(d["circles"]) == len(exact.candidates)
    assert len(d["regions"]) == len(exact.candidates)
    assert len(d["items"]) == len(doc["trays"]) + len(doc["obstacles"])
    for s, h in zip(exact.stops, d["stops"], strict=True):
        assert (h["x"], h["y"]) == (s.x, s.y) and f"yaw {math.degrees(s.yaw):.0f}°" in h["text"]
    for c, h in zip(exact.candidates, d["circles"], strict=True):
        assert h["r"] == c.inscribed_radius
        named = [("bolts M6" if t == "tray_1" else t) for t in c.trays]
        assert all(n in h["text"] for n in named) and ("tray_1" not in h["text"])
        if c.status == "rejected":
            assert h["text"].startswith("Rejected candidate") and c.reason in h["text"]
    tray1 = next(i for i in d["items"] if "bolts M6" in i["text"])
    assert "tray tray_1" in tray1["text"] and tray1["top"] > 0.725


def test_regions_are_simplified_within_a_few_millimetres(plans):
    exact, _ = plans
    d = hover_data(exact, json.loads(SCENE.read_text()))
    for c, h in zip(exact.candidates, d["regions"], strict=True):
        exact_poly = Polygon(c.polygon[0], c.polygon[1:])
        simple = Polygon(h["rings"][0], h["rings"][1:])
        assert exact_poly.hausdorff_distance(simple) <= SIMPLIFY + 1e-3
        asser = exact_poly.representative_point()
        assert simple.buffer(SIMPLIFY + 1e-3).contains(Point(asser.x, asser.y))


def test_without_a_plan_only_items_and_the_element_is_safe_html():
    doc = json.loads(SCENE.read_text())
    bad = copy.deepcopy(doc)
    bad["trays"][0]["name"] = "</script><script>alert(1)</script>"
    d = hover_data(None, bad)
    assert d["stops"] == d["circles"] == d["regions"] == [] and d["items"]
    html = hover_element(d)
    assert html.count("</script>") == 1 and html.endswith("</script>")
    assert parse_layout("1280,800,880") == (1280.0, 800.0, 880.0)
    assert parse_layout("1280,800,2000") == (1280.0, 800.0, 1280.0)
    assert parse_layout("x,1,2") is None and parse_layout("0,800,10") is None


def test_a_stop_placed_for_success_tells_its_circles_centre_and_rates(plans):
    """A placed stop's words name its clearance and, at the circle's centre, the estimate
    and the Monte Carlo there."""
    from pickstop.sequence.plan_model import Success

    exact, _ = plans
    s0 = exact.stops[0]
    placed = s0.model_copy(update={
        "x": s0.x + 0.03, "clearance": s0.inscribed_radius - 0.03, "circle_centre": (s0.x, s0.y),
        "circle_estimated_success": 0.9123,
        "circle_success": Success(samples=100, successes=90, rate=0.9, interval=(0.83, 0.94)),
    })  # fmt: skip
    plan = exact.model_copy(update={"stops": [placed, *exact.stops[1:]]})
    text = hover_data(plan, json.loads(SCENE.read_text()))["stops"][0]["text"]
    assert f"{placed.clearance:.3f} m clear" in text
    assert f"({s0.x:.2f}, {s0.y:.2f})" in text and "estimate 91.2%" in text
    assert "Monte Carlo 90.0%" in text
    plain = hover_data(exact, json.loads(SCENE.read_text()))["stops"][0]["text"]
    assert "circle's centre" not in plain
