"""The planner window wired to a fake API (no browser): it draws the scene from the pure
view, plans through the worker, writes the panel and greys out on a refused plan."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest

from pickstop_ui.client import ApiProblem, PlanResult, StoredScene
from tests.conftest import free_port

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


class FakeApi:
    """A stored paper-like scene; every plan is the exact one, unless ``refuse`` is set."""

    base_url = "http://fake"

    def __init__(self, plan) -> None:
        self.doc, self._plan, self.refuse, self.calls = json.loads(SCENE.read_text()), plan, None, 0

    def scene(self, scene_id: str) -> StoredScene:
        return StoredScene(scene_id, "e1", 1, self.doc)

    def plan(self, scene, options, store=False, preview=False, cancel=None) -> PlanResult:
        self.calls += 1
        if self.refuse is not None:
            raise self.refuse
        return PlanResult(self._plan, None, 0.0)


def _wait(cond, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


@pytest.fixture
def window(plans):
    from pickstop_ui.app import PlannerApp

    api = FakeApi(plans[0])
    app = PlannerApp(api, "s1", port=free_port(), draw_robot=False, flat_lighting=True)  # type: ignore[arg-type]
    yield app, api
    app.close()


def test_the_window_draws_the_scene_plans_and_writes_the_panel(window):
    app, api = window
    nodes = app.server.scene._handle_from_node_name
    for tray in api.doc["trays"]:
        assert f"/trays/{tray['id']}/body/wall0" in nodes and f"/trays/{tray['id']}/label" in nodes
    assert "/lights/flat" in nodes and "/start" in nodes and "/goal" in nodes
    _wait(lambda: "ready" in app.status.content)  # the quick plan, then the Monte Carlo
    assert api.calls == 2 and app.state.plan is not None and app.state.drawn_seq == 1
    assert "Stops: **" in app.summary.content and app.stops_md.content.startswith("**Stops**")


def test_a_refused_plan_is_explained_and_the_last_plan_greyed(window):
    app, api = window
    _wait(lambda: "ready" in app.status.content)
    api.refuse = ApiProblem(422, "Infeasible plan", "no plan with sigma = 0.500 m", "sigma")
    app.sigma.value = 0.5
    _wait(lambda: "⚠" in app.status.content and "greyed out" in app.summary.content)
    assert app.status.content == "**Status:** no plan — ⚠ Infeasible plan (field `sigma`)"
    assert "greyed out" in app.summary.content and app.state.error is not None
    assert app.state.plan is not None  # the last valid plan stays


def test_a_removed_tray_leaves_the_drawing_and_the_task(window):
    app, _ = window
    _wait(lambda: "ready" in app.status.content)
    tid = app.state.doc["trays"][0]["id"]
    from pickstop_ui import edits

    app._edit(edits.remove_tray, tid, cause="remove")
    assert all(t["id"] != tid for t in app.state.doc["trays"])
    assert f"/trays/{tid}" not in app.server.scene._handle_from_node_name
    assert f"cb:{tid}" not in app._tray_ui
    _wait(lambda: app.state.seq == 2 and app.state.drawn_seq == 2)


def test_draft_resolution_from_a_change_until_its_success_rates(window):
    """The panel's hidden switch says draft from the change until the plan with success
    rates is drawn; a refused plan ends it too."""
    from pickstop_ui.draft import ATTR

    app, api = window
    _wait(lambda: "ready" in app.status.content)
    assert not app.draft.on and f'{ATTR}="off"' in app.draft._element.content
    gate = threading.Event()
    plan0 = api.plan

    def held(scene, options, store=False, preview=False, cancel=None):
        gate.wait(5)
        return plan0(scene, options, store, preview, cancel)

    api.plan = held
    app.sigma.value = 0.12
    assert app.draft.on and f'{ATTR}="on"' in app.draft._element.content
    gate.set()
    _wait(lambda: "ready" in app.status.content and not app.draft.on)
    assert f'{ATTR}="off"' in app.draft._element.content
    api.plan = plan0
    api.refuse = ApiProblem(422, "Infeasible plan", "no plan with sigma = 0.500 m", "sigma")
    app.sigma.value = 0.5
    _wait(lambda: "⚠" in app.status.content and not app.draft.on)


def test_a_draft_scale_outside_0_to_1_is_refused():
    import viser

    from pickstop_ui.draft import DraftResolution

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        for bad in (0.0, -0.5, 1.5):
            with pytest.raises(ValueError, match="draft scale must be in"):
                DraftResolution(server, bad)
        assert not DraftResolution(server, 1.0).on
    finally:
        server.stop()
