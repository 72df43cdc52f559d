"""Work reused across tray positions gives the regions a computation from scratch gives."""

from __future__ import annotations

import copy

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pickstop.regions.pipeline import compute_tray_region
from pickstop.regions.reuse import ReuseCache, TrayAnchor
from pickstop.scene.load import parse_scene
from pickstop.scene.model import SceneError
from tests.utils import assert_cells_verified


def _moved(doc, tray_id, dx, dy):
    doc = copy.deepcopy(doc)
    for t in doc["trays"]:
        if t["id"] == tray_id:
            t["pose"]["x"] += dx
            t["pose"]["y"] += dy
    try:
        return parse_scene(doc)
    except SceneError:
        return None  # the move put the tray into a neighbour or off its table


def _from_scratch(planner, scene, tray_id):
    kept, planner.reuse = planner.reuse, ReuseCache()
    try:
        return compute_tray_region(planner, scene, scene.tray(tray_id), scene.base_yaw.yaws[0])
    finally:
        planner.reuse = kept


@settings(
    max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    tray=st.sampled_from(["tray_1", "tray_2", "tray_3"]),
    di=st.integers(-20, 20),
    dj=st.integers(-8, 8),
    fraction=st.sampled_from([0.0, 0.0, 0.0, 0.4]),
)
def test_moved_tray_regions_match_from_scratch(planner, paper_doc, tray, di, dj, fraction):
    """A tray moved by whole cells (and sometimes part of one) on a warm planner: the same
    verified cells as from scratch, or more, each extra one with exactly verified witnesses;
    its neighbours likewise (the moved tray is in their way)."""
    scene0 = parse_scene(paper_doc)
    res = scene0.base_grid.resolution
    for t in scene0.task_trays:  # warm: every tray's refinements at the starting layout
        planner.tray_region(scene0, t)
    scene = _moved(paper_doc, tray, (di + fraction) * res, dj * res)
    assume(scene is not None)
    for tid in scene.task_trays:
        before = sum(m.hits for m in planner.reuse.values())
        reused = compute_tray_region(planner, scene, scene.tray(tid), scene.base_yaw.yaws[0])
        if fraction == 0.0 and reused.reason is None:
            assert sum(m.hits for m in planner.reuse.values()) > before  # the memo was used
        scratch = _from_scratch(planner, scene, tid)
        assert not (scratch.mask & ~reused.mask).any(), f"{tid}: a cell from scratch is missing"
        extra = np.flatnonzero(~scratch.mask[reused.cells[:, 0], reused.cells[:, 1]])
        assert_cells_verified(planner, scene, reused, extra)
        if tid == tray:
            assert reused.counts["feasible"] == len(reused.cells)


def test_anchor_keys_follow_the_tray():
    """Cells at the same offset from a tray get the same key wherever the tray stands."""
    from pickstop.scene.model import Pose, Tray

    def tray(x, y):
        return Tray(id="t", pose=Pose(x=x, y=y), inner_size=(0.2, 0.2))

    a = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.5, 0.3))
    b = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.5 + 7 * 0.025, 0.3 - 3 * 0.025))
    c = TrayAnchor.of(-1.0, -1.0, 0.025, tray(0.51, 0.3))
    assert a.phase == b.phase and a.phase != c.phase
    ix, iy = np.arange(5), np.arange(5)
    assert (a.cell_keys(ix, iy) == b.cell_keys(ix + 7, iy - 3)).all()
    assert len(set(a.cell_keys(ix, iy).tolist())) == 5


def test_a_preview_carries_only_the_same_tray(planner, paper_doc):
    """A region is carried to a tray of the same id only if it is the same tray (pose aside)
    under the same settings: another scene's tray_1, with other parts, is not carried."""
    scene = parse_scene(paper_doc)
    yaw = scene.base_yaw.yaws[0]
    planner.regions(scene)
    moved = _moved(paper_doc, "tray_1", -0.05, 0.0)
    assert moved is not None
    assert set(planner.known_regions(moved, [("tray_1", yaw)])) == {("tray_1", yaw)}
    other = copy.deepcopy(paper_doc)
    other["trays"][0]["parts"] = other["trays"][0]["parts"][:1]
    assert planner.known_regions(parse_scene(other), [("tray_1", yaw)]) == {}
    finer = copy.deepcopy(paper_doc)
    finer["floor_clearance"] = 0.02
    assert planner.known_regions(parse_scene(finer), [("tray_1", yaw)]) == {}
