"""Disabled pairs (MoveIt style), the exact checker, and the conservative sphere screen."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pickstop.robot.selfcollision as sc
from pickstop.errors import InputError
from pickstop.robot.kinematics import Chain, fk_soa
from pickstop.robot.link_geometry import LinkShape, distance_grid, point_triangle_distance
from pickstop.robot.selfcollision import (
    DisabledPairs,
    ExactSelfCollision,
    SphereModel,
    collision_links,
    disabled_pairs,
    false_rejection_rate,
    home_thetas,
    screen,
    srdf_pairs,
)
from pickstop.robot.spheres import cover

# Configurations found colliding by coal: the hand (TIAGo) or gripper (PR2) inside the base.
TIAGO_HAND_IN_BASE = [0.01, 2.57, -1.34, 0.78, 0.62, 1.89, -0.28, 1.83]
PR2_GRIPPER_IN_BASE = [0.09, -0.82, 1.25, -2.95, -0.62, -1.56, -1.69, -1.11]


@pytest.fixture(scope="module")
def tiago_pairs(tiago):
    return disabled_pairs(tiago, samples=2000, seed=0)


@pytest.fixture(scope="module")
def pr2_pairs(pr2):
    return disabled_pairs(pr2)


@pytest.fixture(scope="module")
def setups(tiago, pr2):
    """robot name -> (robot, disabled pairs, sphere model, exact checker): the robot's own
    derived data, made once per run and shared through the run's cache."""
    from pickstop.robot.artifacts import self_collision
    from pickstop.settings import cache_dir

    out = {}
    for name, robot in (("tiago", tiago), ("pr2", pr2)):
        pairs, model = self_collision(robot, cache_dir())
        out[name] = (robot, pairs, model, ExactSelfCollision(robot, pairs))
    return out


def _screen(robot, model, thetas):
    _, _, frames = fk_soa(Chain.from_robot(robot), np.ascontiguousarray(thetas.T), frames=True)
    return screen(model, frames)


def test_collision_links_group_geometries(tiago):
    links = {lk.name: lk for lk in collision_links(tiago)}
    assert len(links) == len(set(links))
    assert len(links["torso_lift_link"].geometry_ids) == 3
    assert links["base_link"].joint == 0 and links["arm_1_link"].joint == 2
    assert links["hand_palm_link"].joint == tiago.dof  # the whole hand rides on arm_7
    assert links["hand_index_flex_3_link"].joint == tiago.dof
    assert "hand_safety_box" not in links  # a padding volume the preset ignores


def test_adjacent_pairs_present(tiago_pairs):
    reasons = tiago_pairs.reasons()
    for pair in [
        ("arm_1_link", "arm_2_link"),
        ("arm_1_link", "torso_lift_link"),
        ("base_link", "torso_lift_link"),
        ("arm_6_link", "hand_palm_link"),  # through arm_7_link (no geometry) and fixed joints
        ("arm_6_link", "wrist_ft_link"),
    ]:
        assert reasons[pair] == "adjacent", pair
    # Only pairs on different joints are candidates: the palm and a finger are not.
    assert ("hand_index_abd_link", "hand_palm_link") not in reasons


def test_default_never_and_enabled(tiago, tiago_pairs):
    reasons = tiago_pairs.reasons()
    assert reasons[("arm_1_link", "torso_fixed_column_link")] == "default"
    assert reasons[("arm_2_link", "wheel_left_link")] == "never"
    enabled = set(tiago_pairs.enabled_pairs())
    assert any(a == "base_link" and b.startswith("hand_") for a, b in enabled)  # it reaches down
    counts = tiago_pairs.counts()
    assert counts["enabled"] + len(tiago_pairs.pairs) == counts["candidates"]
    assert tiago_pairs.source == "computed" and tiago_pairs.samples == 2000
    # With the default pair disabled, the home pose is free.
    assert not ExactSelfCollision(tiago, tiago_pairs).colliding(home_thetas(tiago)[None])[0]


def test_srdf_pairs_used_for_pr2(pr2, pr2_pairs):
    assert pr2_pairs.source == "srdf"
    assert {p.reason for p in pr2_pairs.pairs} == {"srdf"}
    listed = srdf_pairs(pr2.srdf_path)
    candidates = set(pr2_pairs.candidates())
    assert {(p.link1, p.link2) for p in pr2_pairs.pairs} == listed & candidates
    assert pr2_pairs.reasons()[("r_shoulder_lift_link", "r_shoulder_pan_link")] == "srdf"
    assert ("base_link", "r_gripper_palm_link") in pr2_pairs.enabled_pairs()


def test_cache_round_trip_and_corrupt_file(tiago, tmp_path, monkeypatch):
    first = disabled_pairs(tiago, samples=300, seed=1, cache_dir=tmp_path)
    (path,) = tmp_path.glob("*.json")
    assert json.loads(path.read_text())["robot_hash"] == tiago.robot_hash

    def boom(*args, **kwargs):
        raise AssertionError("recomputed although cached")

    with monkeypatch.context() as m:
        m.setattr(sc, "_compute", boom)
        again = disabled_pairs(tiago, samples=300, seed=1, cache_dir=tmp_path)
    assert again.pairs == first.pairs and again.samples == 300

    calls = []  # recomputations, stubbed: only the cache logic is under test here
    monkeypatch.setattr(sc, "_compute", lambda *a: calls.append(a) or first.pairs)
    for bad in ["{not json", json.dumps({"format": 1}), path.read_text().replace("never", "nope")]:
        path.write_text(bad)
        assert disabled_pairs(tiago, samples=300, seed=1, cache_dir=tmp_path).pairs == first.pairs
    assert len(calls) == 3
    assert json.loads(path.read_text())["pairs"]  # rewritten, valid

    # Another request (samples) is not served from this file.
    disabled_pairs(tiago, samples=200, seed=1, cache_dir=tmp_path)
    assert len(calls) == 4 and len(list(tmp_path.glob("*.json"))) == 2


def test_bad_samples_rejected(tiago):
    with pytest.raises(InputError):
        disabled_pairs(tiago, samples=0)


def _across_the_boundary(exact, th, col, n, steps):
    """Pairs just either side of the collision boundary: up to ``n`` free and colliding rows
    of ``th`` (``col``: coal's answers), bisected ``steps`` times toward each other."""
    hit, free = th[col][:n], th[~col][:n]
    k = min(len(hit), len(free))
    lo, hi = free[:k], hit[:k]
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        c = exact.colliding(mid)
        hi = np.where(c[:, None], mid, hi)
        lo = np.where(c[:, None], lo, mid)
    return lo, hi


def test_known_self_collision_caught(setups):
    for name, theta in (("tiago", TIAGO_HAND_IN_BASE), ("pr2", PR2_GRIPPER_IN_BASE)):
        robot, _, model, exact = setups[name]
        th = np.array([theta])
        assert exact.colliding(th)[0], name
        assert _screen(robot, model, th)[0], name


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from(["tiago", "pr2"]), seed=st.integers(0, 2**32 - 1))
def test_screen_is_conservative(setups, name, seed):
    """Screen says free => coal says free, on random and on barely colliding configurations."""
    robot, _, model, exact = setups[name]
    rng = np.random.default_rng(seed)
    th = rng.uniform(robot.lower, robot.upper, (200, robot.dof))
    col = exact.colliding(th)
    _, hi = _across_the_boundary(exact, th, col, 6, 12)
    th = np.concatenate([th, hi])
    col = np.concatenate([col, np.ones(len(hi), dtype=bool)])
    flagged = _screen(robot, model, th)
    assert not (col & ~flagged).any(), th[col & ~flagged]


@settings(max_examples=10, deadline=None)
@given(name=st.sampled_from(["tiago", "pr2"]), seed=st.integers(0, 2**32 - 1))
def test_compiled_screen_answers_as_the_numpy_passes(setups, name, seed):
    """screen walks each configuration's trees compiled, depth first: the same answer as the
    breadth-first numpy passes, configuration by configuration (random ones, and ones near
    the collision boundary, where a bound decides), in batches of one to hundreds."""
    from pickstop.robot.screen import _run

    robot, _, model, exact = setups[name]
    rng = np.random.default_rng(seed)
    th = rng.uniform(robot.lower, robot.upper, (300, robot.dof))
    lo, hi = _across_the_boundary(exact, th, exact.colliding(th), 20, 10)
    th = np.concatenate([th, lo, hi])
    chain = Chain.from_robot(robot)
    for B in (1, 7, len(th)):
        _, _, frames = fk_soa(chain, np.ascontiguousarray(th[:B].T), frames=True)
        np.testing.assert_array_equal(screen(model, frames), _run(model, frames, False))


@pytest.mark.parametrize("name", ["tiago", "pr2"])
def test_false_rejection_rate_below_5_percent(setups, name):
    robot, pairs, model, _ = setups[name]
    fig = false_rejection_rate(robot, pairs, model, n=1500, seed=7)
    assert fig["false_acceptances"] == 0
    assert 0.02 < fig["colliding"] < 0.5
    assert fig["false_rejection"] < 0.05, fig


def test_a_tightening_round_rescreens_the_same_trial(setups):
    """A tightening round judges the first round's configurations by its finer screen and
    keeps coal's verdicts on them: the trial equals one made from scratch for that screen."""
    from pickstop.robot.exact import rescreened, screen_trial

    robot, pairs, model, _ = setups["tiago"]
    finer = SphereModel.from_robot(robot, pairs, link_excess=dict.fromkeys(model.link_names, 0.005))
    first = screen_trial(robot, pairs, model, 150, seed=3)
    again = rescreened(robot, first, finer)
    fresh = screen_trial(robot, pairs, finer, 150, seed=3)
    np.testing.assert_array_equal(again.thetas, fresh.thetas)
    np.testing.assert_array_equal(again.colliding, fresh.colliding)
    np.testing.assert_array_equal(again.flagged, fresh.flagged)
    assert (again.flagged != first.flagged).any()  # the finer screen judges some otherwise
    assert again.figures() == fresh.figures()


def test_sphere_cover_holds_every_point(tiago):
    """Points on meshes and inside solids (box, cylinder, sphere) lie in some sphere."""
    rng = np.random.default_rng(0)
    links = {lk.name: lk for lk in collision_links(tiago)}
    for name in ["arm_4_link", "hand_palm_link", "wheel_left_link", "caster_back_left_2_link"]:
        shape = LinkShape.of(tiago, links[name].geometry_ids)
        spheres = cover(shape, excess=0.01)
        pts = []
        for s in shape.shapes:
            if s.tris is not None:
                w = rng.dirichlet([1, 1, 1], size=(len(s.tris), 8))
                pts.append(np.einsum("tsk,tkd->tsd", w, s.tris).reshape(-1, 3))
                pts.append(s.tris.reshape(-1, 3))
            else:
                p = rng.uniform(s.lo, s.hi, (20000, 3))
                pts.append(p[s.sdf(p) <= 0])
        P = np.concatenate(pts)
        gap = np.linalg.norm(P[:, None] - spheres[None, :, :3], axis=2) - spheres[None, :, 3]
        assert (gap.min(axis=1) <= 1e-9).all(), name


def test_distance_grid_is_exact_lower_bound(tiago):
    links = {lk.name: lk for lk in collision_links(tiago)}
    shape = LinkShape.of(tiago, links["arm_3_link"].geometry_ids)
    h = 0.01
    origin = np.floor((shape.lo - 0.05) / h) * h
    dims = tuple(int(v) for v in np.ceil((shape.hi + 0.05 - origin) / h) + 1)
    grid = distance_grid(shape, origin, dims, h)
    idx = np.random.default_rng(1).integers(0, dims, (400, 3))
    nodes = origin + idx * h
    ref = point_triangle_distance(nodes, shape.shapes[0].tris).min(axis=1)
    got = grid[idx[:, 0], idx[:, 1], idx[:, 2]]
    assert (got <= ref + 1e-9).all()
    np.testing.assert_allclose(got[ref < 0.1], ref[ref < 0.1], atol=1e-9)


def test_nothing_disabled_covers_all_candidates(tiago):
    none = DisabledPairs.none(tiago)
    assert none.enabled_pairs() == none.candidates()
    assert all(a < b for a, b in none.candidates())
