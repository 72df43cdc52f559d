"""Shared assertions and factories for the tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pickstop.robot.config import example_robot_data_share

TIAGO_URDF = (
    example_robot_data_share() / "example-robot-data/robots/tiago_description/robots/tiago.urdf"
)


def random_thetas(robot, n: int, seed: int = 0) -> np.ndarray:
    """``(n, dof)`` joint values uniform within the robot's limits."""
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))


def write_config(folder: Path, text: str, name: str = "robot.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


TIAGO_CONFIG = """
name: mytiago
urdf: {urdf}
arm_joints: [torso_lift_joint, arm_1_joint, arm_2_joint, arm_3_joint, arm_4_joint,
             arm_5_joint, arm_6_joint, arm_7_joint]
tool_frame: hand_grasping_frame
footprint: {{radius: 0.275}}
"""
