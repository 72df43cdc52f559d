"""The planner's orders: an order's trays (parts bring their tray), the document planned for
it, and the mix's weighted figures in words."""

from __future__ import annotations

import json

from pickstop_ui.orders import TASK, mix_summary, order_ids, order_trays, with_order
from tests.ui.conftest import SCENE

ORDERS = [
    {"id": "o1", "trays": ["tray_2", "tray_1"], "weight": 3},
    {"id": "o2", "trays": ["tray_9"], "parts": ["p4a", "p4b"]},
]


def _doc():
    return {**json.loads(SCENE.read_text()), "orders": ORDERS}


def test_an_orders_trays_are_its_trays_then_its_parts_trays_each_once():
    doc = _doc()
    assert order_ids(doc) == ["o1", "o2"] and order_ids({"trays": []}) == []
    assert order_trays(doc, "o1") == ["tray_2", "tray_1"]
    assert order_trays(doc, "o2") == ["tray_4"]  # tray_9 is no tray of the scene
    assert order_trays(doc, "nope") == []


def test_the_document_planned_for_an_order_has_its_trays_as_task_and_leaves_the_layout():
    doc = _doc()
    planned = with_order(doc, "o2")
    assert planned["task"] == ["tray_4"] and doc["task"] == ["tray_1", "tray_2", "tray_4"]
    assert {k: v for k, v in planned.items() if k != "task"} == {
        k: v for k, v in doc.items() if k != "task"
    }
    assert with_order(doc, TASK) == doc and with_order(doc, "nope") == doc


def test_the_mix_summary_gives_weighted_stops_time_success_and_each_order():
    mix = {
        "totals": {"orders": 2, "planned": 2, "failed": [], "stops": 1.75, "time": 21.25,
                   "success": 0.934},
        "orders": [{"id": "o1", "weight": 3.0, "stops": 2, "time": 24.0},
                   {"id": "o2", "weight": 1.0, "stops": 1, "time": 13.0}],
    }  # fmt: skip
    text = mix_summary(mix)
    assert "Mix of 2 orders" in text and "**1.75**" in text and "**21.2 s**" in text
    assert "93.4%" in text and "o1 (×3): 2 stops, 24.0 s" in text
    mix["totals"].update(success=None, failed=["o2"])
    assert "success —" in mix_summary(mix) and "no plan: o2" in mix_summary(mix)
