"""The region planner (speedups/region_planner.py): verified witnesses through its facade,
the regions of recent layouts it keeps, serial and parallel alike, forgetting them."""

from __future__ import annotations

import copy

import numpy as np

from pickstop.scene.load import parse_scene
from tests.regions.helpers import assert_verified


def test_every_feasible_cell_has_exactly_verified_witnesses(planner, paper_doc, tiago):
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_2")
    assert region.reason is None and len(region.cells) > 20
    xy = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    assert_verified(
        tiago, planner, scene, "tray_2", xy, region.yaw, region.thetas, region.grasp_index
    )


def test_a_layout_edited_away_from_and_back_keeps_its_regions(planner, paper_doc):
    """More layouts than a tray keeps regions for are tried around the scene as it is,
    going back to it after each: the regions of the scene as it is stay cached (used last),
    so they serve it again without a recompute once its whole layout is forgotten."""
    from pickstop.speedups.region_planner import LAYOUTS_PER_TRAY

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
    real = planner.compute_region
    planner.compute_region = lambda *a: computed.append(a) or real(*a)  # type: ignore[method-assign]
    try:
        again = planner.regions(scene, workers=1)
    finally:
        del planner.compute_region
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
    planner.forget()  # what earlier tests left would make the first regions reused ones
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


def test_a_planner_that_reuses_nothing_across_layouts_computes_as_from_scratch(planner, paper_doc):
    """``across_layouts=False`` (the layout search's verification): no memo is kept, and each
    region is the pipeline's from scratch, bit for bit."""
    from pickstop.regions import pure
    from pickstop.speedups.region_planner import RegionPlanner

    fresh = RegionPlanner(planner.robot, planner.db, cache_dir=planner.cache_dir,
                          across_layouts=False)  # fmt: skip
    scene = parse_scene(paper_doc)
    yaw = scene.base_yaw.yaws[0]
    for tray in ("tray_1", "tray_4"):
        got = fresh.tray_region(scene, tray)
        ref = pure.tray_region(planner.scratch(), scene, tray, yaw)
        assert got.key == ref.key and got.counts == ref.counts
        for a, b in ((got.cells, ref.cells), (got.thetas, ref.thetas)):
            assert np.array_equal(a, b)
    assert len(fresh.reuse) == 0
    fresh.close()


def test_the_planner_keeps_what_its_kit_derives_and_a_scratch_kit_keeps_nothing(planner, paper_doc):
    """The planner hands its kit bounded caches (``KEPT``) and hangs the footprint's on the
    robot; a scratch kit asks a ``KeepNothing`` and checks the arm with its own, and its
    regions are the planner's, bit for bit."""
    from pickstop.caching import Cache
    from pickstop.regions import pure
    from pickstop.regions.keep import KeepNothing
    from pickstop.speedups.region_planner import KEPT

    scene = parse_scene(paper_doc)
    yaw = scene.base_yaw.yaws[0]
    got = planner.compute_region(scene, "tray_3", yaw)
    kept = [planner.grasp_memo, planner._hand_spaces, planner._bounds, planner._own_verdicts,
            planner.exact_arm._bounds_memo]  # fmt: skip
    assert [c.name for c in kept] == list(KEPT) and all(isinstance(c, Cache) for c in kept)
    assert len(planner.grasp_memo) > 0 and len(planner.robot.derived.blocked_pieces) > 0
    scratch = planner.scratch()
    mine = [scratch.grasp_memo, scratch._hand_spaces, scratch._bounds, scratch._own_verdicts,
            scratch.exact_arm._bounds_memo]  # fmt: skip
    assert all(isinstance(k, KeepNothing) for k in mine)
    assert scratch.exact_arm is not planner.exact_arm
    ref = pure.tray_region(scratch, scene, "tray_3", yaw)
    assert list(scratch.grasp_memo) == [] and got.key == ref.key
    assert np.array_equal(got.cells, ref.cells) and np.array_equal(got.thetas, ref.thetas)
