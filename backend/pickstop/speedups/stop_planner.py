"""The plan's steps with their answers kept: :class:`StopPlanner`.

A :class:`~pickstop.sequence.steps.PlanSteps` whose every step is the plain function of
:mod:`pickstop.sequence.pure` behind a bounded cache keyed by what its answer depends on, over
the region planner's regions (:class:`~pickstop.speedups.region_planner.RegionPlanner`). A plan,
preview, plan ahead or prefetched selection runs the request
(:class:`~pickstop.sequence.request.PlanRequest`: the algorithm's steps in order) over it;
:func:`~pickstop.sequence.request.plan_from_scratch` runs the same request over
:class:`~pickstop.sequence.pure.PureSteps` (the algorithm alone).
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import math
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any, Literal

import numpy as np
import shapely
from shapely.geometry import Polygon

from pickstop.caching import Cache
from pickstop.regions.cells import TrayRegion
from pickstop.regions.offgrid import check_key
from pickstop.runtime.cancel import Cancelled, giving_way
from pickstop.scene.model import Scene
from pickstop.scene.positioning import ErrorDist, of_scene
from pickstop.sequence import plan_model as pm
from pickstop.sequence import pure
from pickstop.sequence.cover import InfeasiblePlanError, Selection, select_stops
from pickstop.sequence.intersections import Intersection, inscribed_circle
from pickstop.sequence.refine import Refinement
from pickstop.sequence.request import PlanRequest, world_key
from pickstop.sequence.route import Paths
from pickstop.sequence.steps import Floor
from pickstop.sequence.success import Kind, Rate
from pickstop.speedups.region_planner import RegionPlanner

PREFETCH_BANDS = 24  # sigma bands planned ahead in the background after a plan
_digest = pure.digest


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
                    PlanRequest(self, scene, opts, unlock=lock).run()
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
        with lock, giving_way(lambda: stale() or lock.waiting()) as token:
            try:
                self.regions.regions(scene)
            except Cancelled:
                if token.reason != "give way":  # the computation around it was cancelled
                    raise
                return False
        if stale():
            return False
        with lock:
            PlanRequest(self, scene, options.model_copy(update={"samples": 0}), unlock=lock).run()
        return True

    # -- the plan ------------------------------------------------------------------------------
    def plan(self, scene: Scene, options: pm.PlanOptions | None = None) -> pm.Plan:
        opts = options or pm.PlanOptions()
        return PlanRequest(self, scene, opts).run()

    def preview(self, scene: Scene, options: pm.PlanOptions | None = None) -> pm.Plan:
        """A plan to draw while the layout is being edited: each tray's known region carried
        with it (:meth:`RegionPlanner.known_region`), intersected anew, the rule, the stop
        selection and the route, nothing verified (``verified`` is false, no witnesses, no
        Monte Carlo). A tray never planned before gets its exact region."""
        opts = options or pm.PlanOptions()
        return PlanRequest(self, scene, opts, preview=True).run()
