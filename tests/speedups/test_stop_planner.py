"""Plans of the example scenes: structure, verification, rules and every infeasible case."""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner
from tests.utils import assert_stop_verified, count_regions

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def test_plan_serves_every_task_tray_once_from_verified_stops(paper_plan, planner):
    scene, plan = paper_plan
    served = [t for s in plan.stops for t in s.trays]
    assert sorted(served) == sorted(scene.task_trays)
    assert plan.totals.stops == len(plan.stops) <= len(plan.naive.stops) == len(scene.task_trays)
    for s in plan.stops:
        assert s.inscribed_radius >= plan.parameters.sigma
        assert set(s.trays) <= set(s.region_trays)
        # Every witness is a real IK solution: exact FK reaches one of the part's grasps.
        parts = {(w.tray_id, w.part_id) for w in s.witnesses}
        assert parts == {(t, p.id) for t in s.trays for p in scene.tray(t).parts}
        assert_stop_verified(planner, scene, s)
        # Each witness carries the hand's joint values, so it can be replayed.
        assert all(
            w.hand == planner.hand.joints and w.hand["hand_thumb_abd_joint"] == 1.5707
            for w in s.witnesses
        )
        assert all(w.T_part_tcp is not None for w in s.witnesses)
        assert s.success is not None and s.success.samples == 300
        lo, hi = s.success.interval
        assert lo <= s.success.rate <= hi
    # The bundled TIAGo is checked with its Hey5's own meshes: no stand-in note.
    assert not any("hand.boxes" in n for n in plan.notes)


def test_rack_cell_plans_every_level_from_verified_stops(stop_planner, planner):
    """Floor bin, lower shelf under the overhanging board, slanted flow-rack tray, upper
    shelf and table: each served once, from stops whose witnesses keep clear of the floor."""
    scene = parse_scene(json.loads((EXAMPLES / "rack_cell.json").read_text()))
    plan = stop_planner.plan(scene, PlanOptions(samples=100))
    served = sorted(t for s in plan.stops for t in s.trays)
    assert served == sorted(scene.task_trays) and len(served) == 5
    assert plan.totals.stops < len(scene.task_trays)
    for s in plan.stops:
        assert s.inscribed_radius >= plan.parameters.sigma
        assert_stop_verified(planner, scene, s)
        assert s.success is not None and s.success.rate > 0.5


def test_sigma_change_reuses_regions_and_candidates(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    stop_planner.plan(scene, PlanOptions(samples=0))
    again = stop_planner.plan(scene, PlanOptions(sigma=0.05, samples=0))
    assert again.timings.regions < 0.2 and again.parameters.sigma == 0.05


# -- impossible requests: an explanation naming trays and numbers, never a partial plan ------
def test_sigma_too_large_names_trays_and_radii(stop_planner, paper_doc):
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(parse_scene(paper_doc), PlanOptions(sigma=0.4, samples=0))
    msg = e.value.message
    assert "sigma = 0.400 m" in msg
    for t in ("tray_1", "tray_2", "tray_4"):
        assert f"tray {t}:" in msg
    assert "below sigma 0.400 m" in msg and e.value.field == "sigma"


def test_sigma_too_large_states_the_largest_sigma_that_plans(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(scene, PlanOptions(sigma=0.4, samples=0))
    m = re.search(r"the largest sigma that keeps a candidate stop for every tray is ([\d.]+) m",
                  e.value.message)  # fmt: skip
    assert m, e.value.message
    largest = float(m.group(1))
    assert 0.0 < largest < 0.4
    plan = stop_planner.plan(scene, PlanOptions(sigma=largest, samples=0))  # it plans
    assert all(s.inscribed_radius >= largest for s in plan.stops)
    with pytest.raises(InfeasiblePlanError):  # and a millimetre more does not
        stop_planner.plan(scene, PlanOptions(sigma=largest + 0.0011, samples=0))


def test_tray_out_of_reach_has_an_empty_region(stop_planner, paper_doc):
    doc = copy.deepcopy(paper_doc)
    tray = next(t for t in doc["trays"] if t["id"] == "tray_4")
    tray["pose"]["z"] = 2.4  # far above the arm's reach, on a column standing on its table
    column = {"shape": "box", "size": [0.4, 0.3, 1.675]}
    at = {"x": tray["pose"]["x"], "y": tray["pose"]["y"], "z": 0.72}
    doc["obstacles"].append({"id": "column", "geometry": column, "pose": at})
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(parse_scene(doc), PlanOptions(samples=0))
    assert "tray tray_4 has an empty base region" in e.value.message


def test_start_inside_an_obstacle(stop_planner, paper_doc):
    paper_doc["start"] = {"x": 1.4, "y": 1.9}  # behind table_a, against it
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    assert "the start (1.40, 1.90) is not a valid base position" in e.value.message
    assert "table_a" in e.value.message and e.value.field == "start"
    # Nor can it dock at its own yaw: the footprint there overlaps the table.
    assert "and the base at yaw 0 deg does not fit there: it meets" in e.value.message


def test_goal_walled_off(stop_planner, paper_doc):
    paper_doc["obstacles"].append(
        {"id": "wall", "geometry": {"shape": "box", "size": [0.1, 4.2, 1.0]},
         "pose": {"x": 4.15, "y": 1.0}}
    )  # fmt: skip
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    assert "the goal (4.50, 0.00) cannot be reached from the start" in e.value.message


def test_prefetched_checks_make_a_sigma_change_need_no_verification(stop_planner, paper_doc):
    scene = parse_scene(paper_doc)
    stop_planner.plan(scene, PlanOptions(samples=0))
    stop_planner.prefetch_checks(scene)
    assert stop_planner.prefetch_checks(scene) == 0  # everything is checked now
    for sigma in (0.0, 0.06, 0.11):
        try:
            plan = stop_planner.plan(scene, PlanOptions(sigma=sigma, samples=0))
        except InfeasiblePlanError:
            continue
        assert plan.timings.verification < 0.02


def test_sigma_and_objective_changes_after_planning_ahead_match_a_fresh_planner(
    planner, paper_doc, monkeypatch
):
    """Planned ahead (every sigma band, the other objective, every centre checked), a change
    of sigma, or of objective at the scene's sigma, solves nothing anew; whatever changes, the
    plan, its witnesses and every candidate's verdict are exactly what a planner that has seen
    nothing gives."""
    import threading

    import pickstop.speedups.stop_planner as plan_module

    scene = parse_scene(paper_doc)
    warm = StopPlanner(planner)
    first = warm.plan(scene, PlanOptions(samples=0))
    lock = threading.Lock()
    assert warm.prefetch_selections(scene, PlanOptions(samples=0), lock) >= 2
    warm.prefetch_checks(scene, lock)
    assert not lock.locked()
    radii = sorted({c.inscribed_radius for c in first.candidates})
    sigmas = [0.0, *radii, *(r - 1e-4 for r in radii), radii[-1] + 0.01, 0.06, scene.sigma]
    solved: list[int] = []
    real = plan_module.select_stops

    def counted(*a, **k):
        solved.append(1)
        return real(*a, **k)

    monkeypatch.setattr(plan_module, "select_stops", counted)
    compared = 0
    for sigma in sigmas:
        for objective in ("stops", "time"):
            opts = PlanOptions(sigma=sigma, samples=0, objective=objective)
            ahead = objective == "stops" or sigma == scene.sigma  # what was planned ahead
            solved.clear()
            try:
                a = warm.plan(scene, opts)
            except InfeasiblePlanError as e:
                with pytest.raises(InfeasiblePlanError) as fresh:
                    StopPlanner(planner).plan(scene, opts)
                assert fresh.value.message == e.message
                continue
            if ahead:
                assert solved == [], (sigma, objective)
            solved.clear()
            b = StopPlanner(planner).plan(scene, opts)
            assert solved  # the fresh planner did solve
            assert a.model_dump(exclude={"timings"}) == b.model_dump(exclude={"timings"})
            assert [c.status for c in a.candidates] == [c.status for c in b.candidates]
            compared += 1
    assert compared >= 6


def test_a_background_selection_lets_go_of_the_lock_while_solving(stop_planner, monkeypatch):
    import threading

    import numpy as np

    import pickstop.speedups.stop_planner as plan_module

    lock = threading.Lock()
    seen = []
    real = plan_module.select_stops

    def solve(*a, **k):
        seen.append(lock.locked())
        return real(*a, **k)

    monkeypatch.setattr(plan_module, "select_stops", solve)
    cost = np.array([[0, 5, 1, 2], [5, 0, 1, 2], [1, 1, 0, 1], [2, 2, 1, 0]], float)
    with lock:
        sel = StopPlanner(stop_planner.regions).selection(
            [frozenset("a"), frozenset("ab")], ["a", "b"], cost, "stops", 0.0, 5.0, unlock=lock
        )
        assert lock.locked()  # held again on return
    assert seen == [False] and sel.order == (1,)


def _moved_doc(doc, tray_id, dx):
    doc = copy.deepcopy(doc)
    next(t for t in doc["trays"] if t["id"] == tray_id)["pose"]["x"] += dx
    return doc


def test_a_layout_planned_ahead_leaves_its_plan_nothing_to_compute(planner, paper_doc, monkeypatch):
    """The exact plan of a previewed layout, made ahead while the editor holds still: the
    plan asked for on release computes no region and is the verified plan of that layout."""
    import threading

    from pickstop.runtime.plan_ahead import Yielding

    sp = StopPlanner(planner)
    sp.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    moved = parse_scene(_moved_doc(paper_doc, "tray_1", 2 * 0.025))
    lock = Yielding(threading.Lock(), lambda: False)
    assert sp.plan_ahead(moved, PlanOptions(samples=0), lock)
    assert not lock.lock.locked()
    made = count_regions(monkeypatch)
    plan = sp.plan(moved, PlanOptions(samples=0))
    assert made == [] and plan.verified
    for stop in plan.stops:
        assert_stop_verified(planner, moved, stop)


def test_planning_ahead_gives_way_to_a_request_and_keeps_nothing_half_done(
    planner, paper_doc, monkeypatch
):
    """A request waiting for the planner stops the plan ahead at the regions' next
    checkpoint: the lock is let go, no region of the unfinished layout is kept as done, and
    the request's own plan of that layout is verified."""
    import threading

    from pickstop.regions.kit import RegionKit
    from pickstop.runtime.plan_ahead import Yielding

    sp = StopPlanner(planner)
    sp.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    moved = parse_scene(_moved_doc(paper_doc, "tray_1", -3 * 0.025))
    checks: list[int] = []
    real = RegionKit.checkpoint

    def counted(self):
        checks.append(1)
        return real(self)

    monkeypatch.setattr(RegionKit, "checkpoint", counted)

    def waiting():  # a request comes while the second region step is under way
        return len(checks) >= 2

    lock = Yielding(threading.Lock(), waiting)
    assert not sp.plan_ahead(moved, PlanOptions(samples=0), lock)
    assert not lock.lock.locked()
    assert planner._cached(moved, "tray_1", moved.base_yaw.yaws[0]) is None
    made = count_regions(monkeypatch)
    plan = sp.plan(moved, PlanOptions(samples=0))
    assert "tray_1" in made and plan.verified
    for stop in plan.stops:
        assert_stop_verified(planner, moved, stop)


def test_a_stop_check_is_reused_until_something_near_its_tray_changes(
    stop_planner, planner, paper_doc, monkeypatch
):
    """A stop's exact check depends on its tray's region and the objects the arm can meet
    from there (regions/offgrid.check_key): moving a pillar near trays 1 and 2 checks their
    stops anew and leaves tray 4's as they were."""
    import pickstop.sequence.pure as pure_module
    from pickstop.regions.pipeline import arm_radius

    pillar = {"id": "pillar", "geometry": {"shape": "cylinder", "radius": 0.1, "height": 2.0},
              "pose": {"x": -0.7, "y": 2.7}}  # fmt: skip
    paper_doc["obstacles"].append(pillar)
    scene = parse_scene(paper_doc)
    near = {
        t: any('"pillar"' in d for d in planner.objects_near(scene, scene.tray(t), arm_radius(
            planner, scene.tray(t))))
        for t in ("tray_1", "tray_4")
    }  # fmt: skip
    assert near == {"tray_1": True, "tray_4": False}
    stop_planner.plan(scene, PlanOptions(samples=0))
    checked: list[str] = []
    real = pure_module.feasible_near

    def counted(kit, scene, region, *a, **k):
        checked.append(region.tray_id)
        return real(kit, scene, region, *a, **k)

    monkeypatch.setattr(pure_module, "feasible_near", counted)
    pillar["pose"]["y"] = 2.5
    moved = parse_scene(paper_doc)
    plan = stop_planner.plan(moved, PlanOptions(samples=0))
    assert "tray_4" not in checked and "tray_1" in checked
    for stop in plan.stops:
        assert_stop_verified(planner, moved, stop)


def test_a_tray_only_another_heading_reaches_is_refused_naming_it_and_planned_with_it(
    stop_planner, paper_doc
):
    """The tables against the floor's edge and the base held facing away from them: no base
    position reaches tray_2, and the refusal names the headings that do; letting the plan
    choose among them plans every tray, each stop at a heading that reaches it."""
    paper_doc["floor"]["max"][1] = 2.0
    paper_doc["base_yaw"] = {"fixed": -math.pi / 2}
    with pytest.raises(InfeasiblePlanError) as e:
        stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    msg = str(e.value)
    assert "empty base region" in msg and "the base reaches tray tray_" in msg
    headings = re.search(r"the base reaches tray \S+ at yaw ([-\d, ]+) deg", msg)
    assert headings and "90" in headings.group(1).split(", ") and "base_yaw.candidates" in msg
    paper_doc["base_yaw"] = {"candidates": [-math.pi / 2, math.pi / 2]}
    plan = stop_planner.plan(parse_scene(paper_doc), PlanOptions(samples=0))
    assert sorted(t for s in plan.stops for t in s.trays) == sorted(paper_doc["task"])
    assert all(s.yaw == pytest.approx(math.pi / 2) for s in plan.stops)
