"""Geometry checks of scenes, remembered (scene/checks.py)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop.scene.model import SceneError

PAPER = json.loads(
    (Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json").read_text()
)


def test_checked_scenes_remember_a_geometry_and_check_a_new_one():
    from pickstop.scene.checks import CheckedScenes

    checked = CheckedScenes(size=4)
    scene = parse_scene(PAPER, check=checked)
    assert checked(scene.model_copy(update={"sigma": 0.2})) == []  # the same geometry
    bad = copy.deepcopy(PAPER)
    bad["trays"][1]["pose"]["x"] = bad["trays"][0]["pose"]["x"]  # into its neighbour
    for _ in range(2):  # checked, then remembered: refused the same way both times
        with pytest.raises(SceneError) as e:
            parse_scene(bad, check=checked)
        assert any("intersects" in m for _, m in e.value.problems)
    assert len(checked._checked) == 2
