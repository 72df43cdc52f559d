"""Per-robot derived data kept on disk: made once, never taken for another robot or kind."""

from __future__ import annotations

import numpy as np

from pickstop.regions.arm import ArmSpheres
from pickstop.robot.artifacts import derived


def test_derived_value_is_made_once_per_robot_and_kind(tmp_path, tiago, pr2):
    calls = []

    def make(robot, tag):
        def run():
            calls.append((robot.name, tag))
            return {"robot": robot.name, "tag": tag}

        return run

    assert derived(tiago, tmp_path, "thing", make(tiago, 1)) == {"robot": "tiago", "tag": 1}
    assert derived(tiago, tmp_path, "thing", make(tiago, 2)) == {"robot": "tiago", "tag": 1}
    assert derived(tiago, tmp_path, "other", make(tiago, 3))["tag"] == 3
    assert derived(pr2, tmp_path, "thing", make(pr2, 4))["robot"] == "pr2"
    assert calls == [("tiago", 1), ("tiago", 3), ("pr2", 4)]
    # A damaged file is made again, never trusted.
    for f in (tmp_path / "robots").glob("thing-*"):
        f.write_bytes(b"not a pickle")
    assert derived(tiago, tmp_path, "thing", make(tiago, 5))["tag"] == 5
    assert derived(tiago, None, "thing", make(tiago, 6))["tag"] == 6  # no cache folder


def test_cached_arm_spheres_equal_fresh_ones(tmp_path, tiago):
    fresh = ArmSpheres.of(tiago)
    derived(tiago, tmp_path, "arm", lambda: ArmSpheres.of(tiago))
    kept = derived(tiago, tmp_path, "arm", lambda: None)
    for name in ("link_joint", "is_hand", "bound_c", "bound_r", "leaf_link", "leaf_c", "leaf_r"):
        assert np.array_equal(getattr(kept, name), getattr(fresh, name)), name
