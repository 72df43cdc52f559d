"""Which candidate stops a plan may use: the paper's sigma rule, the success rule, reachability.

One home for the verdicts, so that a plan (``POST /plans``), the regions endpoint
(``GET /scenes/{id}/regions``) and the planner drawing either of them judge every candidate
the same way, with the same reason.

- ``sigma`` (the paper's rule): keep a candidate whose inscribed radius r >= sigma.
- ``success``: keep a candidate whose predicted success under the scene's error model reaches
  ``target``; the prediction is the larger of the disc bound P(|e| <= r) and the fraction of
  sampled errors that land inside the candidate's own polygon (the region's shape). With a
  :class:`~pickstop.scene.positioning.Positioning` the model is the one of the candidate's
  station (anisotropic, biased: drawn in the candidate's frame).
- Whatever the rule, a kept candidate the start cannot reach over the floor is rejected
  (:func:`cut_off`): being cut off depends on the obstacles, not on the candidate.

Exact verification at a chosen stop's centre can still reject a kept candidate later; that
belongs to the plan request (``sequence/request.py``, :func:`pickstop.sequence.pure.check`),
not to the rule.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
import shapely

from pickstop.scene.positioning import ErrorDist, Positioning, rot
from pickstop.sequence.intersections import Intersection
from pickstop.sequence.success import Kind, disc_probability, radius_for, sample_errors

RuleName = Literal["sigma", "success"]
SHAPE_SAMPLES = 4000  # sampled errors of the region-shape success estimate ('success' rule)
CUT_OFF = "obstacles cut it off from the start"


@dataclass(frozen=True)
class Rule:
    """A rule with its parameters: ``sigma`` [m], the error model ``kind``, ``target`` in (0, 1)."""

    name: RuleName
    sigma: float
    kind: Kind = "gaussian"
    target: float = 0.95
    seed: int = 0
    positioning: Positioning | None = None  # per-station models; None: (kind, sigma) alone

    @property
    def threshold(self) -> float:
        """The inscribed radius [m] that guarantees the rule on its own (the global model)."""
        if self.name == "sigma":
            return self.sigma
        if self.positioning is not None:
            d = self.positioning.default
            return d.radius_for(self.target) if d.spread or d.mean != (0.0, 0.0) else 0.0
        return radius_for(self.kind, self.sigma, self.target) if self.sigma > 0 else 0.0

    def describe(self) -> str:
        if self.name == "sigma":
            return f"sigma = {self.sigma:.3f} m"
        return f"target success {self.target:.0%} at sigma = {self.sigma:.3f} m ({self.kind} error)"


@dataclass(frozen=True)
class Verdict:
    """A candidate's verdict: kept or not, why not, and its predicted success (success rule)."""

    kept: bool
    reason: str | None = None
    predicted: float | None = None


def judge(rule: Rule, candidates: Sequence[Intersection]) -> list[Verdict]:
    """The rule's verdict on each candidate (reachability aside: see :func:`cut_off`)."""
    if rule.name == "sigma":
        return [_sigma_verdict(rule.sigma, c.radius) for c in candidates]
    if rule.positioning is not None:
        return _judge_by_station(rule, rule.positioning, candidates)
    threshold = rule.threshold
    dxy = None
    if rule.sigma > 0:
        rng = np.random.default_rng(rule.seed)
        dxy, _ = sample_errors(rule.kind, rule.sigma, 0.0, SHAPE_SAMPLES, rng)
    out = []
    for c in candidates:
        shape = 1.0
        if dxy is not None:
            x, y = c.centre[0] + dxy[:, 0], c.centre[1] + dxy[:, 1]
            shape = float(shapely.contains_xy(c.polygon, x, y).mean())
        p = max(shape, disc_probability(rule.kind, rule.sigma, c.radius))
        out.append(_success_verdict(rule, c, p, threshold))
    return out


def _success_verdict(rule: Rule, c: Intersection, p: float, threshold: float) -> Verdict:
    if c.radius < threshold and p < rule.target:
        why = (
            f"predicted success {p:.1%} is below the target {rule.target:.0%} (inscribed "
            f"radius {c.radius:.3f} m, {threshold:.3f} m would guarantee it)"
        )
        return Verdict(False, why, p)
    return Verdict(True, None, p)


def _judge_by_station(
    rule: Rule, pos: Positioning, candidates: Sequence[Intersection]
) -> list[Verdict]:
    """The success rule with each candidate's own model: its threshold radius, the disc
    bound and the share of its draws (turned to the candidate's heading for a ``base``
    model) inside its polygon."""
    draws: dict[ErrorDist, tuple[np.ndarray | None, float]] = {}
    out = []
    for c in candidates:
        dist = pos.at(c.centre, sorted(c.trays))
        if dist not in draws:  # each model draws as the isotropic rule always has
            moves = dist.spread or dist.mean != (0.0, 0.0)
            own = replace(dist, frame="map", yaw_sigma=0.0)  # in the model's own axes
            rng = np.random.default_rng(rule.seed)
            draws[dist] = (
                own.sample(SHAPE_SAMPLES, rng)[0] if moves else None,
                dist.radius_for(rule.target) if moves else 0.0,
            )
        dxy, threshold = draws[dist]
        shape = 1.0
        if dxy is not None:
            if dist.frame == "base" and not dist.legacy:
                dxy = dxy @ rot(c.yaw).T
            x, y = c.centre[0] + dxy[:, 0], c.centre[1] + dxy[:, 1]
            shape = float(shapely.contains_xy(c.polygon, x, y).mean())
        p = max(shape, dist.disc_probability(c.radius))
        out.append(_success_verdict(rule, c, p, threshold))
    return out


def cut_off(verdicts: Sequence[Verdict], reachable: Sequence[bool]) -> list[Verdict]:
    """Reject the kept candidates the start cannot reach (``reachable[i]`` for candidate i)."""
    if len(verdicts) != len(reachable):
        raise ValueError(f"{len(verdicts)} verdicts but {len(reachable)} reachability flags")
    return [
        Verdict(False, CUT_OFF, v.predicted) if v.kept and not ok else v
        for v, ok in zip(verdicts, reachable, strict=True)
    ]


def _sigma_verdict(sigma: float, radius: float) -> Verdict:
    if radius >= sigma:
        return Verdict(True)
    return Verdict(False, f"inscribed radius {radius:.3f} m is below sigma {sigma:.3f} m")
