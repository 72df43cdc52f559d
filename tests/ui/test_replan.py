"""The re-plan worker with a fake API and a fake planner window (no server, no browser)."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace
from typing import Any

import pytest

from pickstop_ui.client import ApiProblem, RequestCancelled
from pickstop_ui.replan import Replanner, Request


class FakeApi:
    """Answers each plan request after ``delay`` [s] with a token naming what was asked;
    ``gate`` (when set) holds every answer until it is opened."""

    def __init__(self, delay: float = 0.0, fail: dict[int, Exception] | None = None) -> None:
        self.delay, self.fail = delay, fail or {}
        self.calls: list[tuple[int, int, bool]] = []  # (scene's n, samples, preview)
        self.gate: threading.Event | None = None
        self.hold: dict[int, threading.Event] = {}  # scene's n -> answer once this is set

    def plan(self, scene: dict[str, Any], options: dict[str, Any], store: bool = False,
             preview: bool = False, cancel: threading.Event | None = None) -> Any:  # fmt: skip
        self.calls.append((scene["n"], options["samples"], preview))
        if self.gate is not None:
            self.gate.wait(5)
        if scene["n"] in self.hold:
            self.hold[scene["n"]].wait(5)
        time.sleep(self.delay)
        if (scene["n"], options["samples"]) in self.fail:
            raise self.fail[scene["n"], options["samples"]]
        return SimpleNamespace(plan=("plan", scene["n"], options["samples"]))


class Window:
    def __init__(self) -> None:
        self.events: list[tuple[str, int, Any]] = []
        self.done = threading.Event()

    def plan_ready(self, req: Request, plan: Any, final: bool) -> None:
        self.events.append(("final" if final else "quick", req.seq, plan))
        self.done.set()

    def plan_failed(self, req: Request, problem: ApiProblem) -> None:
        self.events.append(("failed", req.seq, problem))
        self.done.set()

    def success_rates_started(self, req: Request) -> None:
        self.events.append(("mc", req.seq, None))

    def success_rates_failed(self, req: Request, problem: ApiProblem) -> None:
        self.events.append(("mc failed", req.seq, problem))
        self.done.set()


def _wait_for(cond, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.005)


def _settle(r: Replanner, seconds: float = 0.6) -> None:
    time.sleep(seconds)
    r.close()


@pytest.fixture
def window() -> Window:
    return Window()


def test_a_request_is_planned_quickly_then_with_success_rates(window):
    api = FakeApi()
    r = Replanner(api, window, mc_samples=50, mc_quiet=0.05)
    doc = {"n": 1}
    req = r.submit(doc, {"samples": 0}, "open")
    doc["n"] = 99  # the request copied the document as it was
    _settle(r)
    assert req.seq == 1 and req.scene == {"n": 1} and req.cause == "open"
    assert api.calls == [(1, 0, False), (1, 50, False)]
    assert window.events == [
        ("quick", 1, ("plan", 1, 0)), ("mc", 1, None), ("final", 1, ("plan", 1, 50)),
    ]  # fmt: skip


def test_a_preview_gets_no_monte_carlo(window):
    api = FakeApi()
    r = Replanner(api, window, mc_quiet=0.01)
    r.submit({"n": 1}, {"samples": 0}, "dragging", preview=True)
    _settle(r, 0.3)
    assert api.calls == [(1, 0, True)] and [e[0] for e in window.events] == ["quick"]


def test_requests_made_while_one_is_planned_collapse_into_the_newest(window):
    api = FakeApi()
    api.gate = threading.Event()
    r = Replanner(api, window, mc_quiet=10.0)
    api.hold[7] = window.done  # 7 is answered once 1's answer is drawn (else it may replace it)
    r.submit({"n": 1}, {"samples": 0}, "a", preview=True)
    _wait_for(lambda: api.calls)  # the worker now waits on the API with request 1
    for n in range(2, 8):
        r.submit({"n": n}, {"samples": 0}, "drag", preview=True)
    api.gate.set()
    _settle(r, 0.3)
    # 1 was asked, 2..6 were replaced while pending, 7 was asked; 1's answer is drawn
    # although newer requests wait: it is newer than what the window shows.
    assert [c[0] for c in api.calls] == [1, 7]
    assert window.events == [("quick", 1, ("plan", 1, 0)), ("quick", 7, ("plan", 7, 0))]
    assert r.newer(Request(6, {}, {}, 0.0, "")) and not r.newer(Request(7, {}, {}, 0.0, ""))


def test_a_change_during_the_quiet_time_skips_the_monte_carlo(window):
    api = FakeApi()
    r = Replanner(api, window, mc_samples=50, mc_quiet=0.3)
    r.submit({"n": 1}, {"samples": 0}, "sigma")
    time.sleep(0.1)
    r.submit({"n": 2}, {"samples": 0}, "sigma")
    _settle(r, 0.8)
    assert (1, 50, False) not in api.calls and (2, 50, False) in api.calls
    assert [e[:2] for e in window.events] == [("quick", 1), ("quick", 2), ("mc", 2), ("final", 2)]


def test_problems_are_reported_and_an_unreachable_api_is_named(window):
    refused = ApiProblem(422, "Infeasible plan", "no plan with sigma = 0.5 m", "sigma")
    api = FakeApi(fail={(1, 0): refused, (2, 0): ConnectionError("refused"),
                        (3, 50): ApiProblem(500, "Server error", "boom")})  # fmt: skip
    r = Replanner(api, window, mc_samples=50, mc_quiet=0.01)
    for n in (1, 2, 3):
        window.done.clear()
        r.submit({"n": n}, {"samples": 0}, "x")
        assert window.done.wait(2)
        time.sleep(0.2)
    r.close()
    kinds = [(e[0], e[1]) for e in window.events]
    assert kinds == [("failed", 1), ("failed", 2), ("quick", 3), ("mc", 3), ("mc failed", 3)]
    assert window.events[0][2] is refused
    unreachable = window.events[1][2]
    assert unreachable.status == 0 and unreachable.title == "API unreachable"
    assert "refused" in unreachable.detail


def test_a_stale_failure_is_not_reported(window):
    api = FakeApi(delay=0.2, fail={(1, 0): ApiProblem(422, "Infeasible plan", "x")})
    r = Replanner(api, window, mc_quiet=10.0)
    r.submit({"n": 1}, {"samples": 0}, "a")
    time.sleep(0.05)
    r.submit({"n": 2}, {"samples": 0}, "b")
    _settle(r, 0.8)
    assert [e[:2] for e in window.events] == [("quick", 2)]


def test_a_drag_faster_than_the_api_still_draws_previews(window):
    """Poses every 20 ms, the API answering in 50 ms: previews follow at the API's pace
    instead of waiting for the drag to pause."""
    api = FakeApi(delay=0.05)
    r = Replanner(api, window, mc_quiet=10.0)
    for n in range(50):
        r.submit({"n": n}, {"samples": 0}, "drag", preview=True)
        time.sleep(0.02)
    _settle(r, 0.3)
    drawn = [e[1] for e in window.events]
    assert len(drawn) >= 10 and drawn == sorted(drawn) and drawn[-1] == 50


def test_a_result_not_yet_drawn_is_replaced_by_a_newer_one():
    class SlowWindow(Window):
        def plan_ready(self, req, plan, final):
            time.sleep(0.3)  # drawing is slower than the API
            super().plan_ready(req, plan, final)

    window = SlowWindow()
    r = Replanner(FakeApi(delay=0.01), window, mc_quiet=10.0)
    for n in range(20):
        r.submit({"n": n}, {"samples": 0}, "drag", preview=True)
        time.sleep(0.03)
    _settle(r, 1.0)
    drawn = [e[1] for e in window.events]
    assert drawn[-1] == 20 and len(drawn) <= 5 and r.skipped >= 10


def test_a_drawing_error_does_not_stop_the_worker():
    class Broken(Window):
        def plan_ready(self, req, plan, final):
            if req.seq == 1:
                raise RuntimeError("bad drawing")
            super().plan_ready(req, plan, final)

    window = Broken()
    r = Replanner(FakeApi(), window, mc_quiet=10.0)
    r.submit({"n": 1}, {"samples": 0}, "a", preview=True)
    time.sleep(0.2)
    r.submit({"n": 2}, {"samples": 0}, "b", preview=True)
    _settle(r, 0.3)
    assert [e[:2] for e in window.events] == [("quick", 2)]


def test_close_stops_the_worker(window):
    r = Replanner(FakeApi(), window)
    r.close()
    assert not any(t.is_alive() for t in r._threads)


def test_a_request_during_the_monte_carlo_is_asked_at_once(window):
    """The success rates run beside the quick plans: a change while they are computed is
    planned without waiting for them, and their result, now stale, is not drawn."""
    api = FakeApi()
    slow_mc = threading.Event()
    plan0 = api.plan

    def plan(scene, options, store=False, preview=False, cancel=None):
        if options["samples"]:
            slow_mc.wait(2)  # a long Monte Carlo
        return plan0(scene, options, store, preview)

    api.plan = plan  # type: ignore[method-assign]
    r = Replanner(api, window, mc_samples=50, mc_quiet=0.05)
    r.submit({"n": 1}, {"samples": 0}, "sigma")
    time.sleep(0.3)  # the Monte Carlo of 1 is running
    t0 = time.perf_counter()
    window.done.clear()
    r.submit({"n": 2}, {"samples": 0}, "sigma")
    while not any(e[:2] == ("quick", 2) for e in window.events):
        assert time.perf_counter() - t0 < 1.0, "the quick plan waited for the Monte Carlo"
        time.sleep(0.01)
    slow_mc.set()
    _settle(r, 0.5)
    assert ("final", 1) not in [e[:2] for e in window.events]
    assert [e[:2] for e in window.events][-1] == ("final", 2)


def test_a_newer_request_cancels_the_monte_carlo_under_way(window):
    """The API computes one request at a time: the Monte Carlo under way is cancelled (its
    connection closed) when a change comes, so the next quick plan does not wait for it."""
    api = FakeApi()
    plan0 = api.plan
    cancels: list[threading.Event] = []

    def plan(scene, options, store=False, preview=False, cancel=None):
        if options["samples"]:
            assert cancel is not None, "a Monte Carlo is always asked cancellably"
            cancels.append(cancel)
            if scene["n"] == 2 or not cancel.wait(5):  # the first would take 5 s
                return plan0(scene, options, store, preview)
            raise RequestCancelled("cancelled")
        return plan0(scene, options, store, preview)

    api.plan = plan  # type: ignore[method-assign]
    r = Replanner(api, window, mc_samples=50, mc_quiet=0.05)
    r.submit({"n": 1}, {"samples": 0}, "sigma")
    _wait(lambda: len(cancels) == 1)
    assert not cancels[0].is_set()
    r.submit({"n": 2}, {"samples": 0}, "sigma")
    _wait(lambda: cancels[0].is_set())
    _wait(lambda: ("final", 2) in [e[:2] for e in window.events])
    r.close()
    assert r.cancelled == 1
    kinds = [e[:2] for e in window.events]
    assert ("final", 1) not in kinds and ("mc failed", 1) not in kinds, "no word of it"
    assert kinds[-1] == ("final", 2) and len(cancels) == 2 and not cancels[1].is_set()


def _wait(cond, timeout: float = 3.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)
