"""The rack cell: low, overhung and slanted trays; the floor kept clear by every witness."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pickstop.regions.reference import comparison_cells, oracle_region, verify_witnesses
from pickstop.robot.floor import ExactFloor
from pickstop.robot.kinematics import fk
from pickstop.scene.load import parse_scene

RACK = Path(__file__).parents[2] / "examples" / "scenes" / "rack_cell.json"


@pytest.fixture(scope="module")
def rack_doc():
    return json.loads(RACK.read_text())


@pytest.fixture(scope="module")
def rack(rack_doc):
    return parse_scene(rack_doc)


@pytest.fixture(scope="module")
def rack_regions(planner, rack):
    return {t.id: planner.tray_region(rack, t.id) for t in rack.trays}


def test_every_level_of_the_rack_cell_has_a_region(rack_regions):
    for tray_id, region in rack_regions.items():
        assert region.reason is None and region.area > 0.02, (tray_id, region.reason)


def test_floor_bin_witnesses_keep_every_link_above_the_floor(planner, rack, rack_regions, tiago):
    """Every witness of the floor bin, exactly: each arm link and the hand stay above the
    floor plus the clearance, and nothing of the scene is touched."""
    region = rack_regions["floor_bin"]
    exact = ExactFloor(tiago)
    th = region.thetas.reshape(-1, tiago.dof)
    assert not exact.colliding(th, rack.floor_clearance).any()
    assert verify_witnesses(planner, rack, region).failures == 0
    # The bin is deep: the witnesses reach well below the shelf trays' height.
    _, ps = fk(planner.solver.chain, th)
    assert (ps[:, 2] < 0.2).all()


def test_tilted_tray_region_matches_the_multi_start_oracle(planner, rack, rack_regions):
    """The flow-rack tray's region on a few cells: every region cell is confirmed by dense
    multi-start IK (no database), and its witnesses pass the exact checks."""
    region = rack_regions["flow_tray"]
    cmp = comparison_cells(planner, rack, region, width=1, sample=4)
    rng = np.random.default_rng(3)
    inside = region.cells[rng.choice(len(region.cells), 10, replace=False)]
    band = cmp.band[rng.choice(len(cmp.band), min(6, len(cmp.band)), replace=False)]
    cells = np.concatenate([inside, band, cmp.sample])
    oracle = oracle_region(planner, rack, "flow_tray", seeds=(4, 16, 64), cells=cells)
    produced = region.mask[cells[:, 0], cells[:, 1]]
    confirmed = oracle.mask[cells[:, 0], cells[:, 1]]
    assert produced.sum() == 10 and (confirmed | ~produced).all()
    assert verify_witnesses(planner, rack, oracle).failures == 0
    assert verify_witnesses(planner, rack, region).failures == 0


def test_a_larger_floor_clearance_explains_the_bin_out_of_reach(planner, rack_doc):
    """With 3 cm of clearance no grasp of the bin's box part keeps the open hand clear of the
    floor: its region is empty and says so, naming the tray, the part and the numbers."""
    doc = json.loads(json.dumps(rack_doc))
    doc["floor_clearance"] = 0.03
    region = planner.tray_region(parse_scene(doc), "floor_bin")
    assert region.area == 0
    why = region.reason or ""
    assert "'floor_bin'" in why and "'pfa'" in why and "0.030 m" in why
    assert "too close to the floor" in why
