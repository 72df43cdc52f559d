"""Solving cells (regions/solve.py): the database pass, the exact check, growth from neighbours."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.scene.load import parse_scene


def test_growth_recovers_cells_from_their_neighbours_witnesses(planner, paper_doc):
    """Cells the database pass did not reach are grown into from solved neighbours, and
    every grown cell carries a witness that passes the exact checks."""
    from pickstop.regions import solve
    from pickstop.regions.arm import ArmWorld
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
    world = ArmWorld(boxes, solids, region.yaw, Envelope.empty(scene.floor.min, scene.floor.max))
    targets = [solve.Targets.of(gs, cen, R_base_world) for gs in planner.grasps(scene, tray)]
    forgotten = int((~found).sum())
    added = solve.grow(planner, world, targets, cen, ij, found, thetas, grasp)
    assert added == int(found.sum()) - (len(ij) - forgotten)
    assert added >= 0.9 * forgotten  # ring by ring, from both sides of the band
    # replace(), not the instance's __dict__: that holds cached properties (the digest) once
    # another test has read them
    grown = dataclasses.replace(
        region, cells=ij[found], thetas=thetas[found], grasp_index=grasp[found]
    )
    check = verify_witnesses(planner, scene, grown)
    assert check.failures == 0 and check.witnesses == int(found.sum()) * len(tray.parts)


def test_candidates_the_screen_flags_go_to_the_exact_check(planner, paper_doc, monkeypatch):
    """The sphere screen is conservative: a database candidate it flags may well be free.
    With a screen that flags everything, the cells are still solved, by coal alone, and each
    witness holds exactly: on its grasp, free of the scene and of itself."""
    from pickstop.regions import solve
    from pickstop.regions.arm import ArmWorld
    from pickstop.regions.envelope import Envelope
    from pickstop.regions.pipeline import tray_world
    from pickstop.regions.reference import pose_ok

    scene = parse_scene(paper_doc)
    tray = scene.tray("tray_4")
    region = planner.tray_region(scene, "tray_4")
    ij = region.cells[:: max(1, len(region.cells) // 30)]
    cen = region.grid.centres(ij[:, 1], ij[:, 0])
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, region.yaw)
    world = ArmWorld(boxes, solids, region.yaw, Envelope.empty(scene.floor.min, scene.floor.max))
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
