"""Predicted operation time: drive each leg from rest to rest, stop, pick.

A leg of length L [m] with top speed v [m/s] and acceleration a [m/s^2] follows a trapezoidal
speed profile: L / v + v / a when it is long enough to reach v (L >= v^2 / a), else the
triangular 2 sqrt(L / a). Every stop adds ``stop_time`` (decelerate, dock, relocalise) and every
part ``pick_time``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def leg_time(length: np.ndarray | float, v: float, a: float) -> np.ndarray:
    """Rest-to-rest travel time [s] of legs ``length`` [m] (array or scalar)."""
    L = np.asarray(length, dtype=float)
    knee = v * v / a  # shortest leg that reaches top speed [m]
    full = knee <= L
    with np.errstate(invalid="ignore"):
        return np.where(full, L / v + v / a, 2.0 * np.sqrt(np.maximum(L, 0.0) / a))


@dataclass(frozen=True)
class TimeBreakdown:
    travel: float  # [s]
    stops: float  # [s]
    picks: float  # [s]

    @property
    def total(self) -> float:
        return self.travel + self.stops + self.picks


def plan_time(
    legs: list[float],
    n_stops: int,
    n_parts: int,
    v: float,
    a: float,
    stop_time: float,
    pick_time: float,
) -> TimeBreakdown:
    """Time of a plan whose route has ``legs`` [m] between start, stops and goal."""
    travel = float(np.sum(leg_time(np.asarray(legs, float), v, a))) if legs else 0.0
    return TimeBreakdown(travel, n_stops * stop_time, n_parts * pick_time)
