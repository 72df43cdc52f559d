"""/robots: confinement at every open (symlinks included), answers that reveal no server."""

from __future__ import annotations

import shutil

import pytest

from tests.utils import TIAGO_URDF

from ..conftest import AUTH
from ..factories import paper, problem, titled_problem

ARM = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]


def _config(name: str, urdf: str) -> dict:
    return {"name": name, "urdf": urdf, "arm_joints": ARM, "tool_frame": "hand_grasping_frame",
            "footprint": {"radius": 0.275}}  # fmt: skip


def test_a_urdf_swapped_for_a_symlink_outside_is_refused_at_open(client, api_settings, tmp_path):
    robots = api_settings.data_dir / "robots"
    shutil.copy(TIAGO_URDF, robots / "swapbot.urdf")
    r = client.post("/api/v1/robots", json=_config("swapbot", "swapbot.urdf"), headers=AUTH)
    assert r.status_code == 201, r.text
    outside = tmp_path / "outside.urdf"
    shutil.copy(TIAGO_URDF, outside)
    (robots / "swapbot.urdf").unlink()
    (robots / "swapbot.urdf").symlink_to(outside)
    body = problem(client.post("/api/v1/databases", json={"robot": "swapbot", "samples": 1000},
                               headers=AUTH), 422, "robot")  # fmt: skip
    assert "outside the allowed folders" in body["detail"]
    doc = paper()
    doc["robot"] = {"preset": "swapbot"}
    body = problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422, "robot.preset")
    assert "outside the allowed folders" in body["detail"]
    assert str(tmp_path) not in body["detail"] and str(api_settings.data_dir) not in body["detail"]


def test_outside_answers_the_same_whether_or_not_the_file_exists(client):
    details = []
    for urdf in ("/etc/passwd", "/etc/no_such_file_here"):
        body = problem(client.post("/api/v1/robots", json=_config("probe", urdf), headers=AUTH),
                       422, "urdf")  # fmt: skip
        details.append(body["detail"].replace(urdf, "<urdf>"))
    assert details[0] == details[1]
    body = problem(client.post("/api/v1/robots", json=_config("probe", "missing.urdf"),
                               headers=AUTH), 422, "urdf")  # fmt: skip
    assert body["detail"].replace("missing.urdf", "<urdf>") == details[0]


def test_problem_details_name_no_server_folder(client, api_settings):
    bad = _config("probe2", "package://example-robot-data/robots/nothing.urdf")
    body = problem(client.post("/api/v1/robots", json=bad, headers=AUTH), 422)
    assert "/" + str(api_settings.data_dir).strip("/") not in body["detail"]
    assert "site-packages" not in body["detail"]


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"urdf": "/etc/passwd"}, "urdf"),
        ({"urdf": "../../../etc/robot.urdf"}, "urdf"),
        ({"urdf": "robot.urdf", "package_dirs": ["../../.."]}, "package_dirs.0"),
    ],
)
def test_robot_paths_are_confined(client, config, field):
    base = {"name": "evil", "arm_joints": ["j1"], "tool_frame": "tool",
            "footprint": {"radius": 0.3}}  # fmt: skip
    body = titled_problem(client.post("/api/v1/robots", json={**base, **config}, headers=AUTH), 422)
    assert "outside the allowed folders" in body["detail"] and body["field"] == field
    assert "evil" not in [r["name"] for r in client.get("/api/v1/robots").json()]


def test_register_a_robot_from_the_bundled_data(client):
    pr2 = {"name": "tiago_copy", "urdf": "package://example-robot-data/robots/tiago_description/"
           "robots/tiago.urdf", "arm_joints": ["torso_lift_joint", "arm_1_joint", "arm_2_joint",
           "arm_3_joint", "arm_4_joint", "arm_5_joint", "arm_6_joint", "arm_7_joint"],
           "tool_frame": "hand_grasping_frame", "footprint": {"radius": 0.275}}  # fmt: skip
    r = client.post("/api/v1/robots", json=pr2, headers=AUTH)
    assert r.status_code == 201, r.text
    assert r.json()["dof"] == 8
    names = [x["name"] for x in client.get("/api/v1/robots").json()]
    assert "tiago" in names and "tiago_copy" in names
    titled_problem(client.post("/api/v1/robots", json=pr2, headers=AUTH), 409)  # exists already


YAML_CONFIG = """\
# a robot config as people write them
name: tiago_yaml
urdf: package://example-robot-data/robots/tiago_description/robots/tiago.urdf
arm_joints: [torso_lift_joint, arm_1_joint, arm_2_joint, arm_3_joint, arm_4_joint,
             arm_5_joint, arm_6_joint, arm_7_joint]
tool_frame: hand_grasping_frame
footprint: {radius: 0.275}
"""


def test_register_a_robot_as_yaml(client):
    headers = {**AUTH, "Content-Type": "application/yaml"}
    r = client.post("/api/v1/robots", content=YAML_CONFIG, headers=headers)
    assert r.status_code == 201, r.text
    assert r.json()["name"] == "tiago_yaml" and r.json()["dof"] == 8
    # A wrong frame names the field and lists the frames that exist.
    bad = YAML_CONFIG.replace("tiago_yaml", "tiago_bad").replace(
        "hand_grasping_frame", "gripper_tcp"
    )
    body = titled_problem(client.post("/api/v1/robots", content=bad, headers=headers), 422)
    assert body["field"] == "tool_frame" and "arm_tool_link" in body["detail"]
    # Broken YAML says where; aliases (a few bytes standing for gigabytes) are refused.
    broken = titled_problem(
        client.post("/api/v1/robots", content="name: [unclosed", headers=headers), 422
    )
    assert broken["field"] == "body" and "line" in broken["detail"]
    bomb = "a: &a [x, x]\nb: &b [*a, *a]\nc: [*b, *b]\n"
    aliased = titled_problem(client.post("/api/v1/robots", content=bomb, headers=headers), 422)
    assert "aliases" in aliased["detail"]
    other = client.post(
        "/api/v1/robots", content="x", headers={**AUTH, "Content-Type": "text/plain"}
    )
    assert other.status_code == 415 and "application/yaml" in other.json()["detail"]


BASE_STL = "package://example-robot-data/robots/tiago_description/meshes/pmb2/base/base.stl"
BASE_COLLISION = BASE_STL.replace("base.stl", "base_collision.stl")


def _urdf_with(api_settings, name: str, old: str, new: str) -> str:
    """A copy of TIAGo's URDF in the data folder's robots/ with the mesh ``old`` now ``new``."""
    text = TIAGO_URDF.read_text()
    assert old in text
    (api_settings.data_dir / "robots" / name).write_text(text.replace(old, new, 1))
    return name


def test_a_urdf_mesh_outside_answers_the_same_whether_or_not_it_exists(client, api_settings):
    details = []
    for i, mesh in enumerate(("/etc/passwd", "/etc/no_such_file_here")):
        urdf = _urdf_with(api_settings, f"leak{i}.urdf", BASE_COLLISION, mesh)
        r = client.post("/api/v1/robots", json=_config(f"leak{i}", urdf), headers=AUTH)
        body = problem(r, 422, "urdf")
        details.append(body["detail"].replace(mesh, "<mesh>").replace(urdf, "<urdf>"))
    assert details[0] == details[1]
    assert "outside the allowed folders or is not a file" in details[0]


def test_a_visual_mesh_outside_the_allowed_folders_is_refused(client, api_settings):
    urdf = _urdf_with(api_settings, "visual.urdf", BASE_STL + '"', '/etc/passwd"')
    body = problem(client.post("/api/v1/robots", json=_config("visual", urdf), headers=AUTH),
                   422, "urdf")  # fmt: skip
    assert "outside the allowed folders" in body["detail"]
    assert "visual" not in [r["name"] for r in client.get("/api/v1/robots").json()]


@pytest.mark.parametrize("urdf", ["robot\0.urdf", "x" * 5000 + ".urdf", "a/" * 600 + "r.urdf"])
def test_a_urdf_path_no_file_system_takes_is_refused(client, urdf):
    titled_problem(client.post("/api/v1/robots", json=_config("odd", urdf), headers=AUTH), 422)


def test_a_path_component_too_long_for_the_file_system_is_refused(client):
    body = problem(client.post("/api/v1/robots", json=_config("long", "y" * 1000 + ".urdf"),
                               headers=AUTH), 422, "urdf")  # fmt: skip
    assert "outside the allowed folders or is not a file" in body["detail"]


@pytest.mark.parametrize(
    ("line", "field"),
    [
        ("name: !!binary dGlhZ28=", "body"),
        ("name: !!set {tiago: null}", "body"),
        ("? !!binary dGlhZ28=\n: 1\nname: tiago_k", "body"),
        ("name: " + "9" * 5000, "body"),
        ("name: 2024-13-45", None),  # an invalid date: a name like any other
    ],
)
def test_yaml_beyond_json_never_fails_the_server(client, line, field):
    text = YAML_CONFIG.replace("name: tiago_yaml", line)
    headers = {**AUTH, "Content-Type": "application/yaml"}
    r = client.post("/api/v1/robots", content=text, headers=headers)
    if field is None:
        assert r.status_code == 201, r.text
    else:
        problem(r, 422, field)


def test_a_yaml_date_is_the_string_it_reads_as(client):
    headers = {**AUTH, "Content-Type": "application/yaml"}
    text = YAML_CONFIG.replace("name: tiago_yaml", "name: 2024-01-01")
    r = client.post("/api/v1/robots", content=text, headers=headers)
    assert r.status_code == 201, r.text
    assert r.json()["name"] == "2024-01-01"


def test_a_yaml_body_over_its_limit_is_413(client, api_settings):
    headers = {**AUTH, "Content-Type": "application/yaml"}
    big = YAML_CONFIG + "#" * api_settings.max_yaml_bytes
    problem(client.post("/api/v1/robots", content=big, headers=headers), 413, "body")


def test_a_robot_file_is_documented_as_the_bytes_it_is(client):
    spec = client.get("/api/v1/openapi.json").json()["paths"]
    ok = spec["/api/v1/robots/{name}/files/{file_id}"]["get"]["responses"]["200"]
    assert list(ok["content"]) == ["application/octet-stream"]
