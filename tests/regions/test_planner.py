"""Base regions (regions/planner.py and what it composes): verified witnesses, explained
emptiness, precise cache invalidation, off-grid checks, the worker pool."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pickstop.reach.so3 import quats_to_matrices
from pickstop.regions.arm import ExactArm, screen_arm
from pickstop.regions.geojson import read_polygons, regions_geojson
from pickstop.robot.kinematics import Chain, fk, fk_soa
from pickstop.scene.load import parse_scene
from pickstop.scene.world import BoxArrays, scene_solids

from .conftest import add_high_shelf_tray


def _assert_verified(tiago, planner, scene, tray_id, xy, yaw, thetas, grasp_index):
    """Each witness ``thetas: (N, P, dof)`` on its base ``xy: (N, 2)`` reaches its grasp's
    tool pose, keeps the joint limits and is free of the scene and of itself (exact)."""
    from pickstop.robot.artifacts import self_collision
    from pickstop.robot.selfcollision import ExactSelfCollision

    chain = Chain.from_robot(tiago)
    grasps = planner.grasps(scene, scene.tray(tray_id))
    solids = scene_solids(scene)
    exact_arm = ExactArm(tiago)
    exact_self = ExactSelfCollision(tiago, self_collision(tiago, planner.cache_dir)[0])
    c, s = np.cos(yaw), np.sin(yaw)
    for k, gs in enumerate(grasps):
        th = thetas[:, k]
        R, p = fk(chain, th)
        for i in range(len(th)):
            T_wt = gs.Ts_world_tool[grasp_index[i, k]]
            # The tool pose in the world from the witness on its base.
            Rw = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ R[i]
            pw = np.array(
                [
                    c * p[i, 0] - s * p[i, 1] + xy[i, 0],
                    s * p[i, 0] + c * p[i, 1] + xy[i, 1],
                    p[i, 2],
                ]
            )
            assert np.linalg.norm(pw - T_wt[:3, 3]) <= 1e-3
            cosang = (np.trace(Rw.T @ T_wt[:3, :3]) - 1) / 2
            assert np.arccos(np.clip(cosang, -1, 1)) <= np.radians(0.5) + 1e-9
            assert (th[i] >= tiago.lower - 1e-9).all() and (th[i] <= tiago.upper + 1e-9).all()
            assert not exact_arm.colliding(th[i], xy[i, 0], xy[i, 1], yaw, solids)
        assert not exact_self.colliding(th).any()


def test_every_feasible_cell_has_exactly_verified_witnesses(planner, paper_doc, tiago):
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_2")
    assert region.reason is None and len(region.cells) > 20
    xy = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    _assert_verified(
        tiago, planner, scene, "tray_2", xy, region.yaw, region.thetas, region.grasp_index
    )


def test_region_polygon_matches_cells_and_geojson_round_trip(planner, paper_doc):
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")
    assert region.polygon.area == pytest.approx(region.area, rel=1e-9)
    assert region.mask.sum() == len(region.cells)
    doc = json.loads(json.dumps(regions_geojson([region])))
    polys = read_polygons(doc)
    assert polys[("tray_1", region.yaw)].symmetric_difference(region.polygon).area < 1e-9
    props = doc["features"][0]["properties"]
    assert props["cells"] == len(region.cells) and props["area_m2"] == pytest.approx(region.area)


def test_tray_out_of_reach_has_empty_region_with_reason(planner, paper_doc):
    # A tray on a high shelf: the base can stand in front, the arm cannot reach it.
    tray_id = add_high_shelf_tray(paper_doc)
    region = planner.tray_region(parse_scene(paper_doc), tray_id)
    assert len(region.cells) == 0 and region.polygon.is_empty
    assert "part 'hp'" in region.reason and "tray 'high'" in region.reason


def test_tray_beyond_the_grid_explains(planner, paper_doc):
    paper_doc["base_grid"] = {
        "resolution": 0.05,
        "extent": {"min": [-1.0, -1.0], "max": [0.0, 0.0]},
    }
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_4")
    assert len(region.cells) == 0 and "farther than the arm reaches" in region.reason


def test_moving_a_tray_recomputes_only_what_it_affects(planner, paper_doc):
    scene = parse_scene(paper_doc)
    before = {t: planner.tray_region(scene, t) for t in ("tray_1", "tray_2", "tray_4")}
    # tray_4 sits on its own table 2 m away; slide it along that table.
    for t in paper_doc["trays"]:
        if t["id"] == "tray_4":
            t["pose"]["x"] += 0.2
    moved = parse_scene(paper_doc)
    after = {t: planner.tray_region(moved, t) for t in ("tray_1", "tray_2", "tray_4")}
    assert after["tray_1"] is before["tray_1"]
    assert after["tray_2"] is before["tray_2"]
    assert after["tray_4"] is not before["tray_4"]
    # Bring tray_3 (not in the task) right next to tray_2: tray_2's region must be recomputed.
    for t in paper_doc["trays"]:
        if t["id"] == "tray_3":
            t["pose"]["x"] = 1.73
    crowded = parse_scene(paper_doc)
    assert planner.tray_region(crowded, "tray_2") is not after["tray_2"]


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


def test_top_down_grasp_targets_point_down(planner, paper_doc):
    scene = parse_scene(paper_doc)
    hand = planner.hand  # the approach axis is the hand's, in the grasp point's frame
    a_tool = hand.T_tcp_tool[:3, :3].T @ hand.approach
    for gs in planner.grasps(scene, scene.tray("tray_1")):
        assert set(gs.kinds) == {"top"}
        approach = gs.Ts_world_tool[:, :3, :3] @ a_tool
        assert np.allclose(approach, [0, 0, -1], atol=1e-9)
    assert quats_to_matrices(np.array([0.70710678, 0, 0.70710678, 0]))[2, 0] == pytest.approx(
        -1, abs=1e-6
    )


def test_feasible_at_agrees_with_the_grid(planner, paper_doc):
    from pickstop.regions.offgrid import feasible_at, feasible_near

    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_2")
    centres = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    ok, thetas, _ = feasible_at(planner, scene, "tray_2", centres, region.yaw)
    # The database alone, without the grid's growth from neighbouring cells: most cells.
    assert ok.mean() > 0.9
    assert thetas.shape == (len(centres), 1, planner.robot.dof)
    # Seeded by the region's witnesses, as the stop planner asks: every cell.
    ok, _, _ = feasible_near(planner, scene, region, centres, region.yaw)
    assert ok.mean() > 0.99
    far = np.array([[4.5, -0.5], [0.0, 0.0]])
    assert not feasible_at(planner, scene, "tray_2", far, region.yaw)[0].any()


def test_seeds_first_passes_the_same_poses_with_verified_witnesses(planner, paper_doc, tiago):
    """The stop checks try the seeds before the database: the same poses pass as the
    other way round (off the grid, near the region and beyond it), each with a witness
    verified where it stands."""
    from pickstop.regions.offgrid import feasible_near

    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_2")
    rng = np.random.default_rng(7)
    cells = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    xy = cells[rng.integers(len(cells), size=60)] + rng.uniform(-0.12, 0.12, (60, 2))
    # The whole region seeds nearly every pose; a region of its one farthest cell seeds
    # hardly any, so the database must settle them.
    far = np.argmax(np.hypot(*(cells - cells.mean(0)).T))
    thin = dataclasses.replace(
        region,
        cells=region.cells[far : far + 1],
        thetas=region.thetas[far : far + 1],
        grasp_index=region.grasp_index[far : far + 1],
    )
    for r in (region, thin):
        ok, _, _ = feasible_near(planner, scene, r, xy, r.yaw)
        first, th, g = feasible_near(planner, scene, r, xy, r.yaw, seeds_first=True)
        assert (first == ok).all()
        assert 0 < ok.sum() < len(ok)  # some poses pass, some do not
        _assert_verified(tiago, planner, scene, "tray_2", xy[first], r.yaw, th[first], g[first])


def test_a_layout_edited_away_from_and_back_keeps_its_regions(planner, paper_doc):
    """More layouts than a tray keeps regions for are tried around the scene as it is,
    going back to it after each: the regions of the scene as it is stay cached (used last),
    so they serve it again without a recompute once its whole layout is forgotten."""
    from pickstop.regions.planner import LAYOUTS_PER_TRAY

    scene = parse_scene(paper_doc)
    planner.forget()
    before = planner.regions(scene, workers=1)
    for k in range(LAYOUTS_PER_TRAY + 1):
        doc = copy.deepcopy(paper_doc)
        doc["trays"][0]["pose"]["y"] += 0.05 * (k + 1)
        moved = planner.regions(parse_scene(doc), workers=1)
        yaw = scene.base_yaw.yaws[0]
        assert moved["tray_2", yaw] is not before["tray_2", yaw]  # tray_2 computed anew
        assert planner.regions(scene, workers=1) == before
    planner._layouts.clear()  # the scene's layout forgotten: each region from the cache
    computed = []
    real = planner._compute
    planner._compute = lambda *a: computed.append(a) or real(*a)  # type: ignore[method-assign]
    try:
        again = planner.regions(scene, workers=1)
    finally:
        del planner._compute
    assert computed == [] and all(again[p] is before[p] for p in before)


def test_parallel_regions_equal_serial(planner, paper_doc):
    scene = parse_scene(paper_doc)
    planner.forget()
    serial = planner.regions(scene, workers=1)
    planner.forget()  # nor the layout's regions: the workers compute every one
    try:
        parallel = planner.regions(scene, workers=2)
    finally:
        planner.close()
    assert serial.keys() == parallel.keys()
    for k in serial:
        np.testing.assert_array_equal(serial[k].mask, parallel[k].mask)
        np.testing.assert_allclose(serial[k].thetas, parallel[k].thetas)
        assert parallel[k] is not serial[k]  # computed by a worker, not taken from a memo


def test_forget_drops_every_kept_region(planner, paper_doc):
    scene = parse_scene(paper_doc)
    first = planner.regions(scene)
    again = planner.regions(scene)
    assert all(again[k] is first[k] for k in first)  # the layout's regions, as they were
    assert planner.known_regions(scene, list(first)).keys() == first.keys()
    planner.forget()
    assert planner.known_regions(scene, list(first)) == {}
    fresh = planner.regions(scene)
    for k in first:
        assert fresh[k] is not first[k]
        np.testing.assert_array_equal(fresh[k].cells, first[k].cells)
        np.testing.assert_array_equal(fresh[k].thetas, first[k].thetas)


def test_region_processes_want_one_process_at_least(planner):
    from pickstop.regions.processes import RegionProcesses

    with pytest.raises(ValueError, match="processes must be at least 1, got 0"):
        RegionProcesses(planner, 0)


def test_touching_cells_merge_into_one_polygon():
    """Cells share bit-identical edges, so a solid block is one polygon with its holes."""
    import numpy as np

    from pickstop.regions.cells import CellGrid

    grid = CellGrid(x0=-1.1, y0=0.37, res=0.025, nx=40, ny=30)
    mask = np.ones((30, 40), bool)
    mask[10:14, 20:25] = False  # a hole
    iy, ix = np.nonzero(mask)
    poly = grid.cells_polygon(iy, ix)
    assert poly.geom_type == "Polygon" and len(poly.interiors) == 1
    assert abs(poly.area - mask.sum() * 0.025**2) < 1e-9


def test_a_mesh_obstacle_from_a_relative_path_blocks_base_cells(planner, tmp_path):
    import json as _json

    from pickstop.scene.load import load_scene
    from tests.scene.test_scene_model import write_box_stl

    doc = _json.loads(
        (Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json").read_text()
    )
    (tmp_path / "scene.json").write_text(_json.dumps(doc))
    before = planner.tray_region(load_scene(tmp_path / "scene.json"), "tray_4")
    write_box_stl(tmp_path / "pillar.stl", 0.3, 0.3, 1.5)
    doc["obstacles"].append({"id": "pillar", "geometry": {"shape": "mesh", "path": "pillar.stl"},
                             "pose": {"x": 3.6, "y": 0.8}})  # fmt: skip
    (tmp_path / "scene.json").write_text(_json.dumps(doc))
    after = planner.tray_region(load_scene(tmp_path / "scene.json"), "tray_4")
    assert 0 < len(after.cells) < len(before.cells)
    centres = after.grid.centres(after.cells[:, 1], after.cells[:, 0])
    # The footprint (TIAGo's derived outline) stays clear of the pillar at every cell (2 mm:
    # the buffer's polygon).
    import shapely
    from shapely import affinity

    pillar = shapely.box(3.45 + 2e-3, 0.65 + 2e-3, 3.75 - 2e-3, 0.95 - 2e-3)
    outline = affinity.rotate(
        shapely.Polygon(planner.robot.footprint.polygon), after.yaw, origin=(0, 0), use_radians=True
    )
    for x, y in centres:
        assert not affinity.translate(outline, x, y).intersects(pillar)


def test_growth_recovers_cells_from_their_neighbours_witnesses(planner, paper_doc):
    """Cells the database pass did not reach are grown into from solved neighbours, and
    every grown cell carries a witness that passes the exact checks."""
    from pickstop.regions import solve
    from pickstop.regions.envelope import Envelope
    from pickstop.regions.pipeline import tray_world
    from pickstop.regions.reference import verify_witnesses

    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")
    tray = scene.tray("tray_1")
    ij = region.cells
    cen = region.grid.centres(ij[:, 1], ij[:, 0])
    # Forget a band of four columns across the region: the rest's witnesses are the seeds.
    mid = int(np.median(ij[:, 1]))
    found = (ij[:, 1] < mid) | (ij[:, 1] >= mid + 4)
    thetas = np.where(found[:, None, None], region.thetas, 0.0)
    grasp = np.where(found[:, None], region.grasp_index, 0)
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, region.yaw)
    world = solve.ArmWorld(
        boxes, solids, region.yaw, Envelope.empty(scene.floor.min, scene.floor.max)
    )
    targets = [solve.Targets.of(gs, cen, R_base_world) for gs in planner.grasps(scene, tray)]
    forgotten = int((~found).sum())
    added = solve.grow(planner, world, targets, cen, ij, found, thetas, grasp)
    assert added == int(found.sum()) - (len(ij) - forgotten)
    assert added >= 0.9 * forgotten  # ring by ring, from both sides of the band
    grown = type(region)(
        **{
            **region.__dict__,
            "cells": ij[found],
            "thetas": thetas[found],
            "grasp_index": grasp[found],
        }
    )
    check = verify_witnesses(planner, scene, grown)
    assert check.failures == 0 and check.witnesses == int(found.sum()) * len(tray.parts)


def test_witnesses_clear_sees_an_object_on_a_witness_arm(planner, paper_doc):
    from pickstop.regions.validity import witnesses_clear
    from pickstop.robot.kinematics import Chain, fk_soa
    from pickstop.scene.world import Solid

    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")
    T_far = np.eye(4)
    T_far[:3, 3] = (-30.0, -30.0, 0.5)
    assert witnesses_clear(planner, region, [Solid.box(T_far, (0.2, 0.2, 0.2), "far")])
    # A small box around the elbow of the first cell's first witness.
    chain = Chain.from_robot(planner.robot)
    _, _, frames = fk_soa(chain, region.thetas[0, 0][:, None], frames=True)
    elbow = frames[3][1][:, 0]
    c, s = np.cos(region.yaw), np.sin(region.yaw)
    x, y = region.grid.centres(region.cells[:1, 1], region.cells[:1, 0])[0]
    T = np.eye(4)
    T[:3, 3] = (x + c * elbow[0] - s * elbow[1], y + s * elbow[0] + c * elbow[1], elbow[2])
    assert not witnesses_clear(planner, region, [Solid.box(T, (0.03, 0.03, 0.03), "elbow")])


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.integers(0, 10_000), st.floats(0.01, 0.3), st.floats(-0.15, 0.15))
def test_witness_boxes_hold_every_witness_the_screen_flags(planner, paper_doc, seed, size, off):
    """A box near some joint of a witness arm: every witness the sphere screen flags against
    it has a witness box that meets the solid's bounds (so witnesses_clear may skip the rest),
    and witnesses_clear says the same with the boxes as without."""
    from pickstop.regions.validity import witness_boxes, witnesses_clear
    from pickstop.scene.world import Solid

    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")
    K, P, dof = region.thetas.shape
    rng = np.random.default_rng(seed)
    k, j = int(rng.integers(K)), int(rng.integers(1, dof + 2))
    R_t, p_t, frames = fk_soa(planner.solver.chain, region.thetas[k, 0][:, None], frames=True)
    # at a joint, or past the tool frame along the approach, where the fingers reach
    p = (frames[j - 1][1][:, 0] if j <= dof else p_t[:, 0] + 0.09 * R_t[:, 0, 0]) + off
    c, s_ = np.cos(region.yaw), np.sin(region.yaw)
    x, y = region.grid.centres(region.cells[k : k + 1, 1], region.cells[k : k + 1, 0])[0]
    T = np.eye(4)
    T[:3, :3] = quats_to_matrices(rng.normal(size=(1, 4)))[0]
    T[:3, 3] = (x + c * p[0] - s_ * p[1], y + s_ * p[0] + c * p[1], p[2])
    solid = Solid.box(T, (size, 0.5 * size, 0.03), "probe")
    lo, hi = witness_boxes(planner, region)
    a, b = solid.aabb()
    meets = np.all((lo <= b) & (a <= hi), axis=1)
    xy = np.repeat(region.grid.centres(region.cells[:, 1], region.cells[:, 0]), P, axis=0)
    th = region.thetas.reshape(K * P, dof)
    _, _, fr = fk_soa(planner.solver.chain, np.ascontiguousarray(th.T), frames=True)
    flagged = screen_arm(planner.arm, BoxArrays.of([solid]), fr, xy, region.yaw)
    assert not (flagged & ~meets).any()
    assert witnesses_clear(planner, region, [solid], (lo, hi)) == witnesses_clear(
        planner, region, [solid]
    )


def test_grasps_are_reused_while_nothing_reaches_into_the_hands(planner, paper_doc, monkeypatch):
    from pickstop.regions import kit as kit_module

    calls = []
    real = kit_module.grasps_for_part
    monkeypatch.setattr(kit_module, "grasps_for_part", lambda *a: calls.append(a[2].id) or real(*a))

    def same(a, b):
        return all(
            np.array_equal(x.Ts_world_tool, y.Ts_world_tool) and x.kinds == y.kinds
            for x, y in zip(a, b, strict=True)
        )

    scene = parse_scene(paper_doc)
    before = planner.grasps(scene, scene.tray("tray_4"))
    n = len(calls)
    far = copy.deepcopy(paper_doc)
    next(t for t in far["trays"] if t["id"] == "tray_2")["pose"]["x"] += 0.05
    moved = parse_scene(far)
    assert same(planner.grasps(moved, moved.tray("tray_4")), before) and len(calls) == n
    # tray_4 slid 5 cm along its table: the same grasps in the tray's frame, not computed anew
    slid = copy.deepcopy(paper_doc)
    next(t for t in slid["trays"] if t["id"] == "tray_4")["pose"]["x"] += 0.05
    slid_scene = parse_scene(slid)
    again = planner.grasps(slid_scene, slid_scene.tray("tray_4"))
    assert len(calls) == n
    fresh = [
        real(slid_scene, slid_scene.tray("tray_4"), p, planner.hand)
        for p in slid_scene.tray("tray_4").parts
    ]
    assert same(again, fresh)
    # A board just above tray_4, where the open hands of top-down grasps would be.
    near = copy.deepcopy(paper_doc)
    near["obstacles"].append(
        {
            "id": "board",
            "pose": {"x": 3.6, "y": 1.5, "z": 0.84, "yaw": 0.0},
            "geometry": {"shape": "box", "size": [0.3, 0.2, 0.02]},
        }
    )
    covered = parse_scene(near)
    after = planner.grasps(covered, covered.tray("tray_4"))
    assert len(calls) > n
    assert sum(len(g.Ts_world_tool) for g in after) < sum(len(g.Ts_world_tool) for g in before)


def test_candidates_the_screen_flags_go_to_the_exact_check(planner, paper_doc, monkeypatch):
    """The sphere screen is conservative: a database candidate it flags may well be free.
    With a screen that flags everything, the cells are still solved, by coal alone, and each
    witness holds exactly: on its grasp, free of the scene and of itself."""
    from pickstop.regions import solve
    from pickstop.regions.envelope import Envelope
    from pickstop.regions.pipeline import tray_world
    from pickstop.regions.reference import pose_ok

    scene = parse_scene(paper_doc)
    tray = scene.tray("tray_4")
    region = planner.tray_region(scene, "tray_4")
    ij = region.cells[:: max(1, len(region.cells) // 30)]
    cen = region.grid.centres(ij[:, 1], ij[:, 0])
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, region.yaw)
    world = solve.ArmWorld(
        boxes, solids, region.yaw, Envelope.empty(scene.floor.min, scene.floor.max)
    )
    gs = planner.grasps(scene, tray)[0]
    tg = solve.Targets.of(gs, cen, R_base_world)

    def flag_all(spheres, boxes, frames, base_xy, *args, **kwargs):
        return np.ones(len(base_xy), bool)

    monkeypatch.setattr(solve, "screen_arm", flag_all)
    found, thetas, grasp = solve.solve_part(planner, world, tg, cen)
    # Two rounds of at most three candidates per cell, no growth: about half the region's
    # cells (none when flagged candidates were dropped).
    assert found.sum() >= len(ij) // 3
    th = thetas[found]
    Rs, ps = tg.Rs_base_tool[grasp[found]], tg.ps_base_tool[np.flatnonzero(found), grasp[found]]
    assert pose_ok(planner.solver, th, Rs, ps).all()
    assert not planner.exact_self.colliding(th).any()
    for t, (x, y) in zip(th, cen[found], strict=True):
        assert not planner.exact_arm.colliding(t, x, y, region.yaw, solids, gs.part_id)


def test_a_preview_carries_the_nearest_region_with_cells_and_takes_a_held_region_as_it_is(
    planner, paper_doc
):
    """Once a tray was planned out of reach (its region empty), a preview of it back near its
    first place carries the region computed there, not the empty one; where a cached region
    still holds, the preview takes it exactly as computed."""
    home = parse_scene(paper_doc)
    pair = ("tray_2", home.base_yaw.yaws[0])
    first = planner.tray_region(home, *pair)
    assert len(first.cells) > 20

    def moved(dx: float = 0.0, dz: float = 0.0):
        doc = copy.deepcopy(paper_doc)
        tray = next(t for t in doc["trays"] if t["id"] == "tray_2")
        tray["pose"]["x"] += dx
        tray["pose"]["z"] += dz
        if dz:  # raised on a column standing on its table
            size = [0.4, 0.3, dz]
            pose = {"x": tray["pose"]["x"], "y": tray["pose"]["y"], "z": 0.72}
            doc["obstacles"].append({"id": "column", "geometry": {"shape": "box", "size": size},
                                     "pose": pose})  # fmt: skip
        return parse_scene(doc)

    high = moved(dz=1.5)  # out of the arm's reach: planned empty, now the newest region
    assert len(planner.tray_region(high, *pair).cells) == 0
    assert len(planner.known_regions(high, [pair])[pair].cells) == 0

    assert planner.known_regions(home, [pair])[pair] is first  # held: taken as it is
    near = planner.known_regions(moved(dx=0.05), [pair])[pair]
    assert near.key == f"carried:{first.key}" and len(near.cells) > 0.8 * len(first.cells)
    res = first.grid.res
    xy = first.grid.centres(first.cells[:, 1], first.cells[:, 0])
    got = near.grid.centres(near.cells[:, 1], near.cells[:, 0])
    # every carried cell is a first cell moved with the tray (to within the grid's snap)
    gap = np.abs(got[:, None, :] - (xy + np.array([0.05, 0.0]))[None]).max(axis=2).min(axis=1)
    assert (gap <= res + 1e-9).all()


def test_a_turned_tray_carries_its_region_whole(planner, paper_doc):
    """A preview of a turned tray carries its region turned about the tray, without the holes
    a turned grid falling out of step with the grid would leave: its shape has no more holes
    than the region's, about its area (but for the footprint), and each carried cell comes
    from a cell of the region, turned back."""
    import shapely

    scene = parse_scene(paper_doc)
    pair = ("tray_2", scene.base_yaw.yaws[0])
    first = planner.tray_region(scene, *pair)
    doc = copy.deepcopy(paper_doc)
    tray = next(t for t in doc["trays"] if t["id"] == "tray_2")
    tray["pose"]["yaw"] = 0.3
    turned = parse_scene(doc)
    got = planner.known_regions(turned, [pair])[pair]
    assert got.key == f"carried:{first.key}"

    def holes(region) -> int:
        geoms = getattr(region.polygon, "geoms", [region.polygon])
        return sum(len(g.interiors) for g in geoms if isinstance(g, shapely.Polygon))

    assert holes(got) <= holes(first)
    assert 0.8 * len(first.cells) <= got.counts["footprint_free"] <= 1.1 * len(first.cells)
    t = scene.tray("tray_2").pose
    c, s = np.cos(-0.3), np.sin(-0.3)
    xy = got.grid.centres(got.cells[:, 1], got.cells[:, 0]) - [t.x, t.y]
    back = xy @ np.array([[c, s], [-s, c]]) + [t.x, t.y]
    g = first.grid
    ix = np.floor((back[:, 0] - g.x0) / g.res).astype(int)
    iy = np.floor((back[:, 1] - g.y0) / g.res).astype(int)
    assert first.mask[iy, ix].all()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.booleans()), min_size=0, max_size=60)
)
def test_open_cells_near_solved_ones_are_those_a_bucket_away(points):
    """The cells that also query the vicinity: those in the bucket of a solved one, or in
    one of the eight around it (buckets of the vicinity distance)."""
    from pickstop.regions.solve import _near_found

    cen = np.array([p[:2] for p in points], float).reshape(-1, 2)
    found = np.array([p[2] for p in points], bool)
    key = np.floor(cen / 0.05).astype(int)
    want = [
        any(f and np.abs(key[i] - key[j]).max() <= 1 for j, f in enumerate(found))
        for i in range(len(cen))
    ]
    assert _near_found(cen, found, 0.05).tolist() == want


def test_the_regions_kept_for_previews_stay_within_their_bound(paper_doc):
    """A few poses per tray, and no more regions in all than the bound: the tray remembered
    least recently goes first."""
    from types import SimpleNamespace

    from pickstop.regions.carry import LastRegions

    last = LastRegions(size=5, per_tray=4)

    def at(tray_id: str, dx: float):
        doc = copy.deepcopy(paper_doc)
        next(t for t in doc["trays"] if t["id"] == tray_id)["pose"]["x"] += dx
        return parse_scene(doc)

    fake = {
        t: SimpleNamespace(tray_id=t, yaw=0.0, cells=np.zeros((1, 2))) for t in ("tray_1", "tray_2")
    }
    for k in range(6):
        last.remember(at("tray_1", 0.01 * k), fake["tray_1"])
    assert len(last) == 4  # the four newest poses of tray_1
    last.remember(at("tray_1", 0.03), fake["tray_1"])  # a pose kept already: no second copy
    assert len(last) == 4
    for k in range(3):
        last.remember(at("tray_2", 0.01 * k), fake["tray_2"])
    assert len(last) == 3  # tray_1's four went to make room
