"""Predicted operation time: drive each leg from rest to rest, stop, pick.

A leg of length L [m] with top speed v [m/s] and acceleration a [m/s^2] follows a trapezoidal
speed profile: L / v + v / a when it is long enough to reach v (L >= v^2 / a), else the
triangular 2 sqrt(L / a). The base halts at each end of a docking segment (where it turns
before or after driving at a fixed yaw), so a leg is driven as pieces split there. Every stop
adds ``stop_time`` (decelerate, dock, relocalise) and every
part ``pick_time``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def leg_time(length: np.ndarray | float, v: float, a: float) -> np.ndarray:
    """Rest-to-rest travel time [s] of legs ``length`` [m] (array or scalar)."""
    L = np.asarray(length, dtype=float)
    knee = v * v / a  # shortest leg that reaches top speed [m]
    full = knee <= L
    with np.errstate(invalid="ignore"):
        return np.where(full, L / v + v / a, 2.0 * np.sqrt(np.maximum(L, 0.0) / a))


def rest_pieces(
    polyline: np.ndarray | Sequence[Sequence[float]], segment_yaws: Sequence[float | None]
) -> list[float]:
    """Lengths [m] of the pieces a leg is driven in, rest to rest: its ``polyline`` ``(K, 2)``
    [m] split at every end of a segment held at a yaw (``segment_yaws[k]`` not None)."""
    pts = np.asarray(polyline, float).reshape(-1, 2)
    if len(segment_yaws) not in (0, len(pts) - 1):
        raise ValueError(f"{len(segment_yaws)} segment yaws for {len(pts)} waypoints")
    held = list(segment_yaws) or [None] * (len(pts) - 1)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    out, run = [], 0.0
    for k, (d, y) in enumerate(zip(seg.tolist(), held, strict=True)):
        if y is not None and run > 0:  # halt before a docking segment
            out.append(run)
            run = 0.0
        run += d
        if y is not None or (k + 1 < len(held) and held[k + 1] is not None):
            out.append(run)  # halt after a docking segment, or before the next one
            run = 0.0
    if run > 0 or not out:
        out.append(run)
    return [p for p in out if p > 0] or [0.0]


def pieces_time(pieces: Sequence[float], v: float, a: float) -> float:
    """Travel time [s] of a leg driven as ``pieces`` [m], each rest to rest."""
    return float(np.sum(leg_time(np.asarray(pieces, float), v, a))) if len(pieces) else 0.0


@dataclass(frozen=True)
class TimeBreakdown:
    travel: float  # [s]
    stops: float  # [s]
    picks: float  # [s]

    @property
    def total(self) -> float:
        return self.travel + self.stops + self.picks


def plan_time(
    legs: Sequence[float | Sequence[float]],
    n_stops: int,
    n_parts: int,
    v: float,
    a: float,
    stop_time: float,
    pick_time: float,
) -> TimeBreakdown:
    """Time of a plan whose route has ``legs`` [m] between start, stops and goal; a leg given
    as a list is the lengths of the pieces it is driven in (:func:`rest_pieces`)."""
    pieces = [p for leg in legs for p in ([leg] if isinstance(leg, float | int) else leg)]
    travel = float(np.sum(leg_time(np.asarray(pieces, float), v, a))) if pieces else 0.0
    return TimeBreakdown(travel, n_stops * stop_time, n_parts * pick_time)
