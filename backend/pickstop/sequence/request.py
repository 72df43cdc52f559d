"""From a scene to the plan a factory runs: regions, candidates, stops, route, time, success.

1. Base regions of the task's trays.
2. Every connected component of every k-th order intersection is a candidate stop at its
   largest inscribed circle's centre; the rule (the paper's sigma, or a target success rate)
   decides which are kept, and candidates the start cannot reach are dropped.
3. Shortest floor paths between start, goal and every candidate (a pose the base's bounding
   circle does not fit docks on straight legs at its yaw, the swept body checked exactly);
   CP-SAT picks the fewest stops, then the shortest route (or the least time).
4. Each chosen stop is verified at its centre by the exact pipeline (that gives the witness
   arm configurations) and, with the success rule, confirmed by the Monte Carlo; a stop that
   fails is rejected with its reason and the selection runs again.
5. The naive plan (one stop per tray) through the same route solver, for comparison.

Anything impossible raises :class:`InfeasiblePlanError` naming the trays and numbers involved.
A request (:class:`PlanRequest`) runs these steps in order, top to bottom, and asks each
answer of a :class:`~pickstop.sequence.steps.PlanSteps`:
:class:`~pickstop.speedups.stop_planner.StopPlanner` (cached, reused across edits) or, in
:func:`plan_from_scratch`, :class:`~pickstop.sequence.pure.PureSteps` (the algorithm alone).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import time
from dataclasses import replace
from typing import Any, Literal

import numpy as np
from shapely.geometry import Point

from pickstop.regions.cells import TrayRegion
from pickstop.regions.footprint import upper_body
from pickstop.regions.kit import RegionKit
from pickstop.runtime.cancel import checkpoint
from pickstop.scene.model import Scene, gripper_notes
from pickstop.scene.positioning import of_scene
from pickstop.sequence import expected, pure
from pickstop.sequence import plan_model as pm
from pickstop.sequence.cover import InfeasiblePlanError, Selection
from pickstop.sequence.failure import FailureCosts, failure_time, stop_failures
from pickstop.sequence.intersections import Intersection
from pickstop.sequence.placement import clearance
from pickstop.sequence.route import Paths
from pickstop.sequence.rules import Rule, cut_off, judge
from pickstop.sequence.steps import Floor, PlanSteps
from pickstop.sequence.success import Rate, combined
from pickstop.sequence.timing import TimeBreakdown, leg_time, pieces_time, plan_time, rest_pieces

HEADINGS = 8  # headings tried (every 45 deg) to say where a tray no stop serves is reachable
HEADING_HINT_TRAYS = 3  # such trays tried, at most (each a region per heading)
MAX_VERIFY_ROUNDS = 8  # selection rounds while chosen stops fail their checks


def plan_from_scratch(
    kit: RegionKit, scene: Scene, options: pm.PlanOptions | None = None
) -> pm.Plan:
    """The plan of ``scene`` by the algorithm alone (:class:`~pickstop.sequence.pure.PureSteps`:
    regions, candidates, floor, checks and estimates computed from their inputs, nothing kept
    or reused); :class:`~pickstop.speedups.stop_planner.StopPlanner` gives the same plan faster.
    ``kit``: the robot and database's (only what is built from them is used, none of its
    memos)."""
    return PlanRequest(pure.PureSteps(kit), scene, options or pm.PlanOptions()).run()


def world_key(scene: Scene) -> str:
    """What feasibility at a base pose depends on: everything but task, start, goal, sigma."""
    keep = scene.model_dump(
        exclude={
            "name",
            "description",
            "task",
            "start",
            "goal",
            "sigma",
            "error_model",
            "motion",
            "failure",
        }
    )
    return pure.digest(sorted(keep.items()))


def scene_hash(scene: Scene) -> str:
    return hashlib.sha256(scene.model_dump_json().encode()).hexdigest()


def route_points(scene: Scene, cands: list[Intersection]) -> np.ndarray:
    """``(2 + n, 2)`` floor points [m]: the start, the goal, then each candidate's centre."""
    ends = [[scene.start.x, scene.start.y], [scene.goal.x, scene.goal.y]]
    return np.array(ends + [list(c.centre) for c in cands], float).reshape(-1, 2)


def route_yaws(scene: Scene, cands: list[Intersection]) -> np.ndarray:
    """``(2 + n,)`` [rad]: the base's yaw at each of :func:`route_points`."""
    return np.array([scene.start.yaw, scene.goal.yaw, *(c.yaw for c in cands)], float)


class PlanRequest:
    """One planning request: :meth:`run` takes the algorithm's steps in order, each answer
    asked of ``sp``; holds the request's intermediate results, nothing beyond it."""

    def __init__(
        self,
        sp: PlanSteps,
        scene: Scene,
        opts: pm.PlanOptions,
        preview: bool = False,
        unlock: Any = None,
    ) -> None:
        """sp: the steps (:class:`~pickstop.sequence.steps.PlanSteps`: from scratch or
        cached). unlock: the planner's lock, held by the caller, to release while a stop
        selection is solved
        (:meth:`~pickstop.speedups.stop_planner.StopPlanner.prefetch_selections`)."""
        self.sp, self.scene, self.opts = sp, scene, opts
        self.preview = preview
        self.unlock = unlock
        self.sigma = scene.sigma if opts.sigma is None else opts.sigma
        self.kind = scene.error_model.kind
        self.positioning = of_scene(scene, self.sigma)
        self.required = scene.task_trays
        self.world = world_key(scene)
        self.t: dict[str, float] = dict.fromkeys(
            ["regions", "intersections", "routing", "estimates", "selection", "verification",
             "monte_carlo", "naive"], 0.0
        )  # fmt: skip
        self.rejected: dict[int, str] = {}
        self.unusable: set[int] = set()  # rejected whatever the rule: cut off, exact check failed
        self.predicted: dict[int, float] = {}
        self.costs = FailureCosts.of(scene.failure)
        self.est: dict[int, dict[frozenset[str], float]] = {}  # candidate -> tray set -> rate
        self.cands: list[Intersection] = []
        self.rows: dict[tuple[Any, ...], dict[int, Selection]] = {}  # see _expected
        self.regions: dict[tuple[str, float], TrayRegion] = {}
        self.circle: dict[int, Intersection] = {}  # placed candidate -> as the circle has it
        self.circle_rates: dict[int, Rate] = {}  # placed and chosen -> Monte Carlo at the circle
        self.floor: Floor | None = None
        self.placed_back: Paths | None = None  # paths after a placed stop went back (see run)

    def _clock(self, name: str, t0: float) -> float:
        """Count the step ``name`` begun at ``t0`` done; the plan stops here if its
        computation is to (:func:`~pickstop.runtime.cancel.checkpoint`)."""
        checkpoint()
        now = time.perf_counter()
        self.t[name] += now - t0
        return now

    def run(self) -> pm.Plan:
        t_start = t0 = time.perf_counter()
        scene, sp = self.scene, self.sp
        regions = self._preview_regions() if self.preview else sp.regions.regions(scene)
        t0 = self._clock("regions", t0)
        self._empty_regions(regions)
        self.regions = regions
        cands = self.cands = sp.candidates(regions)
        t0 = self._clock("intersections", t0)
        if self._placing():
            cands = self.cands = self._place(cands)
            t0 = self._clock("estimates", t0)

        floor = self.floor = sp.floor(scene, self.world)
        paths = self._paths(cands)
        self._check_endpoints(floor, paths)
        if not np.isfinite(paths.dist[0, 1]):
            raise InfeasiblePlanError(
                f"the goal ({scene.goal.x:.2f}, {scene.goal.y:.2f}) cannot be reached from the "
                f"start ({scene.start.x:.2f}, {scene.start.y:.2f}): obstacles close every way",
                field="goal",
            )
        t0 = self._clock("routing", t0)

        threshold = self._apply_rule(cands, paths)
        t0 = time.perf_counter()
        if not self.preview:  # every candidate's estimate, exact near the boundaries
            if not self.positioning.anisotropic:  # one batch; else each by its own model
                stops = [(self._regions_of(c), cands[c].centre) for c in range(len(cands))]
                sp.refine(scene, self.world, stops, self.sigma, self.kind)
            for c in range(len(cands)):
                self._estimates(c)
            t0 = self._clock("estimates", t0)
        sel, witnesses, rates, paths = self._select_verified(regions, cands, paths)
        t0 = time.perf_counter()
        tradeoff = None
        if self.opts.objective == "expected-time" and not self.preview:
            tradeoff = self._tradeoff(paths, sel)
            t0 = self._clock("selection", t0)
        naive = self._naive(regions, cands, paths, sel)
        self._clock("naive", t0)
        plan = self._assemble(cands, paths, sel, witnesses, rates, naive, threshold, t_start)
        return plan if tradeoff is None else plan.model_copy(update={"tradeoff": tradeoff})

    def _preview_regions(self) -> dict[tuple[str, float], TrayRegion]:
        rp, scene = self.sp.regions, self.scene
        pairs = [(t, y) for t in self.required for y in scene.base_yaw.yaws]
        known = rp.known_regions(scene, pairs)
        return {p: known[p] if p in known else rp.tray_region(scene, *p) for p in pairs}

    # -- stops placed for success ------------------------------------------------------------
    def _placing(self) -> bool:
        landing = self.sigma > 0 or self.positioning.anisotropic
        return self.opts.placement == "success" and not self.preview and landing

    def _place(self, cands: list[Intersection]) -> list[Intersection]:
        """Each candidate moved to where it succeeds most for the required trays it serves
        (:meth:`~pickstop.speedups.stop_planner.StopPlanner.placement`); the moved ones keep their
        circle in ``circle``."""
        out = list(cands)
        for c, cand in enumerate(cands):
            trays = [t for t in self.required if t in cand.trays]
            if not trays:
                continue
            regs = [self.regions[t, cand.yaw] for t in trays]
            dist = self.positioning.at(cand.centre, trays)
            xy = self.sp.placement(self.scene, self.world, regs, cand, self.sigma, self.kind, dist)
            if xy is not None:
                self.circle[c] = cand
                out[c] = replace(cand, centre=xy)
        return out

    def _unplace(self, c: int) -> Paths:
        """Candidate ``c`` back at its circle's centre (its placed point failed the exact
        check); returns the paths through the candidates as they now are."""
        self.cands[c] = self.circle.pop(c)
        self.est.pop(c, None)
        self.rows.clear()
        return self._paths(self.cands)

    def _paths(self, cands: list[Intersection]) -> Paths:
        scene = self.scene
        return self.sp.paths(self.floor, route_points(scene, cands), route_yaws(scene, cands))

    def _circle_estimate(self, c: int, trays: frozenset[str]) -> float | None:
        """The estimate at candidate ``c``'s circle centre for ``trays``, when ``c`` is placed
        elsewhere."""
        if c not in self.circle or self.preview:
            return None
        cand = self.circle[c]
        regs = [self.regions[t, cand.yaw] for t in self._serveable(c)]
        dist = self.positioning.at(cand.centre, self._serveable(c))
        return self.sp.estimates(self.scene, self.world, regs, cand.centre, self.sigma,
                                 self.kind, dist, cand.yaw)[trays]  # fmt: skip

    # -- checks and explanations --------------------------------------------------------------
    def _empty_regions(self, regions: dict[tuple[str, float], TrayRegion]) -> None:
        """Refuse a plan with a tray no base position serves, saying at which other headings
        the base would reach it (an exact plan only: the regions at :data:`HEADINGS` headings
        of at most :data:`HEADING_HINT_TRAYS` such trays are computed for the answer)."""
        empty, lost = [], []
        for t in self.required:
            mine = [r for (tt, _), r in regions.items() if tt == t]
            if all(len(r.cells) == 0 for r in mine):
                why = "; ".join(
                    f"yaw {math.degrees(r.yaw):.0f} deg: {r.reason or 'no feasible cell'}"
                    for r in mine
                )
                empty.append(f"tray {t} has an empty base region ({why})")
                lost.append(t)
        if empty:
            hint = "" if self.preview else self._other_headings(lost[:HEADING_HINT_TRAYS])
            raise InfeasiblePlanError("; ".join(empty) + hint, field="trays")

    def _other_headings(self, trays: list[str]) -> str:
        """ "; the base reaches tray t at yaw ... deg: ..." for those of ``trays`` some other
        of :data:`HEADINGS` evenly spaced headings serves (its region has a cell), or ""."""
        scene, rp = self.scene, self.sp.regions
        known = scene.base_yaw.yaws
        found: dict[str, list[float]] = {}
        for t in trays:
            for k in range(HEADINGS):
                yaw = -math.pi + 2 * math.pi * k / HEADINGS
                if any(abs(math.remainder(yaw - y, 2 * math.pi)) < 1e-6 for y in known):
                    continue
                if len(rp.tray_region(scene, t, yaw).cells):
                    found.setdefault(t, []).append(yaw)
        if not found:
            return ""
        said = "; ".join(f"tray {t} at yaw " + ", ".join(f"{math.degrees(y):.0f}" for y in ys)
                         + " deg" for t, ys in found.items())  # fmt: skip
        every = sorted({round(y, 6) for ys in found.values() for y in ys} | set(known))
        return (f"; the base reaches {said}: let the plan choose the heading with "
                f"base_yaw.candidates {[round(y, 4) for y in every]} [rad]")  # fmt: skip

    def _check_endpoints(self, floor: Floor, paths: Paths) -> None:
        radius = upper_body(self.sp.regions.robot).radius
        for k, name in enumerate(("start", "goal")):
            p = getattr(self.scene, name)
            if k not in paths.undocked:
                continue  # the base turns there, or docks at its yaw
            pt = Point(p.x, p.y)
            near = [oid for oid, o in floor.outlines if o.distance(pt) < radius + 0.01]
            where = (
                f"within the body's radius {radius:.2f} m of obstacle(s) {', '.join(near)}"
                if near
                else f"closer than the body's radius {radius:.2f} m to the floor's edge"
            )
            raise InfeasiblePlanError(
                f"the {name} ({p.x:.2f}, {p.y:.2f}) is not a valid base position: {where}, and "
                f"{paths.undocked[k]}",
                field=name,
            )

    def _rule(self) -> Rule:
        opts = self.opts
        return Rule(opts.rule, self.sigma, self.kind, opts.target, opts.seed, self.positioning)

    def _apply_rule(self, cands: list[Intersection], paths: Paths) -> float:
        """Reject candidates by the rule and by reachability; returns the threshold radius."""
        rule = self._rule()
        reachable = [bool(np.isfinite(paths.dist[0, i + 2])) for i in range(len(cands))]
        for i, v in enumerate(cut_off(judge(rule, cands), reachable)):
            if v.predicted is not None:
                self.predicted[i] = v.predicted
            if not v.kept:
                if not reachable[i]:
                    self.unusable.add(i)
                why = paths.undocked.get(i + 2) if reachable[i] is False else None
                self.rejected[i] = (
                    f"the base cannot get there: {why}" if why else (v.reason or "rejected")
                )
        return rule.threshold

    def _explain_uncovered(self, cands: list[Intersection], missing: list[str]) -> None:
        parts = []
        for t in missing:
            mine = [(i, c) for i, c in enumerate(cands) if t in c.trays]
            i, best = max(mine, key=lambda ic: ic[1].radius)
            parts.append(
                f"tray {t}: all {len(mine)} candidate stop(s) serving it are rejected; the "
                f"widest (trays {', '.join(sorted(best.trays))} at ({best.centre[0]:.2f}, "
                f"{best.centre[1]:.2f})): {self.rejected[i]}"
            )
        relax = self._what_would_plan(cands)
        raise InfeasiblePlanError(
            f"no plan with {self._rule().describe()}: " + "; ".join(parts) + relax, field="sigma"
        )

    def _what_would_plan(self, cands: list[Intersection]) -> str:
        """The loosest rule that keeps a candidate for every tray, from the candidates' radii
        (sigma rule) or predicted success (success rule), those the base cannot use left out:
        "; the largest sigma that ..." (empty when some tray has no usable candidate)."""
        best: list[float] = []
        for t in self.required:
            mine = [i for i, c in enumerate(cands) if t in c.trays and i not in self.unusable]
            if not mine:
                return ""
            if self.opts.rule == "sigma":
                best.append(max(cands[i].radius for i in mine))
            else:
                best.append(max(self.predicted.get(i, 0.0) for i in mine))
        if self.opts.rule == "sigma":
            return (f"; the largest sigma that keeps a candidate stop for every tray is "
                    f"{math.floor(min(best) * 1000) / 1000:.3f} m")  # fmt: skip
        return (f"; the highest target success that keeps a candidate stop for every tray is "
                f"{math.floor(min(best) * 1000) / 10:.1f}%")  # fmt: skip

    # -- selection with verification ----------------------------------------------------------
    def _select_verified(
        self,
        regions: dict[tuple[str, float], TrayRegion],
        cands: list[Intersection],
        paths: Paths,
    ) -> tuple[Selection, dict[int, list[pm.Witness]], dict[int, Rate], Paths]:
        """The selection whose stops pass the exact check (and, with the success rule, the
        Monte Carlo), their witnesses and rates, and the paths (new if a placed stop went
        back to its circle's centre)."""
        for _ in range(MAX_VERIFY_ROUNDS):
            t0 = time.perf_counter()
            kept = [i for i in range(len(cands)) if i not in self.rejected]
            missing = [t for t in self.required if not any(t in cands[i].trays for i in kept)]
            if missing:
                self._explain_uncovered(cands, missing)
            sel = self._solve([cands[i].trays for i in kept], kept, paths)
            t0 = self._clock("selection", t0)
            if self.preview:  # nothing verified: the selection as it stands
                return sel, {c: [] for c in sel.order}, {}, paths
            serves = {c: tuple(t for t in self.required if sel.serves[t] == c) for c in sel.order}
            witnesses: dict[int, list[pm.Witness]] = {}
            for c in sel.order:  # every stop checked: a round learns all its failures
                ws = self._witnesses(regions, cands[c], c, serves[c])
                if ws is not None:
                    witnesses[c] = ws
            t0 = self._clock("verification", t0)
            if len(witnesses) < len(sel.order):
                if self.placed_back is not None:
                    paths, self.placed_back = self.placed_back, None
                continue
            rates = self._confirm(regions, cands, sel, serves)
            self._clock("monte_carlo", t0)
            if all(c not in self.rejected for c in sel.order):
                return sel, witnesses, rates, paths
        raise InfeasiblePlanError(
            f"no verified plan after {MAX_VERIFY_ROUNDS} rounds of selection: "
            + "; ".join(f"candidate {i}: {why}" for i, why in sorted(self.rejected.items())[-5:])
        )

    def _witnesses(
        self,
        regions: dict[tuple[str, float], TrayRegion],
        cand: Intersection,
        c: int,
        trays: tuple[str, ...],
    ) -> list[pm.Witness] | None:
        """The witnesses of candidate ``c`` serving ``trays`` from where it stands; None if the
        exact check fails there: a placed stop goes back to its circle's centre (the new
        paths in ``placed_back``), any other is rejected with the reason."""
        ws: list[pm.Witness] = []
        for t in trays:
            mine = self.sp.witnesses(self.scene, regions[t, cand.yaw], cand.centre, self.world)
            if mine is None and c in self.circle:  # try the circle's centre instead
                self.placed_back = self._unplace(c)
                return None
            if mine is None:
                self.unusable.add(c)
                self.rejected[c] = (
                    f"the exact check at its centre failed for tray {t} (the region's grid "
                    "cells around it are feasible, the centre itself is not)"
                )
                return None
            ws += mine
        return ws

    def _confirm(
        self,
        regions: dict[tuple[str, float], TrayRegion],
        cands: list[Intersection],
        sel: Selection,
        serves: dict[int, tuple[str, ...]],
    ) -> dict[int, Rate]:
        """The Monte Carlo of each chosen stop (and at the circle's centre of a placed one);
        with the success rule, a stop below the target is rejected with its rate."""
        opts, sp, scene = self.opts, self.sp, self.scene
        rates: dict[int, Rate] = {}
        if opts.samples <= 0 or self.sigma <= 0:
            return rates
        for c in sel.order:
            regs = [regions[t, cands[c].yaw] for t in serves[c]]
            rate = rates[c] = sp.success(scene, self.world, regs, cands[c].centre, self.sigma,
                                         opts.samples, opts.seed)  # fmt: skip
            if c in self.circle:  # placed for success: the circle's rate beside it
                self.circle_rates[c] = sp.success(
                    scene, self.world, regs, self.circle[c].centre, self.sigma, opts.samples,
                    opts.seed,
                )  # fmt: skip
            if opts.rule == "success" and rate.rate < opts.target:
                lo, hi = rate.interval
                self.rejected[c] = (
                    f"Monte Carlo success {rate.rate:.1%} (95% interval {lo:.1%} to "
                    f"{hi:.1%}) is below the target {opts.target:.0%}"
                )
        return rates

    def _solve(self, trays_of: list[frozenset[str]], idx: list[int], paths: Paths) -> Selection:
        """Stop selection over candidates ``idx``; the result is in global candidate indices."""
        motion = self.scene.motion
        if self.opts.objective == "expected-time":  # with the trade-off's rows, if wanted
            ks = None if self.preview else list(range(1, len(self.required) + 1))
            return self._expected(idx, paths, ks)[0]
        if self.opts.objective == "time":
            cost = self._time_cost(paths, idx)
        else:
            cost = paths.dist[np.ix_([0, 1, *(i + 2 for i in idx)], [0, 1, *(i + 2 for i in idx)])]
        sel = self.sp.selection(
            trays_of,
            self.required,
            cost,
            self.opts.objective,  # type: ignore[arg-type]
            motion.stop_time,
            self.opts.time_limit,
            self.unlock,
        )
        return _in_global(sel, idx)

    def _expected(
        self, idx: list[int], paths: Paths, ks: list[int] | None = None
    ) -> dict[int, Selection]:
        """:func:`~pickstop.sequence.expected.select` over candidates ``idx``: the least
        expected-time selection (key 0) and, for each k of ``ks``, the least of k stops; in
        global candidate indices (remembered for the request: the trade-off takes the rows
        of the last selection's candidates)."""
        memo = (tuple(idx), None if ks is None else tuple(ks))
        if memo in self.rows:
            return self.rows[memo]
        motion = self.scene.motion

        def solve(
            trays_of: list[frozenset[str]], required: list[str], cost: np.ndarray,
            stop_cost: float, n_stops: int | None, groups: tuple[int, ...],
        ) -> Selection:  # fmt: skip
            limit = self.opts.time_limit
            return self.sp.selection(trays_of, required, cost, "time", stop_cost, limit,
                                     self.unlock, n_stops, groups)  # fmt: skip

        rows = expected.select(
            [self._serveable(c) for c in idx], self.required, self._time_cost(paths, idx),
            motion.stop_time, [self._estimates(c) for c in idx], self.costs, solve, ks,
        )  # fmt: skip
        self.rows[memo] = {k: _in_global(sel, idx) for k, sel in rows.items()}
        return self.rows[memo]

    def _time_cost(self, paths: Paths, idx: list[int]) -> np.ndarray:
        """``(n + 2, n + 2)`` rest-to-rest travel times [s] between start, goal and candidates
        ``idx`` (inf: no way)."""
        nodes = [0, 1, *(i + 2 for i in idx)]
        dist = paths.dist[np.ix_(nodes, nodes)]
        motion = self.scene.motion
        cost = leg_time(dist, motion.max_speed, motion.max_acceleration)
        cost = np.where(np.isfinite(dist), cost, np.inf)
        if paths.docked:  # a path with docking legs halts at their ends
            for a, b in zip(*np.nonzero(np.isfinite(dist)), strict=True):
                if a != b:
                    pieces = self._pieces(paths, nodes[a], nodes[b])
                    cost[a, b] = pieces_time(pieces, motion.max_speed, motion.max_acceleration)
        return cost

    # -- success estimates and the expected-time objective -----------------------------------
    def _serveable(self, c: int) -> list[str]:
        """The required trays candidate ``c`` can serve."""
        return [t for t in self.required if t in self.cands[c].trays]

    def _regions_of(self, c: int) -> list[TrayRegion]:
        """The regions of the required trays candidate ``c`` can serve."""
        return [self.regions[t, self.cands[c].yaw] for t in self._serveable(c)]

    def _estimates(self, c: int) -> dict[frozenset[str], float]:
        """Success estimates of candidate ``c`` for every set of the trays it can serve (a
        preview's from the cells alone)."""
        hit = self.est.get(c)
        if hit is None:
            hit = self.est[c] = self.sp.estimates(
                self.scene, self.world, self._regions_of(c), self.cands[c].centre, self.sigma,
                self.kind, self.positioning.at(self.cands[c].centre, self._serveable(c)),
                self.cands[c].yaw, exact=not self.preview,
            )  # fmt: skip
        return hit

    def _tradeoff(self, paths: Paths, sel: Selection) -> list[pm.TradeoffRow]:
        """For each number of stops, the least expected time over the kept candidates, its
        predicted time and its success (estimates)."""
        kept = [i for i in range(len(self.cands)) if i not in self.rejected]
        ks = list(range(1, len(self.required) + 1))
        found = self._expected(kept, paths, ks)
        rows = []
        for k in ks:
            row = sel if k == len(sel.order) else found.get(k)
            if row is None:
                continue
            _, lengths = self._legs(paths, row.order)
            tb = self._times(lengths, k)
            ps = [self._estimates(c)[s] for c, s in expected.served(row).items()]
            failures = float(np.sum(failure_time(np.array(ps), self.costs)))
            rows.append(
                pm.TradeoffRow(
                    stops=k,
                    expected_time=tb.total + failures,
                    time=tb.total,
                    success=float(np.prod(ps)),
                    optimal=row.optimal,
                    chosen=row is sel,
                )
            )
        return rows

    # -- naive plan and the document ----------------------------------------------------------
    def _naive(
        self,
        regions: dict[tuple[str, float], TrayRegion],
        cands: list[Intersection],
        paths: Paths,
        sel: Selection,
    ) -> tuple[list[int], Selection]:
        """One stop per tray at the centre of its region's widest reachable component."""
        best: list[int] = []
        for t in self.required:
            mine = [
                i
                for i, c in enumerate(cands)
                if c.trays == frozenset([t]) and np.isfinite(paths.dist[0, i + 2])
            ]
            if not mine:  # every component is cut off: the plan above would have failed
                raise InfeasiblePlanError(f"tray {t}: no reachable component of its region")
            best.append(max(mine, key=lambda i: cands[i].radius))
        naive = self._solve([cands[i].trays for i in best], best, paths)
        return best, naive

    @staticmethod
    def _pieces(paths: Paths, a: int, b: int) -> list[float]:
        """The rest-to-rest pieces [m] of the path from query point a to b."""
        return rest_pieces(paths.polyline(a, b), paths.segment_yaws(a, b))

    def _legs(self, paths: Paths, order: tuple[int, ...]) -> tuple[list[pm.Leg], list[list[float]]]:
        """The route's legs, and each leg's rest-to-rest pieces [m]."""
        motion = self.scene.motion
        nodes = [0, *(c + 2 for c in order), 1]
        names = ["start", *(f"stop {k}" for k in range(len(order))), "goal"]
        legs, pieces = [], []
        for (a, b), (na, nb) in zip(
            itertools.pairwise(nodes), itertools.pairwise(names), strict=True
        ):
            length = float(paths.dist[a, b])
            line = paths.polyline(a, b)
            held = paths.segment_yaws(a, b)
            parts = rest_pieces(line, held)
            pieces.append(parts)
            legs.append(
                pm.Leg(
                    start=na,
                    end=nb,
                    length=length,
                    time=pieces_time(parts, motion.max_speed, motion.max_acceleration),
                    polyline=[(float(x), float(y)) for x, y in line],
                    segment_yaws=held if any(y is not None for y in held) else None,
                )
            )
        return legs, pieces

    def _times(self, lengths: list[list[float]], n_stops: int) -> TimeBreakdown:
        m = self.scene.motion
        n_parts = sum(len(self.scene.tray(t).parts) for t in self.required)
        return plan_time(
            lengths, n_stops, n_parts, m.max_speed, m.max_acceleration, m.stop_time, m.pick_time
        )

    def _assemble(
        self,
        cands: list[Intersection],
        paths: Paths,
        sel: Selection,
        witnesses: dict[int, list[pm.Witness]],
        rates: dict[int, Rate],
        naive: tuple[list[int], Selection],
        threshold: float,
        t_start: float,
    ) -> pm.Plan:
        """The plan document: its stops, route, totals, the naive plan, every candidate."""
        scene, robot = self.scene, self.sp.regions.robot
        stops = self._stop_records(cands, sel, witnesses, rates)
        legs, lengths = self._legs(paths, sel.order)
        route: list[tuple[float, float]] = []
        for leg in legs:
            route += leg.polyline if not route else leg.polyline[1:]
        tb = self._times(lengths, len(sel.order))
        fails_of = [s.failures for s in stops]
        known = [f for f in fails_of if f is not None]
        whole = len(known) == len(stops)
        success, interval = (None, None)
        if rates:
            success, interval = combined([rates[c] for c in sel.order])
        preview_note = (
            "preview: known regions carried with the moved trays and clipped where the base no "
            "longer fits; stops and route are not verified"
        )
        return pm.Plan(
            scene=scene.name,
            scene_hash=scene_hash(scene),
            database=self.sp.regions.db.id,
            robot=robot.name,
            robot_hash=robot.robot_hash,
            joints=[j.name for j in robot.joints],
            notes=([preview_note] if self.preview else []) + gripper_notes(scene)
            + hand_notes(robot),
            trays=list(self.required),
            parameters=self._parameters(threshold),
            stops=stops,
            route=route,
            legs=legs,
            totals=pm.Totals(
                stops=len(stops),
                route_length=float(sum(leg.length for leg in legs)),
                time=_time(tb, fails_of),
                success=success,
                success_interval=interval,
                retries=float(sum(f.retries for f in known)) if whole else None,
                operator_calls=float(sum(f.operator for f in known)) if whole else None,
            ),
            naive=self._naive_record(cands, paths, naive, tb, len(stops)),
            optimal=sel.optimal,
            candidates=self._candidate_records(cands, set(sel.order)),
            timings=pm.Timings(**self.t, total=time.perf_counter() - t_start),
            verified=not self.preview,
        )  # fmt: skip

    def _stop_records(
        self,
        cands: list[Intersection],
        sel: Selection,
        witnesses: dict[int, list[pm.Witness]],
        rates: dict[int, Rate],
    ) -> list[pm.Stop]:
        """The chosen stops in visiting order, with their witnesses, rates and failures."""
        served = expected.served(sel)
        stops = []
        for k, c in enumerate(sel.order):
            cand, rate = cands[c], rates.get(c)
            picked = [t for t in self.required if sel.serves[t] == c]
            est = None if self.preview else self._estimates(c)[served[c]]
            fails = (
                _failures(rate.rate, "monte_carlo", self.costs)
                if rate is not None
                else _failures(est, "estimate", self.costs)
            )
            placed = c in self.circle
            stops.append(
                pm.Stop(
                    index=k,
                    x=cand.centre[0],
                    y=cand.centre[1],
                    yaw=cand.yaw,
                    trays=picked,
                    region_trays=sorted(cand.trays),
                    inscribed_radius=cand.radius,
                    candidate=c,
                    witnesses=witnesses[c],
                    error_model=self.positioning.station_of(cand.centre, picked),
                    estimated_success=est,
                    clearance=clearance(cand.polygon, cand.centre) if placed else cand.radius,
                    circle_centre=self.circle[c].centre if placed else None,
                    circle_estimated_success=self._circle_estimate(c, served[c]),
                    circle_success=_success(self.circle_rates.get(c)),
                    success=_success(rate),
                    failures=fails,
                )
            )
        return stops

    def _parameters(self, threshold: float) -> pm.Parameters:
        scene, opts, m = self.scene, self.opts, self.scene.motion
        return pm.Parameters(
            sigma=self.sigma,
            rule=opts.rule,
            target=opts.target,
            threshold_radius=threshold,
            objective=opts.objective,
            placement=opts.placement,
            error_model=self.kind,
            yaw_sigma=scene.error_model.yaw_sigma,
            samples=opts.samples,
            seed=opts.seed,
            base_yaws=scene.base_yaw.yaws,
            grid_resolution=scene.base_grid.resolution,
            max_speed=m.max_speed,
            max_acceleration=m.max_acceleration,
            stop_time=m.stop_time,
            pick_time=m.pick_time,
            failure=scene.failure,
        )

    def _naive_record(
        self,
        cands: list[Intersection],
        paths: Paths,
        naive: tuple[list[int], Selection],
        tb: TimeBreakdown,
        n_stops: int,
    ) -> pm.Naive:
        """The naive plan (one stop per tray) beside the plan's time ``tb`` and ``n_stops``."""
        best, nsel = naive
        nlegs, nlengths = self._legs(paths, nsel.order)
        ntb = self._times(nlengths, len(best))
        nfails = [
            None if self.preview else _failures(self._estimates(c)[s], "estimate", self.costs)
            for c, s in expected.served(nsel).items()
        ]
        return pm.Naive(
            stops=[
                pm.NaiveStop(
                    tray=next(iter(cands[i].trays)),
                    x=cands[i].centre[0],
                    y=cands[i].centre[1],
                    inscribed_radius=cands[i].radius,
                )
                for i in nsel.order
            ],
            route_length=float(sum(leg.length for leg in nlegs)),
            time=_time(ntb, nfails),
            saving_time=ntb.total - tb.total,
            saving_fraction=(ntb.total - tb.total) / ntb.total if ntb.total > 0 else 0.0,
            saving_stops=len(best) - n_stops,
        )

    def _candidate_records(
        self, cands: list[Intersection], chosen: set[int]
    ) -> list[pm.IntersectionRecord]:
        """Every candidate with its circle (at the circle's centre, placed or not), status,
        reason and success figures."""
        out = []
        for i, c in enumerate(cands):
            status = "chosen" if i in chosen else ("rejected" if i in self.rejected else "kept")
            est = None if self.preview else self._estimates(i)[frozenset(self._serveable(i))]
            cx, cy = self.circle.get(i, c).centre
            out.append(
                pm.IntersectionRecord(
                    index=i,
                    trays=sorted(c.trays),
                    yaw=c.yaw,
                    x=cx,
                    y=cy,
                    inscribed_radius=c.radius,
                    area=c.polygon.area,
                    status=status,
                    reason=self.rejected.get(i),
                    predicted_success=self.predicted.get(i),
                    estimated_success=est,
                    polygon=c.rings,
                )
            )
        return out


def hand_notes(robot: Any) -> list[str]:
    """What a plan's "verified" leaves out of the robot's own geometry, if anything."""
    if robot.config.hand.geometry == "boxes":
        return [
            f"robot {robot.name}: the hand is checked as the boxes of its config's hand.boxes "
            "standing in for the hand links, not the links' own collision geometry"
        ]
    return []


def _in_global(sel: Selection, idx: list[int]) -> Selection:
    """A selection over candidates ``idx`` in global candidate indices."""
    return Selection(
        tuple(idx[c] for c in sel.order),
        {t: idx[c] for t, c in sel.serves.items()},
        sel.cost,
        sel.optimal,
        sel.seconds,
        sel.pruned,
    )


def _time(tb: TimeBreakdown, stops: list[pm.StopFailures | None] | None = None) -> pm.TimeTotals:
    """The time totals; with every stop's expected failures, the expected time too."""
    failures = None
    if stops and all(f is not None for f in stops):
        failures = float(sum(f.time for f in stops if f is not None))
    return pm.TimeTotals(
        travel=tb.travel,
        stops=tb.stops,
        picks=tb.picks,
        total=tb.total,
        failures=failures,
        expected=None if failures is None else tb.total + failures,
    )


def _success(rate: Rate | None) -> pm.Success | None:
    if rate is None:
        return None
    return pm.Success(samples=rate.samples, successes=rate.successes, rate=rate.rate,
                      interval=rate.interval)  # fmt: skip


def _failures(
    p: float | None, source: Literal["monte_carlo", "estimate"], costs: FailureCosts
) -> pm.StopFailures | None:
    """A stop's expected failures at success rate ``p`` (None: no rate known)."""
    if p is None:
        return None
    f = stop_failures(p, costs)
    return pm.StopFailures(success=p, source=source, retries=f.retries, operator=f.operator,
                           time=f.time)  # fmt: skip
