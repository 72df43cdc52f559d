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


def test_a_build_in_a_second_data_folder_reuses_the_cached_screen(tmp_path, monkeypatch):
    import json
    import os
    import subprocess
    import sys
    from collections import Counter

    from pickstop.reach.build import BuildParams
    from pickstop.robot.cache import COMPUTED
    from pickstop.robot.model import load
    from pickstop.store.reach_build import build
    from tests.robot.synthetic import write_dense_robot

    monkeypatch.setenv("PICKSTOP_CACHE_DIR", str(tmp_path / "cache"))
    config = str(write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False))
    params = BuildParams(samples=20_000, chunk_size=10_000)
    before = COMPUTED.copy()
    build(load(config), params, tmp_path / "a", workers=1)
    made = COMPUTED - before
    assert made["pairs"] == made["screen"] == 1 and sum(made.values()) == 3  # + floor spheres
    before = COMPUTED.copy()
    build(load(config), params, tmp_path / "b", workers=1)  # loaded anew: nothing in memory
    assert COMPUTED - before == Counter()  # no pairs, no screen, no covers computed
    assert not (tmp_path / "a" / "cache").exists() and (tmp_path / "cache" / "robots").is_dir()
    # Another process (robot check) finds them too, and says where the cache is.
    env = {**os.environ, "PICKSTOP_CACHE_DIR": str(tmp_path / "cache")}
    proc = subprocess.run(
        [sys.executable, "-m", "pickstop.cli", "robot", "check", config, "--json", "--quiet"],
        capture_output=True, text=True, timeout=300, env=env,
    )  # fmt: skip
    report = json.loads(proc.stdout)
    assert report["cache"] == {"folder": str(tmp_path / "cache"), "computed": []}


def test_the_cache_is_the_users_unless_set(monkeypatch, tmp_path):
    from pickstop.settings import cache_dir

    monkeypatch.delenv("PICKSTOP_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "pickstop"
    assert cache_dir(tmp_path / "some-data-folder") == cache_dir()  # one for every data folder
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert str(cache_dir()).endswith(".cache/pickstop")
    monkeypatch.setenv("PICKSTOP_CACHE_DIR", str(tmp_path / "mine"))
    assert cache_dir() == tmp_path / "mine"
