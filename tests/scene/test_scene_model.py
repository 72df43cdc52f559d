"""The scene format: examples valid, each problem reported with its field, round trip."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.scene.load import load_scene, parse_scene
from pickstop.scene.model import SceneError, scene_json_schema

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())


@pytest.mark.parametrize("name", ["paper_experiment", "five_trays", "factory_cell", "rack_cell"])
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


def test_rack_cell_has_every_level():
    """Floor bin, lower shelf, slanted flow-rack tray, upper shelf, table; the task needs all."""
    scene = load_scene(EXAMPLES / "rack_cell.json")
    heights = sorted(t.pose.z for t in scene.trays)
    assert heights[0] < 0.05 and heights[-1] > 0.85
    assert any(t.tilt is not None and 0.17 <= abs(t.tilt.angle) <= 0.35 for t in scene.trays)
    assert scene.task_trays == [t.id for t in scene.trays]
    boards = {o.id: o for o in scene.obstacles if "shelf" in o.id}
    lower, upper = boards["lower_shelf"], boards["upper_shelf"]
    assert abs(lower.pose.z + lower.geometry.size[2] - 0.25) < 0.01
    assert abs(upper.pose.z + upper.geometry.size[2] - 0.90) < 0.01
    # The upper board reaches further out than the lower one: it overhangs the lower trays.
    front = {k: b.pose.y - b.geometry.size[1] / 2 for k, b in boards.items()}
    assert front["upper_shelf"] < front["lower_shelf"] - 0.1


def test_tilt_and_floor_clearance_are_checked():
    p = _problems(lambda d: d["trays"][0].update(tilt={"axis": "z", "angle": 0.2}))
    assert any(f.startswith("trays.0.tilt.axis") for f, _ in p), p
    p = _problems(lambda d: d["trays"][0].update(tilt={"axis": "x", "angle": 1.2}))
    _has(p, "trays.0.tilt.angle", "less than or equal to 0.8")
    p = _problems(lambda d: d.update(floor_clearance=-0.01))
    _has(p, "floor_clearance", "greater than or equal to 0")


def test_a_tilted_tray_is_checked_by_its_tilted_outline():
    """Tilted 0.6 rad about x, the tray's low edge dips into the table it sits on."""
    p = _problems(lambda d: d["trays"][0].update(tilt={"axis": "x", "angle": 0.6}))
    _has(p, "trays.0", "tray 'tray_1' intersects obstacle 'table_a'")
    doc = copy.deepcopy(PAPER)
    doc["trays"][0]["pose"]["z"] += 0.1
    doc["trays"][0]["tilt"] = {"axis": "y", "angle": -0.6}
    scene = parse_scene(doc)
    from pickstop.scene.world import tray_body_solids, tray_transform

    tray = scene.tray("tray_1")
    T = tray_transform(tray)
    assert abs(T[2, 2] - 0.8253356149) < 1e-9 and T[0, 2] < 0  # z turned towards -x
    floor = tray_body_solids(tray)[0]
    assert abs(floor.T_world_solid[:3, 2] @ T[:3, 2] - 1.0) < 1e-12


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
    _has(p, "trays.0.inner_size.1", "greater than or equal to 0.0001")


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
