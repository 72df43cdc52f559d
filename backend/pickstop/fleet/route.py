"""A plan as a vehicle drives it: waypoints (start, floor-path corners, stops, goal) with the
tolerance each must be reached within, and the picks at each stop.

Where the base's bounding circle does not fit (a long base's stop close to a table), the plan
docks: a straight leg driven at the stop's fixed yaw from a staging point where the base may
turn. Such a leg's end waypoints carry that yaw (``yaw``) and the leg arriving at a waypoint
says the yaw it is driven at (``hold_yaw``); the vehicle halts at both ends to turn.

Shared by the VDA 5050 and Nav2 exports and by the simulated vehicle. A stop's *guaranteed
radius* is the largest circle around it inside which every part of its trays stays graspable:
the inscribed circle of the regions' intersection the stop is the centre of (every floor cell
in it is exactly verified for all those trays), or, checked off the grid, the circle and ellipse
of :mod:`pickstop.fleet.tolerance`. Its yaw tolerance is what the plan's Monte Carlo
sampled: two standard deviations of the scene's yaw error, and at least the yaw lattice.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import ValidationError

from pickstop.errors import InputError
from pickstop.fleet.tolerance import StopShapes
from pickstop.frames import wrap_angle
from pickstop.sequence import plan_model as pm
from pickstop.sequence.success import YAW_LATTICE

MAX_PLAN_BYTES = 64 * 1024 * 1024  # a plan file read from disk

MAX_WAYPOINTS = 10_000  # a route longer than this is refused before any export
VIA_TOLERANCE = 0.25  # [m] how close a floor-path corner must be passed (Nav2's default)
DOCK_TOLERANCE = 0.02  # [m] how close a docking leg's staging point must be reached

Kind = Literal["start", "via", "stop", "goal"]


@dataclass(frozen=True)
class Pick:
    """One part to pick at a stop, with the witness arm configuration the plan verified."""

    tray_id: str
    part_id: str
    grasp_index: int
    joints: tuple[str, ...]
    theta: tuple[float, ...]  # [rad or m], in ``joints`` order


@dataclass(frozen=True)
class Waypoint:
    """A pose the vehicle passes (``via``) or stops at, in the scene's map frame."""

    id: str
    kind: Kind
    x: float  # [m]
    y: float  # [m]
    yaw: float | None  # [rad]; None: the vehicle chooses
    tolerance_xy: float  # [m] radius within which it counts as reached
    tolerance_yaw: float | None  # [rad]
    stop: int | None = None  # stop index for kind "stop"
    picks: tuple[Pick, ...] = ()
    predicted_success: float | None = None
    hold_yaw: float | None = None  # [rad] the yaw held on the way here (a docking leg)
    ellipse: tuple[float, float, float] | None = None  # checked (a, b [m], theta [rad]), if any


def guaranteed_radius(stop: pm.Stop) -> float:
    """Radius [m] around the stop inside which every part of its trays stays graspable: the
    largest circle centred at the stop inside its intersection (the inscribed circle when the
    stop is at its centre)."""
    return float(stop.inscribed_radius if stop.clearance is None else stop.clearance)


def yaw_tolerance(plan: pm.Plan) -> float:
    """Half-width [rad] of the yaw band the plan's success estimate covers."""
    return max(2.0 * plan.parameters.yaw_sigma, YAW_LATTICE)


def load_plan(doc: Any, source: str = "plan") -> pm.Plan:
    """Validate a plan document; a bad one raises :class:`InputError` naming the field."""
    try:
        return pm.Plan.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(root)"
        raise InputError(f"{source}: {loc}: {err['msg']}", field=loc) from None


def read_plan(path: str) -> pm.Plan:
    """The plan in the JSON file ``path``; a missing, oversized or invalid one raises
    :class:`InputError` naming the field ``plan``."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"plan {path}: no such file", field="plan")
    if p.stat().st_size > MAX_PLAN_BYTES:
        raise InputError(f"plan {path}: larger than {MAX_PLAN_BYTES} bytes", field="plan")
    try:
        doc = json.loads(p.read_text())
    except (ValueError, UnicodeDecodeError) as e:
        raise InputError(f"plan {path}: not JSON ({e})", field="plan") from None
    return load_plan(doc, f"plan {path}")


def waypoints(
    plan: pm.Plan,
    start_yaw: float | None = None,
    goal_yaw: float | None = None,
    yaw_tol: float | Sequence[float] | None = None,
    shapes: Sequence[StopShapes] | None = None,
) -> list[Waypoint]:
    """The route as waypoints: start, the corners of each leg's floor path, stops, goal.

    ``yaw_tol``: the stops' yaw tolerance [rad], one for all or one per stop (e.g. from
    :func:`pickstop.fleet.yaw.verified_yaw_tolerances`); default :func:`yaw_tolerance`.
    ``shapes``: one per stop, checked off the grid
    (:func:`pickstop.fleet.tolerance.stop_shapes`): a stop's radius is then its checked
    circle's and it carries its checked ellipse; default :func:`guaranteed_radius`, no ellipse.
    """
    _check_route(plan, shapes)
    tols = _stop_yaw_tolerances(plan, yaw_tol)
    joints = tuple(plan.joints)
    dock_tol = min(tols) if tols else yaw_tolerance(plan)  # the tightest band on docking legs
    if not plan.legs or not plan.legs[0].polyline:
        raise InputError("legs: the plan has no route", field="legs")
    x0, y0 = plan.legs[0].polyline[0]
    out = [Waypoint("start", "start", x0, y0, start_yaw, VIA_TOLERANCE, None)]
    for k, leg in enumerate(plan.legs):
        held = _held_yaws(k, leg)
        if held[0] is not None and k == 0:  # the start itself is docked: it holds that yaw
            first = out[0]
            out[0] = Waypoint(first.id, "start", first.x, first.y, held[0], VIA_TOLERANCE, None)
        out += _vias(k, leg.polyline, held, dock_tol)
        x, y = leg.polyline[-1]
        if k < len(plan.stops):
            sh = None if shapes is None else shapes[k]
            out.append(_stop_waypoint(plan.stops[k], k, joints, tols[k], held[-1], sh))
        else:
            # a docked goal is reached at the yaw it was planned with
            gyaw = held[-1] if held[-1] is not None or goal_yaw is None else wrap_angle(goal_yaw)
            out.append(Waypoint("goal", "goal", x, y, gyaw, VIA_TOLERANCE, None, hold_yaw=held[-1]))
    return out


def _check_route(plan: pm.Plan, shapes: Sequence[StopShapes] | None) -> None:
    """A shape per stop (if any), a leg more than stops, at most :data:`MAX_WAYPOINTS`."""
    if shapes is not None and len(shapes) != len(plan.stops):
        raise InputError(f"shapes: {len(shapes)} for {len(plan.stops)} stops", field="shapes")
    n = sum(max(0, len(leg.polyline) - 1) for leg in plan.legs) + 1
    if n > MAX_WAYPOINTS:
        raise InputError(
            f"legs: the route has {n} waypoints, more than {MAX_WAYPOINTS}", field="legs"
        )
    if len(plan.legs) != len(plan.stops) + 1:
        raise InputError(
            f"legs: {len(plan.legs)} legs for {len(plan.stops)} stops (expected stops + 1)",
            field="legs",
        )


def _stop_yaw_tolerances(plan: pm.Plan, yaw_tol: float | Sequence[float] | None) -> list[float]:
    """The yaw tolerance of each stop [rad], each in [0, pi]."""
    if yaw_tol is None or isinstance(yaw_tol, float | int):
        tols = [yaw_tolerance(plan) if yaw_tol is None else float(yaw_tol)] * len(plan.stops)
    else:
        tols = [float(t) for t in yaw_tol]
        if len(tols) != len(plan.stops):
            raise InputError(
                f"yaw_tolerance: {len(tols)} values for {len(plan.stops)} stops",
                field="yaw_tolerance",
            )
    if any(not 0 <= t <= math.pi for t in tols):
        raise InputError("yaw_tolerance: each must be in [0, pi] rad", field="yaw_tolerance")
    return tols


def _held_yaws(k: int, leg: pm.Leg) -> list[float | None]:
    """The yaw [rad] leg ``k`` holds on each segment (wrapped), None where it is free."""
    line = leg.polyline
    held = leg.segment_yaws or [None] * (len(line) - 1)
    if len(held) != len(line) - 1:
        raise InputError(
            f"legs.{k}.segment_yaws: {len(held)} values for {len(line) - 1} segments",
            field=f"legs.{k}.segment_yaws",
        )
    return [None if y is None else wrap_angle(y) for y in held]


def _vias(
    k: int, line: Sequence[pm.Point2], held: list[float | None], dock_tol: float
) -> list[Waypoint]:
    """The inner corners of leg ``k``'s floor path; docked where a segment holds a yaw."""
    out = []
    for i, (x, y) in enumerate(line[1:-1], start=1):
        yaw = held[i - 1] if held[i - 1] is not None else held[i]
        out.append(
            Waypoint(
                f"leg{k}-via{i}",
                "via",
                x,
                y,
                yaw,
                VIA_TOLERANCE if yaw is None else DOCK_TOLERANCE,
                None if yaw is None else dock_tol,
                hold_yaw=held[i - 1],
            )
        )
    return out


def _stop_waypoint(
    s: pm.Stop,
    k: int,
    joints: tuple[str, ...],
    tol: float,
    hold_yaw: float | None,
    sh: StopShapes | None,
) -> Waypoint:
    """Stop ``k`` with its picks; its radius the checked circle's if ``sh``, else the plan's."""
    picks = tuple(
        Pick(w.tray_id, w.part_id, w.grasp_index, joints, tuple(w.theta)) for w in s.witnesses
    )
    return Waypoint(
        f"stop{k}",
        "stop",
        s.x,
        s.y,
        wrap_angle(s.yaw),
        guaranteed_radius(s) if sh is None else sh.radius,
        tol,
        stop=k,
        picks=picks,
        predicted_success=None if s.success is None else s.success.rate,
        hold_yaw=hold_yaw,
        ellipse=None if sh is None else (sh.ellipse.a, sh.ellipse.b, sh.ellipse.theta),
    )
