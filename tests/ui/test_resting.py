"""What a tray stands on in the planner: the API's placement (the backend's own
``place_tray``, asked here directly) becomes the height a dragged tray follows, a short reason
where it would float or overlap, the panel's support line, and which trays stop the layout
from being planned or saved."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop.scene.supports import place_tray
from pickstop_ui.resting import (
    Standing,
    follow,
    names_of_items,
    short_reason,
    still_placed,
    support_line,
)

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture
def doc():
    d = json.loads(SCENE.read_text())
    d["obstacles"][1]["geometry"]["size"][2] = 0.6  # table B lower than table A
    d["trays"][3]["pose"]["z"] = 0.605  # tray_4 on it
    return d


def _answer(doc, tray, x, y, yaw=0.0, z_hint=None):
    """What ``POST /placements`` answers: the backend's placement as a document."""
    return asdict(place_tray(parse_scene(doc), tray, x, y, yaw, z_hint))


def test_a_tray_moved_to_a_lower_table_follows_its_top(doc):
    names = names_of_items(doc)
    rest = follow(_answer(doc, "tray_1", 3.6, 1.775, z_hint=0.725), 0.725, names)
    assert rest.ok and rest.support == "table_b"
    assert rest.z == pytest.approx(0.605) and rest.top == pytest.approx(0.6)
    assert support_line(rest, names) == "**Support:** table B (top 0.600 m)"
    back = follow(_answer(doc, "tray_1", 0.95, 1.5, z_hint=rest.z), rest.z, names)
    assert back.ok and back.support == "table_a" and back.z == pytest.approx(0.725)


def test_a_tray_that_rests_keeps_its_height_to_the_bit(doc):
    z = doc["trays"][3]["pose"]["z"] = 0.605 + 1e-12  # what an undo puts back
    assert follow(_answer(doc, "tray_4", 3.6, 1.5, z_hint=z), z).z == z


def test_off_the_floor_there_is_nothing_under_it_and_the_height_stays(doc):
    rest = follow(_answer(doc, "tray_4", 3.6, 3.5, z_hint=0.605), 0.605)
    assert not rest.ok and rest.why == "nothing under it" and rest.support is None
    assert rest.z == 0.605
    assert support_line(rest) == "**Support:** none — ⚠ nothing under it"


def test_a_tray_on_another_overlaps_it_and_one_over_an_edge_overhangs(doc):
    names = names_of_items(doc)
    on = follow(_answer(doc, "tray_1", 1.4, 1.5, z_hint=0.725), 0.725, names)
    assert not on.ok and on.why == "overlaps tray_2" and on.support == "table_a"
    edge = follow(_answer(doc, "tray_4", 3.95, 1.5, z_hint=0.605), 0.605, names)
    assert not edge.ok and edge.why.startswith("overhangs table B by 0.")
    assert support_line(edge, names).endswith("— ⚠ " + edge.why)


def test_every_wording_of_the_api_has_its_short_reason():
    names = {"table_b": "table B", "tray_2": "second"}
    said = {
        "tray 't' would stand on nothing at (9.000, 9.000)": "nothing under it",
        "tray 't' would not be inside the floor": "outside the floor",
        "tray 't' would overhang the edge of the floor by 0.100 m (at most 0.02 m)":
            "overhangs the floor by 0.100 m",
        "tray 't' would intersect tray 'tray_2' (by 0.050 m)": "overlaps second",
        "tray 't' would intersect obstacle 'table_b' (by 0.050 m)": "cuts into table B",
        "something new": "something new",
    }  # fmt: skip
    for problem, short in said.items():
        assert short_reason(problem, names) == short
    assert short_reason(None) is None


def test_the_api_is_asked_with_every_tray_where_it_last_stood(doc):
    standing = Standing.start(doc)
    home = dict(doc["trays"][3]["pose"])
    doc["trays"][3]["pose"].update(x=3.6, y=3.5)  # dragged off into the air
    standing = standing.told("tray_4", "nothing under it")
    asked = standing.ask_doc(doc)
    assert asked["trays"][3]["pose"] == home and doc["trays"][3]["pose"]["y"] == 3.5
    parse_scene(asked)  # a scene the API accepts
    assert standing.verdict(names_of_items(doc)) == "tray_4: nothing under it"
    assert standing.unknown(doc) == ["tray_4"]


def test_a_tray_back_where_it_stood_stands_and_a_new_pose_is_asked(doc):
    standing = Standing.start(doc).told("tray_4", "nothing under it")
    assert standing.settle(doc).verdict() is None  # an undo put it back: it stands
    moved = json.loads(json.dumps(doc))
    moved["trays"][0]["pose"]["x"] += 0.1
    moved["trays"] = moved["trays"][:3]  # tray_4 removed
    settled = standing.settle(moved)
    assert settled.unknown(moved) == ["tray_1"] and "tray_4" not in settled.last_good
    good = settled.told("tray_1", None, moved["trays"][0]["pose"])
    assert good.unknown(moved) == [] and good.verdict() is None


def test_after_an_undo_only_the_trays_still_where_they_were_asked_keep_their_rest(doc):
    here = follow(_answer(doc, "tray_4", 3.6, 1.5, z_hint=0.605), 0.605)
    gone = follow(_answer(doc, "tray_1", 3.6, 3.5, z_hint=0.725), 0.725)
    assert still_placed({"tray_4": here, "tray_1": gone, "old": here}, doc) == {"tray_4": here}
