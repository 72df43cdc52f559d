"""Trays stand on something: refused floating, overhanging or inside another solid (named,
with the distance); placed anywhere, a footprint finds the support under it."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.scene.load import load_scene, parse_scene
from pickstop.scene.model import SceneError
from pickstop.scene.supports import (
    SUPPORT_GAP,
    free_spot,
    place_tray,
    support_problems,
    tray_copy,
)
from tests.scene.test_scene_model import write_box_stl

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())
NAMES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]


def _problems(mutate) -> list[tuple[str, str]]:
    doc = copy.deepcopy(PAPER)
    mutate(doc)
    with pytest.raises(SceneError) as e:
        parse_scene(doc)
    return e.value.problems


def _tray4(**pose):
    return lambda d: d["trays"][3]["pose"].update(**pose)


@pytest.mark.parametrize("name", NAMES)
def test_every_example_tray_stands_on_its_support(name):
    scene = load_scene(EXAMPLES / f"{name}.json")
    assert support_problems(scene) == []
    for t in scene.trays:  # each one where it is: free, on what it stands on, at its height
        p = place_tray(scene, t.id, t.pose.x, t.pose.y, t.pose.yaw, t.pose.z)
        assert p.free and p.support is not None, p
        assert p.z == pytest.approx(t.pose.z, abs=SUPPORT_GAP)


def test_a_tray_in_mid_air_beside_its_table_is_refused_with_its_height():
    assert _problems(_tray4(y=1.1)) == [
        ("trays.3.pose", "tray 'tray_4' stands on nothing: its bottom is 0.720 m above the "
         "floor (at most 0.02 m)"),
    ]  # fmt: skip
    p = _problems(_tray4(z=0.8))
    assert p == [("trays.3.pose", "tray 'tray_4' stands on nothing: its bottom is 0.075 m "
                  "above the top of obstacle 'table_b' (at most 0.02 m)")]  # fmt: skip


def test_a_tray_hanging_over_the_edge_is_refused_with_how_far():
    (field, msg), *_ = _problems(_tray4(x=3.9))
    assert field == "trays.3.pose"
    assert "tray 'tray_4' overhangs the edge of the top of obstacle 'table_b' by 0.060 m" in msg
    doc = copy.deepcopy(PAPER)
    doc["trays"][3]["pose"]["x"] = 3.6 + 0.24 + 0.015  # 1.5 cm past the edge
    parse_scene(doc)


def test_overlapping_trays_and_a_tray_in_a_table_are_refused_naming_both_and_the_depth():
    p = _problems(lambda d: d["trays"][1]["pose"].update(x=1.2))
    assert ("trays.1", "tray 'tray_2' intersects tray 'tray_1' (by 0.055 m)") in p
    p = _problems(lambda d: d["trays"][0]["pose"].update(z=0.7))
    assert ("trays.0", "tray 'tray_1' intersects obstacle 'table_a' (by 0.025 m)") in p


def test_the_floor_and_two_tables_side_by_side_carry_a_tray():
    doc = copy.deepcopy(PAPER)
    doc["trays"][3]["pose"].update(x=3.6, y=0.5, z=0.005)  # on the floor
    assert parse_scene(doc).tray("tray_4").pose.z == 0.005
    doc = copy.deepcopy(PAPER)
    # table_b moved against table_a: a tray across their joint stands on both
    doc["obstacles"][1]["pose"]["x"] = 2.2 + 0.4
    doc["trays"][3]["pose"]["x"] = 2.25
    parse_scene(doc)


def test_a_mesh_obstacle_carries_a_tray_within_its_bounds(tmp_path):
    write_box_stl(tmp_path / "crate.stl", 0.5, 0.4, 0.4)
    doc = copy.deepcopy(PAPER)
    doc["obstacles"].append({"id": "crate", "geometry": {"shape": "mesh", "path": "crate.stl"},
                             "pose": {"x": 3.0, "y": 0.0}})  # fmt: skip
    doc["trays"][3]["pose"].update(x=3.0, y=0.0, z=0.405)
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    load_scene(tmp_path / "scene.json")
    doc["trays"][3]["pose"]["z"] = 0.5
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    with pytest.raises(SceneError, match="above the top of obstacle 'crate'"):
        load_scene(tmp_path / "scene.json")


def test_a_dragged_tray_follows_the_support_under_it():
    scene = parse_scene(PAPER)
    on_b = place_tray(scene, "tray_4", 3.7, 1.55, 0.3, 0.725)
    assert (on_b.support, on_b.z, on_b.free) == ("table_b", pytest.approx(0.725), True)
    past = place_tray(scene, "tray_4", 3.9, 1.5, 0.0, 0.725)  # over the edge: drawn invalid
    assert past.support == "table_b" and not past.free and "by 0.060 m" in past.problem
    floor = place_tray(scene, "tray_4", 2.8, 0.4, 0.0, 0.725)  # off the tables: to the floor
    assert (floor.support, floor.z, floor.free) == ("floor", pytest.approx(0.005), True)
    into = place_tray(scene, "tray_4", 1.85, 1.5, 0.0, 0.725)  # onto tray_3
    assert into.support == "table_a" and not into.free
    assert "would intersect tray 'tray_3' (by 0.055 m)" in into.problem


def test_on_a_rack_the_shelf_nearest_the_trays_height_is_kept():
    scene = load_scene(EXAMPLES / "rack_cell.json")
    low = place_tray(scene, "lower_tray", 0.9, 2.38, 0.0, 0.255)
    assert (low.support, low.free) == ("lower_shelf", True)
    assert low.z == pytest.approx(0.255)
    high = place_tray(scene, "lower_tray", 0.9, 2.38, 0.0, 0.9)
    assert (high.support, high.free) == ("upper_shelf", True)
    assert high.z == pytest.approx(0.905)
    # where a shelf is taken, the free one
    taken = place_tray(scene, "lower_tray", 0.35, 2.15, 0.0, 0.905)
    assert (taken.support, taken.free) == ("lower_shelf", True)


@pytest.mark.parametrize(("name", "tray_id"), [("paper_experiment", "tray_1"),
                                               ("rack_cell", "upper_tray")])  # fmt: skip
def test_a_copy_goes_to_a_free_spot_of_the_same_support(name, tray_id):
    scene = load_scene(EXAMPLES / f"{name}.json")
    copy_ = tray_copy(scene, tray_id)
    assert copy_ is not None and copy_.id == f"{tray_id}_2"
    original = scene.tray(tray_id)
    assert copy_.pose.z == pytest.approx(original.pose.z)
    doc = json.loads(scene.model_dump_json())
    doc["trays"].append(json.loads(copy_.model_dump_json()))
    again = parse_scene(doc)  # valid: free, standing, unique part ids
    here = place_tray(again, copy_.id, copy_.pose.x, copy_.pose.y, copy_.pose.yaw, copy_.pose.z)
    there = place_tray(scene, original.id, original.pose.x, original.pose.y, 0.0, original.pose.z)
    assert here.support == there.support


def test_a_full_support_has_no_free_spot():
    scene = load_scene(EXAMPLES / "factory_cell.json")
    big = scene.tray("tray_07")  # turned: 0.42 m deep, and table_2 is full along its length
    assert free_spot(scene, big.model_copy(update={"id": "copy"})) is None


@pytest.mark.parametrize(("name", "tray_id"), [("paper_experiment", "tray_4"),
                                               ("factory_cell", "tray_07"),
                                               ("rack_cell", "lower_tray"),
                                               ("rack_cell", "floor_bin")])  # fmt: skip
def test_a_stand_area_holds_exactly_the_places_a_tray_stands_free(name, tray_id):
    """Random centres near each stand area: inside it where (and only where) place_tray puts
    the tray free on that support at that height."""
    import numpy as np
    import shapely

    from pickstop.scene.supports import stand_areas

    scene = load_scene(EXAMPLES / f"{name}.json")
    tray = scene.tray(tray_id)
    rng = np.random.default_rng(7)
    areas = stand_areas(scene, tray)
    assert areas
    for a in areas:
        x0, y0, x1, y1 = a.area.buffer(0.05).bounds
        for x, y in rng.uniform((x0, y0), (x1, y1), (150, 2)):
            if a.area.boundary.distance(shapely.Point(x, y)) < 1e-6:
                continue
            p = place_tray(scene, tray_id, x, y, tray.pose.yaw, a.z)
            stands = p.free and p.support == a.support and p.z == pytest.approx(a.z)
            assert a.area.contains(shapely.Point(x, y)) == stands, (a.support, x, y, p)
