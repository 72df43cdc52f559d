"""One token per computation: cancelled with a reason, checked at checkpoints, delivered into
a thread between them, given way to in the background, and never swallowed."""

from __future__ import annotations

import threading
import time

import pytest

from pickstop.runtime.cancel import (
    NEVER,
    Cancelled,
    Token,
    Work,
    checkpoint,
    current,
    giving_way,
    scope,
)


def test_a_token_is_cancelled_once_with_its_first_reason():
    token, called = Token(), []
    token.on_cancel(lambda: called.append(1))
    assert not token.cancelled and token.reason is None
    token.check()
    token.cancel("deadline")
    token.cancel("cancelled")
    assert token.reason == "deadline" and called == [1]
    with pytest.raises(Cancelled, match="deadline"):
        token.check()
    token.on_cancel(lambda: called.append(2))  # too late to wait: runs at once
    assert called == [1, 2]


def test_checkpoints_check_the_token_of_the_computation_in_this_thread():
    assert current() is NEVER
    checkpoint()
    token = Token()
    with scope(token):
        checkpoint()
        token.cancel()
        with pytest.raises(Cancelled):
            checkpoint()
    checkpoint()  # outside the scope again
    seen: list[Token] = []
    with scope(token):
        t = threading.Thread(target=lambda: seen.append(current()))
        t.start()
        t.join()
    assert seen == [NEVER]  # another thread is another computation


def test_giving_way_stops_at_the_checkpoint_and_names_why():
    flag = [False]
    outer = Token()
    with scope(outer), giving_way(lambda: flag[0]) as token:
        checkpoint()
        flag[0] = True
        with pytest.raises(Cancelled, match="give way"):
            checkpoint()
        flag[0] = False
        outer.cancel("deadline")  # the computation around it: its reason wins
        assert token.reason == "deadline"
        with pytest.raises(Cancelled, match="deadline"):
            checkpoint()


def test_cancelled_passes_through_except_exception():
    token = Token()
    token.cancel()

    def swallowing():
        try:
            token.check()
        except Exception:  # what core code may do with its own errors
            return "swallowed"
        return "done"

    with pytest.raises(Cancelled):
        swallowing()


def test_work_stops_at_a_checkpoint_or_between_them():
    """A stopped work's thread stops at its next checkpoint, and a thread that never checks
    is stopped at its next bytecode; the token says why."""
    for checks in (True, False):
        work, started, out = Work(), threading.Event(), []

        def busy(checks=checks, started=started):
            started.set()
            end = time.monotonic() + 10
            while time.monotonic() < end:
                if checks:
                    checkpoint()
            return "finished"

        def run(work=work, out=out, busy=busy):
            try:
                out.append(work.run(busy))
            except Cancelled:
                out.append("cancelled")

        t = threading.Thread(target=run)
        t.start()
        started.wait(5)
        t0 = time.monotonic()
        work.stop("deadline")
        t.join(5)
        assert out == ["cancelled"] and time.monotonic() - t0 < 2
        assert work.stopped and work.token.reason == "deadline"
    late = Work()
    late.stop()
    with pytest.raises(Cancelled):
        late.run(lambda: "never")
