"""``robot check`` of a robot as vendors ship them (an SRDF, dense meshes, a 7-joint arm on a
torso, a parallel gripper with its tool frame between the pads): each step told as it goes,
the hand's reach and the offset that fixes it, a screen over its bound said loudly."""

from __future__ import annotations

import json

import pytest

from pickstop.cli import main
from pickstop.cli.robot import STRICT_EXIT
from pickstop.robot.cache import COMPUTED
from pickstop.robot.check import check_robot
from pickstop.settings import cache_dir
from tests.robot.synthetic import FINGER_TIP, PAD_TIP, TOOL_X, write_dense_robot, write_manipulator


@pytest.fixture(scope="module")
def manipulator(tmp_path_factory):
    return write_manipulator(tmp_path_factory.mktemp("gen"), triangles=2500)


def test_check_tells_each_step_and_the_hands_reach(manipulator, tmp_path, monkeypatch):
    monkeypatch.setenv("PICKSTOP_CACHE_DIR", str(tmp_path / "cache"))  # every step runs
    seen: list[tuple[str, int, int]] = []
    report = check_robot(str(manipulator), cache_dir(), lambda *s: seen.append(s))
    names = [n for n, _, _ in seen]
    for step in (
        "loading the URDF, its meshes and the base outline",
        "self-collision screen: covering the links",
        "self-collision screen: exact checks with coal",
        "SRDF comparison, disabled pairs: random configurations",
    ):
        assert step in names
    counted = [(d, t) for n, d, t in seen if n == "self-collision screen: exact checks with coal"]
    assert counted[0] == (0, 4000) and counted[-1][0] > 0
    assert report["srdf"] == "gen_arm.srdf" and len(report["arm_joints"]) == 8
    assert report["cache"]["folder"] == str(tmp_path / "cache")
    assert {"screen", "pairs"} <= set(report["cache"]["computed"])
    # The tool frame between the pads: the open fingers reach past it; the offset to the pads'
    # inner edge is suggested, and warned of.
    hand = report["hand"]
    assert hand["reach"] == pytest.approx(FINGER_TIP - TOOL_X)
    assert hand["top_down_min_height"] == pytest.approx(FINGER_TIP - TOOL_X + 0.003)
    assert hand["pad_tip"] == pytest.approx(PAD_TIP - TOOL_X, abs=1e-6)
    assert hand["pad_gap"] == pytest.approx(0.08, abs=1e-3)  # max_opening: the gap, as said
    sug = hand["suggested_tool_offset"]
    assert sug["position"] == pytest.approx([PAD_TIP - TOOL_X, 0, 0], abs=1e-6)
    assert sug["reach"] == pytest.approx(FINGER_TIP - PAD_TIP, abs=1e-6)
    (warning,) = [w for w in report["warnings"] if "hand.tool_offset" in w]
    assert "reaches 0.031 m past the grasp point" in warning and "lower than 0.034 m" in warning
    assert "{position: [0.016, 0, 0]} puts the grasp point at the pads' inner edge" in warning

    # Checked again (another load, as another process would): nothing is computed again,
    # the disabled pairs compared with the SRDF included.
    before = COMPUTED.copy()
    again = check_robot(str(manipulator), cache_dir())
    assert before == COMPUTED and again["cache"]["computed"] == []
    assert again["screen"] == report["screen"]

    # With the suggested offset the hand fits: no warning, the reach it said.
    config = manipulator.with_name("offset.yaml")
    offset = f"\n  tool_offset: {{position: {sug['position']}}}"
    config.write_text(manipulator.read_text().replace("0.08", "0.08" + offset))
    fixed = check_robot(str(config), cache_dir())
    assert fixed["hand"]["reach"] == pytest.approx(sug["reach"])
    assert not [w for w in fixed["warnings"] if "hand.tool_offset" in w]
    assert before == COMPUTED  # the hand's set-up is not in the robot hash: the screen is kept


def test_a_screen_over_its_bound_is_said_and_strict_fails(tmp_path, monkeypatch, capsys):
    import pickstop.robot.artifacts as art

    monkeypatch.setenv("PICKSTOP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(art, "FALSE_REJECTION_BOUND", 0.001)
    monkeypatch.setattr(art, "MAX_ROUNDS", 0)
    config = str(write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False))
    assert main(["robot", "check", config, "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert "OVER its 0.1% bound" in out
    assert "warning: the self-collision screen drops" in err and "over its 0.1% bound" in err
    assert main(["robot", "check", config, "--quiet", "--strict"]) == STRICT_EXIT
    # A build says it too (even quiet), and the catalog keeps it.
    data = ["--data-dir", str(tmp_path / "data")]
    build = ["reach", "build", "--robot", config, "--samples", "20000", "--workers", "1"]
    assert main([*data, *build, "--quiet"]) == 0
    assert "over its 0.1% bound" in capsys.readouterr().err
    assert main([*data, "reach", "info"]) == 0
    (info,) = json.loads(capsys.readouterr().out)
    assert info["screen_meets_bound"] is False and info["screen_bound"] == 0.001


def test_a_plan_refused_for_the_hands_reach_names_the_offset_and_the_check(
    manipulator, tmp_path, capsys
):
    import re
    import shlex
    from pathlib import Path

    data = ["--data-dir", str(tmp_path / "data")]
    build = ["reach", "build", "--robot", str(manipulator), "--samples", "20000", "--quiet"]
    assert main([*data, *build, "--workers", "1"]) == 0
    capsys.readouterr()
    scene = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"
    assert main([*data, "plan", str(scene), "--robot", str(manipulator)]) == 3
    err = capsys.readouterr().err
    assert "the open hand reaches 0.031 m past its grasp point" in err
    assert "hand.tool_offset places the grasp point" in err
    (command,) = set(re.findall(r"`(pickstop robot check [^`]+)`", err))
    assert main([*shlex.split(command)[1:], "--quiet"]) == 0  # runs as printed
    assert "hand.tool_offset: {position: [0.016, 0, 0]}" in capsys.readouterr().out


def test_check_shows_the_travel_posture_and_warns_when_it_collides():
    from pickstop.robot.check import check_config, format_report
    from pickstop.robot.config import resolve_robot

    config, root = resolve_robot("tiago")
    report = check_config(config, root, "tiago", cache_dir())
    assert report["travel"]["source"] == "config" and report["travel"]["collisions"] == []
    assert report["travel"]["joints"]["arm_4_joint"] == 1.94
    assert "travel posture (config): torso_lift_joint 0.15" in format_report(report)
    assert "collision-free (exact check)" in format_report(report)
    assert not [w for w in report["warnings"] if "travel" in w]
    # The elbow folded back through the torso: told, with the links in contact.
    bent = {"arm_2_joint": -1.5, "arm_4_joint": 2.3}
    bad = check_config(config.model_copy(update={"travel": bent}), root, "tiago", cache_dir())
    (warning,) = [w for w in bad["warnings"] if "travel" in w]
    assert "the config's `travel`) is not collision-free: arm_4_link - torso" in warning
    assert "COLLIDING" in format_report(bad)
