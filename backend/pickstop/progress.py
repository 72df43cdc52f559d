"""Progress of long computations: the core reports steps as data, an edge draws them.

A core function that may run for seconds takes ``steps: Steps | None`` and calls
``steps(name, done, total)`` as it goes (``total`` 0: no count known); :class:`StepLines`
draws those calls on a terminal: a step still running after ``delay`` seconds gets a line
naming it, with its count, elapsed time and an estimate of the rest, redrawn as it goes.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

#: ``steps(name, done, total)``: the step ``name`` has ``done`` of ``total`` units done; a
#: new name starts a new step, an empty one ends the last.
Steps = Callable[[str, int, int], None]


def step(steps: Steps | None, name: str, done: int = 0, total: int = 0) -> None:
    """Report to ``steps`` if there is one."""
    if steps is not None:
        steps(name, done, total)


class StepLines:
    """Draws steps on ``stream``: each one still running after ``delay`` [s] gets a line
    (redrawn in place on a terminal, every ``every`` [s] otherwise), and a last line with
    its time when it ends."""

    def __init__(
        self, prefix: str, stream: TextIO | None = None, delay: float = 2.0, every: float = 10.0
    ) -> None:
        self.prefix, self.stream, self.delay = prefix, stream or sys.stderr, delay
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.every = 0.5 if self.tty else every
        self._lock = threading.Lock()
        self._name: str | None = None
        self._done = self._total = 0
        self._t0 = self._drawn = 0.0
        self._shown = False
        self._stop = threading.Event()
        self._ticker = threading.Thread(target=self._tick, daemon=True)
        self._ticker.start()

    def __call__(self, name: str, done: int, total: int) -> None:
        with self._lock:
            if name != self._name:
                self._end()
                self._name, self._t0, self._shown = name or None, time.perf_counter(), False
            self._done, self._total = done, total

    def close(self) -> None:
        """End the last step and stop drawing."""
        self._stop.set()
        with self._lock:
            self._end()
            self._name = None

    def _tick(self) -> None:
        while not self._stop.wait(0.25):
            with self._lock:
                now = time.perf_counter()
                if self._name is None or now - self._t0 < self.delay:
                    continue
                if not self._shown or now - self._drawn >= self.every:
                    self._draw(now)

    def _line(self, now: float) -> str:
        elapsed = now - self._t0
        text = f"{self.prefix}: {self._name}"
        if self._total:
            frac = min(self._done / self._total, 1.0)
            text += f" {self._done:,}/{self._total:,} ({frac:.0%})"
            if 0 < frac < 1:
                text += f", {elapsed * (1 - frac) / frac:.0f} s to go"
        return text + f", {elapsed:.0f} s"

    def _draw(self, now: float) -> None:
        line = self._line(now)
        if self.tty:
            self.stream.write("\r\033[K" + line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()
        self._shown, self._drawn = True, now

    def _end(self) -> None:
        if self._name is None or not self._shown:
            return
        elapsed = time.perf_counter() - self._t0
        end = f"{self.prefix}: {self._name}: done in {elapsed:.1f} s"
        self.stream.write(("\r\033[K" if self.tty else "") + end + "\n")
        self.stream.flush()
        self._shown = False
