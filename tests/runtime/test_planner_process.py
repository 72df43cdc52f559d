"""Plans are computed in a child process (runtime/planner_process.py): the API process holds no
planner, a child that dies is reported as 503 and replaced, and errors come back typed."""

from __future__ import annotations

import os
import signal
import threading
import time

from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.runtime.planner_process import PlannerProcess
from tests.api.factories import paper, problem

from .conftest import AUTH

PLANS = "/api/v1/plans"


def test_plans_are_computed_in_a_child_process(client, region_db):
    service = client.app.state.service
    quick = {"scene": paper(), "options": {"samples": 0}, "store": False}
    assert client.post(PLANS, json=quick, headers=AUTH).status_code == 200
    assert isinstance(service.planning, PlannerProcess)
    pid = service.planning.pid
    assert pid is not None and pid != os.getpid()
    assert not list(service.planners.slots), "the API process loaded a planner of its own"
    health = client.get("/api/v1/health").json()
    assert {"robot": "tiago", "database": region_db[1].id} in health["loaded"]
    # Errors raised in the child arrive as the same problems: an infeasible plan is a 422.
    tight = {"scene": paper(), "options": {"sigma": 0.9, "samples": 0}, "store": False}
    body = problem(client.post(PLANS, json=tight, headers=AUTH), 422)
    assert body["title"] == "Infeasible plan"


def test_a_planner_process_that_dies_is_reported_and_replaced(api_settings):
    with TestClient(create_app(api_settings)) as c:
        service = c.app.state.service
        quick = {"scene": paper(), "options": {"samples": 0}, "store": False}
        assert c.post(PLANS, json=quick, headers=AUTH).status_code == 200
        first = service.planning.pid
        helpers = _children(first)  # the planner's region helpers (runtime/region_processes.py)
        assert helpers, "the paper scene's regions were computed by one process"
        seed = time.time_ns() % 2**31  # nothing cached: a Monte Carlo of several seconds
        heavy = {"scene": paper(), "options": {"samples": 20000, "seed": seed}, "store": False}
        answer: list[object] = []
        worker = threading.Thread(
            target=lambda: answer.append(c.post(PLANS, json=heavy, headers=AUTH))
        )
        worker.start()
        time.sleep(1.0)
        os.kill(first, signal.SIGKILL)
        worker.join(timeout=60)
        body = problem(answer[0], 503)  # type: ignore[arg-type]
        assert "planner process stopped" in body["detail"], body
        assert answer[0].headers["Retry-After"] == "5"  # type: ignore[attr-defined]
        r = c.post(PLANS, json=quick, headers=AUTH)
        assert r.status_code == 200, r.text
        assert service.planning.pid not in (None, first)
        # Its helpers ended with it (they read the end of their pipes).
        end = time.monotonic() + 10
        while any(_alive(h) for h in helpers) and time.monotonic() < end:
            time.sleep(0.05)
        assert not any(_alive(h) for h in helpers)


def _children(pid: int) -> list[int]:
    out: list[int] = []
    for task in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{task}/children") as f:
            out += [int(x) for x in f.read().split()]
    return out


def _alive(pid: int) -> bool:
    """Running (not gone, not a zombie nobody reaped)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_the_planner_process_ends_with_the_service(api_settings):
    """Killed (kill -9), the service leaves no planner process behind: the child reads the end
    of its socket and exits."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "from pickstop.api.service import Service\n"
        "from pickstop.settings import Settings\n"
        f"s = Service(Settings.model_validate_json({api_settings.model_dump_json()!r}))\n"
        "s.planning.preload()\n"
        "print(s.planning.pid, flush=True)\n"
        "sys.stdin.read()\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        child = int(parent.stdout.readline())
        os.kill(child, 0)  # alive
        parent.kill()
        parent.wait(timeout=10)
        deadline = time.time() + 30
        while time.time() < deadline:
            try:
                os.kill(child, 0)
            except ProcessLookupError:
                return
            try:  # a zombie has exited (init reaps it)
                with open(f"/proc/{child}/stat") as f:
                    if f.read().split()[2] == "Z":
                        return
            except FileNotFoundError:
                return
            time.sleep(0.1)
        raise AssertionError(f"planner process {child} outlived the service")
    finally:
        parent.kill()
