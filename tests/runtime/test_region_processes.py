"""Regions computed by several processes, each tray at home in one
(runtime/region_processes.py): the same regions as one process with the same history, homes
kept across layouts, background work given way to in the helpers, a helper's error or death
never losing a region."""

from __future__ import annotations

import copy
import os
import signal

import numpy as np
import pytest

from pickstop.regions import kit as kit_mod
from pickstop.runtime import region_processes as processes_mod
from pickstop.runtime.cancel import Cancelled, giving_way
from pickstop.scene.load import parse_scene
from pickstop.speedups.region_planner import RegionPlanner
from tests.utils import assert_cells_verified, count_regions


@pytest.fixture()
def fresh(region_db, tiago, tmp_path):
    """A region planner with nothing remembered, ``workers`` processes; closed after."""
    from pickstop.settings import cache_dir

    folder, db = region_db
    made: list[RegionPlanner] = []

    def make(workers: int) -> RegionPlanner:
        made.append(RegionPlanner(tiago, db, cache_dir=cache_dir(folder), workers=workers))
        return made[-1]

    yield make
    for p in made:
        p.close()


def _moved(doc: dict, tray_id: str, dx: float, dy: float = 0.0) -> dict:
    d = copy.deepcopy(doc)
    for t in d["trays"]:
        if t["id"] == tray_id:
            t["pose"]["x"] += dx
            t["pose"]["y"] += dy
    return d


def _helper_tray(planner: RegionPlanner, scene) -> str:
    """A task tray of ``scene`` at home in a helper."""
    w = planner._processes
    assert w is not None
    yaw = scene.base_yaw.yaws[0]
    at = {t: w.homes[processes_mod._home_key(scene, (t, yaw))] for t in scene.task_trays}
    assert sorted(set(at.values())) == [0, 1], at  # the first plan shared them out
    return next(t for t, h in at.items() if h == 1)


def test_two_processes_give_one_process_regions_across_moves(fresh, paper_doc, monkeypatch):
    """Each tray is computed where it was before, its memos there: the regions of a layout
    and of the layout with a tray moved are those of one process with the same history."""
    one, two = fresh(1), fresh(2)
    layouts = [parse_scene(paper_doc)]
    for scene in layouts:
        a, b = one.regions(scene), two.regions(scene)
        assert a.keys() == b.keys()
    mover = _helper_tray(two, layouts[0])
    computed = count_regions(monkeypatch)  # in this process (the helpers were forked before)
    real = kit_mod.grasps_for_part
    made: list[object] = []

    def counted(*a: object) -> object:
        made.append(a)
        return real(*a)

    for dx, dy in ((0.05, 0.0), (0.0, -0.1)):
        scene = parse_scene(_moved(paper_doc, mover, dx, dy))
        a = one.regions(scene)
        del computed[:]
        b = two.regions(scene)
        assert mover not in computed  # its home computed it, not this process
        for k in a:
            np.testing.assert_array_equal(a[k].mask, b[k].mask)
            np.testing.assert_allclose(a[k].thetas, b[k].thetas)
        # The helper's grasps came back with its region: the stops' checks here need them.
        made.clear()
        monkeypatch.setattr(kit_mod, "grasps_for_part", counted)
        two.grasps(scene, scene.tray(mover))
        assert not made
        monkeypatch.setattr(kit_mod, "grasps_for_part", real)
        r = b[(mover, scene.base_yaw.yaws[0])]
        assert_cells_verified(two, scene, r, np.arange(0, len(r.cells), 37))


@pytest.mark.parametrize("where", ["waiting", "computing"])
def test_background_work_gives_way_in_the_helpers(fresh, paper_doc, monkeypatch, where):
    """Told to give way while this process waits for the helper, or while it computes its own
    share: the helper stops too, nothing half done is kept, and the helper answers the next
    request in full."""
    two = fresh(2)
    base = parse_scene(paper_doc)
    two.regions(base)
    mover = _helper_tray(two, base)
    yaw = base.base_yaw.yaws[0]
    scene = parse_scene(_moved(paper_doc, mover, 0.1))
    if where == "waiting":  # this process has nothing of its own left to compute
        for t in scene.task_trays:
            if t != mover:
                two.tray_region(scene, t, yaw)
    inside = [False]  # this process computes its own share
    processes = two._processes
    real = processes.compute

    def own(*a):
        inside[0] = True
        try:
            return real(*a)
        finally:
            inside[0] = False

    monkeypatch.setattr(processes, "compute", own)
    asked: list[bool] = []

    def interrupt() -> bool:
        asked.append(inside[0])
        return (where == "computing") == inside[0] and len(asked) > 3

    with giving_way(interrupt), pytest.raises(Cancelled):
        two.regions(scene)
    assert asked[-1] == (where == "computing")
    assert two._cached(scene, mover, yaw) is None  # nothing half done is kept
    pid = two._processes.pids[0]
    r = two.regions(scene)[(mover, yaw)]
    assert two._processes.pids[0] == pid
    assert r.reason is None and len(r.cells) > 20
    assert_cells_verified(two, scene, r, np.arange(0, len(r.cells), 41))


def test_a_helper_that_dies_is_replaced(fresh, paper_doc, monkeypatch, caplog):
    real = processes_mod._region

    def fragile(scene, tray_id, yaw):
        if scene.name == "dies":
            os._exit(9)
        return real(scene, tray_id, yaw)

    monkeypatch.setattr(processes_mod, "_region", fragile)  # before the helper is forked
    two = fresh(2)
    base = parse_scene(paper_doc)
    two.regions(base)
    mover = _helper_tray(two, base)
    yaw = base.base_yaw.yaws[0]
    # Dead while idle: found out on the next request and replaced.
    pid = two._processes.pids[0]
    os.kill(pid, signal.SIGKILL)
    two._processes._helpers[0].process.join(5)
    scene = parse_scene(_moved(paper_doc, mover, -0.05))
    r = two.regions(scene)[(mover, yaw)]
    assert two._processes.pids[0] not in (None, pid)
    assert r.reason is None and len(r.cells) > 20
    # Dead while computing: this process computes its share instead, and keeps it.
    doc = _moved(paper_doc, mover, 0.05)
    doc["name"] = "dies"
    scene = parse_scene(doc)
    with caplog.at_level("WARNING", logger="pickstop.regions"):
        r = two.regions(scene)[(mover, yaw)]
    assert "a region helper process ended" in caplog.text
    assert r.reason is None and len(r.cells) > 20
    assert_cells_verified(two, scene, r, np.arange(0, len(r.cells), 41))
    assert two._processes.pids[0] is None
    assert two._processes.homes[processes_mod._home_key(scene, (mover, yaw))] == 0


def test_a_helpers_error_reaches_the_caller(fresh, paper_doc, monkeypatch):
    def boom(scene, tray_id, yaw):
        raise ValueError(f"no region for {tray_id} here")

    monkeypatch.setattr(processes_mod, "_region", boom)  # before the helper is forked
    two = fresh(2)
    with pytest.raises(ValueError, match=r"no region for tray_\d here"):
        two.regions(parse_scene(paper_doc))
    # The helper lives on, idle, and answers the next request at once (its copy of the
    # module still fails).
    pid = two._processes.pids[0]
    assert pid is not None  # not given up on after its answer
    with pytest.raises(ValueError, match=r"no region for tray_\d here"):
        two.regions(parse_scene(paper_doc))
    assert two._processes.pids[0] == pid


def test_region_processes_want_one_process_at_least(planner):
    from pickstop.runtime.region_processes import RegionProcesses

    with pytest.raises(ValueError, match="processes must be at least 1, got 0"):
        RegionProcesses(planner, 0, planner.compute_region)
