"""Shared assertions and factories for the tests."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pickstop.robot.config import example_robot_data_share

TIAGO_URDF = (
    example_robot_data_share() / "example-robot-data/robots/tiago_description/robots/tiago.urdf"
)


def random_thetas(robot, n: int, seed: int = 0) -> np.ndarray:
    """``(n, dof)`` joint values uniform within the robot's limits."""
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))


def write_config(folder: Path, text: str, name: str = "robot.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


TIAGO_CONFIG = """
name: mytiago
urdf: {urdf}
arm_joints: [torso_lift_joint, arm_1_joint, arm_2_joint, arm_3_joint, arm_4_joint,
             arm_5_joint, arm_6_joint, arm_7_joint]
tool_frame: hand_grasping_frame
footprint: {{radius: 0.275}}
"""


def assert_stop_verified(planner, scene, stop) -> None:
    """Each witness of ``stop`` reaches its grasp from the stop within 1 mm and 0.5 deg and is
    collision-free for coal: every collision link of the robot (the hand's included, the
    grasped part no obstacle for it) against the scene and the floor (its clearance kept), and
    the robot against itself."""
    import math

    from pickstop.regions.pipeline import tray_world
    from pickstop.robot.kinematics import fk

    c, s_ = math.cos(stop.yaw), math.sin(stop.yaw)
    T_world_base = np.eye(4)
    T_world_base[:2, :2] = [[c, -s_], [s_, c]]
    T_world_base[:2, 3] = stop.x, stop.y
    for w in stop.witnesses:
        tray = scene.tray(w.tray_id)
        k = [p.id for p in tray.parts].index(w.part_id)
        target = planner.grasps(scene, tray)[k].Ts_world_tool[w.grasp_index]
        R, p = fk(planner.solver.chain, np.array([w.theta]))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R[0], p[0]
        got = T_world_base @ T
        assert np.linalg.norm(got[:3, 3] - target[:3, 3]) < 1e-3
        cos = (np.trace(got[:3, :3].T @ target[:3, :3]) - 1) / 2
        assert math.degrees(math.acos(min(1.0, cos))) < 0.5
        _, solids, _, _ = tray_world(planner, scene, tray, stop.yaw)
        theta = np.array(w.theta)
        assert not planner.exact_arm.colliding(
            theta, stop.x, stop.y, stop.yaw, solids, w.part_id, scene.floor_clearance
        )
        assert not planner.exact_self.colliding(theta[None])[0]
        assert w.hand == planner.hand.joints


def assert_cells_verified(planner, scene, region, rows) -> None:
    """Each witness of the region's cells ``rows`` reaches its grasp from the cell's centre
    within 1 mm and 0.5 deg, within the joint limits, and is collision-free for coal (the
    robot's arm against the scene and against itself)."""
    import math

    from pickstop.regions.arm import ExactArm
    from pickstop.robot.artifacts import self_collision
    from pickstop.robot.kinematics import fk
    from pickstop.robot.selfcollision import ExactSelfCollision
    from pickstop.scene.world import scene_solids

    robot = planner.robot
    rows = np.asarray(rows, int)
    if not len(rows):
        return
    grasps = planner.grasps(scene, scene.tray(region.tray_id))
    solids = scene_solids(scene)
    exact_arm = ExactArm(robot)
    exact_self = ExactSelfCollision(robot, self_collision(robot, planner.cache_dir)[0])
    c, s = math.cos(region.yaw), math.sin(region.yaw)
    R_world_base = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    xy = region.grid.centres(region.cells[rows, 1], region.cells[rows, 0])
    for k, gs in enumerate(grasps):
        th = region.thetas[rows, k]
        R, p = fk(planner.solver.chain, th)
        for i in range(len(rows)):
            T_world_tool = gs.Ts_world_tool[region.grasp_index[rows[i], k]]
            pw = R_world_base @ p[i] + [xy[i, 0], xy[i, 1], 0.0]
            assert np.linalg.norm(pw - T_world_tool[:3, 3]) <= 1e-3
            cos = (np.trace((R_world_base @ R[i]).T @ T_world_tool[:3, :3]) - 1) / 2
            assert math.acos(float(np.clip(cos, -1, 1))) <= math.radians(0.5) + 1e-9
            assert (th[i] >= robot.lower - 1e-9).all() and (th[i] <= robot.upper + 1e-9).all()
            assert not exact_arm.colliding(th[i], xy[i, 0], xy[i, 1], region.yaw, solids)
        assert not exact_self.colliding(th).any()


def assert_route_clear(robot, scene, plan, step: float = 0.01) -> None:
    """Every leg of ``plan`` is collision-free for the robot's own base: along a docking
    segment (held at a yaw), sampled every ``step`` [m], the footprint and the upper body at
    that yaw meet no solid (the regions' exact Minkowski test) and the footprint stays on the
    floor; along every other segment, and so at every turn, the body's full bounding circle
    keeps clear of whatever reaches below the body's top and stays on the floor (exact: the
    segment's distance)."""
    import math

    import shapely
    import shapely.affinity

    from pickstop.regions.footprint import blocked_by, floor_outline, upper_body
    from pickstop.scene.world import scene_solids

    solids = scene_solids(scene)
    body = upper_body(robot)
    low = shapely.union_all(
        [shapely.Polygon(floor_outline(s)) for s in solids if s.aabb()[0][2] < body.top]
    )
    floor = shapely.box(*scene.floor.min, *scene.floor.max)
    inner = floor.buffer(-body.radius + 1e-4, join_style="mitre")
    fp = robot.footprint
    outline = (
        shapely.Point(0, 0).buffer(fp.radius, quad_segs=32)
        if fp.radius is not None
        else shapely.Polygon(fp.polygon)
    )
    for n, leg in enumerate(plan.legs):
        line = np.asarray(leg.polyline, float)
        held = leg.segment_yaws or [None] * (len(line) - 1)
        assert len(held) == len(line) - 1, n
        for k, yaw in enumerate(held):
            a, b = line[k], line[k + 1]
            if yaw is None:
                seg = shapely.LineString([a, b])
                assert seg.distance(low) > body.radius - 1e-4, (n, k, "circle meets a solid")
                assert inner.covers(seg), (n, k, "circle leaves the floor")
                continue
            m = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
            pts = a + np.linspace(0, 1, m)[:, None] * (b - a)
            assert not blocked_by(robot, solids, pts, yaw).any(), (n, k, yaw)
            turned = shapely.affinity.rotate(outline, yaw, origin=(0, 0), use_radians=True)
            for p in pts:
                assert floor.covers(shapely.affinity.translate(turned, *p)), (n, k, p)
        # a leg ends at its stop at the stop's yaw
        if n < len(plan.stops) and held[-1] is not None:
            assert math.isclose(held[-1], plan.stops[n].yaw, abs_tol=1e-9)


def count_regions(monkeypatch) -> list[str]:
    """The ids of the trays whose regions are computed from now on (the list fills as the
    region planner computes them)."""
    import pickstop.speedups.region_planner as region_planner

    made: list[str] = []
    real = region_planner.compute_tray_region

    def counted(kit, scene, tray, yaw, *args):
        made.append(tray.id)
        return real(kit, scene, tray, yaw, *args)

    monkeypatch.setattr(region_planner, "compute_tray_region", counted)
    return made


def region_of(inside, grid, tray_id: str = "t"):
    """A :class:`~pickstop.regions.cells.TrayRegion` on ``grid`` whose cells are those where
    ``inside(xy (M, 2)) -> (M,) bool`` holds at the centre (no parts, no witnesses)."""
    from pickstop.regions.cells import TrayRegion

    iy, ix = np.mgrid[0 : grid.ny, 0 : grid.nx]
    ok = np.asarray(inside(grid.centres(ix.ravel(), iy.ravel())), bool)
    cells = np.stack([iy.ravel()[ok], ix.ravel()[ok]], axis=1)
    K = len(cells)
    return TrayRegion.of_cells(
        tray_id, 0.0, grid, cells, (), np.zeros((K, 0, 1)), np.zeros((K, 0), int), {}, None, 0.0
    )


def discs(centres, radii):
    """``inside(xy (M, 2)) -> (M,) bool``: the union of discs ``centres (n, 2)`` [m],
    ``radii (n,)`` [m]."""
    cs, rs = np.asarray(centres, float).reshape(-1, 2), np.asarray(radii, float).ravel()

    def inside(xy):
        xy = np.asarray(xy, float).reshape(-1, 2)
        d = np.hypot(xy[:, None, 0] - cs[None, :, 0], xy[:, None, 1] - cs[None, :, 1])
        return (d <= rs[None]).any(axis=1)

    return inside


def unlike_cells(scratch, region):
    """Rows of ``region``'s cells that ``scratch`` lacks or solves with other witnesses."""
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(scratch.cells)}
    out = []
    for k, (a, b) in enumerate(region.cells.tolist()):
        j = index.get((a, b))
        if j is None or not np.allclose(scratch.thetas[j], region.thetas[k], rtol=0, atol=1e-9):
            out.append(k)
    return np.array(out, int)


def same_document(a, b, path: str = "plan") -> None:
    """Assert that the JSON documents ``a`` and ``b`` are equal, floats to 1e-9 (a witness's
    joints may differ in the last bits where grasps were carried with a moved tray rather than
    made there, or on another machine's floating point)."""
    if isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=0, abs_tol=1e-9) or a == b, (path, a, b)
    elif isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), (path, set(a) ^ set(b))
        for k in a:
            same_document(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list | tuple) and isinstance(b, list | tuple):
        assert len(a) == len(b), (path, len(a), len(b))
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            same_document(x, y, f"{path}[{k}]")
    else:
        assert a == b, (path, a, b)
