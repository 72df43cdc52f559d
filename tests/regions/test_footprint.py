"""The base itself: footprint on the floor, base-fixed links under overhangs."""

from __future__ import annotations

import copy
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from pickstop.frames import R_z
from pickstop.regions.footprint import (
    blocked_by,
    floor_outline,
    footprint_free,
    upper_body,
)
from pickstop.robot.link_geometry import collision_links
from pickstop.scene.load import parse_scene
from pickstop.scene.world import Solid, _coal, collide, scene_solids


def _fixed_body_hits(robot, solids, x: float, y: float, yaw: float) -> bool:
    """coal: do the base-fixed links above the footprint touch any of ``solids``?"""
    fp = robot.footprint
    T_wb = pin.SE3(pin.rpy.rpyToMatrix(0, 0, yaw), np.array([x, y, 0.0]))
    for link in collision_links(robot):
        if link.joint != 0:
            continue
        for gid in link.geometry_ids:
            obj = robot.geom_model.geometryObjects[gid]
            M = T_wb * obj.placement
            tf = coal.Transform3s(M.rotation, M.translation)
            for s in solids:
                if s.aabb()[0][2] < fp.height:
                    continue  # the footprint's business
                if collide(obj.geometry, tf, *_coal(s)):
                    return True
    return False


def test_an_overhang_blocks_the_torso_not_the_footprint(tiago, paper_doc):
    doc = copy.deepcopy(paper_doc)
    # A shelf board at 0.55-0.60 m over open floor: no footprint touches it, the torso does.
    doc["obstacles"].append(
        {
            "id": "shelf_board",
            "pose": {"x": 2.5, "y": 0.0, "z": 0.55, "yaw": 0.3},
            "geometry": {"shape": "box", "size": [0.8, 0.6, 0.05]},
        }
    )
    scene = parse_scene(doc)
    yaw = scene.base_yaw.yaws[0]
    xs, ys = np.meshgrid(np.arange(1.6, 3.4, 0.05), np.arange(-0.7, 0.7, 0.05))
    centres = np.column_stack([xs.ravel(), ys.ravel()])
    free = footprint_free(scene, tiago, centres, yaw)
    solids = [s for s in scene_solids(scene) if s.owner == "shelf_board"]
    hits = np.array([_fixed_body_hits(tiago, solids, x, y, yaw) for x, y in centres])
    assert hits.sum() > 50, "the torso column reaches into the board over many positions"
    assert not (free & hits).any(), "free is guaranteed: no free position touches the board"
    # Conservative only by the links' bounding boxes: the blocked band is narrow.
    assert (~free & ~hits).sum() < 0.6 * hits.sum()
    # Without the board those positions are all free: it is the upper body that blocks them.
    doc["obstacles"].pop()
    assert footprint_free(parse_scene(doc), tiago, centres, yaw).all()


def test_upper_body_of_tiago_is_its_torso_column_and_antennas(tiago):
    body = upper_body(tiago)
    fp = tiago.footprint  # derived from the base's collision geometry
    assert len(body.boxes) >= 3 and (body.boxes[:, 0, 2] >= fp.height).all()
    assert 0.8 < body.top < 0.9  # the torso column's top
    assert body.radius == fp.bounding_radius  # inside the base's circle from above


def test_routes_drive_around_an_overhang(planner, paper_doc):
    from pickstop.speedups.stop_planner import StopPlanner

    doc = copy.deepcopy(paper_doc)
    floor = StopPlanner(planner).floor(parse_scene(doc))
    assert floor.fmap.is_free((2.5, 0.0))
    doc["obstacles"].append(
        {
            "id": "shelf_board",
            "pose": {"x": 2.5, "y": 0.0, "z": 0.55, "yaw": 0.0},
            "geometry": {"shape": "box", "size": [0.8, 0.6, 0.05]},
        }
    )
    floor = StopPlanner(planner).floor(parse_scene(doc))
    assert not floor.fmap.is_free((2.5, 0.0)) and not floor.fmap.is_free((2.5, 0.5))


def test_a_board_over_free_cells_invalidates_the_cached_region(planner, paper_doc):
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")

    def with_board(x: float, y: float):
        doc = copy.deepcopy(paper_doc)
        doc["obstacles"].append(
            {
                "id": "board",
                "pose": {"x": x, "y": y, "z": 0.55, "yaw": 0.0},
                "geometry": {"shape": "box", "size": [0.6, 0.4, 0.05]},
            }
        )
        return parse_scene(doc)

    assert planner.tray_region(with_board(4.6, -0.7), "tray_1") is region  # out of reach
    cx, cy = region.grid.centres(region.cells[:, 1], region.cells[:, 0]).mean(axis=0)
    over = planner.tray_region(with_board(cx, cy), "tray_1")
    assert over is not region and 0 < len(over.cells) < len(region.cells)
    xy = over.grid.centres(over.cells[:, 1], over.cells[:, 0])
    board = [s for s in scene_solids(with_board(cx, cy)) if s.owner == "board"]
    assert not any(_fixed_body_hits(planner.robot, board, x, y, over.yaw) for x, y in xy)
    # Taken away again, the first region is valid again.
    assert planner.tray_region(scene, "tray_1") is region


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_blocked_positions_are_those_where_the_body_touches(tiago, seed):
    """Tilted boxes low and high around the base: a position is blocked exactly where the
    footprint (TIAGo's: a convex polygon) at the yaw meets a low box's floor outline, or an
    upper-body box meets a high one's while their heights overlap. The same again with one
    box moved: its pieces alone are made anew."""
    rng = np.random.default_rng(seed)
    fp = tiago.footprint
    assert fp.radius is None  # the convex polygon's exact Minkowski difference
    body = upper_body(tiago)
    yaw = float(rng.uniform(-np.pi, np.pi))
    R = R_z(yaw)[:2, :2]
    solids = []
    for k in range(6):
        T = np.eye(4)
        T[:3, :3] = R_z(float(rng.uniform(0, np.pi)))
        z = rng.uniform(0.0, 0.2) if k % 2 else rng.uniform(0.6, 1.0)
        T[:3, 3] = [*rng.uniform(-1.0, 1.0, 2), z]
        solids.append(Solid.box(T, rng.uniform([0.1, 0.1, 0.05], [0.8, 0.8, 0.4]), f"s{k}"))
    xy = rng.uniform(-1.4, 1.4, (300, 2))
    foot = np.asarray(fp.polygon) @ R.T
    rects = [
        (np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]) @ R.T, lo, hi)
        for lo, hi in body.boxes
    ]

    def want(solids):
        low = np.zeros(len(xy), bool)
        high = np.zeros(len(xy), bool)
        for s in solids:
            lo, hi = s.aabb()
            outline = shapely.Polygon(floor_outline(s))
            for i, c in enumerate(xy):
                if lo[2] < fp.height and shapely.Polygon(foot + c).intersects(outline):
                    low[i] = True
                for rect, blo, bhi in rects:
                    if blo[2] < hi[2] and bhi[2] > lo[2]:
                        high[i] |= shapely.Polygon(rect + c).intersects(outline)
        return low, high

    for k in range(2):
        low, high = want(solids)
        if k == 0:  # a layout where both bodies block somewhere, and not everywhere
            assume(low.any() and high.any() and not (low | high).all())
        assert np.array_equal(blocked_by(tiago, solids, xy, yaw, upper=False), low)
        assert np.array_equal(blocked_by(tiago, solids, xy, yaw, footprint=False), high)
        T = solids[1].T_world_solid.copy()
        T[:2, 3] += rng.uniform(-0.3, 0.3, 2)
        solids[1] = Solid.box(T, 2 * solids[1].half, "s1")


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
