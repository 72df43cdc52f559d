"""Reading scene files (scene/load.py): missing and broken files, mesh paths relative to the
scene file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickstop.scene.load import load_scene
from pickstop.scene.model import SceneError
from tests.scene.test_scene_model import write_box_stl

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def test_missing_and_broken_files(tmp_path):
    from pickstop.errors import InputError

    with pytest.raises(InputError, match="not found"):
        load_scene(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        load_scene(tmp_path / "bad.json")


def test_relative_mesh_paths_start_at_the_scene_file(tmp_path):
    from pickstop.scene.load import load_scene

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
