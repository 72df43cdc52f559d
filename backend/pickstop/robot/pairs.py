"""The link pairs self-collision checking skips, as data: :class:`DisabledPairs`.

Computed (or read from an SRDF) by :func:`pickstop.robot.selfcollision.disabled_pairs`, used by
the screen (:mod:`pickstop.robot.screen`) and the exact check (:mod:`pickstop.robot.exact`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pickstop.robot.link_geometry import CollisionLink, collision_links
from pickstop.robot.model import RobotModel

Reason = Literal["adjacent", "default", "always", "never", "srdf"]
REASONS: tuple[Reason, ...] = ("adjacent", "default", "always", "never", "srdf")


@dataclass(frozen=True)
class DisabledPair:
    link1: str  # link1 < link2
    link2: str
    reason: Reason


@dataclass(frozen=True)
class DisabledPairs:
    """The candidate link pairs that self-collision checking skips, with their reasons.

    samples: random configurations behind "always"/"never" (0 when read from an SRDF).
    """

    robot_hash: str
    links: tuple[CollisionLink, ...]
    pairs: tuple[DisabledPair, ...]
    source: Literal["computed", "srdf"]
    samples: int
    seed: int
    seconds: float = 0.0  # time it took to compute [s]

    def candidates(self) -> list[tuple[str, str]]:
        """Link pairs on different joints, ``(a, b)`` with ``a < b``, sorted."""
        return candidate_pairs(self.links)

    def reasons(self) -> dict[tuple[str, str], Reason]:
        return {(p.link1, p.link2): p.reason for p in self.pairs}

    def enabled_pairs(self) -> list[tuple[str, str]]:
        """Candidate pairs that are checked."""
        off = self.reasons()
        return [p for p in self.candidates() if p not in off]

    def counts(self) -> dict[str, int]:
        """Number of pairs per reason, plus ``enabled`` and ``candidates``."""
        out: dict[str, int] = {r: 0 for r in REASONS}
        for p in self.pairs:
            out[p.reason] += 1
        out["enabled"] = len(self.enabled_pairs())
        out["candidates"] = len(self.candidates())
        return out

    @classmethod
    def none(cls, robot: RobotModel) -> DisabledPairs:
        """Nothing disabled: every candidate pair is checked."""
        return cls(robot.robot_hash, collision_links(robot), (), "computed", 0, 0)


def candidate_pairs(links: tuple[CollisionLink, ...]) -> list[tuple[str, str]]:
    """Pairs of collision links on different joints, ``(a, b)`` with ``a < b``, sorted."""
    out = []
    for i, a in enumerate(links):
        for b in links[i + 1 :]:
            if a.joint != b.joint:
                out.append((min(a.name, b.name), max(a.name, b.name)))
    return sorted(out)
