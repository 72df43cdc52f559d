"""The planner's scene edits as pure functions of the document."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop_ui import edits

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture
def doc():
    return json.loads(SCENE.read_text())


def test_a_dragged_tray_moves_in_whole_base_cells(doc):
    x0, y0 = doc["trays"][0]["pose"]["x"], doc["trays"][0]["pose"]["y"]
    pose = edits.move(doc, "trays", doc["trays"][0]["id"], x0 + 0.061, y0 - 0.013, 0.2)
    assert pose is not None
    assert pose["x"] == pytest.approx(x0 + 0.05) and pose["y"] == pytest.approx(y0 - 0.025)
    assert pose["yaw"] == 0.2 and doc["trays"][0]["pose"]["x"] == pose["x"]
    assert edits.move(doc, "trays", "nope", 0, 0, 0) is None
    ob = doc["obstacles"][0]["id"] if doc.get("obstacles") else None
    if ob is not None:  # obstacles move freely
        assert edits.move(doc, "obstacles", ob, 1.2345, 0.5, 0.0)["x"] == 1.2345


def test_the_task_keeps_the_trays_order_and_all_means_no_list(doc):
    ids = [t["id"] for t in doc["trays"]]
    doc.pop("task", None)
    assert edits.task_of(doc) == ids
    edits.set_needed(doc, ids[0], False)
    assert doc["task"] == ids[1:]
    edits.set_needed(doc, ids[0], True)
    assert doc["task"] == ids  # back in its place, not appended
    for t in ids:
        edits.set_needed(doc, t, False)
    assert doc["task"] == [] and edits.task_of(doc) == []
    edits.set_needed(doc, ids[2], True)
    assert doc["task"] == [ids[2]]
    with pytest.raises(edits.EditError, match="no tray 'nope'"):
        edits.set_needed(doc, "nope", True)


def test_a_copied_tray_is_a_valid_tray_beside_its_original(doc):
    tid = doc["trays"][0]["id"]
    doc["task"] = [tid]
    new = edits.copy_tray(doc, tid, "bolts")
    assert new == f"{tid}_2" and doc["task"] == [tid, new]
    a, b = edits.tray(doc, tid), edits.tray(doc, new)
    assert b["name"] == "bolts 2" and len(b["parts"]) == len(a["parts"])
    assert [p["geometry"] for p in b["parts"]] == [p["geometry"] for p in a["parts"]]
    assert b["parts"][0]["id"] != a["parts"][0]["id"]
    assert edits._footprint(b).distance(edits._footprint(a)) >= edits.COPY_GAP - 1e-9
    assert edits.copy_tray(doc, tid) == f"{tid}_3"
    assert edits.tray(doc, f"{tid}_3")["name"] == f"{tid} 3"


def test_a_copy_placed_by_the_supports_stands_on_the_same_table(doc):
    """The planner's copy takes the pose the API's free-spot search gives (the core's
    :func:`~pickstop.scene.supports.tray_copy` here): the edited scene stays valid."""
    from pickstop.scene.supports import tray_copy

    tid = doc["trays"][0]["id"]
    placed = tray_copy(parse_scene(doc), tid)
    assert placed is not None
    new = edits.copy_tray(doc, tid, "bolts", json.loads(placed.model_dump_json()))
    assert edits.tray(doc, new)["pose"] == json.loads(placed.model_dump_json())["pose"]
    parse_scene(doc)  # the edited document is still a valid scene


def test_remove_and_rename(doc):
    ids = [t["id"] for t in doc["trays"]]
    doc["task"] = list(ids)
    edits.rename_tray(doc, ids[1], "screws")
    assert edits.tray(doc, ids[1])["name"] == "screws"
    edits.remove_tray(doc, ids[0])
    assert [t["id"] for t in doc["trays"]] == ids[1:] and doc["task"] == ids[1:]
    for t in ids[1:-1]:
        edits.remove_tray(doc, t)
    before = copy.deepcopy(doc)
    with pytest.raises(edits.EditError, match="at least one tray"):
        edits.remove_tray(doc, ids[-1])
    assert doc == before  # a refused edit changes nothing
    parse_scene(doc)


def test_a_drag_is_named_by_what_changed_and_by_the_trays_name(doc):
    before = copy.deepcopy(doc)
    edits.rename_tray(doc, "tray_4", "brackets B-12")
    edits.move(doc, "trays", "tray_4", 3.7, 1.5, 0.0)
    assert edits.move_label(before, doc, "trays", "tray_4") == "move brackets B-12"
    turned = copy.deepcopy(doc)
    edits.move(turned, "trays", "tray_4", 3.7, 1.5, 0.5)
    assert edits.move_label(doc, turned, "trays", "tray_4") == "turn brackets B-12"
    edits.move(turned, "obstacles", "table_b", 3.0, 1.0, 0.1)
    assert edits.move_label(doc, turned, "obstacles", "table_b") == "move and turn table_b"
    assert edits.pose_of(doc, "trays", "nope") is None


def test_the_snap_steps_set_in_the_panel_hold_for_trays_and_obstacles(doc):
    import math

    x0 = doc["trays"][0]["pose"]["x"]
    pose = edits.move(doc, "trays", "tray_1", x0 + 0.26, 1.5, math.radians(47), step=0.1,
                      yaw_step=math.radians(15))  # fmt: skip
    assert pose["x"] == pytest.approx(x0 + 0.3) and pose["yaw"] == pytest.approx(math.radians(45))
    pose = edits.move(doc, "obstacles", "table_b", 3.63, 1.6, 0.0, step=0.05)
    assert pose["x"] == pytest.approx(3.65)
    pose = edits.move(doc, "trays", "tray_2", 1.3512, 1.5, 0.1, step=0.0)
    assert pose["x"] == 1.3512 and pose["yaw"] == 0.1  # 0: free


def test_typed_numbers_are_taken_exactly_and_nonsense_is_refused(doc):
    pose = edits.place(doc, "trays", "tray_4", 3.5, 1.5, 0.25, 0.74)
    assert (pose["x"], pose["y"], pose["yaw"], pose["z"]) == (3.5, 1.5, 0.25, 0.74)
    before = copy.deepcopy(doc)
    with pytest.raises(edits.EditError, match="x must be a finite number"):
        edits.place(doc, "trays", "tray_4", float("nan"), 1.0, 0.0, 0.7)
    with pytest.raises(edits.EditError, match="no tray 'nope'"):
        edits.place(doc, "trays", "nope", 1.0, 1.0, 0.0, 0.7)
    assert doc == before
    parse_scene(doc)
