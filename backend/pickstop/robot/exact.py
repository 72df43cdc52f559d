"""Exact self-collision with pinocchio + coal, the reference for the sphere screen.

:class:`ExactSelfCollision` checks the enabled link pairs of a :class:`DisabledPairs` with
``pin.computeCollisions``; :func:`false_rejection_rate` measures the screen against it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from pickstop.progress import Steps, step
from pickstop.robot.kinematics import BLOCK, Chain, fk_soa
from pickstop.robot.link_geometry import collision_links
from pickstop.robot.model import RobotModel
from pickstop.robot.screen import SphereModel, screen

if TYPE_CHECKING:
    from pickstop.robot.pairs import DisabledPairs


def _geometry_model(robot: RobotModel, link_pairs: list[tuple[str, str]]) -> tuple[Any, list]:
    """A copy of the collision model with the geometry pairs of ``link_pairs``.

    Returns the model and, per link pair, the indices of its collision pairs.
    """
    by_name = {lk.name: lk for lk in collision_links(robot)}
    gm = pin.GeometryModel(robot.geom_model)
    gm.removeAllCollisionPairs()
    slices = []
    for a, b in link_pairs:
        ks = []
        for ga in by_name[a].geometry_ids:
            for gb in by_name[b].geometry_ids:
                ks.append(len(gm.collisionPairs))
                gm.addCollisionPair(pin.CollisionPair(min(ga, gb), max(ga, gb)))
        slices.append(ks)
    return gm, slices


def _geometry_data(gm: Any) -> Any:
    gd = pin.GeometryData(gm)
    for req in gd.collisionRequests:
        req.security_margin = 0.0
        req.enable_contact = False
    return gd


class PairChecker:
    """Exact collision of individual link pairs, one configuration at a time."""

    def __init__(self, robot: RobotModel, link_pairs: list[tuple[str, str]]) -> None:
        self.robot = robot
        self.gm, self.slices = _geometry_model(robot, link_pairs)
        self.data = robot.model.createData()
        self.gd = _geometry_data(self.gm)

    def set_config(self, theta: np.ndarray) -> None:
        q = self.robot.angles_to_q(theta)
        pin.updateGeometryPlacements(self.robot.model, self.data, self.gm, self.gd, q)

    def colliding(self, pair: int) -> bool:
        return any(pin.computeCollision(self.gm, self.gd, k) for k in self.slices[pair])


class ExactSelfCollision:
    """Exact self-collision of the enabled link pairs with pinocchio + coal (the reference)."""

    def __init__(self, robot: RobotModel, disabled: DisabledPairs) -> None:
        self.robot = robot
        self.pairs = disabled.enabled_pairs()
        self.geom_model, _ = _geometry_model(robot, self.pairs)
        self._data = robot.model.createData()
        self._gdata = _geometry_data(self.geom_model)

    def colliding(self, thetas: np.ndarray) -> np.ndarray:
        """``thetas: (N, dof)`` joint values [rad or m] -> ``(N,)`` bool, True if colliding."""
        thetas = np.asarray(thetas, dtype=float)
        assert thetas.ndim == 2 and thetas.shape[1] == self.robot.dof, thetas.shape
        qs = self.robot.angles_to_q(thetas)
        m, gm, d, gd = self.robot.model, self.geom_model, self._data, self._gdata
        return np.array([bool(pin.computeCollisions(m, d, gm, gd, q, True)) for q in qs])

    def colliding_pairs(self, theta: np.ndarray) -> list[tuple[str, str]]:
        """The enabled link pairs in collision at ``theta: (dof,)``."""
        q = self.robot.angles_to_q(np.asarray(theta, dtype=float))
        pin.computeCollisions(self.robot.model, self._data, self.geom_model, self._gdata, q, False)
        hit = set()
        by_geom = {g: lk.name for lk in collision_links(self.robot) for g in lk.geometry_ids}
        results = self._gdata.collisionResults
        for cp, res in zip(self.geom_model.collisionPairs, results, strict=True):
            if res.isCollision():
                a, b = by_geom[cp.first], by_geom[cp.second]
                hit.add((min(a, b), max(a, b)))
        return sorted(hit)


@dataclass(frozen=True)
class ScreenTrial:
    """The screen and the exact check on the same random configurations."""

    thetas: np.ndarray  # (n, dof) [rad or m]
    flagged: np.ndarray  # (n,) the screen says possibly colliding
    colliding: np.ndarray  # (n,) coal says colliding

    def figures(self) -> dict[str, float]:
        """``colliding`` (exact fraction), ``flagged`` (screen fraction), ``false_rejection``
        (flagged among exactly free configurations), ``false_acceptances`` (count; must be 0)."""
        free = ~self.colliding
        return {
            "n": float(len(self.thetas)),
            "colliding": float(self.colliding.mean()),
            "flagged": float(self.flagged.mean()),
            "false_rejection": float((self.flagged & free).sum() / max(free.sum(), 1)),
            "false_acceptances": float((~self.flagged & self.colliding).sum()),
        }


def screen_trial(
    robot: RobotModel,
    disabled: DisabledPairs,
    sphere_model: SphereModel,
    n: int,
    seed: int,
    steps: Steps | None = None,
    what: str = "self-collision screen",
) -> ScreenTrial:
    """:func:`screen` and :class:`ExactSelfCollision` on ``n`` uniform random configurations
    (``steps``: told of the exact checks as they go, as ``what``)."""
    th = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))
    exact = ExactSelfCollision(robot, disabled)
    colliding = np.empty(n, dtype=bool)
    for s in range(0, n, 200):
        step(steps, f"{what}: exact checks with coal", s, n)
        colliding[s : s + 200] = exact.colliding(th[s : s + 200])
    return ScreenTrial(th, _flags(robot, sphere_model, th), colliding)


def rescreened(robot: RobotModel, trial: ScreenTrial, sphere_model: SphereModel) -> ScreenTrial:
    """``trial``'s configurations judged by another screen of the same robot and disabled
    pairs: coal's verdicts depend on the configurations alone and are kept, so the trial
    equals :func:`screen_trial` of ``sphere_model`` with the same ``n`` and seed."""
    return ScreenTrial(trial.thetas, _flags(robot, sphere_model, trial.thetas), trial.colliding)


def _flags(robot: RobotModel, sphere_model: SphereModel, th: np.ndarray) -> np.ndarray:
    """:func:`screen` of the ``(n, dof)`` configurations ``th``: ``(n,)`` bool, flagged."""
    chain = Chain.from_robot(robot)
    flagged = np.empty(len(th), dtype=bool)
    for s in range(0, len(th), BLOCK):
        _, _, frames = fk_soa(chain, np.ascontiguousarray(th[s : s + BLOCK].T), frames=True)
        flagged[s : s + BLOCK] = screen(sphere_model, frames)
    return flagged


def false_rejection_rate(
    robot: RobotModel,
    disabled: DisabledPairs,
    sphere_model: SphereModel,
    n: int = 5000,
    seed: int = 0,
) -> dict[str, float]:
    """Compare :func:`screen` with :class:`ExactSelfCollision` on ``n`` random configurations
    (:meth:`ScreenTrial.figures`)."""
    return screen_trial(robot, disabled, sphere_model, n, seed).figures()


def responsible_links(
    robot: RobotModel,
    disabled: DisabledPairs,
    trial: ScreenTrial,
    near: float = 0.03,
    most: int = 300,
) -> list[str]:
    """Links that make the screen reject valid configurations: among (at most ``most`` of)
    the configurations of ``trial`` that the screen flags but coal finds free, the links of
    the enabled pairs closer than ``near`` [m] (coal collisions with that security margin),
    most frequent first (those covering half the cases, at least one)."""
    exact = ExactSelfCollision(robot, disabled)
    false = trial.thetas[trial.flagged & ~trial.colliding][:most]  # random already
    by_geom = {g: lk.name for lk in collision_links(robot) for g in lk.geometry_ids}
    gm, data = exact.geom_model, exact._data
    gd = _geometry_data(gm)
    for req in gd.collisionRequests:
        req.security_margin = near
    counts: dict[str, int] = {}
    for theta in false:
        pin.computeCollisions(robot.model, data, gm, gd, robot.angles_to_q(theta), False)
        close = set()
        for cp, res in zip(gm.collisionPairs, gd.collisionResults, strict=True):
            if res.isCollision():
                close |= {by_geom[cp.first], by_geom[cp.second]}
        for name in close:
            counts[name] = counts.get(name, 0) + 1
    ranked = sorted(counts, key=lambda k: -counts[k])
    out, covered = [], 0
    for name in ranked:
        out.append(name)
        covered += counts[name]
        if covered >= 0.5 * sum(counts.values()):
            break
    return out
