"""The arm's travel posture: how the robot holds its arm while the base drives.

A config gives it as ``travel`` (arm joint -> value [rad or m]; unlisted joints at 0 clipped
into their limits). Without one, the posture is computed from the robot: the most compact of
the home pose and :data:`SAMPLES` seeded random configurations (every joint origin and the tool
point as near the base's vertical axis as can be, the tool point at least
:data:`MIN_TOOL_HEIGHT` above the floor) that the exact self-collision check finds free.
Either way the posture is checked with the exact check (pinocchio + coal, the robot's full
collision geometry, hand in its pre-grasp posture); a colliding one is reported with the link
pairs in contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from pickstop.robot.kinematics import Chain, fk_soa
from pickstop.robot.model import RobotModel
from pickstop.robot.selfcollision import home_thetas

if TYPE_CHECKING:
    from pickstop.robot.exact import ExactSelfCollision
    from pickstop.robot.pairs import DisabledPairs

SAMPLES = 4096  # random configurations a computed posture is chosen from
SEED = 0
CANDIDATES = 256  # the most compact ones checked exactly, in order, until one is free
MIN_TOOL_HEIGHT = 0.3  # a computed posture keeps the tool point this high [m]


@dataclass(frozen=True)
class Travel:
    """The travel posture of a robot and what the exact check says of it."""

    theta: np.ndarray  # (dof,) arm joint values [rad or m], in the arm's joint order
    source: Literal["config", "computed"]
    collisions: tuple[tuple[str, str], ...]  # link pairs in contact (empty: collision-free)

    def by_joint(self, robot: RobotModel) -> dict[str, float]:
        """The posture as arm joint name -> value [rad or m]."""
        return {j.name: float(v) for j, v in zip(robot.joints, self.theta, strict=True)}


def configured(robot: RobotModel) -> np.ndarray | None:
    """``(dof,)`` the config's travel posture (None: the config gives none)."""
    given = robot.config.travel
    if given is None:
        return None
    theta = home_thetas(robot)
    for i, j in enumerate(robot.joints):
        if j.name in given:
            theta[i] = given[j.name]
    return theta


def reach(robot: RobotModel, thetas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far ``thetas: (N, dof)`` spread the arm: the largest horizontal distance from the
    base's vertical axis of any arm joint origin or the tool point ``(N,)`` [m], and the tool
    point's height ``(N,)`` [m]."""
    thetas = np.asarray(thetas, dtype=float)
    assert thetas.ndim == 2 and thetas.shape[1] == robot.dof, thetas.shape
    _, p_tool, frames = fk_soa(Chain.from_robot(robot), np.ascontiguousarray(thetas.T), True)
    points = np.stack([p for _, p in frames] + [p_tool])  # (dof + 1, 3, N)
    return np.hypot(points[:, 0], points[:, 1]).max(axis=0), p_tool[2]


def compact(robot: RobotModel, exact: ExactSelfCollision) -> np.ndarray:
    """``(dof,)`` the most compact collision-free posture found (module docstring); the home
    pose if none of the candidates is free."""
    rng = np.random.default_rng(SEED)
    home = home_thetas(robot)
    thetas = np.vstack([home, rng.uniform(robot.lower, robot.upper, (SAMPLES, robot.dof))])
    spread, height = reach(robot, thetas)
    spread[height < MIN_TOOL_HEIGHT] = np.inf
    order = np.argsort(spread, kind="stable")[:CANDIDATES]
    order = order[np.isfinite(spread[order])]
    for s in range(0, len(order), 32):
        block = order[s : s + 32]
        free = ~exact.colliding(thetas[block])
        if free.any():
            return thetas[block[int(np.argmax(free))]]
    return home


def travel_posture(robot: RobotModel, exact: ExactSelfCollision) -> Travel:
    """The robot's travel posture (its config's, else computed) and its exact check."""
    theta = configured(robot)
    source: Literal["config", "computed"] = "config"
    if theta is None:
        theta, source = compact(robot, exact), "computed"
    return Travel(np.asarray(theta, float), source, tuple(exact.colliding_pairs(theta)))


def travel_of(robot: RobotModel, disabled: DisabledPairs) -> Travel:
    """:func:`travel_posture` with the exact check of ``disabled``'s enabled pairs, made once
    per loaded robot."""
    from pickstop.robot.exact import ExactSelfCollision

    if robot.derived.travel is None:
        robot.derived.travel = travel_posture(robot, ExactSelfCollision(robot, disabled))
    hit: Travel = robot.derived.travel
    return hit


def problem(robot: RobotModel, travel: Travel) -> str | None:
    """What is wrong with ``travel`` in words (None: it is collision-free)."""
    if not travel.collisions:
        return None
    pairs = ", ".join(f"{a} - {b}" for a, b in travel.collisions[:6])
    if len(travel.collisions) > 6:
        pairs += f" and {len(travel.collisions) - 6} more pairs"
    where = "the config's `travel`" if travel.source == "config" else "the computed posture"
    return f"travel posture ({where}) is not collision-free: {pairs}"
