"""Layout suggestions: verified figures that a fresh exact plan repeats, witnesses exact with
the robot's whole geometry, plans that do not depend on what was tried before, and the optimum
of a small instance found."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickstop.layout.search import SearchSettings, build_space, exhaustive, search, suggest
from pickstop.layout.slots import tray_slots
from pickstop.layout.verify import LocalEvaluator, scratch_planner
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Order
from pickstop.sequence.mix import mix_document, plan_mix
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner
from tests.utils import assert_stop_verified

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())
TASK = [Order(id="task", trays=["tray_1", "tray_2", "tray_4"])]


def _figures(mix):
    doc = mix_document(mix)
    return doc.totals.model_dump(), [o.model_dump(exclude={"plan"}) for o in doc.orders]


def test_a_suggestion_is_what_a_fresh_exact_plan_of_its_moved_scene_gives(planner):
    scene = parse_scene(PAPER)
    options = PlanOptions(samples=100)
    evaluator = LocalEvaluator(StopPlanner(planner), TASK, options)
    settings = SearchSettings(step=0.1, turns=(0,), suggestions=2, shortlist=6)
    try:
        doc = suggest(planner, evaluator, scene, TASK, ["tray_4"], options, settings)
    finally:
        evaluator.close()
    assert doc.suggestions, doc.notes
    best = doc.suggestions[0]
    assert best.gain.time > 0 and best.after.totals.stops < doc.before.totals.stops
    [move] = best.moves
    assert move.tray == "tray_4" and move.was == scene.tray("tray_4").pose and move.turn == 0
    moved = parse_scene(best.scene)  # a valid scene: standing, free
    assert moved.tray("tray_4").pose == move.to
    fresh = scratch_planner(planner)  # nothing of the search's
    try:
        mix = plan_mix(fresh, moved, TASK, options)
    finally:
        fresh.regions.close()
    totals, orders = _figures(mix)
    assert best.after.totals.model_dump() == totals
    assert [o.model_dump(exclude={"plan"}) for o in best.after.orders] == orders
    for stop in mix.orders[0].plan.stops:
        assert_stop_verified(planner, moved, stop)
    doc_json = json.loads(doc.model_dump_json())
    assert doc_json["suggestions"][0]["moves"][0]["from"]["x"] == 3.6  # 'from' on the wire


def test_a_verified_plan_does_not_depend_on_the_layouts_verified_before(planner):
    layouts = []
    for x, y in ((1.6, 1.8), (3.4, 1.5), (2.0, 1.8)):
        doc = json.loads(json.dumps(PAPER))
        doc["trays"][3]["pose"].update(x=x, y=y)
        layouts.append(parse_scene(doc))
    options = PlanOptions(samples=50)
    got = []
    for order in (layouts, layouts[::-1]):
        sp = scratch_planner(planner)
        try:
            got.append({s.tray("tray_4").pose.x: _figures(plan_mix(sp, s, TASK, options))
                        for s in order})  # fmt: skip
        finally:
            sp.regions.close()
    assert got[0] == got[1]


def test_the_search_finds_the_optimum_of_a_small_instance(planner):
    """Two movable trays, a few slots each: every layout planned exactly is the reference;
    the search ranks a shortlist as long as the instance and finds its optimum."""
    scene = parse_scene(PAPER)
    options = PlanOptions(samples=0)
    settings = SearchSettings(step=0.2, turns=(0,), suggestions=1, shortlist=40)
    space = build_space(planner, scene, TASK, ["tray_4", "tray_2"], options, settings)
    space.slots = {t: s[:5] for t, s in space.slots.items()}
    sp = scratch_planner(planner)  # ranks by plans that do not depend on what came before
    evaluator = LocalEvaluator(sp, TASK, options)
    try:
        every = exhaustive(space, evaluator)
        found = search(space, evaluator, options, settings)
    finally:
        sp.regions.close()
    (_, best), home = every[0], next(v for k, v in every if k == space.home)
    if best < home:
        [s] = found.suggestions
        assert (0, s.ranked["time"], s.ranked["stops"]) == best
    else:
        assert not found.suggestions


def test_slots_stay_on_the_trays_height_in_the_zones_that_admit_them():
    doc = json.loads(json.dumps(PAPER))
    doc["zones"] = [{"id": "b", "outline": [[3.2, 1.3], [4.0, 1.3], [4.0, 1.9], [3.2, 1.9]]},
                    {"id": "a", "outline": [[0.6, 1.3], [1.3, 1.3], [1.3, 1.9], [0.6, 1.9]],
                     "trays": ["tray_1"]}]  # fmt: skip
    scene = parse_scene(doc)
    for s in tray_slots(scene, "tray_4", ["tray_4"], 0.05):
        assert s.z == pytest.approx(0.725) and s.support == "table_b"
        assert s.turn in (0, 90, 180, 270)
    on_a = [s for s in tray_slots(scene, "tray_1", ["tray_1"], 0.05) if s.support == "table_a"]
    assert on_a and all(0.6 <= s.x <= 1.3 for s in on_a)
