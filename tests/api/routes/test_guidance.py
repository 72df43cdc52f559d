"""/guidance: zones of a stored or inline scene's tray, as GeoJSON; bad trays and orders 422."""

from __future__ import annotations

from ..conftest import AUTH
from ..factories import paper, problem


def test_guidance_of_a_stored_and_an_inline_scene(client):
    doc = {**paper(), "orders": [{"id": "a", "trays": ["tray_4", "tray_1"]}]}
    sid = client.post("/api/v1/scenes", json=doc, headers=AUTH).json()["id"]
    r = client.get(f"/api/v1/scenes/{sid}/guidance", params={"tray": "tray_4"})
    assert r.status_code == 200, r.text
    g = r.json()
    assert g["type"] == "FeatureCollection" and g["properties"]["here"] == "own"
    assert g["properties"]["groups"] == [["tray_1", "tray_2"]]
    kinds = {(f["properties"]["kind"], tuple(f["properties"]["trays"])) for f in g["features"]}
    assert ("shares", ("tray_1", "tray_2")) in kinds
    inline = client.post(
        "/api/v1/guidance", json={"scene": doc, "tray": "tray_4", "order": "a"}, headers=AUTH
    )
    assert inline.json()["properties"]["groups"] == [["tray_1"]]
    problem(client.get(f"/api/v1/scenes/{sid}/guidance", params={"tray": "nope"}), 422, "tray")
    problem(client.post("/api/v1/guidance", json={"scene": doc, "tray": "tray_2", "order": "a"},
                        headers=AUTH),
            422, "order")  # fmt: skip


def test_guidance_of_an_unknown_database_is_a_documented_409_naming_no_folder(client):
    sid = client.post("/api/v1/scenes", json=paper(), headers=AUTH).json()["id"]
    r = client.get(f"/api/v1/scenes/{sid}/guidance",
                   params={"tray": "tray_4", "database": "nope"})  # fmt: skip
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert "'nope'" in detail and " /" not in detail, detail  # no server path
    spec = client.get("/api/v1/openapi.json").json()["paths"]
    for path, method in (("/api/v1/scenes/{scene_id}/guidance", "get"),
                         ("/api/v1/guidance", "post")):  # fmt: skip
        assert "409" in spec[path][method]["responses"], path
