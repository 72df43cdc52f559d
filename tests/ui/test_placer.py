"""The placement worker: drag poses newest-wins, releases and checks never dropped and asked
before a drag's pose, the API's problems handed on as problems."""

from __future__ import annotations

import threading
import time

from pickstop_ui.client import ApiProblem
from pickstop_ui.placer import Placer


class SlowApi:
    """Answers each placement once ``gate`` opens; refuses x < 0."""

    def __init__(self) -> None:
        self.gate, self.asked = threading.Event(), []

    def placement(self, scene, tray, x, y, yaw, z_hint=None):
        self.gate.wait(5)
        self.asked.append((tray, x))
        if x < 0:
            raise ApiProblem(422, "Invalid input", "no", "x")
        return {"tray": tray, "x": x, "y": y, "yaw": yaw, "z": 0.7, "support": "t",
                "free": True, "problem": None, "top": 0.695}  # fmt: skip


def _wait(cond, timeout=5.0):
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def test_a_drag_asks_for_its_newest_pose_and_a_release_is_never_dropped():
    api, got = SlowApi(), []
    placer = Placer(api, lambda ask, answer: got.append((ask.kind, ask.x, answer)))
    try:
        placer.submit("a", {}, 0.1, 0.0, 0.0, 0.7, "drag", 1)  # under way: the gate is shut
        _wait(placer.idle)  # taken, and waiting on the gate
        time.sleep(0.05)
        for x in (0.2, 0.3, 0.4):
            placer.submit("a", {}, x, 0.0, 0.0, 0.7, "drag", 1)
        placer.submit("a", {}, 0.5, 0.0, 0.0, 0.7, "commit", 1, "move a")
        placer.submit("a", {}, 0.6, 0.0, 0.0, 0.7, "drag", 1)
        placer.submit("b", {}, -1.0, 0.0, 0.0, 0.7, "check", 1)
        api.gate.set()
        _wait(lambda: len(got) == 4 and placer.idle())
    finally:
        placer.close()
    # The first pose, then the release and the check in their order, then the newest pose.
    assert [(k, x) for k, x, _ in got] == [("drag", 0.1), ("commit", 0.5), ("check", -1.0),
                                           ("drag", 0.6)]  # fmt: skip
    assert got[1][2]["z"] == 0.7 and isinstance(got[2][2], ApiProblem)
    assert placer.replaced == 3


def test_an_unreachable_api_is_a_problem_with_status_0():
    class Down:
        def placement(self, *a, **k):
            raise OSError("connection refused")

    got = []
    placer = Placer(Down(), lambda ask, answer: got.append(answer))
    try:
        placer.submit("a", {}, 0.0, 0.0, 0.0, 0.0, "check", 1)
        _wait(lambda: len(got) == 1)
    finally:
        placer.close()
    assert isinstance(got[0], ApiProblem) and got[0].status == 0
