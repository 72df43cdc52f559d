"""Arrivals at stops, as a dispatch observes them: the log a fit learns error models from.

An arrival is one stop node of one order: the pose the order planned there, the pose the
vehicle reported once it stood at the node (the first state whose ``lastNodeId`` is the node,
not driving), when, and how its picks ended. Logs are JSON lines (``pickstop.arrival``, one
record a line, appended as arrivals complete), map frame, metres and radians.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pickstop.errors import InputError

FORMAT = "pickstop.arrival"
MAX_LINES = 1_000_000
MAX_BYTES = 512 * 1024 * 1024


class Pose(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    x: float = Field(allow_inf_nan=False)  # [m]
    y: float = Field(allow_inf_nan=False)  # [m]
    theta: float | None = Field(default=None, allow_inf_nan=False)  # [rad]


class PickOutcome(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    action_id: str
    tray_id: str | None = None
    part_id: str | None = None
    status: str  # the action's last status: FINISHED, FAILED, or where it stood
    result: str | None = None


class Arrival(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Literal["pickstop.arrival"] = "pickstop.arrival"
    version: Literal[1] = 1
    order_id: str
    node_id: str
    sequence_id: int
    stop: int | None = None  # index among the order's stop nodes
    trays: list[str] = Field(default_factory=list)  # the trays its picks are from
    manufacturer: str
    serial_number: str
    map_id: str | None = None
    planned: Pose
    reported: Pose
    time: str  # ISO 8601: the vehicle's state timestamp on arrival
    picks: list[PickOutcome]
    ok: bool  # every pick finished


def line(a: Arrival) -> str:
    """One log line (no newline)."""
    return a.model_dump_json(exclude_none=True)


class Recorder:
    """Appends arrivals to a JSON-lines file as they come (thread-safe; flushed per line)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        self.written = 0
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.touch()
        except OSError as e:
            raise InputError(f"--record {path}: {e}", field="record") from None

    def __call__(self, a: Arrival) -> None:
        with self._lock, self.path.open("a") as f:
            f.write(line(a) + "\n")
            self.written += 1


def parse(doc: Any, where: str = "arrival") -> Arrival:
    try:
        return Arrival.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(root)"
        raise InputError(f"{where}: {loc}: {err['msg']}", field=loc) from None


def read_log(path: str | Path) -> list[Arrival]:
    """Every arrival of a JSON-lines log (blank lines skipped); InputError naming the line."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"log {path}: no such file", field="log")
    if p.stat().st_size > MAX_BYTES:
        raise InputError(f"log {path}: larger than {MAX_BYTES} bytes", field="log")
    out: list[Arrival] = []
    with p.open() as f:
        for k, text in enumerate(f, start=1):
            if not text.strip():
                continue
            if len(out) >= MAX_LINES:
                raise InputError(f"log {path}: more than {MAX_LINES} arrivals", field="log")
            try:
                doc = json.loads(text)
            except ValueError as e:
                raise InputError(f"log {path}: line {k}: not JSON ({e})", field="log") from None
            out.append(parse(doc, f"log {path}: line {k}"))
    return out
