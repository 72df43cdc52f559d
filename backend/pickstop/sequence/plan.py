"""From a scene to the plan a factory runs: regions, candidates, stops, route, time, success.

1. Base regions of the task's trays (cached by the region planner).
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
A request (:class:`_Planning`) asks each step of a :class:`~pickstop.sequence.steps.PlanSteps`:
:class:`StopPlanner` (cached, reused across edits) or, in :func:`plan_from_scratch`,
:class:`~pickstop.sequence.pure.PureSteps` (the algorithm alone).
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import math
import time
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import replace
from typing import Any, Literal

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from pickstop.caching import Cache
from pickstop.regions.cells import TrayRegion
from pickstop.regions.footprint import (
    upper_body,
)
from pickstop.regions.kit import Interrupted, RegionKit
from pickstop.regions.offgrid import check_key
from pickstop.regions.planner import RegionPlanner
from pickstop.scene.model import Scene, gripper_notes
from pickstop.scene.positioning import ErrorDist, of_scene
from pickstop.sequence import expected, pure
from pickstop.sequence import plan_model as pm
from pickstop.sequence.cover import InfeasiblePlanError, Selection, select_stops
from pickstop.sequence.failure import FailureCosts, failure_time, stop_failures
from pickstop.sequence.intersections import Intersection, inscribed_circle
from pickstop.sequence.placement import clearance
from pickstop.sequence.refine import Refinement
from pickstop.sequence.route import Paths
from pickstop.sequence.rules import Rule, cut_off, judge
from pickstop.sequence.steps import Floor, PlanSteps
from pickstop.sequence.success import Kind, Rate, combined
from pickstop.sequence.timing import TimeBreakdown, leg_time, pieces_time, plan_time, rest_pieces

HEADINGS = 8  # headings tried (every 45 deg) to say where a tray no stop serves is reachable
HEADING_HINT_TRAYS = 3  # such trays tried, at most (each a region per heading)
MAX_VERIFY_ROUNDS = 8  # selection rounds while chosen stops fail their checks
PREFETCH_BANDS = 24  # sigma bands planned ahead in the background after a plan
_digest = pure.digest


def hand_notes(robot: Any) -> list[str]:
    """What a plan's "verified" leaves out of the robot's own geometry, if anything."""
    if robot.config.hand.geometry == "boxes":
        return [
            f"robot {robot.name}: the hand is checked as the boxes of its config's hand.boxes "
            "standing in for the hand links, not the links' own collision geometry"
        ]
    return []


class StopPlanner:
    """Plans stops and routes for scenes of one robot and database, caching what it can.

    A change of sigma, rule or objective reuses the regions, the candidates, the floor paths
    and the exact checks at candidate centres (with their witnesses); moving a tray recomputes
    only what it affects. :meth:`prefetch_selections` makes the stop selections of the
    neighbouring sigma bands ahead of the slider, :meth:`prefetch_checks` every centre check.

    Its caches are bounded LRUs keyed by value, so nothing needs invalidating: a key changes
    with what its entry depends on (candidates: the regions' masks; floors: the floor, the
    body's reach and the blocking solids; paths: the floor's key and the points; checks and
    success rates: the world's key, trays, pose and error model; selections: their inputs;
    floors per world: the world's key).
    The robot and database are fixed per planner (one per pair in
    :class:`pickstop.pool.PlannerPool`).
    """

    def __init__(self, regions: RegionPlanner, cache_size: int = 64) -> None:
        self.regions = regions
        n = cache_size

        def memo(name: str, size: int) -> Cache[Any, Any]:
            return Cache(f"stop_planner.{name}", max_items=size)

        # Each keyed by what its value depends on, by value (see the class docstring).
        self._candidates = memo("candidates", n)  # regions -> intersection components
        self._floors = memo("floors", n)
        self._world_floors = memo("world_floors", n)  # world key -> floor: no rebuild
        self._fmaps = memo("fmaps", n)
        self._paths = memo("paths", n)
        self._checks = memo("checks", 4096)
        self._check_keys = memo("check_keys", 4096)  # (world, region, pose) -> check key
        self._witnesses = memo("witnesses", 4096)
        self._rates = memo("rates", 4096)
        self._estimates = memo("estimates", 4096)  # (world, regions, pose, model) -> rates
        self._refinements = memo("refinements", 256)  # (world, region) -> exact outcomes
        self._selections = memo("selections", 256)
        self._circles = memo("circles", 4096)  # component (WKB digest) -> inscribed circle
        self._placements = memo("placements", 4096)  # (world, regions, candidate) -> point
        self._solving: dict[Any, Future[Selection]] = {}  # selections being solved unlocked
        self._planned = memo("planned", 1024)  # (layout, options) planned ahead

    # -- pieces ------------------------------------------------------------------------------
    def candidates(self, regions: dict[tuple[str, float], TrayRegion]) -> list[Intersection]:
        """All intersection components of the regions, per yaw, duplicates dropped."""
        key = tuple(
            sorted(
                (t, y, r.key, hashlib.sha1(r.mask.tobytes()).hexdigest())
                for (t, y), r in regions.items()
            )
        )
        hit = self._candidates.get(key)
        if hit is not None:
            return list(hit)
        return list(self._candidates.put(key, tuple(pure.candidates(regions, self._circle))))

    def _circle(self, poly: Polygon) -> tuple[tuple[float, float], float]:
        """The largest inscribed circle of an intersection component, kept by its exact
        coordinates: a layout that moves one tray leaves the intersections of the others as
        they were."""
        key = hashlib.sha1(shapely.to_wkb(poly)).digest()
        hit = self._circles.get(key)
        return hit if hit is not None else self._circles.put(key, inscribed_circle(poly))

    def floor(self, scene: Scene, world: str | None = None) -> Floor:
        """Where the base may drive: the floor minus obstacles inflated by the footprint.

        world: the scene's :func:`world_key`, if known; the floor is a function of it (the
        floor, the solids and the robot), so a scene of the same world takes it as it was."""
        world = world_key(scene) if world is None else world
        hit = self._world_floors.get(world)
        if hit is not None:
            return hit
        return self._world_floors.put(world, self._floor(scene))

    def _floor(self, scene: Scene) -> Floor:
        spec = pure.floor_spec(self.regions, scene)
        hit = self._floors.get(spec.full)
        if hit is not None:
            return hit
        fmap = self._fmaps.get_or_make(spec.key, lambda: pure.floor_map(scene, spec))
        return self._floors.put(spec.full, pure.floor(self.regions, scene, spec, fmap))

    def paths(self, floor: Floor, points: np.ndarray, yaws: np.ndarray) -> Paths:
        """Shortest paths between ``points: (Q, 2)`` [m] held at ``yaws: (Q,)`` [rad] where
        the base's bounding circle does not fit (cached)."""
        key = (floor.key, points.tobytes(), yaws.tobytes())
        hit = self._paths.get(key)
        if hit is not None:
            return hit
        return self._paths.put(key, pure.paths(floor, points, yaws))

    def check_key(
        self, scene: Scene, region: TrayRegion, xy: tuple[float, float], world: str | None = None
    ) -> str:
        """What :meth:`check` of ``region`` at ``xy`` depends on
        (:func:`~pickstop.regions.offgrid.check_key`): a tray moved elsewhere leaves it.
        ``world``: the scene's :func:`world_key`, if known (the key is then looked up: the
        same world, region and pose have the same key)."""
        known = None if world is None else (world, region.digest, xy)
        if known is not None and (hit := self._check_keys.get(known)) is not None:
            return str(hit)
        key = check_key(self.regions, scene, region, xy, region.yaw)
        return key if known is None else str(self._check_keys.put(known, key))

    def check(
        self, scene: Scene, region: TrayRegion, xy: tuple[float, float], key: str | None = None
    ) -> tuple[bool, np.ndarray, np.ndarray]:
        """The exact region test for one tray at one base pose (cached by
        :meth:`check_key`, ``key`` if known)."""
        key = self.check_key(scene, region, xy) if key is None else key
        hit = self._checks.get(key)
        if hit is None:
            hit = self._checks.put(key, pure.check(self.regions, scene, region, xy))
        return hit

    def witnesses(
        self, scene: Scene, region: TrayRegion, xy: tuple[float, float], world: str | None = None
    ) -> list[pm.Witness] | None:
        """The arm configurations that pick every part of the region's tray from ``xy`` (one
        witness per part, from :meth:`check`), or None if the exact check fails there
        (cached with the check; ``world`` as for :meth:`check_key`)."""
        key = self.check_key(scene, region, xy, world)
        if key in self._witnesses:
            return self._witnesses.get(key)
        ws = pure.witnesses(self.regions, scene, region, self.check(scene, region, xy, key))
        return self._witnesses.put(key, ws)

    def success(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        xy: tuple[float, float],
        sigma: float,
        samples: int,
        seed: int,
    ) -> Rate:
        """Monte Carlo success rate of stopping at ``xy`` to pick the regions' trays (cached),
        under the error model of the stop's station (:mod:`pickstop.scene.positioning`)."""
        trays = tuple(r.tray_id for r in regions)
        yaw = regions[0].yaw
        dist = of_scene(scene, sigma).at(xy, trays)
        key = (world_key, trays, xy, yaw, dist, samples, seed)
        hit = self._rates.get(key)
        if hit is not None:
            return hit
        rate = pure.success(self.regions, scene, regions, xy, sigma, samples, seed)
        return self._rates.put(key, rate)

    def estimates(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        xy: tuple[float, float],
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
        yaw: float = 0.0,
        exact: bool = True,
    ) -> dict[frozenset[str], float]:
        """Fast success estimates (:mod:`~pickstop.sequence.estimate`) of a stop at ``xy``
        (heading ``yaw``) serving each set of the regions' trays, under the isotropic
        ``kind`` and ``sigma`` or the stop's own model ``dist``, refined exactly near the
        regions' boundaries (:meth:`refine`) unless ``exact`` is false (cached)."""
        key = (world_key, tuple(r.digest for r in regions), xy, sigma, kind, dist, yaw, exact)
        hit = self._estimates.get(key)
        if hit is not None:
            return dict(hit)
        found = pure.estimates(self.regions, scene, regions, xy, (sigma, kind, dist, yaw), exact,
                               lambda r: self.refinement(world_key, r))  # fmt: skip
        return dict(self._estimates.put(key, found))

    def placement(
        self,
        scene: Scene,
        world_key: str,
        regions: list[TrayRegion],
        cand: Intersection,
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
    ) -> tuple[float, float] | None:
        """Where in ``cand`` a stop serving the regions' trays succeeds most
        (:mod:`~pickstop.sequence.placement`), when its estimate there beats the circle's
        centre's by :data:`~pickstop.sequence.placement.MIN_GAIN`; None: the centre is as
        good (cached). The search scores the regions' verified cells alone and the decision
        compares the two estimates, both refined exactly near the boundaries: neither depends
        on what was estimated before."""
        key = (world_key, tuple(r.digest for r in regions), cand.centre, cand.yaw,
               hashlib.sha1(shapely.to_wkb(cand.polygon)).digest(), sigma, kind, dist)  # fmt: skip
        if key in self._placements:
            return self._placements.get(key)  # type: ignore[no-any-return]
        every = frozenset(r.tray_id for r in regions)

        def estimate(xy: tuple[float, float]) -> float:
            return self.estimates(scene, world_key, regions, xy, sigma, kind, dist, cand.yaw)[every]

        out = pure.placement(regions, cand, sigma, kind, dist, estimate)
        return self._placements.put(key, out)  # type: ignore[no-any-return]

    def refinement(self, world_key: str, region: TrayRegion) -> Refinement:
        """The exact boundary outcomes found so far for ``region`` (kept per world)."""
        key = (world_key, region.digest)
        hit = self._refinements.get(key)
        return hit if hit is not None else self._refinements.put(key, Refinement.of(region))

    def refine(
        self,
        scene: Scene,
        world_key: str,
        stops: list[tuple[list[TrayRegion], tuple[float, float]]],
        sigma: float,
        kind: Kind,
        dist: ErrorDist | None = None,
        yaw: float = 0.0,
    ) -> int:
        """Check exactly, a region at a time, the boundary cells where the landings of any of
        ``stops`` (each: its trays' regions and its position; landing by ``kind`` and
        ``sigma``, or by ``dist`` at heading ``yaw``) need it
        (:mod:`~pickstop.sequence.refine`); returns the tests run."""
        return pure.refine(self.regions, scene, stops, sigma, kind, dist, yaw,
                           lambda r: self.refinement(world_key, r))  # fmt: skip

    def prefetch_checks(
        self, scene: Scene, lock: Any = None, stale: Callable[[], bool] = lambda: False
    ) -> int:
        """Check every candidate's centre for each of its trays ahead of time (one at a time,
        under ``lock`` if given), so that a later change of sigma or rule finds its stops
        verified; stops early once ``stale()``. Returns how many checks were computed."""
        import contextlib

        guard = lock if lock is not None else contextlib.nullcontext()
        with guard:
            regions = self.regions.regions(scene)
            cands = self.candidates(regions)
            world = world_key(scene)
        done = 0
        for c in sorted(cands, key=lambda c: -c.radius):
            for t in sorted(c.trays):
                if stale():
                    return done
                with guard:
                    key = self.check_key(scene, regions[t, c.yaw], c.centre, world)
                    if key not in self._checks:
                        self.check(scene, regions[t, c.yaw], c.centre, key)
                        done += 1
        return done

    def selection(
        self,
        trays_of: list[frozenset[str]],
        required: list[str],
        cost: np.ndarray,
        objective: Literal["stops", "time"],
        stop_cost: float,
        time_limit: float,
        unlock: Any = None,
        n_stops: int | None = None,
        groups: tuple[int, ...] | None = None,
    ) -> Selection:
        """:func:`~pickstop.sequence.cover.select_stops`, remembered: while sigma or the rule
        moves, the kept candidates often stay the same set. ``unlock``: the planner's lock,
        held by the caller, released while the solver runs (background plans)."""
        key = (
            tuple(tuple(sorted(t)) for t in trays_of),
            tuple(required),
            hashlib.sha1(np.ascontiguousarray(cost).tobytes()).hexdigest(),
            cost.shape,
            objective,
            stop_cost,
            time_limit,
            n_stops,
            groups,
        )
        hit = self._selections.get(key)
        if hit is not None:
            return hit
        running = self._solving.get(key)
        while running is not None:  # the same inputs being solved in the background: its answer
            with contextlib.suppress(FutureTimeout):  # (in polls: a Cancelled gets through)
                return running.result(timeout=0.05)

        def solve() -> Selection:
            return select_stops(trays_of, required, cost, objective=objective,
                                stop_cost=stop_cost, time_limit=time_limit, n_stops=n_stops,
                                groups=groups)  # fmt: skip

        if unlock is None:
            return self._selections.put(key, solve())
        # A background selection lets go of the planner's lock while the solver runs (it
        # releases the GIL too), so a request is not kept waiting behind it.
        fut: Future[Selection] = Future()
        self._solving[key] = fut
        unlock.release()
        try:
            sel = solve()
            fut.set_result(sel)
        except BaseException as e:
            fut.set_exception(e)
            raise
        finally:
            unlock.acquire()
            self._solving.pop(key, None)
        return self._selections.put(key, sel)

    def prefetch_selections(
        self,
        scene: Scene,
        options: pm.PlanOptions,
        lock: Any,
        limit: int = PREFETCH_BANDS,
        stale: Callable[[], bool] = lambda: False,
    ) -> int:
        """Plan ahead, in the background, what the 3D planner's sigma slider and objective
        switch will ask for next: for the sigma rule, one plan per band of sigma between two
        candidates' inscribed radii (a band keeps the same candidates, so its stop selection
        is the same), nearest the current sigma first, at most ``limit``; then the other
        objective at the current sigma. No Monte Carlo (a band's selection does not depend
        on it). Each runs the plan exactly as a request would, under ``lock`` except while
        the solver runs; what it leaves behind are memo entries keyed by their inputs. Stops
        early once ``stale()`` (a newer request has its own plans ahead). Returns how many
        plans it ran."""
        sigma = scene.sigma if options.sigma is None else options.sigma
        with lock:
            cands = self.candidates(self.regions.regions(scene))
        radii = sorted({c.radius for c in cands})
        todo: list[pm.PlanOptions] = []
        if options.rule == "sigma":
            own = next((r for r in radii if r >= sigma), None)  # the band sigma lies in
            up = [r for r in radii if r > sigma and r != own]
            down = [r for r in reversed(radii) if r < sigma]
            bands = [r for pair in itertools.zip_longest(up, down) for r in pair if r is not None]
            todo += [options.model_copy(update={"sigma": r, "samples": 0})
                     for r in bands[:limit]]  # fmt: skip
        other = "time" if options.objective == "stops" else "stops"
        todo.append(options.model_copy(update={"objective": other, "sigma": sigma, "samples": 0}))
        layout = _digest(scene.model_dump_json(exclude={"name", "description", "sigma"}))
        ceiling = math.inf  # sigma above which no plan exists (fewer candidates kept)
        done = 0
        for opts in todo:
            if stale():
                break
            key = (layout, opts.model_dump_json())
            if (opts.sigma is not None and opts.sigma >= ceiling) or self._planned.get(key):
                continue
            with lock:
                try:
                    _Planning(self, scene, opts, unlock=lock).run()
                except InfeasiblePlanError:
                    if opts.rule == "sigma" and opts.sigma is not None and opts.sigma > sigma:
                        ceiling = min(ceiling, opts.sigma)
                self._planned.put(key, True)
            done += 1
        return done

    def plan_ahead(
        self,
        scene: Scene,
        options: pm.PlanOptions,
        lock: Any,
        stale: Callable[[], bool] = lambda: False,
    ) -> bool:
        """The exact plan of a layout being previewed, made in the background while the
        editor holds still, so that the plan asked for on release finds it done: the regions
        first, given up at their next checkpoint once a request waits for ``lock`` (its
        ``waiting()``) or ``stale()``; then the plan as a request makes it, no Monte Carlo.
        Work given up is not lost: the memos keep what was done (each keyed by its inputs,
        so nothing is taken for a layout it does not hold for). Returns whether it finished."""
        with lock:
            self.regions.interrupt = lambda: stale() or lock.waiting()
            try:
                self.regions.regions(scene)
            except Interrupted:
                return False
            finally:
                self.regions.interrupt = None
        if stale():
            return False
        with lock:
            _Planning(self, scene, options.model_copy(update={"samples": 0}), unlock=lock).run()
        return True

    # -- the plan ------------------------------------------------------------------------------
    def plan(self, scene: Scene, options: pm.PlanOptions | None = None) -> pm.Plan:
        opts = options or pm.PlanOptions()
        return _Planning(self, scene, opts).run()

    def preview(self, scene: Scene, options: pm.PlanOptions | None = None) -> pm.Plan:
        """A plan to draw while the layout is being edited: each tray's known region carried
        with it (:meth:`RegionPlanner.known_region`), intersected anew, the rule, the stop
        selection and the route, nothing verified (``verified`` is false, no witnesses, no
        Monte Carlo). A tray never planned before gets its exact region."""
        opts = options or pm.PlanOptions()
        return _Planning(self, scene, opts, preview=True).run()


def plan_from_scratch(
    kit: RegionKit, scene: Scene, options: pm.PlanOptions | None = None
) -> pm.Plan:
    """The plan of ``scene`` by the algorithm alone (:class:`~pickstop.sequence.pure.PureSteps`:
    regions, candidates, floor, checks and estimates computed from their inputs, nothing kept
    or reused); :class:`StopPlanner` gives the same plan faster. ``kit``: the robot and
    database's (only what is built from them is used, none of its memos)."""
    return _Planning(pure.PureSteps(kit), scene, options or pm.PlanOptions()).run()


def route_points(scene: Scene, cands: list[Intersection]) -> np.ndarray:
    """``(2 + n, 2)`` floor points [m]: the start, the goal, then each candidate's centre."""
    ends = [[scene.start.x, scene.start.y], [scene.goal.x, scene.goal.y]]
    return np.array(ends + [list(c.centre) for c in cands], float).reshape(-1, 2)


def route_yaws(scene: Scene, cands: list[Intersection]) -> np.ndarray:
    """``(2 + n,)`` [rad]: the base's yaw at each of :func:`route_points`."""
    return np.array([scene.start.yaw, scene.goal.yaw, *(c.yaw for c in cands)], float)


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
    return _digest(sorted(keep.items()))


def scene_hash(scene: Scene) -> str:
    return hashlib.sha256(scene.model_dump_json().encode()).hexdigest()


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


class _Planning:
    """One planning request; holds its intermediate results."""

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
        selection is solved (:meth:`StopPlanner.prefetch_selections`)."""
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
        (:meth:`StopPlanner.placement`); the moved ones keep their circle in ``circle``."""
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
