"""Robot configs and the model loader: every bad input names the file and the problem."""

from __future__ import annotations

import re

import pytest

from pickstop.errors import RobotConfigError
from pickstop.robot.config import load_config, preset_names, resolve_robot
from pickstop.robot.model import load, load_robot
from tests.utils import TIAGO_CONFIG, TIAGO_URDF, write_config


def test_presets_listed():
    assert "tiago" in preset_names()


def test_tiago_preset_shape(tiago):
    assert tiago.dof == 8
    assert [j.kind for j in tiago.joints] == ["prismatic"] + ["revolute"] * 7
    assert tiago.base_frame == "base_footprint"
    assert tiago.model.frames[tiago.tool_frame_id].name == "hand_grasping_frame"
    assert len(tiago.robot_hash) == 64


def test_pr2_has_continuous_joints_with_two_coordinates(pr2):
    kinds = [j.kind for j in pr2.joints]
    assert kinds[0] == "prismatic" and kinds.count("continuous") == 2
    assert pr2.model.nq == pr2.dof + 2
    assert pr2.srdf_path is not None


def test_user_config_equals_preset_kinematics(tmp_path, tiago):
    path = write_config(tmp_path, TIAGO_CONFIG.format(urdf=TIAGO_URDF))
    mine = load(str(path))
    assert mine.dof == tiago.dof and mine.name == "mytiago"
    assert mine.robot_hash != tiago.robot_hash  # a different config is a different robot


def test_locked_joint_value_changes_hash(tmp_path):
    a = load(str(write_config(tmp_path, TIAGO_CONFIG.format(urdf=TIAGO_URDF), "a.yaml")))
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF) + "locked_joints: {head_2_joint: -0.5}\n"
    b = load(str(write_config(tmp_path, text, "b.yaml")))
    assert a.robot_hash != b.robot_hash


def _err(tmp_path, text: str, name: str = "robot.yaml") -> str:
    path = write_config(tmp_path, text, name)
    with pytest.raises(RobotConfigError) as e:
        config, root = load_config(path)
        load_robot(config, root)
    return e.value.message


def test_missing_config_file(tmp_path):
    with pytest.raises(RobotConfigError, match="not found"):
        load_config(tmp_path / "nope.yaml")


def test_unknown_robot_name():
    with pytest.raises(RobotConfigError, match="unknown robot 'fetchy'"):
        resolve_robot("fetchy")


def test_not_yaml(tmp_path):
    assert "not valid" in _err(tmp_path, "name: [unclosed")


def test_unknown_joint_named(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace("arm_7_joint]", "arm_8_joint]")
    msg = _err(tmp_path, text)
    assert "unknown arm joint 'arm_8_joint'" in msg and "tiago.urdf" in msg


def test_unknown_frame_named(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace("hand_grasping_frame", "no_frame")
    assert "unknown tool frame 'no_frame'" in _err(tmp_path, text)


def test_joints_out_of_chain_order(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace(
        "arm_1_joint, arm_2_joint", "arm_2_joint, arm_1_joint"
    )
    assert "serial chain" in _err(tmp_path, text)


def test_duplicate_joint(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace("arm_2_joint,", "arm_1_joint,")
    assert "listed twice: arm_1_joint" in _err(tmp_path, text)


def test_footprint_takes_at_most_one_shape(tmp_path):  # neither: derived from the URDF
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace(
        "{radius: 0.275}", "{radius: 0.3, polygon: [[0, 0], [1, 0], [0, 1]]}"
    )
    msg = _err(tmp_path, text)
    assert "footprint" in msg and "at most one" in msg


def test_negative_radius(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace("0.275", "-1")
    assert re.search(r"footprint\.radius: .*greater than 0", _err(tmp_path, text))


def test_broken_urdf_named(tmp_path):
    urdf = tmp_path / "broken.urdf"
    urdf.write_text("<robot name='x'><link name='a'></robot>")
    msg = _err(tmp_path, TIAGO_CONFIG.format(urdf=urdf))
    assert "broken.urdf" in msg and "broken URDF" in msg


def test_missing_mesh_named(tmp_path):
    urdf = tmp_path / "nomesh.urdf"
    urdf.write_text(
        TIAGO_URDF.read_text().replace("arm_3_collision.dae", "arm_3_collision_missing.dae")
    )
    msg = _err(tmp_path, TIAGO_CONFIG.format(urdf=urdf))
    assert "nomesh.urdf" in msg and "arm_3_collision_missing.dae" in msg and "arm_3_link" in msg


def test_missing_urdf(tmp_path):
    assert "urdf file not found" in _err(tmp_path, TIAGO_CONFIG.format(urdf="nothere.urdf"))


def test_locked_value_outside_limits(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF) + "locked_joints: {head_2_joint: 3.0}\n"
    assert "outside its limits" in _err(tmp_path, text)


def test_angles_q_round_trip(robot):
    import numpy as np

    th = np.random.default_rng(1).uniform(robot.lower, robot.upper, (50, robot.dof))
    assert np.allclose(robot.q_to_angles(robot.angles_to_q(th)), th)


def test_travel_names_an_arm_joint(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF) + "travel: {head_1_joint: 0.0}\n"
    with pytest.raises(RobotConfigError) as e:
        load_config(write_config(tmp_path, text))
    assert e.value.field == "travel"
    assert "travel: Value error, not arm joints: head_1_joint" in e.value.message
    assert "arm_1_joint" in e.value.message  # the joints it may name


def test_travel_value_outside_limits(tmp_path):
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF) + "travel: {arm_4_joint: 3.0}\n"
    with pytest.raises(RobotConfigError) as e:
        config, root = load_config(write_config(tmp_path, text))
        load_robot(config, root)
    assert e.value.field == "travel.arm_4_joint"
    assert "travel posture: joint 'arm_4_joint' value 3.0 is outside its limits" in e.value.message
    assert "rad" in e.value.message


def test_travel_does_not_change_the_robot_hash(tmp_path):
    a = load(str(write_config(tmp_path, TIAGO_CONFIG.format(urdf=TIAGO_URDF), "a.yaml")))
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF) + "travel: {torso_lift_joint: 0.1}\n"
    b = load(str(write_config(tmp_path, text, "b.yaml")))
    assert a.robot_hash == b.robot_hash and b.config.travel == {"torso_lift_joint": 0.1}
