"""A plan as a Nav2 ``NavigateThroughPoses`` goal, with per-stop goal-checker tolerances.

``goal`` is the action's goal message (``nav2_msgs/action/NavigateThroughPoses``: Humble and
Jazzy take ``geometry_msgs/PoseStamped[] poses``; Kilted wraps them in ``nav_msgs/Goals``,
chosen with ``distro="kilted"``). NavigateThroughPoses does not halt at intermediate poses and
its goal checker (default ``xy_goal_tolerance`` 0.25 m, larger than a typical sigma) holds for
the last pose only, so ``segments`` splits the route at each stop: one goal per stop, ending at
it, with the tolerance the stop needs and the picks to run there.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any, Literal

import yaml

from pickstop.errors import InputError
from pickstop.fleet import route as rt
from pickstop.fleet.tolerance import StopShapes
from pickstop.frames import quat_yaw, yaw_quat
from pickstop.sequence import plan_model as pm

Distro = Literal["humble", "jazzy", "kilted"]
FORMAT = "pickstop.nav2"

NOTES = [
    "Frame: every pose is in the map frame given (default 'map'), x forward, z up, "
    "quaternions xyzw as geometry_msgs.",
    "NavigateThroughPoses does not stop at intermediate poses: send each entry of `segments` "
    "as its own goal (poses[first:last + 1]) and run its picks when it succeeds.",
    "Before each segment set the goal checker of the controller server to the segment's "
    "tolerances (nav2_controller::SimpleGoalChecker: <checker>.xy_goal_tolerance, "
    "<checker>.yaw_goal_tolerance, stateful: true), e.g. with `ros2 param set "
    "/controller_server general_goal_checker.xy_goal_tolerance <value>`, or give one goal "
    "checker per stop and select it with the behaviour tree's goal_checker_id.",
    "Intermediate poses (floor path corners) carry no orientation of their own: their yaw "
    "points along the next segment of the path.",
    "Where the base cannot turn (a docking leg to a stop close to a table), both ends of the "
    "leg carry the stop's yaw: drive it straight at that yaw (turn at its outer end), e.g. as "
    "its own goal with a controller that holds the heading; each segment's `docking` lists "
    "the poses reached along such a leg.",
    "The localisation error (AMCL) counts against the tolerance: the stop is only "
    "guaranteed if the true base lies within xy_goal_tolerance of the stop.",
]


DEFAULT_XY_TOLERANCE = 0.25  # [m] nav2_controller::SimpleGoalChecker's default


def _tolerance_note(radii: list[float]) -> str:
    """What the default goal checker means for stops guaranteed within ``radii`` [m]."""
    tight = sum(r < DEFAULT_XY_TOLERANCE for r in radii)
    if tight:
        return (
            f"The default xy_goal_tolerance ({DEFAULT_XY_TOLERANCE} m) is larger than the "
            f"guaranteed radius of {tight} of the {len(radii)} stops: leaving it unchanged lets "
            "the robot stop where a part may be out of reach."
        )
    return (
        f"Every stop is guaranteed within at least the default xy_goal_tolerance "
        f"({DEFAULT_XY_TOLERANCE} m); its own xy_goal_tolerance is that guaranteed radius."
    )


def quaternion(yaw: float) -> dict[str, float]:
    """Rotation about z by ``yaw`` [rad] as a geometry_msgs quaternion (x, y, z, w)."""
    w, x, y, z = yaw_quat(yaw)
    return {"x": x, "y": y, "z": z, "w": w}


def yaw_of(q: dict[str, float]) -> float:
    """Inverse of :func:`quaternion`: the heading [rad] of a geometry_msgs quaternion."""
    return quat_yaw((q["w"], q["x"], q["y"], q["z"]))


def _yaws(wps: list[rt.Waypoint]) -> list[float]:
    out = []
    for i, w in enumerate(wps):
        if w.yaw is not None:
            out.append(w.yaw)
            continue
        j = i + 1 if i + 1 < len(wps) else i - 1
        a, b = (w, wps[j]) if j > i else (wps[j], w)
        out.append(math.atan2(b.y - a.y, b.x - a.x) if j >= 0 else 0.0)
    return out


def build_nav2(
    plan: pm.Plan,
    frame_id: str = "map",
    distro: Distro = "jazzy",
    start_yaw: float | None = None,
    goal_yaw: float | None = None,
    yaw_tolerance: float | Sequence[float] | None = None,
    shapes: Sequence[StopShapes] | None = None,
) -> dict[str, Any]:
    """The goal, per-stop segments with tolerances, the picks beside them, and the notes;
    ``shapes``: checked per stop (:mod:`pickstop.fleet.tolerance`), their circles as the
    stops' ``xy_goal_tolerance``."""
    if distro not in ("humble", "jazzy", "kilted"):
        raise InputError(f"distro: {distro!r} is not humble, jazzy or kilted", field="distro")
    # the robot is at start
    wps = rt.waypoints(plan, start_yaw, goal_yaw, yaw_tolerance, shapes)[1:]
    goal = _goal(wps, frame_id, distro)
    segments = _segments(wps)
    picks = [
        {"segment": k, "stop": seg["name"], "pose_index": seg["last"], **p}
        for k, seg in enumerate(segments)
        for p in seg["picks"]
    ]
    return {
        "format": FORMAT,
        "version": 1,
        "action": "nav2_msgs/action/NavigateThroughPoses",
        "distro": distro,
        "frame_id": frame_id,
        "scene": plan.scene,
        "goal": goal,
        "segments": segments,
        "picks": picks,
        "notes": [*NOTES, _tolerance_note([rt.guaranteed_radius(s) for s in plan.stops])],
    }


def _goal(wps: list[rt.Waypoint], frame_id: str, distro: Distro) -> dict[str, Any]:
    """The NavigateThroughPoses goal through ``wps``: one stamped pose [m, quaternion] each,
    wrapped in ``nav_msgs/Goals`` for Kilted."""

    def header() -> dict[str, Any]:  # stamp zero: "use the latest transform"
        return {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame_id}

    poses = [
        {
            "header": header(),
            "pose": {
                "position": {"x": w.x, "y": w.y, "z": 0.0},
                "orientation": quaternion(yaw),
            },
        }
        for w, yaw in zip(wps, _yaws(wps), strict=True)
    ]
    goal: dict[str, Any] = {"poses": poses, "behavior_tree": ""}
    if distro == "kilted":
        goal = {"poses": {"header": header(), "goals": poses},
                "behavior_tree": ""}  # fmt: skip
    return goal


def _segments(wps: list[rt.Waypoint]) -> list[dict[str, Any]]:
    """One segment per stop (and the goal): its poses ``first..last`` into ``wps``, its
    tolerances [m, rad], the docking poses along it and the picks to run at its end."""
    segments, first = [], 0
    for i, w in enumerate(wps):
        if w.kind not in ("stop", "goal"):
            continue
        seg: dict[str, Any] = {
            "name": w.id,
            "first": first,
            "last": i,
            "xy_goal_tolerance": w.tolerance_xy,
            "yaw_goal_tolerance": w.tolerance_yaw if w.tolerance_yaw is not None else math.pi,
            "docking": [j for j in range(first, i + 1) if wps[j].hold_yaw is not None],
            "picks": [
                {
                    "tray_id": p.tray_id,
                    "part_id": p.part_id,
                    "grasp_index": p.grasp_index,
                    "joint_names": list(p.joints),
                    "joint_positions": list(p.theta),
                }
                for p in w.picks
            ],
        }
        if w.predicted_success is not None:
            seg["predicted_success"] = w.predicted_success
        segments.append(seg)
        first = i + 1
    return segments


def dumps(doc: dict[str, Any], fmt: Literal["json", "yaml"]) -> str:
    if fmt == "json":
        return json.dumps(doc, indent=1) + "\n"
    return yaml.safe_dump(doc, sort_keys=False, width=100)


def loads(text: str) -> dict[str, Any]:
    """Read either form back (YAML is a superset of JSON)."""
    doc = yaml.safe_load(text)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"not a {FORMAT} document", field="format")
    return doc


def goal_poses(doc: dict[str, Any]) -> list[tuple[float, float, float]]:
    """``(x, y, yaw)`` of every pose of a goal document, whichever distro's form."""
    poses = doc["goal"]["poses"]
    if isinstance(poses, dict):
        poses = poses["goals"]
    return [
        (p["pose"]["position"]["x"], p["pose"]["position"]["y"], yaw_of(p["pose"]["orientation"]))
        for p in poses
    ]
