"""The travel posture: the config's (TIAGo's) or one computed from the robot, checked exactly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pickstop.robot.artifacts import self_collision
from pickstop.robot.exact import ExactSelfCollision
from pickstop.robot.selfcollision import home_thetas
from pickstop.robot.travel import compact, problem, reach, travel_posture
from pickstop.settings import cache_dir


@pytest.fixture(scope="module")
def exact(tiago):
    disabled, _ = self_collision(tiago, cache_dir())
    return ExactSelfCollision(tiago, disabled)


def test_tiagos_travel_posture_is_its_configs_and_collision_free(tiago, exact):
    t = travel_posture(tiago, exact)
    assert t.source == "config"
    assert t.by_joint(tiago) == pytest.approx(tiago.config.travel)
    assert np.all((tiago.lower <= t.theta) & (t.theta <= tiago.upper))
    assert t.collisions == () and not exact.colliding(t.theta[None])[0]
    assert problem(tiago, t) is None
    # Folded: every joint origin and the grasp frame within 0.25 m of the base's axis.
    assert reach(tiago, t.theta[None])[0][0] < 0.25


def test_without_a_config_posture_one_is_computed_folded_and_free(tiago, exact):
    bare = dataclasses.replace(tiago, config=tiago.config.model_copy(update={"travel": None}))
    t = travel_posture(bare, exact)
    assert t.source == "computed" and t.collisions == ()
    spread, height = reach(tiago, np.vstack([t.theta, home_thetas(tiago)]))
    assert spread[0] < 0.5 * spread[1] and height[0] >= 0.3  # far tighter than the home pose
    assert np.array_equal(compact(bare, exact), t.theta)  # the same every time


def test_a_colliding_travel_posture_is_told_with_its_pairs(tiago, exact):
    # The arm folded through the torso: arm_2 down, the elbow bent fully back.
    theta = {"torso_lift_joint": 0.0, "arm_1_joint": 0.0, "arm_2_joint": -1.5,
             "arm_3_joint": 0.0, "arm_4_joint": 2.3}  # fmt: skip
    bad = dataclasses.replace(tiago, config=tiago.config.model_copy(update={"travel": theta}))
    t = travel_posture(bad, exact)
    assert t.collisions
    assert "not collision-free" in (problem(bad, t) or "")
