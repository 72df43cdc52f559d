"""One tray's region from scratch (regions/pipeline.py): empty regions explain why."""

from __future__ import annotations

from pickstop.scene.load import parse_scene

from .conftest import add_high_shelf_tray


def test_tray_out_of_reach_has_empty_region_with_reason(planner, paper_doc):
    # A tray on a high shelf: the base can stand in front, the arm cannot reach it.
    tray_id = add_high_shelf_tray(paper_doc)
    region = planner.tray_region(parse_scene(paper_doc), tray_id)
    assert len(region.cells) == 0 and region.polygon.is_empty
    assert "part 'hp'" in region.reason and "tray 'high'" in region.reason


def test_tray_beyond_the_grid_explains(planner, paper_doc):
    paper_doc["base_grid"] = {
        "resolution": 0.05,
        "extent": {"min": [-1.0, -1.0], "max": [0.0, 0.0]},
    }
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_4")
    assert len(region.cells) == 0 and "farther than the arm reaches" in region.reason
