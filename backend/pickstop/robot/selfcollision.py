"""The link pairs self-collision checking skips, picked as MoveIt's setup assistant does.

Links on the same joint never move relative to each other, so only pairs of collision links
(:func:`pickstop.robot.link_geometry.collision_links`) on different joints are *candidates*.
:func:`disabled_pairs` gives each skipped candidate a reason:

- ``adjacent``: joined by one URDF joint, once links joined by fixed joints are merged and
  links without collision geometry are walked through;
- ``default``: colliding at the home pose (every arm joint at 0, clipped into its limits);
- ``always``: colliding in >= 95 % of random samples (uniform within the joint limits);
- ``never``: colliding in none of them;
- ``srdf``: listed by the robot's SRDF, which is then used instead of all of the above.

Samples are screened with the conservative :mod:`pickstop.robot.screen` and checked exactly
with coal only where it flags a pair, so tens of thousands of samples take seconds.
The public names of the self-collision API (the pair types of :mod:`pickstop.robot.pairs`
among them) are re-exported here.
"""

from __future__ import annotations

import json
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from pickstop.errors import InputError, RobotConfigError
from pickstop.progress import Steps, step
from pickstop.robot.cache import COMPUTED, making, write_atomic
from pickstop.robot.exact import ExactSelfCollision, PairChecker, false_rejection_rate
from pickstop.robot.kinematics import BLOCK, Chain, fk_soa
from pickstop.robot.link_geometry import CollisionLink, collision_links
from pickstop.robot.model import RobotModel
from pickstop.robot.pairs import REASONS, DisabledPair, DisabledPairs, Reason, candidate_pairs
from pickstop.robot.screen import SphereModel, screen, screen_pairs

__all__ = [
    "REASONS",
    "CollisionLink",
    "DisabledPair",
    "DisabledPairs",
    "ExactSelfCollision",
    "SphereModel",
    "adjacent_pairs",
    "collision_links",
    "disabled_pairs",
    "false_rejection_rate",
    "home_thetas",
    "screen",
    "screen_pairs",
    "srdf_pairs",
]

#: Random samples for "always"/"never" (MoveIt's default: 10000): ~8 s for TIAGo on one core.
DEFAULT_SAMPLES = 50000
ALWAYS_FRACTION = 0.95
_CACHE_FORMAT = 1


# ---------------------------------------------------------------------------------------------
# Adjacency and SRDF


def adjacent_pairs(urdf_path: Path, links: tuple[CollisionLink, ...]) -> set[tuple[str, str]]:
    """Link pairs joined by one URDF joint, as MoveIt sees them.

    Links joined by fixed joints form one rigid group; links without collision geometry are
    passed through (their neighbours become adjacent). Two links are adjacent when they are in
    one group or in groups joined directly (or through geometry-less groups) by a joint.
    """
    try:
        root = ET.parse(urdf_path).getroot()
    except (OSError, ET.ParseError) as e:
        raise RobotConfigError(f"{urdf_path}: cannot read URDF: {e}") from None
    parent, edges = _fixed_groups(root)
    names = {lk.name for lk in links}
    members: dict[str, set[str]] = defaultdict(set)
    for lk in root.iter("link"):
        members[_find(parent, lk.get("name", ""))].add(lk.get("name", ""))
    graph: dict[str, set[str]] = defaultdict(set)
    for a, b in edges:
        ga, gb = _find(parent, a), _find(parent, b)
        graph[ga].add(gb)
        graph[gb].add(ga)

    def has_geom(g: str) -> bool:
        return bool(members[g] & names)

    out: set[tuple[str, str]] = set()
    for g in list(members):
        if not has_geom(g):
            continue
        reach = _neighbour_groups(g, graph, has_geom)
        mine = members[g] & names
        for h in reach:
            for a in mine:
                for b in members[h] & names:
                    if a != b:
                        out.add((min(a, b), max(a, b)))
    return out


def _fixed_groups(root: ET.Element) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """Union-find parents merging the links a URDF joins by fixed joints, and the (parent,
    child) links of its other joints."""
    parent: dict[str, str] = {}
    edges = []
    for j in root.iter("joint"):
        p, c = j.find("parent"), j.find("child")
        if p is None or c is None:
            continue
        a, b = p.get("link", ""), c.get("link", "")
        if j.get("type") == "fixed":
            parent[_find(parent, b)] = _find(parent, a)
        else:
            edges.append((a, b))
    return parent, edges


def _find(parent: dict[str, str], x: str) -> str:
    """The group (root link) of link ``x`` in the union-find ``parent``."""
    while parent.get(x, x) != x:
        x = parent[x]
    return x


def _neighbour_groups(
    g: str, graph: dict[str, set[str]], has_geom: Callable[[str], bool]
) -> set[str]:
    """``g`` and the groups with geometry joined to it by a joint, walking through groups
    without geometry."""
    reach, stack, seen = {g}, [g], {g}
    while stack:
        for nb in graph[stack.pop()]:
            if nb in seen:
                continue
            seen.add(nb)
            if has_geom(nb):
                reach.add(nb)
            else:
                stack.append(nb)
    return reach


def srdf_pairs(srdf_path: Path) -> set[tuple[str, str]]:
    """The ``<disable_collisions link1 link2>`` entries of an SRDF."""
    try:
        root = ET.parse(srdf_path).getroot()
    except (OSError, ET.ParseError) as e:
        raise RobotConfigError(f"{srdf_path}: cannot read SRDF: {e}") from None
    out = set()
    for dc in root.iter("disable_collisions"):
        a, b = dc.get("link1"), dc.get("link2")
        if a and b and a != b:
            out.add((min(a, b), max(a, b)))
    return out


# ---------------------------------------------------------------------------------------------
# Disabled pairs: compute or read, with a JSON cache


def home_thetas(robot: RobotModel) -> np.ndarray:
    """``(dof,)`` the home pose: every arm joint at 0 clipped into its limits."""
    return np.clip(np.zeros(robot.dof), robot.lower, robot.upper)


def _compute(
    robot: RobotModel, samples: int, seed: int, steps: Steps | None = None
) -> tuple[DisabledPair, ...]:
    """The candidate pairs to skip, each with its reason: adjacent, colliding at home, then
    always or never colliding in ``samples`` random configurations (generator ``seed``)."""
    links = collision_links(robot)
    cands = candidate_pairs(links)
    reasons: dict[tuple[str, str], Reason] = {}
    adj = adjacent_pairs(robot.urdf_path, links)
    for p in cands:
        if p in adj:
            reasons[p] = "adjacent"

    rest = [p for p in cands if p not in reasons]
    checker = PairChecker(robot, rest)
    checker.set_config(home_thetas(robot))
    for k, p in enumerate(rest):
        if checker.colliding(k):
            reasons[p] = "default"

    # Random samples: the sphere screen (conservative) proposes, coal decides.
    partial = DisabledPairs(
        robot.robot_hash,
        links,
        tuple(DisabledPair(a, b, r) for (a, b), r in reasons.items()),
        "computed",
        0,
        seed,
    )
    step(steps, "disabled pairs: covering the links")
    spheres = SphereModel.from_robot(robot, partial, excess=0.015, step=0.02, per_pair=True)
    model_pairs = [(spheres.link_names[i], spheres.link_names[j]) for i, j in spheres.pairs]
    col = {p: k for k, p in enumerate(rest)}
    to_checker = np.array([col[(min(a, b), max(a, b))] for a, b in model_pairs], dtype=np.int64)
    hits = _sampled_hits(robot, checker, spheres, to_checker, samples, seed, steps)

    for k, (a, b) in enumerate(model_pairs):
        p = (min(a, b), max(a, b))
        if hits[k] == 0:
            reasons[p] = "never"
        elif hits[k] >= ALWAYS_FRACTION * samples:
            reasons[p] = "always"
    return tuple(DisabledPair(a, b, r) for (a, b), r in sorted(reasons.items()))


def _sampled_hits(
    robot: RobotModel,
    checker: PairChecker,
    spheres: SphereModel,
    to_checker: np.ndarray,
    samples: int,
    seed: int,
    steps: Steps | None,
) -> np.ndarray:
    """``(P,)`` how many of ``samples`` uniform configurations (generator ``seed``) put each
    pair of ``spheres`` (``to_checker``: its index in ``checker``) in contact, by coal where
    the screen flags it. A pair seen colliding and free too often to be "always" is no longer
    checked (its count stays above 0, below the "always" fraction)."""
    hits = np.zeros(len(spheres.pairs), dtype=np.int64)
    misses = np.zeros(len(spheres.pairs), dtype=np.int64)  # flagged or not, but free
    undecided = np.ones(len(spheres.pairs), dtype=bool)
    allowed_misses = int((1 - ALWAYS_FRACTION) * samples)

    chain = Chain.from_robot(robot)
    rng = np.random.default_rng(seed)
    for s in range(0, samples, BLOCK):
        step(steps, "disabled pairs: random configurations", s, samples)
        n = min(BLOCK, samples - s)
        th = rng.uniform(robot.lower, robot.upper, (n, robot.dof))
        _, _, frames = fk_soa(chain, np.ascontiguousarray(th.T), frames=True)
        flags = screen_pairs(spheres, frames) & undecided[:, None]  # (P, n)
        misses += n - flags.sum(axis=1)
        for b in np.flatnonzero(flags.any(axis=0)):
            ks = np.flatnonzero(flags[:, b] & undecided)
            if not len(ks):
                continue
            checker.set_config(th[b])
            for kp in ks:
                if checker.colliding(int(to_checker[kp])):
                    hits[kp] += 1
                else:
                    misses[kp] += 1
            # A pair seen colliding, and free too often to be "always", is decided: enabled.
            undecided &= ~((hits > 0) & (misses > allowed_misses))
    return hits


def _from_srdf(robot: RobotModel, links: tuple[CollisionLink, ...]) -> tuple[DisabledPair, ...]:
    assert robot.srdf_path is not None
    listed = srdf_pairs(robot.srdf_path)
    return tuple(DisabledPair(a, b, "srdf") for a, b in candidate_pairs(links) if (a, b) in listed)


def _cache_file(cache_dir: Path, robot: RobotModel, samples: int, seed: int) -> Path:
    key = "srdf" if robot.srdf_path is not None else f"s{samples}-seed{seed}"
    return cache_dir / f"selfcollision-{robot.robot_hash[:24]}-{key}.json"


def _read_cache(
    path: Path, robot: RobotModel, links: tuple[CollisionLink, ...], samples: int, seed: int
) -> DisabledPairs | None:
    """The cached pairs, or None if the file is missing, corrupt or for another request."""
    try:
        doc = json.loads(path.read_text())
        source = doc["source"]
        if (
            doc["format"] != _CACHE_FORMAT
            or doc["robot_hash"] != robot.robot_hash
            or source not in ("computed", "srdf")
            or (source == "computed" and (doc["samples"], doc["seed"]) != (samples, seed))
        ):
            return None
        cands = set(candidate_pairs(links))
        pairs = []
        for a, b, r in doc["pairs"]:
            if (a, b) not in cands or r not in REASONS:
                return None
            pairs.append(DisabledPair(a, b, r))
        return DisabledPairs(
            robot.robot_hash,
            links,
            tuple(pairs),
            source,
            int(doc["samples"]),
            int(doc["seed"]),
            float(doc["seconds"]),
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _write_cache(path: Path, dp: DisabledPairs) -> None:
    doc = {
        "format": _CACHE_FORMAT,
        "robot_hash": dp.robot_hash,
        "source": dp.source,
        "samples": dp.samples,
        "seed": dp.seed,
        "seconds": dp.seconds,
        "pairs": [[p.link1, p.link2, p.reason] for p in dp.pairs],
    }
    write_atomic(path, json.dumps(doc, indent=1).encode())


def disabled_pairs(
    robot: RobotModel,
    samples: int = DEFAULT_SAMPLES,
    seed: int = 0,
    cache_dir: Path | None = None,
    steps: Steps | None = None,
) -> DisabledPairs:
    """The link pairs to skip: from the robot's SRDF if it has one, else computed.

    samples: random configurations behind "always" and "never".
    seed: seed of their generator.
    cache_dir: folder for a JSON cache keyed by ``robot.robot_hash``, samples and seed (None:
    no cache); a corrupt or mismatching file is recomputed and replaced.
    steps: told how the computation goes (:mod:`pickstop.progress`).
    """
    if samples < 1:
        raise InputError(f"samples must be >= 1, got {samples}", field="samples")
    links = collision_links(robot)
    path = _cache_file(cache_dir, robot, samples, seed) if cache_dir is not None else None
    if path is not None:
        cached = _read_cache(path, robot, links, samples, seed)
        if cached is not None:
            return cached
    with making(path):  # another process computing them: wait, then read them
        if path is not None:
            cached = _read_cache(path, robot, links, samples, seed)
            if cached is not None:
                return cached
        t0 = time.perf_counter()
        if robot.srdf_path is not None:
            pairs = _from_srdf(robot, links)
            dp = DisabledPairs(robot.robot_hash, links, pairs, "srdf", 0, seed)
        else:
            pairs = _compute(robot, samples, seed, steps)
            dp = DisabledPairs(robot.robot_hash, links, pairs, "computed", samples, seed)
            COMPUTED["pairs"] += 1
        dp = replace(dp, seconds=time.perf_counter() - t0)
        if path is not None:
            _write_cache(path, dp)
    return dp
