"""A stop's yaw tolerance verified by the exact check: the largest yaw offset, on a lattice,
at which every tray of the stop stays graspable from its centre, turning either way.

The plan verifies each stop at one yaw (and, with a yaw error, samples it by Monte Carlo);
this scans ``step``, ``2 step``, ... up to ``limit`` and stops at the first offset that fails
either way. It holds at the centre only: combined with a position error it is not guaranteed.
"""

from __future__ import annotations

import math

from pickstop.fleet.vehicle import Check
from pickstop.sequence import plan_model as pm

STEP = math.radians(0.5)  # [rad]
LIMIT = math.radians(10.0)  # [rad]


def verified_yaw_tolerance(
    check: Check, stop: pm.Stop, step: float = STEP, limit: float = LIMIT
) -> float:
    """Largest ``k * step`` <= ``limit`` [rad] such that all offsets up to it pass, both ways."""
    if step <= 0 or limit < 0:
        raise ValueError("step must be > 0 and limit >= 0")
    tol, k = 0.0, 1
    while k * step <= limit + 1e-12:
        d = k * step
        for sign in (1.0, -1.0):
            if not all(check(t, stop.x, stop.y, stop.yaw + sign * d)[0] for t in stop.trays):
                return tol
        tol, k = d, k + 1
    return tol


def verified_yaw_tolerances(check: Check, plan: pm.Plan, **kw: float) -> tuple[float, ...]:
    """:func:`verified_yaw_tolerance` of every stop of the plan, in order."""
    return tuple(verified_yaw_tolerance(check, s, **kw) for s in plan.stops)
