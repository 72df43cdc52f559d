"""Placement guidance: the zones' arithmetic against brute force, and the zones of the paper
scene's tray_4 against exact plans of the tray moved into them."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.ops import polylabel

from pickstop.layout.guidance import eroded, guidance, meeting_offsets, partner_groups
from pickstop.scene.load import parse_scene
from pickstop.scene.supports import stand_areas
from pickstop.sequence.intersections import inscribed_circle
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())

masks = st.integers(0, 2**30).map(lambda seed: np.random.default_rng(seed).random((12, 14)) < 0.35)


@settings(max_examples=60, deadline=None)
@given(moving=masks, fixed=masks, lo=st.tuples(st.integers(-15, 0), st.integers(-15, 0)))
def test_meeting_offsets_are_the_shifts_at_which_the_masks_meet(moving, fixed, lo):
    lo = np.array(lo)
    hi = lo + np.array([20, 22])
    got = meeting_offsets(moving, fixed, lo, hi)
    ys, xs = np.nonzero(moving)
    for dy in range(lo[0], hi[0] + 1):
        for dx in range(lo[1], hi[1] + 1):
            y, x = ys + dy, xs + dx
            inside = (y >= 0) & (y < 12) & (x >= 0) & (x < 14)
            want = bool(fixed[y[inside], x[inside]].any())
            assert got[dy - lo[0], dx - lo[1]] == want, (dy, dx)


@pytest.mark.parametrize("sigma", [0.05, 0.1, 0.15])
def test_an_eroded_mask_holds_the_centres_of_circles_of_radius_sigma(sigma):
    """Where the erosion is not empty the region's inscribed circle is at least sigma, less
    the half-cell the grid rounds by, and where it is empty less than sigma plus that."""
    from pickstop.regions.cells import CellGrid

    grid = CellGrid(0.0, 0.0, 0.025, 40, 40)
    rng = np.random.default_rng(3)
    for _ in range(40):
        mask = np.zeros((40, 40), bool)
        for _ in range(3):  # a few overlapping rectangles
            y0, x0 = rng.integers(0, 30, 2)
            mask[y0 : y0 + rng.integers(2, 14), x0 : x0 + rng.integers(2, 14)] = True
        iy, ix = np.nonzero(mask)
        poly = grid.cells_polygon(iy, ix)
        radius = max(inscribed_circle(p)[1] for p in getattr(poly, "geoms", [poly]))
        if eroded(mask, grid.res, sigma).any():
            assert radius >= sigma - grid.res / 2
        else:
            assert radius < sigma + grid.res


def test_zones_of_tray_4_agree_with_exact_plans_of_it_moved_there(planner):
    scene = parse_scene(PAPER)
    groups = partner_groups(scene, "tray_4")
    assert groups == [["tray_1", "tray_2"]]
    g = guidance(planner, scene, "tray_4", groups)
    assert g.here == "own"  # alone on its table: a stop of its own
    kinds = {(z.kind, z.trays) for z in g.zones}
    assert ("shares", ("tray_1", "tray_2")) in kinds and ("own", ()) in kinds
    # the zones of a support cover its stand area once
    for a in stand_areas(scene, scene.tray("tray_4")):
        mine = [z.area for z in g.zones if z.support == a.support]
        assert shapely.union_all(mine).symmetric_difference(a.area).area < 1e-6
        assert sum(m.area for m in mine) == pytest.approx(a.area.area, abs=1e-6)
    sp = StopPlanner(planner)
    for z in g.zones:
        if z.kind not in ("shares", "own"):
            continue
        biggest = max(getattr(z.area, "geoms", [z.area]), key=lambda p: p.area)
        at = polylabel(biggest, 0.005)
        doc = copy.deepcopy(PAPER)
        doc["trays"][3]["pose"].update(x=at.x, y=at.y)
        plan = sp.plan(parse_scene(doc), PlanOptions(samples=0))
        wide = [set(c.trays) for c in plan.candidates if "tray_4" in c.trays
                and c.inscribed_radius >= plan.parameters.sigma]  # fmt: skip
        if z.kind == "shares":
            assert {"tray_4", *z.trays} in wide, (z.trays, at)
        else:
            assert wide == [{"tray_4"}], at


def test_groups_follow_the_order_shown_or_the_mix():
    scene = parse_scene({**PAPER, "orders": [{"id": "a", "trays": ["tray_4", "tray_3"]},
                                             {"id": "b", "trays": ["tray_2", "tray_4"]},
                                             {"id": "c", "trays": ["tray_1"]}]})  # fmt: skip
    assert partner_groups(scene, "tray_4", order="a") == [["tray_3"]]
    assert partner_groups(scene, "tray_4", mix=True) == [["tray_3"], ["tray_2"]]
    assert partner_groups(scene, "tray_4") == [["tray_1", "tray_2"]]  # the task's
    assert partner_groups(scene, "tray_3") == []  # not in the task: no partners
