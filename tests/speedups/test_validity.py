"""When a cached region still holds (speedups/validity.py): precise invalidation, witness arms
against new objects."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pickstop.reach.so3 import quats_to_matrices
from pickstop.regions.arm import screen_arm
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.load import parse_scene
from pickstop.scene.world import BoxArrays


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


def test_witnesses_clear_sees_an_object_on_a_witness_arm(planner, paper_doc):
    from pickstop.robot.kinematics import Chain, fk_soa
    from pickstop.scene.world import Solid
    from pickstop.speedups.validity import witnesses_clear

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
    from pickstop.scene.world import Solid
    from pickstop.speedups.validity import witness_boxes, witnesses_clear

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
