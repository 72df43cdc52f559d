"""``pickstop robot check``: what PickStop makes of a robot config, and how long each step took.

:func:`check_robot` loads the config and its URDF (errors name the file and field, and a wrong
joint or frame lists those that exist), then reports the resolved tool, hand and footprint,
the collision links (and which dense meshes the screens replace by their hulls), the disabled
self-collision pairs with their source (the SRDF, or computed as MoveIt's setup assistant does;
with an SRDF both, and where they disagree) and the sphere screen's false rejection against
exact coal checks.
"""

from __future__ import annotations

import fnmatch
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from pickstop.robot.config import RobotConfig, resolve_robot
from pickstop.robot.hand import hand_joints, hand_shape
from pickstop.robot.model import RobotModel, load_robot

T = TypeVar("T")

#: Random configurations behind the computed "always"/"never" pairs in a check (MoveIt's
#: setup assistant uses 10,000 too); a build uses more.
CHECK_SAMPLES = 10_000


def check_robot(ref: str, cache_dir: Any = None) -> dict[str, Any]:
    """The report of the robot ``ref`` (a preset name or a config file) as plain data."""
    t0 = time.perf_counter()
    config, root = resolve_robot(ref)
    return check_config(config, root, ref, cache_dir, round(time.perf_counter() - t0, 3))


def check_config(
    config: RobotConfig, root: Path, label: str, cache_dir: Any = None, parse_s: float = 0.0
) -> dict[str, Any]:
    """The report of a parsed robot config whose relative paths start at ``root``."""
    from pickstop.robot.artifacts import screen_quality, self_collision
    from pickstop.robot.link_geometry import DENSE_TRIANGLES, collision_links
    from pickstop.robot.selfcollision import disabled_pairs

    seconds: dict[str, float] = {"config": parse_s}
    ref = label

    def step(name: str, fn: Callable[[], T]) -> T:
        t0 = time.perf_counter()
        out = fn()
        seconds[name] = round(time.perf_counter() - t0, 3)
        return out

    robot: RobotModel = step("model", lambda: load_robot(config, root))
    links = step("collision_links", lambda: collision_links(robot))
    disabled, _ = step("screen", lambda: self_collision(robot, cache_dir))
    quality = screen_quality(robot, cache_dir)
    report: dict[str, Any] = {
        "robot": robot.name,
        "config": ref,
        "urdf": robot.urdf_path.name,
        "srdf": robot.srdf_path.name if robot.srdf_path else None,
        "robot_hash": robot.robot_hash,
        "base_frame": robot.base_frame,
        "arm_joints": [
            {"name": j.name, "kind": j.kind, "lower": j.lower, "upper": j.upper}
            for j in robot.joints
        ],
        "locked_joints": _locked(robot),
        "tool": _tool(robot),
        "hand": _hand(robot, links),
        "footprint": robot.footprint.model_dump(exclude_none=True),
        "collision_links": [
            {
                "name": lk.name,
                "joint": robot.joints[lk.joint - 1].name if lk.joint else "base",
                "triangles": (tris := _triangles(robot, lk.geometry_ids)),
                "screened_as_hull": tris > DENSE_TRIANGLES,
            }
            for lk in links
        ],
        "self_collision": {
            "source": disabled.source,
            "counts": disabled.counts(),
            "disabled": [[p.link1, p.link2, p.reason] for p in disabled.pairs],
        },
        "screen": {k: quality[k] for k in ("false_rejection", "flagged", "n", "rounds")},
        "seconds": seconds,
    }
    if robot.srdf_path is not None:
        # What the setup assistant would compute, beside what the SRDF says.
        computed = step(
            "computed_pairs", lambda: disabled_pairs(_without_srdf(robot), samples=CHECK_SAMPLES)
        )
        srdf = {(p.link1, p.link2) for p in disabled.pairs}
        mine = {(p.link1, p.link2): p.reason for p in computed.pairs}
        report["self_collision"]["disagreements"] = {
            "srdf_only": sorted([a, b] for a, b in srdf - set(mine)),
            "computed_only": sorted([a, b, mine[(a, b)]] for a, b in set(mine) - srdf),
        }
    return report


def _without_srdf(robot: RobotModel) -> RobotModel:
    from dataclasses import replace

    return replace(robot, srdf_path=None)


def _triangles(robot: RobotModel, ids: tuple[int, ...]) -> int:
    return sum(
        int(getattr(robot.geom_model.geometryObjects[g].geometry, "num_tris", 0)) for g in ids
    )


def _locked(robot: RobotModel) -> dict[str, float]:
    full = robot.full_model
    arm = {j.name for j in robot.joints}
    out = {}
    for jid in range(1, full.njoints):
        name, iq, nq = str(full.names[jid]), full.idx_qs[jid], full.nqs[jid]
        if name in arm:
            continue
        q = robot.q_full[iq : iq + nq]
        out[name] = float(np.arctan2(q[1], q[0])) if nq == 2 else float(q[0])
    return out


def _tool(robot: RobotModel) -> dict[str, Any]:
    frame = robot.model.frames[robot.tool_frame_id]
    T_joint_tool = frame.placement  # in the last arm joint's frame
    return {
        "frame": robot.config.tool_frame,
        "carried_by": robot.joints[-1].name,
        "position_in_joint": np.asarray(T_joint_tool.translation).round(6).tolist(),
        "approach_axis": list(robot.config.hand.approach_axis),
    }


def _hand(robot: RobotModel, links: Any) -> dict[str, Any]:
    pats = robot.config.hand.links
    matched = sorted(lk.name for lk in links if any(fnmatch.fnmatch(lk.name, p) for p in pats))
    unmatched = [p for p in pats if not any(fnmatch.fnmatch(n, p) for n in matched)]
    cfg = robot.config.hand
    out: dict[str, Any] = {
        "patterns": pats,
        "links": matched,
        "patterns_matching_nothing": unmatched,
        "geometry": cfg.geometry,
        "tool_offset": cfg.tool_offset.model_dump(mode="json"),
        "approach_axis": list(cfg.approach_axis),
        "closing_axis": list(cfg.closing_axis),
        "max_opening": cfg.max_opening,
        "pregrasp": hand_joints(robot),  # every joint moving a hand link, as the hand is checked
    }
    if not unmatched:
        out["reach"] = round(hand_shape(robot).reach, 6)  # past the grasp point [m]
    return out


def _footprint_line(fp: dict[str, Any]) -> str:
    drive = f"; {fp.get('drive', 'differential')} drive"
    if fp.get("radius") is not None:
        return f"radius {fp['radius']} m{drive}"
    xs, ys = zip(*fp["polygon"], strict=True)
    how = (
        f"derived from the base's collision geometry below {fp['height']} m plus "
        f"{fp['clearance']} m"
        if fp.get("derived")
        else "given"
    )
    return (
        f"polygon of {len(xs)} vertices ({how}): x {min(xs):.3f}..{max(xs):.3f} m, "
        f"y {min(ys):.3f}..{max(ys):.3f} m, bounding radius "
        f"{max(math.hypot(x, y) for x, y in fp['polygon']):.3f} m{drive}"
    )


def format_report(report: dict[str, Any]) -> str:
    """The report as text for a terminal."""
    sc, scr, sec = report["self_collision"], report["screen"], report["seconds"]
    tool, hand = report["tool"], report["hand"]
    lines = [
        f"robot {report['robot']} ({report['config']}): URDF {report['urdf']}"
        + (f", SRDF {report['srdf']}" if report["srdf"] else ""),
        f"  base frame {report['base_frame']}; arm: "
        + ", ".join(
            f"{j['name']} [{j['lower']:.3g}, {j['upper']:.3g}]" for j in report["arm_joints"]
        ),
        f"  tool frame {tool['frame']} on {tool['carried_by']} at {tool['position_in_joint']}, "
        f"approach {tool['approach_axis']}",
        f"  hand links ({len(hand['links'])}): {', '.join(hand['links']) or 'none'}"
        + (
            f"; patterns matching nothing: {', '.join(hand['patterns_matching_nothing'])}"
            if hand["patterns_matching_nothing"]
            else ""
        ),
        f"  hand: {hand['geometry']}; grasp point {hand['tool_offset']['position']} (rpy "
        f"{hand['tool_offset']['rpy']}) in the tool frame; approach {hand['approach_axis']}, "
        f"closing {hand['closing_axis']}; opening {hand['max_opening']} m"
        + (f"; reaches {hand['reach']} m past the grasp point" if "reach" in hand else ""),
        "  pre-grasp posture: "
        + (", ".join(f"{k} {v:.4g}" for k, v in hand["pregrasp"].items()) or "none"),
        f"  footprint {_footprint_line(report['footprint'])}",
        f"  locked joints: {len(report['locked_joints'])}",
        f"  collision links: {len(report['collision_links'])}"
        + "".join(
            f"\n    {lk['name']} ({lk['triangles']:,} triangles: screened as its hull)"
            for lk in report["collision_links"]
            if lk["screened_as_hull"]
        ),
        f"  self-collision pairs ({sc['source']}): "
        + ", ".join(f"{k} {v}" for k, v in sc["counts"].items()),
    ]
    if "disagreements" in sc:
        d = sc["disagreements"]
        lines.append(
            f"  SRDF vs computed: {len(d['srdf_only'])} pairs only the SRDF disables, "
            f"{len(d['computed_only'])} only the computation would"
        )
        lines += [f"    srdf only: {a} - {b}" for a, b in d["srdf_only"][:20]]
        lines += [f"    computed only: {a} - {b} ({r})" for a, b, r in d["computed_only"][:20]]
    lines.append(
        f"  screen: drops {100 * scr['false_rejection']:.1f}% of valid configurations, flags "
        f"{100 * scr['flagged']:.1f}% ({int(scr['n']):,} checked with coal, "
        f"{int(scr['rounds'])} tightening rounds)"
    )
    lines.append("  seconds: " + ", ".join(f"{k} {v}" for k, v in sec.items()))
    return "\n".join(lines)
