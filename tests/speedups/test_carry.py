"""Regions carried to previews (speedups/carry.py)."""

from __future__ import annotations

import copy

import numpy as np

from pickstop.scene.load import parse_scene


def test_a_preview_carries_the_nearest_region_with_cells_and_takes_a_held_region_as_it_is(
    planner, paper_doc
):
    """Once a tray was planned out of reach (its region empty), a preview of it back near its
    first place carries the region computed there, not the empty one; where a cached region
    still holds, the preview takes it exactly as computed."""
    home = parse_scene(paper_doc)
    pair = ("tray_2", home.base_yaw.yaws[0])
    first = planner.tray_region(home, *pair)
    assert len(first.cells) > 20

    def moved(dx: float = 0.0, dz: float = 0.0):
        doc = copy.deepcopy(paper_doc)
        tray = next(t for t in doc["trays"] if t["id"] == "tray_2")
        tray["pose"]["x"] += dx
        tray["pose"]["z"] += dz
        if dz:  # raised on a column standing on its table
            size = [0.4, 0.3, dz]
            pose = {"x": tray["pose"]["x"], "y": tray["pose"]["y"], "z": 0.72}
            doc["obstacles"].append({"id": "column", "geometry": {"shape": "box", "size": size},
                                     "pose": pose})  # fmt: skip
        return parse_scene(doc)

    high = moved(dz=1.5)  # out of the arm's reach: planned empty, now the newest region
    assert len(planner.tray_region(high, *pair).cells) == 0
    assert len(planner.known_regions(high, [pair])[pair].cells) == 0

    assert planner.known_regions(home, [pair])[pair] is first  # held: taken as it is
    near = planner.known_regions(moved(dx=0.05), [pair])[pair]
    assert near.key == f"carried:{first.key}" and len(near.cells) > 0.8 * len(first.cells)
    res = first.grid.res
    xy = first.grid.centres(first.cells[:, 1], first.cells[:, 0])
    got = near.grid.centres(near.cells[:, 1], near.cells[:, 0])
    # every carried cell is a first cell moved with the tray (to within the grid's snap)
    gap = np.abs(got[:, None, :] - (xy + np.array([0.05, 0.0]))[None]).max(axis=2).min(axis=1)
    assert (gap <= res + 1e-9).all()


def test_a_turned_tray_carries_its_region_whole(planner, paper_doc):
    """A preview of a turned tray carries its region turned about the tray, without the holes
    a turned grid falling out of step with the grid would leave: its shape has no more holes
    than the region's, about its area (but for the footprint), and each carried cell comes
    from a cell of the region, turned back."""
    import shapely

    scene = parse_scene(paper_doc)
    pair = ("tray_2", scene.base_yaw.yaws[0])
    first = planner.tray_region(scene, *pair)
    doc = copy.deepcopy(paper_doc)
    tray = next(t for t in doc["trays"] if t["id"] == "tray_2")
    tray["pose"]["yaw"] = 0.3
    turned = parse_scene(doc)
    got = planner.known_regions(turned, [pair])[pair]
    assert got.key == f"carried:{first.key}"

    def holes(region) -> int:
        geoms = getattr(region.polygon, "geoms", [region.polygon])
        return sum(len(g.interiors) for g in geoms if isinstance(g, shapely.Polygon))

    assert holes(got) <= holes(first)
    assert 0.8 * len(first.cells) <= got.counts["footprint_free"] <= 1.1 * len(first.cells)
    t = scene.tray("tray_2").pose
    c, s = np.cos(-0.3), np.sin(-0.3)
    xy = got.grid.centres(got.cells[:, 1], got.cells[:, 0]) - [t.x, t.y]
    back = xy @ np.array([[c, s], [-s, c]]) + [t.x, t.y]
    g = first.grid
    ix = np.floor((back[:, 0] - g.x0) / g.res).astype(int)
    iy = np.floor((back[:, 1] - g.y0) / g.res).astype(int)
    assert first.mask[iy, ix].all()


def test_the_regions_kept_for_previews_stay_within_their_bound(paper_doc):
    """A few poses per tray, and no more regions in all than the bound: the tray remembered
    least recently goes first."""
    from types import SimpleNamespace

    from pickstop.speedups.carry import LastRegions

    last = LastRegions(size=5, per_tray=4)

    def at(tray_id: str, dx: float):
        doc = copy.deepcopy(paper_doc)
        next(t for t in doc["trays"] if t["id"] == tray_id)["pose"]["x"] += dx
        return parse_scene(doc)

    fake = {
        t: SimpleNamespace(tray_id=t, yaw=0.0, cells=np.zeros((1, 2))) for t in ("tray_1", "tray_2")
    }
    for k in range(6):
        last.remember(at("tray_1", 0.01 * k), fake["tray_1"])
    assert len(last) == 4  # the four newest poses of tray_1
    last.remember(at("tray_1", 0.03), fake["tray_1"])  # a pose kept already: no second copy
    assert len(last) == 4
    for k in range(3):
        last.remember(at("tray_2", 0.01 * k), fake["tray_2"])
    assert len(last) == 3  # tray_1's four went to make room
