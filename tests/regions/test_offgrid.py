"""Checks of base poses off the grid (regions/offgrid.py)."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickstop.scene.load import parse_scene

from .helpers import assert_verified


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
        assert_verified(tiago, planner, scene, "tray_2", xy[first], r.yaw, th[first], g[first])
