"""A product mix on one layout: each tray's region computed once, each order's plan the plan
of its trays alone, the totals weighted by how often each order is made."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from pickstop.errors import InputError
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Order, SceneError
from pickstop.scene.orders import parse_orders, scene_orders
from pickstop.sequence import mix_model as mm
from pickstop.sequence.mix import mix_document, mix_totals, order_scene, plan_mix
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner
from tests.utils import assert_stop_verified, count_regions

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = json.loads((EXAMPLES / "paper_experiment.json").read_text())
ORDERS = [
    {"id": "a", "trays": ["tray_1", "tray_2", "tray_4"], "weight": 3},
    {"id": "b", "trays": ["tray_2", "tray_3"]},
    {"id": "c", "parts": ["p4a", "p1b"], "weight": 0.5},  # trays 4 and 1, by their parts
]


def _same_plan(a, b) -> None:
    """Two plan documents equal but for how long they took."""
    assert a.model_dump(exclude={"timings"}) == b.model_dump(exclude={"timings"})


def test_each_tray_region_is_computed_once_and_each_order_plans_as_alone(planner, monkeypatch):
    scene = parse_scene({**PAPER, "orders": ORDERS})
    planner.forget()
    made = count_regions(monkeypatch)
    sp = StopPlanner(planner)
    mix = plan_mix(sp, scene, scene_orders(scene), PlanOptions(samples=100), workers=1)
    assert sorted(made) == ["tray_1", "tray_2", "tray_3", "tray_4"]  # once each, shared
    assert [op.trays for op in mix.orders] == [
        ("tray_1", "tray_2", "tray_4"), ("tray_2", "tray_3"), ("tray_4", "tray_1"),
    ]  # fmt: skip
    alone = StopPlanner(planner)  # a planner of its own: nothing of the mix's plans
    for op in mix.orders:
        assert op.plan is not None and op.plan.trays == list(op.trays)
        _same_plan(op.plan, alone.plan(order_scene(scene, op.trays), PlanOptions(samples=100)))
        for stop in op.plan.stops:
            assert_stop_verified(planner, scene, stop)
    assert sorted(made) == ["tray_1", "tray_2", "tray_3", "tray_4"]  # and none again since


def test_the_mix_document_weighs_each_order_by_how_often_it_is_made(planner):
    scene = parse_scene({**PAPER, "orders": ORDERS})
    mix = plan_mix(StopPlanner(planner), scene, scene_orders(scene), PlanOptions(samples=50))
    doc = mix_document(mix, ["a.plan.json", "b.plan.json", "c.plan.json"])
    plans = [op.plan for op in mix.orders]
    w = [3.0, 1.0, 0.5]
    mean = sum(wi * p.totals.time.total for wi, p in zip(w, plans, strict=True)) / sum(w)
    assert doc.totals.time == pytest.approx(mean)
    stops = sum(wi * p.totals.stops for wi, p in zip(w, plans, strict=True)) / sum(w)
    assert doc.totals.stops == pytest.approx(stops)
    assert doc.totals.naive_stops == pytest.approx((3 * 3 + 2 + 0.5 * 2) / 4.5)
    assert doc.orders[0].plan == "a.plan.json" and doc.orders[2].trays == ["tray_4", "tray_1"]
    assert doc.totals.success is not None and 0 < doc.totals.success <= 1
    assert mm.Mix.model_validate_json(doc.model_dump_json()) == doc


def test_an_order_without_a_plan_keeps_its_reason_and_the_rest_are_planned(planner):
    doc = copy.deepcopy(PAPER)
    tray = doc["trays"][3]  # tray_4 on a column far above the arm's reach
    tray["pose"]["z"] = 2.4
    column = {"shape": "box", "size": [0.4, 0.3, 1.675]}
    at = {"x": tray["pose"]["x"], "y": tray["pose"]["y"], "z": 0.72}
    doc["obstacles"].append({"id": "column", "geometry": column, "pose": at})
    scene = parse_scene(doc)
    orders = [Order(id="low", trays=["tray_1", "tray_2"]), Order(id="high", trays=["tray_4"])]
    mix = plan_mix(StopPlanner(planner), scene, orders, PlanOptions(samples=0))
    low, high = mix.orders
    assert low.plan is not None and high.plan is None
    assert "tray tray_4 has an empty base region" in high.error
    totals = mix_document(mix).totals
    assert totals.failed == ["high"] and totals.planned == 1 and totals.weight == 1.0
    assert totals.stops == low.plan.totals.stops


def test_totals_are_weighted_means_over_the_planned_orders():
    figs = [
        mm.OrderFigures(id="a", weight=1, trays=["t"], stops=1, time=10, route_length=1,
                        success=0.9, naive_stops=2, naive_time=20),
        mm.OrderFigures(id="b", weight=3, trays=["t"], stops=3, time=30, route_length=3,
                        success=0.5, naive_stops=3, naive_time=40),
        mm.OrderFigures(id="c", weight=9, trays=["t"], error="none"),
    ]  # fmt: skip
    t = mix_totals(figs)
    assert (t.orders, t.planned, t.failed, t.weight) == (3, 2, ["c"], 4)
    assert (t.stops, t.time, t.success) == (2.5, 25, pytest.approx(0.6))
    assert (t.naive_time, t.saving_time, t.saving_fraction) == (35, 10, pytest.approx(10 / 35))


def test_orders_naming_what_the_scene_lacks_are_refused_by_field():
    with pytest.raises(SceneError) as e:
        parse_scene({**PAPER, "orders": [*ORDERS, {"id": "a", "trays": ["tray_9", "tray_1"]}]})
    assert e.value.problems == [
        ("orders", "duplicate order id 'a'"),
        ("orders.3.trays.0", "order 'a': unknown tray 'tray_9'"),
    ]
    scene = parse_scene(PAPER)
    with pytest.raises(SceneError) as e:
        parse_orders([{"id": "x", "parts": ["p1a", "nope", "p1a"], "weight": -1}], scene)
    assert e.value.problems[0] == ("orders.0.weight", "Input should be greater than 0")
    with pytest.raises(SceneError) as e:
        parse_orders([{"id": "x", "parts": ["p1a", "nope", "p1a"]}], scene)
    assert e.value.problems == [
        ("orders.0.parts.1", "order 'x': unknown part 'nope'"),
        ("orders.0.parts", "order 'x' lists 'p1a' twice"),
    ]
    with pytest.raises(SceneError, match="an order needs at least one tray or part"):
        parse_orders([{"id": "x"}], scene)
    with pytest.raises(InputError, match="the scene has no orders") as e2:
        scene_orders(scene)
    assert e2.value.field == "orders"
