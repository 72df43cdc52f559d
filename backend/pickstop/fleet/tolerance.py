"""A stop's tolerance shapes, checked by the exact off-grid test: the largest ellipse (centred
on the stop, any orientation) and the largest circle inside which every part of its trays
stays graspable.

A candidate ellipse is the largest inscribed in the stop trays' regions' intersection (the
union of verified cells' squares; and, a second candidate, in that union shrunk by half a cell,
which the cell centres reach); each is then checked off the grid with the region's exact test
(:func:`pickstop.regions.offgrid.feasible_near`) at samples of its boundary (arc spacing
``res / 4``), of a second ring ``res / 8`` inside it (the shape exported) and of its interior
(a square lattice of spacing ``res / 2``, anchored at the stop), ``res`` being the base grid's
cell edge. Where a sample fails the shape shrinks to just inside it and its new rings are
checked; lattice samples inside it were checked already.
The circle is checked the same way, starting from the stop's inscribed radius.

Why these spacings: the grid itself verifies one pose per cell (spacing ``res``); the shapes
are drawn up to the cells' edges, where a failure first shows, so their boundary is sampled
four times as finely and their interior, far from the edges, twice. What is *verified* is every
sample, with the robot's full geometry; between samples the claim rests on the test's outcome
not changing within ``res / 8`` near the rim and ``res / 4`` inside (half the spacing), 4 to
8 times finer than the grid the regions themselves rest on. Scanned at 2 mm, the example
plans' exported shapes hold no failing pose. Cost is bounded: at most
``BOUNDARY_MAX`` boundary and ``INTERIOR_MAX`` interior samples per shape and round (the
spacing widens past ``res / 4`` or ``res / 2`` when a shape is large, and says so), at most
``ROUNDS`` rounds, each sample tested once per tray of the stop.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

BOUNDARY_MAX = 512  # boundary samples per shape and round
INTERIOR_MAX = 3000  # interior lattice samples per shape (once: later rounds reuse them)
ROUNDS = 6  # shrink-and-check rounds per shape
ANGLES = 36  # ellipse orientations tried, over [0, pi)
SIZES = 48  # semi-axis lengths tried per orientation
SHRINK = 0.97  # a failed sample's shape shrinks to this fraction of its offset

# ``test(tray_id, xy: (M, 2) [m], yaw [rad]) -> ok: (M,) bool``: the exact off-grid test.
BatchTest = Callable[[str, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class Ellipse:
    """Centred on the stop: semi-axes ``a >= b`` [m], ``a`` along ``theta`` [rad] in the map
    frame, ``theta`` in [-pi/2, pi/2] (VDA 5050 3.0's ``allowedDeviationXY``)."""

    a: float
    b: float
    theta: float

    @classmethod
    def of(cls, a: float, b: float, theta: float) -> Ellipse:
        """Normalised: ``a >= b`` (swapping turns ``theta`` by pi/2), theta wrapped."""
        if b > a:
            a, b, theta = b, a, theta + math.pi / 2
        theta = (theta + math.pi / 2) % math.pi - math.pi / 2
        return cls(float(a), float(b), float(theta))

    @property
    def area(self) -> float:  # [m^2]
        return math.pi * self.a * self.b

    def scaled(self, s: float) -> Ellipse:
        return Ellipse(self.a * s, self.b * s, self.theta)

    def rho(self, d: np.ndarray) -> np.ndarray:
        """``d: (N, 2)`` offsets [m] -> (N,) their ellipse norm (< 1 inside, 1 on it)."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        u, v = d @ np.array([c, s]), d @ np.array([-s, c])
        with np.errstate(divide="ignore", invalid="ignore"):
            r2 = np.where(u == 0, 0.0, (u / self.a) ** 2) + np.where(v == 0, 0.0, (v / self.b) ** 2)
        return np.sqrt(r2)

    def perimeter(self) -> float:  # [m], Ramanujan's approximation
        a, b = self.a, self.b
        return math.pi * (3 * (a + b) - math.sqrt((3 * a + b) * (a + 3 * b)))

    def boundary(self, spacing: float) -> np.ndarray:
        """Offsets ``(N, 2)`` [m] on the ellipse, at most ``spacing`` apart along it."""
        t = np.linspace(0, 2 * math.pi, max(8, math.ceil(self.perimeter() / spacing) + 1))[:-1]
        c, s = math.cos(self.theta), math.sin(self.theta)
        u, v = self.a * np.cos(t), self.b * np.sin(t)
        return np.stack([c * u - s * v, s * u + c * v], -1)


@dataclass(frozen=True)
class StopShapes:
    """A stop's checked shapes: the circle's radius [m] and the ellipse, with how densely they
    were sampled [m], how many exact tests (pose x tray) it took and how long [s]."""

    radius: float
    ellipse: Ellipse
    boundary_spacing: float
    interior_spacing: float
    tests: int
    seconds: float


def largest_inscribed(
    region: BaseGeometry, centre: tuple[float, float], r_in: float, res: float
) -> Ellipse:
    """The largest-area ellipse centred on ``centre`` inside ``region`` (a polygon [m]),
    searched over ``ANGLES`` orientations and ``SIZES`` semi-axes; at least the inscribed
    circle (or one of radius ``r_in`` [m]). ``res``: the grid's cell edge [m] (the boundary
    is densified to res/8)."""
    cx, cy = centre
    if region.is_empty or not region.contains(shapely.Point(centre)):
        return Ellipse(r_in, r_in, 0.0)
    r0 = max(r_in, float(shapely.distance(shapely.Point(centre), region.boundary)))
    reach = 8 * max(r0, res)
    near = shapely.clip_by_rect(region, cx - reach, cy - reach, cx + reach, cy + reach)
    edge = shapely.segmentize(near.boundary, res / 8)
    pts = shapely.get_coordinates(edge) - np.array(centre)
    pts = np.concatenate([pts, _box_ring(reach)])  # nothing beyond the clipped window
    best = Ellipse(r0, r0, 0.0)
    sizes = np.geomspace(max(r0, res / 4), reach, SIZES)
    for th in np.linspace(0, math.pi, ANGLES, endpoint=False):
        c, s = math.cos(th), math.sin(th)
        u, v = np.abs(pts @ np.array([c, s])), np.abs(pts @ np.array([-s, c]))
        q = u[:, None] / sizes[None]  # (N, S)
        with np.errstate(divide="ignore", invalid="ignore"):
            lim = np.where(q < 1, v[:, None] / np.sqrt(1 - q**2), np.inf)
        bs = np.min(lim, axis=0)  # (S,) the widest b for each a
        k = int(np.argmax(sizes * bs))
        if math.isfinite(bs[k]) and math.pi * sizes[k] * bs[k] > best.area:
            best = Ellipse.of(float(sizes[k]), float(bs[k]), float(th))
    return best


def _box_ring(h: float) -> np.ndarray:
    t = np.linspace(-h, h, 33)
    one = np.full_like(t, h)
    return np.concatenate([np.stack([t, one], -1), np.stack([t, -one], -1),
                           np.stack([one, t], -1), np.stack([-one, t], -1)])  # fmt: skip


class _Tests:
    """The exact test of every tray of a stop at offsets from it, each pose tested once."""

    def __init__(
        self, test: BatchTest, trays: Sequence[str], centre: tuple[float, float], yaw: float
    ) -> None:
        self.test, self.trays, self.yaw = test, tuple(trays), yaw
        self.centre = np.asarray(centre, float)
        self.known: dict[tuple[int, int], bool] = {}
        self.count = 0

    def ok(self, d: np.ndarray) -> np.ndarray:
        """``d: (N, 2)`` offsets [m] -> (N,) whether every tray passes there."""
        keys = [(round(x * 1e7), round(y * 1e7)) for x, y in d]
        todo = sorted({k for k in keys if k not in self.known})
        if todo:
            xy = self.centre + np.array(todo, float) / 1e7
            alive = np.ones(len(todo), bool)
            for t in self.trays:
                idx = np.flatnonzero(alive)
                if not len(idx):
                    break
                self.count += len(idx)
                alive[idx] = np.asarray(self.test(t, xy[idx], self.yaw), bool)
            self.known.update(zip(todo, alive.tolist(), strict=True))
        return np.array([self.known[k] for k in keys], bool)


def _lattice(e: Ellipse, spacing: float) -> np.ndarray:
    """Offsets of the square lattice of ``spacing`` [m] anchored at the centre, inside ``e``."""
    n = math.ceil(e.a / spacing)
    g = np.arange(-n, n + 1) * spacing
    d = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    return d[e.rho(d) < 1]


def spacings(e: Ellipse, res: float) -> tuple[float, float]:
    """Boundary and interior sample spacing [m] for ``e``: res/4 and res/2, widened where
    that would take more than ``BOUNDARY_MAX`` / ``INTERIOR_MAX`` samples."""
    hb = max(res / 4, e.perimeter() / BOUNDARY_MAX)
    hi = max(res / 2, math.sqrt(e.area / INTERIOR_MAX))
    return hb, hi


def prove(tests: _Tests, e: Ellipse, hb: float, hi: float) -> Ellipse:
    """``e`` shrunk (about the stop) until its boundary samples at ``hb``, its interior
    lattice at ``hi`` [m] and the boundary of the shape returned, ``e`` scaled to lie ``hb / 2``
    inside it, all pass; ``ROUNDS`` at most, else a zero ellipse. The two rings leave a
    failure between boundary samples no room inside the shape returned."""
    zero = Ellipse(0.0, 0.0, e.theta)
    if e.a <= 0 or not tests.ok(np.zeros((1, 2)))[0]:
        return zero
    inner = _lattice(e, hi)
    for _ in range(ROUNDS):
        if e.b <= hb:
            break
        out = e.scaled(1 - hb / 2 / e.b)
        d = np.concatenate([e.boundary(hb), out.boundary(hb), inner[e.rho(inner) < 1]])
        ok = tests.ok(d)
        if ok.all():
            return out
        e = e.scaled(SHRINK * float(np.min(e.rho(d[~ok]))))
    return zero


def stop_shapes(
    test: BatchTest,
    trays: Sequence[str],
    centre: tuple[float, float],
    yaw: float,
    region: BaseGeometry,
    r_in: float,
    res: float,
) -> StopShapes:
    """The checked circle and ellipse of one stop at ``centre`` [m], ``yaw`` [rad].

    ``region``: the stop trays' regions' intersection (polygon [m]); ``r_in``: its inscribed
    radius there [m]; ``res``: the base grid's cell edge [m]. The ellipse's area is at least
    the circle's (the circle is an ellipse)."""
    t0 = time.perf_counter()
    tests = _Tests(test, trays, centre, yaw)
    circle = Ellipse(r_in, r_in, 0.0)
    cb, ci = spacings(circle, res)
    radius = prove(tests, circle, cb, ci).a
    best, hb, hi = Ellipse(radius, radius, 0.0), cb, ci
    # Inscribed in the cells' squares and in their centres' reach (res/2 inside): the first
    # is larger, the second fails less where the squares' corners reach past the test.
    for inner in (region, region.buffer(-res / 2)):
        cand = largest_inscribed(inner, centre, 0.0, res)
        h = spacings(cand, res)
        got = prove(tests, cand, *h)
        if got.area > best.area:
            best, (hb, hi) = got, h
    return StopShapes(radius, best, hb, hi, tests.count, time.perf_counter() - t0)
