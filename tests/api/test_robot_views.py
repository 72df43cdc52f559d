"""A robot's check report and drawing through the API."""

from __future__ import annotations

import re


def test_robot_model_serves_its_urdf_and_meshes(client):
    r = client.get("/api/v1/robots/tiago/model")
    assert r.status_code == 200
    model = r.json()
    assert model["arm_joints"][0] == "torso_lift_joint"
    assert model["joint_values"]["head_2_joint"] == -0.6  # locked, for drawing
    assert "hand_thumb_joint" in model["hand_joints"]
    # The arm's travel posture, every arm joint, collision-free by the exact check.
    assert list(model["travel"]) == model["arm_joints"]
    assert model["travel"]["arm_4_joint"] == 1.94 and model["travel_collisions"] == []
    refs = set(re.findall(r'filename="files/([^"]+)"', model["urdf"]))
    assert refs == set(model["files"]) and len(refs) > 10
    assert "/" not in "".join(refs) and "site-packages" not in model["urdf"]
    fid = sorted(refs)[0]
    f = client.get(f"/api/v1/robots/tiago/files/{fid}")
    assert f.status_code == 200 and len(f.content) > 1000
    assert client.get("/api/v1/robots/tiago/files/..%2F..%2Fetc%2Fpasswd").status_code == 404
    assert client.get("/api/v1/robots/tiago/files/0123456789abcdef0123.stl").status_code == 404


def test_robot_check_over_the_api(client):
    r = client.get("/api/v1/robots/tiago/check")
    assert r.status_code == 200
    report = r.json()
    assert report["tool"]["frame"] == "hand_grasping_frame"
    assert 0 <= report["screen"]["false_rejection"] <= 0.05
    assert report["self_collision"]["source"] == "computed"
    assert "/" not in report["urdf"]
    unknown = client.get("/api/v1/robots/nobody/check")
    assert unknown.status_code == 404 and "no robot" in unknown.json()["detail"]
