"""The base's positioning error at a stop: one distribution (:class:`ErrorDist`) with its
sampler, density and disc probability, and which one applies where (:class:`Positioning`).

Everything that draws, weighs or bounds where the base lands goes through this module: the
Monte Carlo success rates, the rules, the simulated vehicle and the fit of recorded arrivals.

An error is where the base lands relative to the planned stop: a position offset ``(dx, dy)``
[m] and a yaw offset [rad]. A model's ``mean`` and ``covariance`` are given in its ``frame``:
``base`` (x along the planned heading, y to its left; a stop of yaw psi turns them by psi in
the map) or ``map``. Kinds:

- ``gaussian``: ``N(mean, covariance)``; without a covariance, isotropic with *mean error
  magnitude* sigma (per-axis standard deviation ``sigma sqrt(2 / pi)``, the paper's wording).
- ``bounded``: ``mean`` plus a point uniform in the disc of radius sigma.

The yaw offset is ``N(yaw_mean, yaw_sigma)``, drawn on the lattice of :data:`YAW_LATTICE` so
that the exact test, vectorised over positions at one yaw, runs once per distinct yaw.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import shapely
from shapely.geometry import Polygon

if TYPE_CHECKING:
    from pickstop.scene.model import Scene

Kind = Literal["bounded", "gaussian"]
Frame = Literal["base", "map"]
YAW_LATTICE = math.radians(0.25)  # [rad]
Matrix2 = tuple[tuple[float, float], tuple[float, float]]
ANGLES = 2048  # directions of the disc-probability quadrature


def rayleigh_scale(sigma: float) -> float:
    """Per-axis standard deviation of a 2D Gaussian whose mean error magnitude is ``sigma``."""
    return sigma * math.sqrt(2.0 / math.pi)


def rot(yaw: float) -> np.ndarray:
    """``R_map_base`` (2, 2) of a heading ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class ErrorDist:
    """One positioning error model. ``sigma`` [m]: the bounded disc's radius, or the
    isotropic Gaussian's mean error magnitude when ``covariance`` [m^2] is None."""

    kind: Kind = "gaussian"
    sigma: float = 0.0
    mean: tuple[float, float] = (0.0, 0.0)  # [m], in ``frame``
    covariance: Matrix2 | None = None  # [m^2], in ``frame``; gaussian only
    yaw_mean: float = 0.0  # [rad]
    yaw_sigma: float = 0.0  # [rad]
    frame: Frame = "base"
    name: str | None = None  # the station it belongs to; None: the scene's global model

    def __post_init__(self) -> None:
        if self.covariance is not None and self.kind != "gaussian":
            raise ValueError("a covariance needs kind 'gaussian'")
        if self.sigma < 0 or self.yaw_sigma < 0:
            raise ValueError("sigma and yaw_sigma must be >= 0")

    @property
    def legacy(self) -> bool:
        """Isotropic and unbiased: the same in every frame (drawn as before there were
        anisotropic models, the same samples from the same generator)."""
        return self.covariance is None and self.mean == (0.0, 0.0)

    @property
    def spread(self) -> bool:
        """Does the position vary at all?"""
        if self.covariance is not None:
            return bool(np.any(np.asarray(self.covariance) != 0))
        return self.sigma > 0

    def cov(self) -> np.ndarray:
        """The position covariance (2, 2) [m^2] in the model's frame."""
        if self.covariance is not None:
            return np.asarray(self.covariance, float)
        if self.kind == "bounded":
            return np.eye(2) * (self.sigma**2 / 4.0)  # uniform in a disc of radius sigma
        return np.eye(2) * rayleigh_scale(self.sigma) ** 2

    def in_map(self, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Mean (2,) [m] and covariance (2, 2) [m^2] in the map frame at a stop of ``yaw``."""
        mu, C = np.asarray(self.mean, float), self.cov()
        if self.frame == "map":
            return mu, C
        R = rot(yaw)
        return R @ mu, R @ C @ R.T

    def sample(
        self, n: int, rng: np.random.Generator, yaw: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """``n`` position offsets ``(n, 2)`` [m] in the map frame at a stop of heading ``yaw``
        [rad], and yaw offsets ``(n,)`` [rad] on the lattice."""
        if self.kind == "bounded":
            r = self.sigma * np.sqrt(rng.random(n))
            a = rng.random(n) * 2.0 * math.pi
            dxy = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
        elif self.covariance is None:
            dxy = rng.normal(scale=rayleigh_scale(self.sigma), size=(n, 2))
        else:
            dxy = rng.normal(size=(n, 2)) @ _root(self.cov()).T
        if not self.legacy:
            dxy = dxy + np.asarray(self.mean, float)
            if self.frame == "base":
                dxy = dxy @ rot(yaw).T
        dyaw = np.zeros(n)
        if self.yaw_sigma > 0.0:
            dyaw = rng.normal(scale=self.yaw_sigma, size=n)
            dyaw = np.round((self.yaw_mean + dyaw) / YAW_LATTICE) * YAW_LATTICE
        elif self.yaw_mean != 0.0:
            dyaw += round(self.yaw_mean / YAW_LATTICE) * YAW_LATTICE
        return dxy, dyaw

    def density(self, dxy: np.ndarray, yaw: float = 0.0) -> np.ndarray:
        """Probability density [1/m^2] of position offsets ``dxy: (n, 2)`` (map frame) at a
        stop of heading ``yaw`` [rad]."""
        dxy = np.asarray(dxy, float).reshape(-1, 2)
        mu, C = self.in_map(yaw)
        d = dxy - mu
        if self.kind == "bounded":
            if self.sigma == 0:
                return np.where(np.all(d == 0, axis=1), np.inf, 0.0)
            inside = (d * d).sum(1) <= self.sigma**2
            return inside / (math.pi * self.sigma**2)
        P = np.linalg.inv(C)
        q = np.einsum("ni,ij,nj->n", d, P, d)
        return np.exp(-0.5 * q) / (2.0 * math.pi * math.sqrt(np.linalg.det(C)))

    def yaw_density(self, dyaw: np.ndarray) -> np.ndarray:
        """Density [1/rad] of yaw offsets (of the Gaussian before the lattice)."""
        z = (np.asarray(dyaw, float) - self.yaw_mean) / self.yaw_sigma
        return np.exp(-0.5 * z * z) / (self.yaw_sigma * math.sqrt(2.0 * math.pi))

    def disc_probability(self, r: float) -> float:
        """P(|e| <= r): the success rate a stop whose every point within ``r`` [m] works
        guarantees (yaw aside). The norm does not depend on the frame or the stop's yaw."""
        if not self.spread:
            return float(math.hypot(*self.mean) <= r)
        # Ratios first: sigma may be as small as a subnormal number, whose square is 0.
        if self.kind == "bounded":
            if self.legacy:
                q = min(1.0, r / self.sigma)
                return q * q
            return _lens(r, self.sigma, math.hypot(*self.mean)) / (math.pi * self.sigma**2)
        if self.legacy:
            q = r / rayleigh_scale(self.sigma)
            return 1.0 - math.exp(-0.5 * q * q)
        return _gaussian_disc(np.asarray(self.mean, float), self.cov(), r)

    def radius_for(self, target: float) -> float:
        """The smallest r [m] with P(|e| <= r) >= ``target`` in (0, 1)."""
        if not 0.0 < target < 1.0:
            raise ValueError(f"target must be in (0, 1), got {target}")
        if not self.spread:
            return math.hypot(*self.mean)
        if self.legacy and self.kind == "gaussian":
            return rayleigh_scale(self.sigma) * math.sqrt(-2.0 * math.log(1.0 - target))
        if self.legacy:  # bounded: the disc's area fraction
            return self.sigma * math.sqrt(target)
        lo, hi = 0.0, math.hypot(*self.mean) + 12.0 * math.sqrt(np.linalg.eigvalsh(self.cov())[-1])
        hi = max(hi, math.hypot(*self.mean) + self.sigma)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.disc_probability(mid) < target else (lo, mid)
        return hi


def _root(C: np.ndarray) -> np.ndarray:
    """``L`` with ``L L^T = C`` for a symmetric positive semi-definite ``C`` (2, 2)."""
    w, V = np.linalg.eigh(C)
    return V * np.sqrt(np.clip(w, 0.0, None))


def _lens(r: float, s: float, d: float) -> float:
    """Area [m^2] of the intersection of discs of radii ``r`` and ``s`` whose centres are
    ``d`` apart."""
    if d >= r + s:
        return 0.0
    if d <= abs(r - s):
        return math.pi * min(r, s) ** 2
    a = r * r * math.acos((d * d + r * r - s * s) / (2 * d * r))
    b = s * s * math.acos((d * d + s * s - r * r) / (2 * d * s))
    c = 0.5 * math.sqrt((-d + r + s) * (d + r - s) * (d - r + s) * (d + r + s))
    return a + b - c


def _gaussian_disc(mu: np.ndarray, C: np.ndarray, r: float) -> float:
    """P(|mu + L z| <= r), z standard normal in 2D: along each direction u of z the ray
    ``t u`` lies in the disc for t in [t1, t2] (roots of a quadratic), which carries the
    probability ``exp(-t1^2 / 2) - exp(-t2^2 / 2)`` of that direction; averaged over
    :data:`ANGLES` directions (a periodic integrand: the trapezoid rule converges fast)."""
    phi = np.arange(ANGLES) * (2.0 * math.pi / ANGLES)
    Lu = np.stack([np.cos(phi), np.sin(phi)], 1) @ _root(C).T  # (A, 2)
    a = (Lu * Lu).sum(1)
    b = 2.0 * Lu @ mu
    c = float(mu @ mu) - r * r
    disc = b * b - 4 * a * c
    ok = (disc >= 0) & (a > 0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(ok, (-b - sq) / (2 * a), 0.0)
        t2 = np.where(ok, (-b + sq) / (2 * a), 0.0)
    t1, t2 = np.clip(t1, 0.0, None), np.clip(t2, 0.0, None)
    mass = np.where(ok, np.exp(-0.5 * t1 * t1) - np.exp(-0.5 * t2 * t2), 0.0)
    if c <= 0 and not ok.all():  # a direction the disc holds entirely (a degenerate L)
        mass = np.where(ok, mass, 1.0)
    return float(np.clip(mass.mean(), 0.0, 1.0))


@dataclass(frozen=True)
class Station:
    """A station's own model: stops in ``zone`` (map frame [m]) or picking from ``trays``."""

    name: str
    dist: ErrorDist
    trays: frozenset[str] | None = None
    zone: tuple[tuple[float, float], ...] | None = None

    def holds(self, xy: tuple[float, float], trays: Sequence[str]) -> bool:
        if self.trays is not None and self.trays & set(trays):
            return True
        if self.zone is not None:
            return bool(shapely.contains_xy(Polygon(self.zone), xy[0], xy[1]))
        return False


@dataclass(frozen=True)
class Positioning:
    """Which model applies where: the first station (in order) whose zone holds a stop's
    centre or whose trays meet the stop's, else the global model."""

    default: ErrorDist
    stations: tuple[Station, ...] = ()

    def at(self, xy: tuple[float, float], trays: Sequence[str]) -> ErrorDist:
        """The model of a stop at ``xy`` [m] picking from ``trays``."""
        for s in self.stations:
            if s.holds(xy, trays):
                return s.dist
        return self.default

    def station_of(self, xy: tuple[float, float], trays: Sequence[str]) -> str | None:
        """The name of the station whose model applies there (None: the global model)."""
        return next((s.name for s in self.stations if s.holds(xy, trays)), None)

    @property
    def anisotropic(self) -> bool:
        """Does any model differ from an isotropic, unbiased one?"""
        return not all(d.legacy for d in (self.default, *(s.dist for s in self.stations)))


def _dist(m: Any, kind: Kind, sigma: float, yaw_sigma: float, name: str | None) -> ErrorDist:
    """An :class:`ErrorDist` from a scene's error model block (global or a station's)."""
    return ErrorDist(
        kind=kind,
        sigma=sigma,
        mean=(float(m.mean[0]), float(m.mean[1])),
        covariance=None if m.covariance is None else
        ((m.covariance[0][0], m.covariance[0][1]), (m.covariance[1][0], m.covariance[1][1])),
        yaw_mean=m.yaw_mean,
        yaw_sigma=yaw_sigma,
        frame=m.frame,
        name=name,
    )  # fmt: skip


def of_scene(scene: Scene, sigma: float | None = None) -> Positioning:
    """The scene's models; ``sigma`` [m] overrides the scene's (a plan's option) wherever a
    model takes the scene's sigma rather than its own."""
    return of_model(scene.error_model, scene.sigma if sigma is None else sigma)


def of_model(em: Any, sigma: float) -> Positioning:
    """The models of an error model block (a scene's ``error_model``) with the scene's
    ``sigma`` [m] for those that give none of their own."""
    stations = []
    for s in em.stations:
        own_sigma = sigma if s.sigma is None else s.sigma
        own_yaw = em.yaw_sigma if s.yaw_sigma is None else s.yaw_sigma
        stations.append(
            Station(
                s.name,
                _dist(s, s.kind or em.kind, own_sigma, own_yaw, s.name),
                None if s.trays is None else frozenset(s.trays),
                None if s.zone is None else tuple((float(x), float(y)) for x, y in s.zone),
            )
        )
    return Positioning(_dist(em, em.kind, sigma, em.yaw_sigma, None), tuple(stations))
