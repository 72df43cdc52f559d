"""/placements: the support under a dragged tray, a copy on a free spot; a floating tray in a
scene is refused naming it and the distance."""

from __future__ import annotations

import pytest

from ..conftest import AUTH
from ..factories import paper, problem


def test_a_tray_in_mid_air_is_refused_naming_it_and_the_distance(client):
    doc = paper()
    doc["trays"][3]["pose"]["y"] = 1.1  # beside its table
    body = problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422, "trays.3.pose")
    assert (
        "tray 'tray_4' stands on nothing: its bottom is 0.720 m above the floor" in body["detail"]
    )
    plan = {"scene": doc, "store": False, "mode": "preview"}
    problem(client.post("/api/v1/plans", json=plan, headers=AUTH), 422, "scene.trays.3.pose")


def test_a_dragged_tray_follows_the_support_under_it(client):
    ask = {"scene": paper(), "tray": "tray_4", "y": 1.5, "z_hint": 0.725}
    on = client.post("/api/v1/placements", json={**ask, "x": 3.7}, headers=AUTH).json()
    assert on == {"tray": "tray_4", "x": 3.7, "y": 1.5, "yaw": 0.0, "z": pytest.approx(0.725),
                  "support": "table_b", "free": True, "problem": None,
                  "top": pytest.approx(0.72)}  # fmt: skip
    off = client.post("/api/v1/placements", json={**ask, "x": 3.95}, headers=AUTH).json()
    assert off["support"] == "table_b" and not off["free"] and "overhang" in off["problem"]
    problem(
        client.post("/api/v1/placements", json={**ask, "x": 3.7, "tray": "nope"}, headers=AUTH),
        422,
        "tray",
    )
    problem(client.post("/api/v1/placements", json={**ask, "x": "far"}, headers=AUTH), 422, "x")


def test_a_copy_lands_on_a_free_spot_of_its_table(client):
    doc = paper()
    got = client.post(
        "/api/v1/placements/copy", json={"scene": doc, "tray": "tray_1"}, headers=AUTH
    ).json()
    copy = got["tray"]
    assert copy["id"] == "tray_1_2" and copy["pose"]["z"] == pytest.approx(0.725)
    doc["trays"].append(copy)
    assert client.post("/api/v1/scenes", json=doc, headers=AUTH).status_code == 201


def test_asking_where_a_tray_would_stand_needs_a_key(client):
    ask = {"scene": paper(), "tray": "tray_4", "x": 3.7, "y": 1.5}
    assert client.post("/api/v1/placements", json=ask).status_code == 401
