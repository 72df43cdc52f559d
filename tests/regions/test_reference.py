"""Reference regions: the fixed-seed baseline and the multi-start oracle, on a few dozen cells."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pickstop.regions.reference import (
    ReachBound,
    baseline_region,
    comparison_cells,
    dilate,
    oracle_region,
    verify_witnesses,
)
from pickstop.robot.kinematics import fk, reference_fk
from pickstop.scene.load import parse_scene
from tests.utils import random_thetas

from .conftest import add_high_shelf_tray

PAPER = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"
SEEDS = (4, 16, 64)  # enough for a few dozen cells; the benchmark escalates to 256


@pytest.fixture(scope="module")
def tray_2(planner, tiago):
    """The paper scene, tray_2's production region and a few dozen cells on both sides of
    its boundary."""
    scene = parse_scene(json.loads(PAPER.read_text()))
    region = planner.tray_region(scene, "tray_2")
    assert region.reason is None and len(region.cells) > 30
    cmp = comparison_cells(planner, scene, region, width=1, sample=6)
    rng = np.random.default_rng(0)
    inside = region.cells[rng.choice(len(region.cells), 24, replace=False)]
    band = cmp.band[rng.choice(len(cmp.band), min(16, len(cmp.band)), replace=False)]
    return scene, region, np.concatenate([inside, band, cmp.sample])


def _world_tool(theta, x, y, yaw, robot):
    """Tool pose in the world of one configuration on base (x, y, yaw), with pinocchio."""
    T_wb = pin.SE3(pin.rpy.rpyToMatrix(0, 0, yaw), np.array([x, y, 0.0]))
    return T_wb * reference_fk(robot, theta)


def test_reach_bound_holds_every_configuration(planner, tiago):
    bound = ReachBound.of(planner.solver)
    Rs, ps = fk(planner.solver.chain, random_thetas(tiago, 20_000, seed=3))
    assert bound.contains(Rs, ps).all()
    # A target 1.5 m above the shoulder is out of reach whatever its orientation.
    above = ps[:1] + np.array([0.0, 0.0, 1.5 + bound.radius])
    assert not bound.contains(Rs[:1], above).any()


def test_baseline_cells_are_feasible_by_exact_checks(planner, tray_2, tiago):
    scene, _, cells = tray_2
    base = baseline_region(planner, scene, "tray_2", cells=cells)
    assert base.reason is None and len(base.cells) > 0
    assert verify_witnesses(planner, scene, base).failures == 0
    # Independently of the numpy FK: pinocchio puts the tool on the chosen grasp.
    grasps = planner.grasps(scene, scene.tray("tray_2"))[0]
    xy = base.grid.centres(base.cells[:, 1], base.cells[:, 0])
    for i in range(len(base.cells)):
        T = _world_tool(base.thetas[i, 0], *xy[i], base.yaw, tiago)
        T_target = grasps.Ts_world_tool[base.grasp_index[i, 0]]
        assert np.linalg.norm(T.translation - T_target[:3, 3]) <= 1e-3
        assert np.linalg.norm(pin.log3(T.rotation.T @ T_target[:3, :3])) <= np.radians(0.5)
    # The reach bound only skips hopeless targets: the same cells without it.
    full = baseline_region(planner, scene, "tray_2", cells=cells, prune=False)
    assert np.array_equal(full.mask, base.mask)


def test_oracle_confirms_production_cells(planner, tray_2):
    scene, region, cells = tray_2
    oracle = oracle_region(planner, scene, "tray_2", seeds=SEEDS, cells=cells)
    assert oracle.counts["evaluated"] == len(cells)
    asked = np.zeros_like(oracle.mask)
    asked[cells[:, 0], cells[:, 1]] = True
    assert not (oracle.mask & ~asked).any()
    produced = region.mask[cells[:, 0], cells[:, 1]]
    confirmed = oracle.mask[cells[:, 0], cells[:, 1]]
    assert (confirmed | ~produced).all()  # precision: every production cell is confirmed
    assert verify_witnesses(planner, scene, oracle).failures == 0
    # A cell's answer does not depend on which other cells are evaluated.
    few = cells[::7]
    alone = oracle_region(planner, scene, "tray_2", seeds=SEEDS, cells=few)
    assert np.array_equal(alone.mask[few[:, 0], few[:, 1]], oracle.mask[few[:, 0], few[:, 1]])


def test_comparison_cells_band_and_sample(planner, tray_2):
    scene, region, _ = tray_2
    cmp = comparison_cells(planner, scene, region, width=2, sample=50, rng_seed=1)
    assert np.array_equal(cmp.region, region.cells)
    assert not region.mask[cmp.band[:, 0], cmp.band[:, 1]].any()
    near = dilate(region.mask, 2)
    assert near[cmp.band[:, 0], cmp.band[:, 1]].all()
    assert not near[cmp.sample[:, 0], cmp.sample[:, 1]].any() and len(cmp.sample) == 50
    lin = cmp.all[:, 0] * region.grid.nx + cmp.all[:, 1]
    assert len(np.unique(lin)) == len(lin)


def test_dilate_is_chebyshev():
    m = np.zeros((7, 7), bool)
    m[3, 3] = True
    assert dilate(m, 2).sum() == 25 and dilate(m, 2)[1:6, 1:6].all()


def _far_tray(doc):
    # The base grid ends some 3.9 m from tray_4: no cell is within the arm's reach.
    doc["base_grid"] = {"resolution": 0.05, "extent": {"min": [-1.0, -1.0], "max": [0.0, 0.0]}}
    return "tray_4", "farther than the arm reaches"


def _high_tray(doc):
    return add_high_shelf_tray(doc), "part 'hp'"


@pytest.mark.parametrize("place", [_far_tray, _high_tray])
def test_unreachable_tray_gives_empty_regions_with_reason(planner, paper_doc, place):
    tray_id, why = place(paper_doc)
    scene = parse_scene(paper_doc)
    for region in (
        baseline_region(planner, scene, tray_id),
        oracle_region(planner, scene, tray_id, seeds=SEEDS),
    ):
        assert len(region.cells) == 0 and not region.mask.any() and region.polygon.is_empty
        assert region.reason is not None and why in region.reason
        assert region.thetas.shape == (0, len(scene.tray(tray_id).parts), planner.robot.dof)
