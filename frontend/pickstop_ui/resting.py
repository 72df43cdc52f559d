"""What a tray stands on while the planner edits it: pure functions of the API's placements.

The API's ``POST /placements`` (:func:`pickstop.scene.supports.place_tray`, the rule the
scene check applies) says, for a tray's footprint at ``(x, y, yaw)``, the support under it,
the pose height that rests it there and why it would not stand free. Here that answer becomes
what the planner shows: the height a dragged tray follows (:func:`follow`), a short reason
when it floats or overlaps (:func:`short_reason`: "nothing under it", "overlaps tray_2"), the
panel's support line, and :class:`Standing`, which trays of the working document do not
stand and where each last stood (the scene the API is asked with, which it must accept).
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

FLOOR = "floor"  # the support id of the floor (as the API names it)
INVALID = (230, 30, 30)  # a tray that does not stand: red
INVALID_OPACITY = 0.45  # and translucent
SAME_Z = 1e-9  # [m] a followed height this close to the tray's own is its own

_REASONS = (
    (re.compile(r"would stand on nothing"), lambda m, n: "nothing under it"),
    (re.compile(r"would not be inside the floor"), lambda m, n: "outside the floor"),
    (
        re.compile(
            r"would overhang the edge of (?:the top of obstacle '([^']+)'|the floor) by ([\d.]+) m"
        ),
        lambda m, n: f"overhangs {_name(m[1] or FLOOR, n)} by {m[2]} m",
    ),
    (re.compile(r"would intersect tray '([^']+)'"), lambda m, n: f"overlaps {n.get(m[1], m[1])}"),
    (re.compile(r"would intersect obstacle '([^']+)'"), lambda m, n: f"cuts into {_name(m[1], n)}"),
)


def _name(support: str, names: Mapping[str, str]) -> str:
    return "the floor" if support == FLOOR else names.get(support, support)


def short_reason(problem: str | None, names: Mapping[str, str] | None = None) -> str | None:
    """The API's ``problem`` of a placement in a few words (None: it stands free); ``names``
    maps ids to what the engineer calls them. An unknown wording is kept whole."""
    if problem is None:
        return None
    for pattern, say in _REASONS:
        m = pattern.search(problem)
        if m is not None:
            return say(m, names or {})
    return problem


@dataclass(frozen=True)
class Rest:
    """Where a tray asked about at ``(x, y)`` [m], ``yaw`` [rad] stands: ``z`` the pose height
    [m] it is drawn and kept at, ``support`` the id under it (None: nothing), ``top`` that
    support's top height [m], ``why`` the short reason it does not stand free (None: it does)."""

    tray: str
    x: float
    y: float
    yaw: float
    z: float
    support: str | None
    top: float | None
    why: str | None

    @property
    def ok(self) -> bool:
        return self.why is None


def follow(answer: Mapping[str, Any], z_now: float, names: Mapping[str, str] | None = None) -> Rest:
    """The rest of a tray from the API's placement ``answer``: its height follows the support
    under it; with nothing under it the height stays ``z_now`` [m] (it floats, and says so)."""
    z, top = answer.get("z"), answer.get("top")
    if z is None or abs(float(z) - z_now) <= SAME_Z:
        z = z_now  # a tray that rests keeps its height to the bit (an undo stays exact)
    return Rest(
        tray=str(answer["tray"]),
        x=float(answer["x"]),
        y=float(answer["y"]),
        yaw=float(answer["yaw"]),
        z=float(z),
        support=answer.get("support"),
        top=None if top is None else float(top),
        why=None if answer.get("free") else short_reason(answer.get("problem"), names) or "?",
    )


def still_placed(rests: Mapping[str, Rest], doc: Mapping[str, Any]) -> dict[str, Rest]:
    """The ``rests`` of trays of ``doc`` still at the place they were asked about (x, y, yaw):
    an undo or another edit leaves the others to be asked anew."""
    poses = {t["id"]: t.get("pose", {}) for t in doc.get("trays", [])}
    return {
        k: r for k, r in rests.items()
        if k in poses and (r.x, r.y, r.yaw) == tuple(float(poses[k].get(a, 0.0))
                                                     for a in ("x", "y", "yaw"))
    }  # fmt: skip


def support_line(rest: Rest | None, names: Mapping[str, str] | None = None) -> str:
    """The panel's support readout: what the tray stands on and at what height."""
    if rest is None:
        return ""
    if rest.support is None:
        return f"**Support:** none — ⚠ {rest.why}"
    top = "" if rest.top is None else f" (top {rest.top:.3f} m)"
    said = f"**Support:** {_name(rest.support, names or {})}{top}"
    return said if rest.ok else f"{said} — ⚠ {rest.why}"


def names_of_items(doc: Mapping[str, Any]) -> dict[str, str]:
    """What the engineer calls each tray and obstacle: its name, else its id."""
    items = [*doc.get("trays", []), *doc.get("obstacles", [])]
    return {str(i["id"]): str(i.get("name") or i["id"]) for i in items}


def same_place(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> bool:
    """Do two poses put a tray at the same place (x, y, z [m] and yaw [rad], to the bit)?"""
    if a is None or b is None:
        return False
    return all(float(a.get(k, 0.0)) == float(b.get(k, 0.0)) for k in ("x", "y", "z", "yaw"))


@dataclass(frozen=True)
class Standing:
    """The trays of the working document that do not stand (id -> short reason) and, for
    every tray, the last pose at which it stood (the stored scene's poses to begin with)."""

    problems: Mapping[str, str] = field(default_factory=dict)
    last_good: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    @classmethod
    def start(cls, doc: Mapping[str, Any]) -> Standing:
        """A scene the API accepted: every tray stands where it is."""
        return cls({}, {t["id"]: dict(t.get("pose", {})) for t in doc.get("trays", [])})

    def told(self, tid: str, why: str | None, pose: Mapping[str, Any] | None = None) -> Standing:
        """Tray ``tid`` stands (``why`` None; at ``pose``, if given, which becomes its last
        good pose) or does not, for ``why``."""
        problems = {k: v for k, v in self.problems.items() if k != tid}
        if why is not None:
            problems[tid] = why
        good = dict(self.last_good)
        if why is None and pose is not None:
            good[tid] = dict(pose)
        return replace(self, problems=problems, last_good=good)

    def unknown(self, doc: Mapping[str, Any]) -> list[str]:
        """The trays of ``doc`` whose standing must be asked: not at their last good pose
        (an undo, a copy, a revert) or said not to stand; a tray at its last good pose stands."""
        return [
            t["id"]
            for t in doc.get("trays", [])
            if t["id"] in self.problems
            or not same_place(t.get("pose"), self.last_good.get(t["id"]))
        ]

    def settle(self, doc: Mapping[str, Any]) -> Standing:
        """Forget trays no longer in ``doc``, and the problems of trays back at a good pose."""
        poses = {t["id"]: t.get("pose") for t in doc.get("trays", [])}
        problems = {
            k: v for k, v in self.problems.items()
            if k in poses and not same_place(poses[k], self.last_good.get(k))
        }  # fmt: skip
        good = {k: v for k, v in self.last_good.items() if k in poses}
        return Standing(problems, good)

    def ask_doc(self, doc: Mapping[str, Any]) -> dict[str, Any]:
        """``doc`` as the API is asked with about a tray: every tray not at a pose known to
        stand put back at its last good pose (the API checks the scene first and refuses one
        with a floating tray; the asked tray's own place does not count)."""
        out = copy.deepcopy(dict(doc))
        for t in out.get("trays", []):
            good = self.last_good.get(t["id"])
            if good is not None:
                t["pose"] = dict(good)
        return out

    def verdict(self, names: Mapping[str, str] | None = None) -> str | None:
        """Why the layout cannot be planned or saved ("tray_4: nothing under it; ..."), or
        None when every tray stands."""
        if not self.problems:
            return None
        n = names or {}
        return "; ".join(f"{n.get(k, k)}: {v}" for k, v in sorted(self.problems.items()))
