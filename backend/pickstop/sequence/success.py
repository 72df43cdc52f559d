"""Positioning error at a stop: the radius a success rate needs, Monte Carlo success rates.

The error models themselves (isotropic, anisotropic, biased, per station; their sampler,
density and disc probability) live in :mod:`pickstop.scene.positioning`; the functions here
taking ``(kind, sigma, yaw_sigma)`` are the isotropic, unbiased case of it:

- ``bounded``: uniform in the disc of radius sigma. A stop whose inscribed circle has radius
  >= sigma then always succeeds (the paper's rule); radius r covers a fraction (r / sigma)^2.
- ``gaussian``: isotropic, with *mean error magnitude* sigma (the paper's wording). The
  magnitude is Rayleigh with scale s = sigma sqrt(2 / pi), so P(|e| <= r) = 1 - exp(-r^2 / 2 s^2):
  the paper's rule (r >= sigma) alone guarantees only 1 - exp(-pi / 4) = 54.4%.

A yaw error is optional (Gaussian, standard deviation ``yaw_sigma``). Yaw samples are drawn on
a lattice of :data:`YAW_LATTICE`, so that the exact feasibility test, which is vectorised over
positions at one yaw, runs once per distinct yaw.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickstop.scene.positioning import YAW_LATTICE, ErrorDist, Kind, rayleigh_scale

__all__ = (
    "YAW_LATTICE",
    "Kind",
    "Rate",
    "combined",
    "disc_probability",
    "monte_carlo",
    "monte_carlo_at",
    "radius_for",
    "rayleigh_scale",
    "sample_errors",
)
Z95 = 1.959963984540054


def disc_probability(kind: Kind, sigma: float, r: float) -> float:
    """P(|e| <= r): the success rate a stop with inscribed radius r guarantees (yaw aside)."""
    if sigma <= 0.0:
        return 1.0
    return ErrorDist(kind, sigma).disc_probability(r)


def radius_for(kind: Kind, sigma: float, target: float) -> float:
    """The smallest inscribed radius [m] whose disc alone guarantees ``target`` success."""
    if not 0.0 < target < 1.0:
        raise ValueError(f"target must be in (0, 1), got {target}")
    if kind == "bounded":
        return sigma * math.sqrt(target)
    return ErrorDist(kind, sigma).radius_for(target)


def sample_errors(
    kind: Kind, sigma: float, yaw_sigma: float, n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` position errors ``(n, 2)`` [m] and yaw errors ``(n,)`` [rad] (on the lattice)."""
    return ErrorDist(kind, sigma, yaw_sigma=yaw_sigma).sample(n, rng)


def density(kind: Kind, sigma: float, dxy: np.ndarray) -> np.ndarray:
    """The position error's probability density [1/m^2] at offsets ``dxy: (..., 2)`` [m]
    (``sigma > 0``): what the fast success estimate (:mod:`pickstop.sequence.estimate`)
    integrates, the same distribution :func:`sample_errors` draws from."""
    dxy = np.asarray(dxy, float)
    assert dxy.shape[-1] == 2 and sigma > 0
    r2 = (dxy * dxy).sum(-1)
    if kind == "bounded":
        return np.where(r2 <= sigma * sigma, 1.0 / (math.pi * sigma * sigma), 0.0)
    s2 = rayleigh_scale(sigma) ** 2
    return np.exp(-r2 / (2.0 * s2)) / (2.0 * math.pi * s2)


def support(kind: Kind, sigma: float) -> float:
    """The radius [m] holding all of :func:`density` but a mass below 1e-5."""
    if kind == "bounded":
        return sigma
    return rayleigh_scale(sigma) * math.sqrt(-2.0 * math.log(1e-5))


@dataclass(frozen=True)
class Rate:
    """A success rate with its 95% Wilson score interval."""

    samples: int
    successes: int

    @property
    def rate(self) -> float:
        return self.successes / self.samples if self.samples else float("nan")

    @property
    def interval(self) -> tuple[float, float]:
        return self.wilson(Z95)

    def wilson(self, z: float) -> tuple[float, float]:
        """The Wilson score interval at ``z`` standard deviations (:attr:`interval`: 95%)."""
        n, k = self.samples, self.successes
        if n == 0:
            return (0.0, 1.0)
        p, z2 = k / n, z * z
        centre = (p + z2 / (2 * n)) / (1 + z2 / n)
        half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
        # It holds the observed rate; at 0 or all successes its end is exactly 0 or 1, which
        # rounding would otherwise leave a hair inside.
        return (min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half)))


#: Feasibility of base poses: ``evaluate(xy (M, 2), yaw) -> ok (M,)``.
Evaluate = Callable[[np.ndarray, float], np.ndarray]


def monte_carlo(
    evaluate: Evaluate,
    centre: tuple[float, float],
    yaw: float,
    kind: Kind,
    sigma: float,
    yaw_sigma: float,
    n: int,
    rng: np.random.Generator,
) -> Rate:
    """Success rate of stopping at ``centre``/``yaw`` when the base lands off by the error model."""
    dist = ErrorDist(kind, sigma, yaw_sigma=yaw_sigma)
    return monte_carlo_at(evaluate, centre, yaw, dist, n, rng)


def monte_carlo_at(
    evaluate: Evaluate,
    centre: tuple[float, float],
    yaw: float,
    dist: ErrorDist,
    n: int,
    rng: np.random.Generator,
) -> Rate:
    """Success rate of stopping at ``centre`` [m] / ``yaw`` [rad] when the base lands off by
    ``dist`` (drawn in the stop's frame: a ``base`` model turns with ``yaw``)."""
    dxy, dyaw = dist.sample(n, rng, yaw)
    xy = np.asarray(centre, float) + dxy
    ok = np.zeros(n, bool)
    for d in np.unique(dyaw):
        sel = dyaw == d
        ok[sel] = evaluate(xy[sel], yaw + float(d))
    return Rate(n, int(ok.sum()))


def combined(rates: list[Rate]) -> tuple[float, tuple[float, float]]:
    """Success of a whole plan (independent errors at each stop): the product of the stops'
    rates, and the products of their 95% interval ends (jointly they hold with at least
    1 - 0.05 k confidence for k stops, by Bonferroni)."""
    if not rates:
        return 1.0, (1.0, 1.0)
    p = float(np.prod([r.rate for r in rates]))
    lo = float(np.prod([r.interval[0] for r in rates]))
    hi = float(np.prod([r.interval[1] for r in rates]))
    return p, (lo, hi)
