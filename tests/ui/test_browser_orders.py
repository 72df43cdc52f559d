"""The order selector in the browser: a scene with orders shows the selector and the mix's
weighted figures; choosing an order draws that order's plan (its trays' stops only)."""

from __future__ import annotations

import json

import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium

ORDERS = [
    {"id": "o1", "trays": ["tray_1", "tray_2"], "weight": 3},
    {"id": "o2", "parts": ["p4a"], "weight": 1},
]


@pytest.fixture(scope="module")
def app(live_api, tmp_path_factory):
    path = tmp_path_factory.mktemp("orders") / "paper_orders.json"
    path.write_text(json.dumps({**json.loads(b.PAPER.read_text()), "orders": ORDERS}))
    with b.planner(live_api, scene=path) as app:
        yield app


def _trays(plan):
    return {t for s in plan.stops for t in s.trays}


def test_the_mix_shows_and_an_orders_plan_is_drawn(pg, app):
    b.settled(app)
    assert app.order.visible and _trays(app.state.plan) == {"tray_1", "tray_2", "tray_4"}
    b.wait_for(lambda: "Mix of 2 orders" in pg.inner_text("body"), 90, "the mix summary")
    assert "o1 (×3)" in app.mix_md.content and "success" in app.mix_md.content
    seq = app.state.seq
    app.order.value = "o2"
    b.settled(app, since=seq)
    assert _trays(app.state.plan) == {"tray_4"}
    b.wait_for(lambda: "tray_1" not in app.stops_md.content, 10, "the stops list")
    seq = app.state.seq
    app.order.value = "o1"
    b.settled(app, since=seq)
    assert _trays(app.state.plan) == {"tray_1", "tray_2"}
    assert app.state.doc["task"] == ["tray_1", "tray_2", "tray_4"]  # the task is untouched
