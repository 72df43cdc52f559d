"""Progress lines: a step still running after the delay is drawn and named, a quick one not."""

from __future__ import annotations

import io
import time

from pickstop.progress import StepLines


def test_a_long_step_gets_a_line_naming_it_and_a_quick_one_none():
    out = io.StringIO()
    lines = StepLines("robot check", out, delay=0.2, every=0.2)
    lines("quick", 0, 0)
    lines("slow", 0, 100)
    time.sleep(1.0)
    lines("slow", 50, 100)
    time.sleep(1.0)
    lines("", 0, 0)
    lines.close()
    text = out.getvalue()
    assert "quick" not in text
    assert "robot check: slow 0/100 (0%)" in text
    assert "robot check: slow 50/100 (50%)" in text and "s to go" in text
    assert "robot check: slow: done in" in text
