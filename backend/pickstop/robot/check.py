"""``pickstop robot check``: what PickStop makes of a robot config, and how long each step took.

:func:`check_robot` loads the config and its URDF (errors name the file and field, and a wrong
joint or frame lists those that exist), then reports the resolved tool, hand and footprint,
the collision links (and which dense meshes the screens replace by their hulls), the disabled
self-collision pairs with their source (the SRDF, or computed as MoveIt's setup assistant does;
with an SRDF both, and where they disagree) and the sphere screen's false rejection against
exact coal checks, and the arm's travel posture with the exact check of it.
"""

from __future__ import annotations

import fnmatch
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from pickstop.progress import Steps
from pickstop.progress import step as report_step
from pickstop.robot.cache import COMPUTED, robots_folder
from pickstop.robot.config import RobotConfig, resolve_robot
from pickstop.robot.hand import hand_fit, hand_joints
from pickstop.robot.model import RobotModel, load_robot
from pickstop.robot.travel import problem, travel_of

T = TypeVar("T")

#: Random configurations behind the computed "always"/"never" pairs in a check (MoveIt's
#: setup assistant uses 10,000 too); a build uses more.
CHECK_SAMPLES = 10_000


def check_robot(ref: str, cache_dir: Any = None, steps: Steps | None = None) -> dict[str, Any]:
    """The report of the robot ``ref`` (a preset name or a config file) as plain data;
    ``steps``: told of each step as it goes (:mod:`pickstop.progress`)."""
    t0 = time.perf_counter()
    config, root = resolve_robot(ref)
    return check_config(config, root, ref, cache_dir, round(time.perf_counter() - t0, 3), steps)


def check_config(
    config: RobotConfig,
    root: Path,
    label: str,
    cache_dir: Any = None,
    parse_s: float = 0.0,
    steps: Steps | None = None,
) -> dict[str, Any]:
    """The report of a parsed robot config whose relative paths start at ``root``."""
    from pickstop.robot.artifacts import bound_missed, screen_quality, self_collision
    from pickstop.robot.link_geometry import collision_links

    seconds: dict[str, float] = {"config": parse_s}
    timed = _Timer(steps, seconds)
    before = Counter(COMPUTED)
    robot: RobotModel = timed(
        "model",
        "loading the URDF, its meshes and the base outline",
        lambda: load_robot(config, root),
    )
    links = timed("collision_links", "grouping the collision links", lambda: collision_links(robot))
    disabled, _ = timed(
        "screen", "the self-collision screen", lambda: self_collision(robot, cache_dir, steps)
    )
    quality = screen_quality(robot, cache_dir)
    travel = timed("travel", "the travel posture", lambda: travel_of(robot, disabled))
    report: dict[str, Any] = {
        **_describe(robot, links, label),
        "self_collision": _pairs(disabled),
        "screen": _screen(quality),
        "travel": _travel(robot, travel),
        "seconds": seconds,
        "warnings": [],
    }
    if robot.srdf_path is not None:
        report["self_collision"]["disagreements"] = timed(
            "computed_pairs",
            "the SRDF against the pairs MoveIt's setup assistant would compute",
            lambda: _srdf_disagreements(robot, disabled, cache_dir, steps),
        )
    missed = bound_missed(quality)
    if missed:
        report["warnings"].append(missed)
    report["warnings"] += _hand_warnings(report["hand"])
    travel_problem = problem(robot, travel)
    if travel_problem:
        report["warnings"].append(travel_problem)
    report_step(steps, "")
    report["cache"] = {
        "folder": None if cache_dir is None else str(cache_dir),
        "computed": sorted((COMPUTED - before).elements()),  # the rest was read from it
    }
    return report


@dataclass(frozen=True)
class _Timer:
    """Runs a step of the check, telling ``steps`` of it and keeping its time in ``seconds``
    [s, rounded to ms] under its name."""

    steps: Steps | None
    seconds: dict[str, float]

    def __call__(self, name: str, what: str, fn: Callable[[], T]) -> T:
        report_step(self.steps, what)
        t0 = time.perf_counter()
        out = fn()
        self.seconds[name] = round(time.perf_counter() - t0, 3)
        return out


def _pairs(disabled: Any) -> dict[str, Any]:
    """The disabled self-collision pairs: their source, counts by reason and each pair."""
    return {
        "source": disabled.source,
        "counts": disabled.counts(),
        "disabled": [[p.link1, p.link2, p.reason] for p in disabled.pairs],
    }


def _travel(robot: RobotModel, travel: Any) -> dict[str, Any]:
    """The travel posture: its source, joint positions [rad or m] and colliding link pairs."""
    return {
        "source": travel.source,
        "joints": {k: round(v, 6) for k, v in travel.by_joint(robot).items()},
        "collisions": [list(p) for p in travel.collisions],
    }


def _describe(robot: RobotModel, links: Any, label: str) -> dict[str, Any]:
    """What the config resolves to: files, joints, tool, hand, footprint, collision links."""
    from pickstop.robot.link_geometry import DENSE_TRIANGLES

    return {
        "robot": robot.name,
        "config": label,
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
    }


def _screen(quality: dict[str, float]) -> dict[str, Any]:
    """The screen's figures, with the bound it is held to and whether it meets it."""
    from pickstop.robot.artifacts import FALSE_REJECTION_BOUND

    out: dict[str, Any] = {k: quality[k] for k in ("false_rejection", "flagged", "n", "rounds")}
    out["bound"] = quality.get("bound", FALSE_REJECTION_BOUND)
    out["meets_bound"] = quality["false_rejection"] <= out["bound"]
    return out


def _srdf_disagreements(
    robot: RobotModel, disabled: Any, cache_dir: Any, steps: Steps | None
) -> dict[str, list[list[str]]]:
    """Where the SRDF's pairs and those MoveIt's setup assistant would compute differ (the
    computed ones kept in the cache like the rest)."""
    from pickstop.robot.selfcollision import disabled_pairs

    def told(name: str, done: int, total: int) -> None:
        report_step(steps, f"SRDF comparison, {name}" if name else "", done, total)

    computed = disabled_pairs(
        _without_srdf(robot),
        samples=CHECK_SAMPLES,
        cache_dir=robots_folder(cache_dir),
        steps=told if steps is not None else None,
    )
    srdf = {(p.link1, p.link2) for p in disabled.pairs}
    mine = {(p.link1, p.link2): p.reason for p in computed.pairs}
    return {
        "srdf_only": sorted([a, b] for a, b in srdf - set(mine)),
        "computed_only": sorted([a, b, mine[(a, b)]] for a, b in set(mine) - srdf),
    }


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
        fit = hand_fit(robot)
        out["reach"] = round(fit.reach, 6)  # past the grasp point [m]
        out["top_down_min_height"] = round(fit.top_down_min, 6)
        out["side_below"] = round(fit.side_below, 6)
        if fit.pad_tip is not None and fit.tool_offset is not None:
            out["pad_tip"] = round(fit.pad_tip, 6)
            out["pad_gap"] = round(fit.pad_gap or 0.0, 6)
            out["suggested_tool_offset"] = {
                "position": [round(v, 6) for v in fit.tool_offset],
                "rpy": list(cfg.tool_offset.rpy),
                "reach": round(fit.reach_at_pads or 0.0, 6),
            }
    return out


#: [m] A small part (the example scenes' lowest, in trays with 5 cm walls): a hand whose
#: top-down grasps cannot take it is warned of.
SMALL_PART = 0.03


def _hand_warnings(hand: dict[str, Any]) -> list[str]:
    """What to warn of in the hand's set-up: patterns matching no link, no hand geometry, a
    grasp point well behind the pads' inner edge."""
    out = []
    if hand["patterns_matching_nothing"]:
        out.append(
            "hand.links patterns matching no collision link: "
            + ", ".join(hand["patterns_matching_nothing"])
        )
    elif not hand["links"] and hand["geometry"] == "links":
        out.append(
            "no hand links: grasps are checked against no hand geometry at all; name them in "
            "hand.links, or let boxes stand in for them (hand.geometry: boxes)"
        )
    gap, opening = hand.get("pad_gap"), hand["max_opening"]
    if gap is not None and abs(gap - opening) > max(0.002, 0.1 * opening):
        out.append(
            f"hand.max_opening is {opening} m but the open pads are {gap:.3f} m apart: "
            "max_opening is the free gap between the pads when open (grasps are generated for "
            "parts up to that wide)"
        )
    if hand.get("top_down_min_height", 0.0) > SMALL_PART:
        fix = "move the grasp point towards the fingertips with hand.tool_offset"
        sug = hand.get("suggested_tool_offset")
        if sug is not None and hand["pad_tip"] > 0:
            fix = (
                f"hand.tool_offset: {{position: {_vec(sug['position'])}}} puts the grasp point "
                f"at the pads' inner edge, {1000 * hand['pad_tip']:.1f} mm further along the "
                f"approach (the hand then reaches {sug['reach']:.3f} m past it)"
            )
        out.append(
            f"the open hand reaches {hand['reach']:.3f} m past the grasp point: top-down grasps "
            f"take no part lower than {hand['top_down_min_height']:.3f} m, and a "
            f"{100 * SMALL_PART:.0f} cm part in a tray with walls has no grasp; {fix}"
        )
    return out


def _vec(v: list[float]) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"


def _hand_lines(hand: dict[str, Any]) -> list[str]:
    """What the open hand rules out, and the tool offset at the pads' inner edge."""
    if "reach" not in hand:
        return []
    low, below = hand["top_down_min_height"], hand["side_below"]
    walls = low / 2 - below
    lines = [
        f"  open hand: top-down grasps take parts from {low:.3f} m up (lower ones would put the "
        f"hand on the tray floor); sideways it reaches {below:.3f} m below the grasp point, so "
        f"a side grasp of a part h high clears tray walls up to h/2 - {below:.3f} m: a part "
        f"lower than {low:.3f} m has no grasp in "
        + (f"a tray with walls over {walls:.3f} m" if walls > 0 else "a tray with walls")
    ]
    sug = hand.get("suggested_tool_offset")
    if sug is None:
        lines.append("  pads: no finger geometry found on both sides of the closing axis")
    else:
        lines.append(
            f"  pads: {hand['pad_gap']:.3f} m apart open (max_opening {hand['max_opening']} m); "
            f"their inner edge {hand['pad_tip']:.4f} m past the grasp point: hand.tool_offset "
            f"{{position: {_vec(sug['position'])}}} puts the grasp point there (the open hand "
            f"then reaches {sug['reach']:.3f} m past it)"
        )
    return lines


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
    lines = [*_robot_lines(report), *_collision_lines(report), _screen_line(report["screen"])]
    if "travel" in report:
        tr = report["travel"]
        lines.append(
            f"  travel posture ({tr['source']}): "
            + ", ".join(f"{k} {v:.4g}" for k, v in tr["joints"].items())
            + ("; collision-free (exact check)" if not tr["collisions"] else "; COLLIDING")
        )
    lines.append("  seconds: " + ", ".join(f"{k} {v}" for k, v in report["seconds"].items()))
    lines += [f"WARNING: {w}" for w in report.get("warnings", [])]
    cache = report.get("cache") or {}
    if cache.get("folder"):
        made = cache["computed"]
        lines.append(
            f"  cache {cache['folder']}: "
            + (f"computed {', '.join(made)} (kept for every later check, build and plan)"
               if made else "everything read from it")
        )  # fmt: skip
    return "\n".join(lines)


def _robot_lines(report: dict[str, Any]) -> list[str]:
    """The robot's files, arm, tool, hand, footprint and locked joints, a line each."""
    tool, hand = report["tool"], report["hand"]
    return [
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
        *_hand_lines(hand),
        "  pre-grasp posture: "
        + (", ".join(f"{k} {v:.4g}" for k, v in hand["pregrasp"].items()) or "none"),
        f"  footprint {_footprint_line(report['footprint'])}",
        f"  locked joints: {len(report['locked_joints'])}",
    ]


def _collision_lines(report: dict[str, Any]) -> list[str]:
    """The collision links (those screened as hulls named), the disabled pairs by reason, and
    where the SRDF and the computed pairs disagree (20 of each at most)."""
    sc = report["self_collision"]
    lines = [
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
    return lines


def _screen_line(scr: dict[str, Any]) -> str:
    bound = f"{100 * scr.get('bound', 0.05):g}% bound"
    return (
        f"  screen: drops {100 * scr['false_rejection']:.1f}% of valid configurations, flags "
        f"{100 * scr['flagged']:.1f}% ({int(scr['n']):,} checked with coal, "
        f"{int(scr['rounds'])} tightening rounds): "
        + (f"within its {bound}" if scr.get("meets_bound", True) else f"OVER its {bound}")
    )
