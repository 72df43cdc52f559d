"""The scene format: examples valid, each problem reported with its field, round trip."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.scene.model import SceneError, load_scene, parse_scene, scene_json_schema

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())


@pytest.mark.parametrize("name", ["paper_experiment", "five_trays", "factory_cell"])
def test_examples_are_valid(name):
    scene = load_scene(EXAMPLES / f"{name}.json")
    assert scene.trays and scene.name


def test_factory_cell_is_large():
    scene = load_scene(EXAMPLES / "factory_cell.json")
    assert len(scene.trays) >= 10 and len(scene.obstacles) >= 5


def test_round_trip():
    scene = parse_scene(PAPER)
    again = parse_scene(json.loads(scene.model_dump_json()))
    assert again == scene


def test_schema_is_published_and_describes_trays():
    schema = scene_json_schema()
    assert schema["title"] == "PickStop scene"
    assert "trays" in schema["properties"]
    shipped = json.loads((Path(__file__).parents[2] / "docs" / "scene.schema.json").read_text())
    assert shipped == schema, "docs/scene.schema.json is stale: run scripts/write_schema.py"


def _problems(mutate) -> list[tuple[str, str]]:
    doc = copy.deepcopy(PAPER)
    mutate(doc)
    with pytest.raises(SceneError) as e:
        parse_scene(doc)
    return e.value.problems


def _has(problems, field, text):
    assert any(f == field and text in m for f, m in problems), problems


def test_part_outside_its_tray():
    p = _problems(lambda d: d["trays"][0]["parts"][0]["pose"].update(x=0.4))
    _has(p, "trays.0.parts.0.pose", "part 'p1a' is outside tray 'tray_1'")


def test_tray_intersecting_obstacle():
    p = _problems(lambda d: d["trays"][0]["pose"].update(z=0.5))
    _has(p, "trays.0", "tray 'tray_1' intersects obstacle 'table_a'")


def test_nan_size():
    p = _problems(lambda d: d["obstacles"][0]["geometry"].update(size=[1.0, float("nan"), 0.7]))
    assert any(f.startswith("obstacles.0.geometry.box.size") for f, _ in p), p


def test_negative_size():
    p = _problems(lambda d: d["trays"][0].update(inner_size=[0.3, -0.2]))
    _has(p, "trays.0.inner_size.1", "greater than 0")


def test_duplicate_ids():
    p = _problems(lambda d: d["trays"][1].update(id="tray_1"))
    _has(p, "trays", "duplicate tray id 'tray_1'")


def test_unknown_task_tray():
    p = _problems(lambda d: d["task"].append("tray_9"))
    _has(p, "task.3", "unknown tray 'tray_9'")


def test_overlapping_parts():
    p = _problems(lambda d: d["trays"][0]["parts"][1]["pose"].update(x=-0.05, y=0.0))
    _has(p, "trays.0.parts.1", "overlaps part 'p1a'")


def test_start_off_the_floor():
    p = _problems(lambda d: d["start"].update(x=-9.0))
    _has(p, "start", "not on the floor")


def test_unknown_field_and_version():
    p = _problems(lambda d: d.update(colour="red"))
    _has(p, "colour", "Extra inputs are not permitted")
    p = _problems(lambda d: d.update(version=7))
    _has(p, "version", "reads version 1")


def test_several_problems_reported_together():
    def bad(d):
        d["trays"][0]["parts"][0]["pose"]["x"] = 0.4
        d["start"]["x"] = -9.0

    assert len(_problems(bad)) >= 2


def test_unknown_robot_is_reported_by_resolving():
    from pickstop.errors import RobotConfigError
    from pickstop.robot.config import resolve_robot

    scene = parse_scene({**PAPER, "robot": {"preset": "nosuchbot"}})
    with pytest.raises(RobotConfigError, match="unknown robot 'nosuchbot'"):
        resolve_robot(scene.robot.ref)


def test_missing_and_broken_files(tmp_path):
    from pickstop.errors import InputError

    with pytest.raises(InputError, match="not found"):
        load_scene(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        load_scene(tmp_path / "bad.json")


def write_box_stl(path, sx, sy, sz):
    """An ASCII STL box centred on x, y with its bottom at z = 0."""
    import itertools

    v = {c: (c[0] * sx / 2, c[1] * sy / 2, (c[2] + 1) * sz / 2)
         for c in itertools.product((-1, 1), repeat=3)}  # fmt: skip
    quads = [((-1, -1, -1), (-1, 1, -1), (1, 1, -1), (1, -1, -1)),
             ((-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)),
             ((-1, -1, -1), (1, -1, -1), (1, -1, 1), (-1, -1, 1)),
             ((-1, 1, -1), (-1, 1, 1), (1, 1, 1), (1, 1, -1)),
             ((-1, -1, -1), (-1, -1, 1), (-1, 1, 1), (-1, 1, -1)),
             ((1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1))]  # fmt: skip
    lines = ["solid box"]
    for a, b, c, d in quads:
        for tri in ((a, b, c), (a, c, d)):
            lines.append(" facet normal 0 0 0\n  outer loop")
            lines += [f"   vertex {v[p][0]} {v[p][1]} {v[p][2]}" for p in tri]
            lines.append("  endloop\n endfacet")
    lines.append("endsolid box")
    path.write_text("\n".join(lines) + "\n")


def test_relative_mesh_paths_start_at_the_scene_file(tmp_path):
    from pickstop.scene.model import load_scene

    (tmp_path / "meshes").mkdir()
    write_box_stl(tmp_path / "meshes" / "pillar.stl", 0.3, 0.3, 1.5)
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    mesh = {"shape": "mesh", "path": "meshes/pillar.stl"}
    doc["obstacles"].append({"id": "pillar", "geometry": mesh, "pose": {"x": 2.5, "y": 0.0}})
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    scene = load_scene(tmp_path / "scene.json")
    mesh = next(o for o in scene.obstacles if o.id == "pillar").geometry
    assert mesh.path == str((tmp_path / "meshes" / "pillar.stl").resolve())
    doc["obstacles"][-1]["geometry"]["path"] = "meshes/missing.stl"
    (tmp_path / "scene.json").write_text(json.dumps(doc))
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path / "scene.json")
    assert e.value.problems == [
        ("obstacles.2.geometry.path", "mesh file 'meshes/missing.stl' not found")
    ]
