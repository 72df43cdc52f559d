"""The guidance fetcher: off the caller's thread, the newest request only, stale answers
dropped, a clear cancels the request under way."""

from __future__ import annotations

import threading
import time

from pickstop_ui.client import ApiProblem, RequestCancelled
from pickstop_ui.guidance_layer import GuidanceFetcher


class FakeClient:
    def __init__(self, delay=0.2):
        self.delay, self.calls, self.cancelled = delay, [], 0

    def guidance(self, scene, tray, sigma=None, cancel=None):
        self.calls.append((tray, threading.current_thread().name))
        end = time.monotonic() + self.delay
        while time.monotonic() < end:
            if cancel is not None and cancel.is_set():
                self.cancelled += 1
                raise RequestCancelled("cancelled")
            time.sleep(0.005)
        if tray == "bad":
            raise ApiProblem(422, "Invalid input", "no tray 'bad'", "tray")
        return {"properties": {"tray": tray}, "features": []}


def _wait(cond, timeout=5.0):
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end
        time.sleep(0.01)


def _fetcher(client):
    got = []
    f = GuidanceFetcher(client, lambda req, ans: got.append((req.tray, ans)))
    return f, got


def test_answers_come_on_the_fetchers_thread_and_only_the_newest_is_drawn():
    client = FakeClient()
    f, got = _fetcher(client)
    try:
        f.submit({"trays": []}, "tray_1", 0.05)
        time.sleep(0.05)
        f.submit({"trays": []}, "tray_2", 0.05)  # cancels tray_1's request under way
        f.submit({"trays": []}, "tray_4", 0.05)  # replaces tray_2's before it is asked
        _wait(lambda: got)
        time.sleep(0.3)
        assert [t for t, _ in got] == ["tray_4"]
        assert client.cancelled == 1 and [t for t, _ in client.calls] == ["tray_1", "tray_4"]
        assert all(name == "pickstop-guidance" for _, name in client.calls)
    finally:
        f.close()


def test_a_clear_drops_the_answer_under_way_and_a_problem_is_handed_on():
    client = FakeClient()
    f, got = _fetcher(client)
    try:
        f.submit({}, "tray_1", 0.05)
        time.sleep(0.05)
        f.clear()
        time.sleep(0.4)
        assert got == [] and client.cancelled == 1
        f.submit({}, "bad", 0.05)
        _wait(lambda: got)
        assert isinstance(got[0][1], ApiProblem) and got[0][1].field == "tray"
    finally:
        f.close()
