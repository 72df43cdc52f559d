"""The arm's collision checks (regions/arm.py): the sphere screen against the exact coal check."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pickstop.regions.arm import ExactArm, screen_arm
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.world import BoxArrays, scene_solids


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_environment_screen_is_conservative(planner, tiago, seed):
    """Screen 'free' is guaranteed: coal finds no collision where the screen finds none."""
    from pickstop.scene.load import load_scene
    from tests.regions.conftest import EXAMPLES

    scene = load_scene(EXAMPLES / "paper_experiment.json")
    solids = scene_solids(scene)
    boxes = BoxArrays.of(solids)
    rng = np.random.default_rng(seed)
    n = 150
    th = rng.uniform(tiago.lower, tiago.upper, (n, tiago.dof))
    # Bases in front of the tables, where the arm often reaches into the trays and tables.
    xy = np.stack([rng.uniform(0.5, 2.2, n), rng.uniform(0.6, 1.1, n)], 1)
    yaw = float(rng.uniform(0, 2 * np.pi))
    _, _, frames = fk_soa(planner.solver.chain, np.ascontiguousarray(th.T), frames=True)
    flagged = screen_arm(planner.arm, boxes, frames, xy, yaw)
    exact = ExactArm(tiago)
    colliding = np.array(
        [exact.colliding(th[i], xy[i, 0], xy[i, 1], yaw, solids) for i in range(n)]
    )
    assert not (colliding & ~flagged).any()
    assert flagged.sum() >= colliding.sum()


@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_exact_check_of_the_sphere_pairs_alone_is_the_whole_exact_check(planner, tiago, seed):
    """coal on the (link, solid) pairs whose covering spheres meet, alone, finds exactly the
    collisions coal finds on every pair whose bounding boxes overlap, the hand's target no
    obstacle and the floor checked."""
    from pickstop.scene.load import load_scene
    from tests.regions.conftest import EXAMPLES

    scene = load_scene(EXAMPLES / "paper_experiment.json")
    solids = scene_solids(scene)
    boxes = BoxArrays.of(solids)
    rng = np.random.default_rng(seed)
    n = 200
    th = rng.uniform(tiago.lower, tiago.upper, (n, tiago.dof))
    xy = np.stack([rng.uniform(0.5, 2.2, n), rng.uniform(0.6, 1.1, n)], 1)
    yaw = float(rng.uniform(0, 2 * np.pi))
    parts = [p.id for t in scene.trays for p in t.parts]
    every, pairs = ExactArm(tiago), ExactArm(tiago, planner.arm)
    hits = []
    for i in range(n):
        target = parts[i % len(parts)] if i % 3 else None
        args = (th[i], xy[i, 0], xy[i, 1], yaw, solids, target, 0.01)
        want = every.colliding(*args)
        assert pairs.colliding(*args, boxes=boxes) == want, i
        hits.append(want)
    assert any(hits) and not all(hits)


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), clearance=st.sampled_from([None, 0.01, 0.35]))
def test_checks_of_many_configurations_answer_as_one_at_a_time(planner, tiago, seed, clearance):
    """:meth:`ExactArm.checks`, rows asked in any order across its chunks, answers each as
    :meth:`ExactArm.colliding` does: the hand's target per row no obstacle for it, the floor
    checked (also high enough to meet) or not."""
    from unittest import mock

    import pickstop.regions.arm as arm_module
    from pickstop.scene.load import load_scene
    from tests.regions.conftest import EXAMPLES

    scene = load_scene(EXAMPLES / "paper_experiment.json")
    solids = scene_solids(scene)
    boxes = BoxArrays.of(solids)
    rng = np.random.default_rng(seed)
    n = 240
    th = rng.uniform(tiago.lower, tiago.upper, (n, tiago.dof))
    xy = np.stack([rng.uniform(0.5, 2.2, n), rng.uniform(0.6, 1.1, n)], 1)
    yaw = float(rng.uniform(0, 2 * np.pi))
    parts = [p.id for t in scene.trays for p in t.parts]
    targets = np.array([parts[i % len(parts)] for i in range(n)])
    one = ExactArm(tiago, planner.arm)
    with mock.patch.object(arm_module, "CHECK_CHUNK", 64):
        many = ExactArm(tiago, planner.arm).checks(th, xy, yaw, solids, targets, clearance, boxes)
    got = {}
    for i in rng.permutation(n).tolist():
        got[i] = many.colliding(i)
    want = [
        one.colliding(th[i], xy[i, 0], xy[i, 1], yaw, solids, targets[i], clearance, boxes)
        for i in range(n)
    ]
    assert [got[i] for i in range(n)] == want
    assume(any(want) and not all(want))  # examples with both answers count toward the three
    floor_only = ExactArm(tiago, planner.arm).checks(th, xy, yaw, [], None, 0.35, BoxArrays.of([]))
    low = [one.colliding(th[i], xy[i, 0], xy[i, 1], yaw, [], None, 0.35) for i in range(n)]
    assert [floor_only.colliding(i) for i in range(n)] == low
    assert any(low) and not all(low)


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_environment_screen_flags_what_every_covering_sphere_flags(planner, tiago, seed):
    """The batched screen flags exactly the configurations where some covering sphere of a
    link touches a solid (the grasped part no obstacle for the hand's spheres), and records
    the owners of exactly the solids those spheres touch (every one each sphere touches)."""
    from types import SimpleNamespace

    from pickstop.regions.arm import owner_codes, points_to_world
    from pickstop.scene.load import load_scene
    from pickstop.scene.world import spheres_hit
    from tests.regions.conftest import EXAMPLES

    scene = load_scene(EXAMPLES / "paper_experiment.json")
    solids = scene_solids(scene)
    boxes = BoxArrays.of(solids)
    rng = np.random.default_rng(seed)
    n = 120
    th = rng.uniform(tiago.lower, tiago.upper, (n, tiago.dof))
    xy = np.stack([rng.uniform(0.5, 2.2, n), rng.uniform(0.6, 1.1, n)], 1)
    yaw = float(rng.uniform(0, 2 * np.pi))
    parts = [o for o in dict.fromkeys(boxes.owners) if "part" in o] or list(boxes.owners)
    targets = np.array([parts[i % len(parts)] for i in range(n)])
    _, _, frames = fk_soa(planner.solver.chain, np.ascontiguousarray(th.T), frames=True)
    env = SimpleNamespace(hit_owners=set())
    flagged = screen_arm(planner.arm, boxes, frames, xy, yaw, env, targets)

    arm = planner.arm
    leaves = points_to_world(
        frames, arm.link_joint[arm.leaf_link], arm.leaf_c, xy, yaw
    )  # (n, S, 3)
    hit = np.zeros((n, len(arm.leaf_r)), bool)
    touched = set()
    for solid in solids:  # one at a time: every solid a sphere touches, not its first
        one = BoxArrays.of([solid])
        code = owner_codes(one, targets, n)
        skip = np.where(arm.is_hand[arm.leaf_link][None, :], code[:, None], -1)  # (n, S)
        mine = spheres_hit(
            one, leaves.reshape(-1, 3), np.tile(arm.leaf_r, n), skip=skip.ravel()
        ).reshape(n, -1)
        if mine.any():
            touched.add(solid.owner)
        hit |= mine
    expected = hit.any(axis=1)
    assert expected.any() and not expected.all()
    assert np.array_equal(flagged, expected)
    assert env.hit_owners == touched
