"""Nav2 export: the goal, per-stop tolerances, round trips through JSON and YAML."""

from __future__ import annotations

import math

import pytest

from pickstop.errors import InputError
from pickstop.fleet import nav2
from tests.fleet.conftest import SCENES


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("fmt", ["json", "yaml"])
def test_nav2_goal_round_trips_and_carries_the_stop_tolerances(example_plans, name, fmt):
    scene, plan = example_plans[name]
    doc = nav2.build_nav2(plan, start_yaw=scene.start.yaw, goal_yaw=scene.goal.yaw)
    back = nav2.loads(nav2.dumps(doc, fmt))
    assert back == doc
    poses = nav2.goal_poses(back)
    for p in back["goal"]["poses"]:
        assert p["header"]["frame_id"] == "map"
        q = p["pose"]["orientation"]
        assert math.isclose(q["x"] ** 2 + q["y"] ** 2 + q["z"] ** 2 + q["w"] ** 2, 1.0)
    segs = back["segments"]
    assert [s["name"] for s in segs] == [f"stop{k}" for k in range(len(plan.stops))] + ["goal"]
    for seg, stop in zip(segs, plan.stops, strict=False):
        x, y, yaw = poses[seg["last"]]
        assert (x, y) == pytest.approx((stop.x, stop.y))
        assert math.cos(yaw - stop.yaw) == pytest.approx(1.0)
        assert seg["xy_goal_tolerance"] == stop.inscribed_radius
        parts = {(p["tray_id"], p["part_id"]) for p in seg["picks"]}
        assert parts == {(w.tray_id, w.part_id) for w in stop.witnesses}
        assert all(p["joint_names"] == plan.joints for p in seg["picks"])
    assert segs[-1]["last"] == len(poses) - 1
    # the picks as one list beside the goal, each naming the pose it is done at
    assert len(back["picks"]) == sum(len(s.witnesses) for s in plan.stops)
    for p in back["picks"]:
        stop = plan.stops[int(p["stop"].removeprefix("stop"))]
        assert poses[p["pose_index"]][:2] == pytest.approx((stop.x, stop.y))
    assert poses[-1][:2] == pytest.approx((scene.goal.x, scene.goal.y))
    assert math.cos(poses[-1][2] - scene.goal.yaw) == pytest.approx(1.0)
    assert any("xy_goal_tolerance" in n for n in back["notes"])
    # The note on Nav2's default goal tolerance says what it means for these stops.
    tight = sum(s.inscribed_radius < 0.25 for s in plan.stops)
    (note,) = [n for n in back["notes"] if "default xy_goal_tolerance" in n]
    assert f"radius of {tight} of the" in note if tight else "at least the default" in note


def test_kilted_wraps_the_poses_in_goals(example_plans):
    _, plan = example_plans["paper_experiment"]
    jazzy = nav2.build_nav2(plan)
    kilted = nav2.build_nav2(plan, distro="kilted")
    assert kilted["goal"]["poses"]["goals"] == jazzy["goal"]["poses"]
    assert nav2.goal_poses(kilted) == nav2.goal_poses(jazzy)
    with pytest.raises(InputError):
        nav2.build_nav2(plan, distro="foxy")  # type: ignore[arg-type]
    with pytest.raises(InputError):
        nav2.loads("format: something.else\n")
