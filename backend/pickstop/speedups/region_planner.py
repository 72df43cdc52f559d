"""The region planner: a region kit with its region caches and its worker processes.

:meth:`RegionPlanner.regions` answers every task tray at every yaw of a scene: from the memo of
the last layouts, from the per-tray cache while :mod:`pickstop.speedups.validity` says a region
still holds, else computed by :mod:`pickstop.regions.pipeline` (with ``workers`` > 1, several
at once, each tray at home in the planner's process or one of its forked helpers:
:mod:`pickstop.runtime.region_processes`). The last region of each tray is kept for previews
(:mod:`pickstop.speedups.carry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pickstop.caching import Cache
from pickstop.regions.cells import TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import compute_tray_region, from_scratch, own_key
from pickstop.runtime.region_processes import RegionProcesses
from pickstop.scene.model import Scene
from pickstop.speedups.carry import LastRegions
from pickstop.speedups.cell_recall import MemoRecall
from pickstop.speedups.region_memo import ReuseCache
from pickstop.speedups.validity import CacheEntry, Snapshot, snapshot, snapshots, still_valid
from pickstop.speedups.warmup import warm_kernels

LAYOUTS = 8  # the regions of this many layouts kept whole
LAYOUTS_PER_TRAY = 4  # cached regions per own key (tray, yaw, ...): a few layouts around it
#: What the kit derives and the planner keeps (:meth:`RegionPlanner.keep`), by name: entries.
KEPT = {
    "kit.grasps": 4096,  # grasps by tray, part, hand and what reaches into the hands' space
    "kit.hand_spaces": 4096,  # open-hand spaces by tray (wherever it stands) and part
    "kit.object_bounds": 4096,  # bounds of each object's solids by its definition
    "kit.own_verdicts": 512,  # a part's grasps judged against its own tray (~0.1 MB each)
    "arm.solid_bounds": 32,  # bounding boxes of the solid lists the exact arm checks against
}
#: The footprint's blocked regions and pieces, kept on the robot's derived data: entries.
ROBOT_KEPT = {
    "blocked_regions": 64,  # per solids, yaw and which body
    "blocked_pieces": 4096,  # per solid, yaw and which body
}


@dataclass
class RegionPlanner(RegionKit):
    """The regions of scenes for one robot and database, cached (see the module)."""

    cache: dict[str, list[CacheEntry]] = field(default_factory=dict)  # by own key
    reuse: ReuseCache = field(default_factory=ReuseCache)  # refinements across tray positions
    # False: every region computed from scratch (regions are still cached whole)
    across_layouts: bool = True
    cache_size: int = 256  # own keys kept
    # processes computing regions: this one and workers - 1 helpers forked from it (they share
    # the database; each tray is computed where it was before, its memos there)
    workers: int = 1
    _layouts: Cache[str, dict[tuple[str, float], TrayRegion]] = field(
        default_factory=lambda: Cache("region_planner.layouts", max_items=LAYOUTS),
        init=False, repr=False,
    )  # the regions of the last layouts  # fmt: skip
    _last: LastRegions = field(init=False, repr=False)
    _processes: RegionProcesses | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        derived = self.robot.derived
        for name, size in ROBOT_KEPT.items():
            if getattr(derived, name) is None:
                setattr(derived, name, Cache(f"robot.{name}", max_items=size))
        super().__post_init__()
        warm_kernels(self)
        self._last = LastRegions(4 * self.cache_size)

    def keep(self, name: str) -> Cache[Any, Any]:
        """What the kit derives under ``name``, kept in a bounded cache (:data:`KEPT`)."""
        return Cache(name, max_items=KEPT[name])

    def tray_region(self, scene: Scene, tray_id: str, yaw: float | None = None) -> TrayRegion:
        """The region of one tray, reused from the cache while nothing it looked at changed."""
        yaw = scene.base_yaw.yaws[0] if yaw is None else yaw
        hit = self._cached(scene, tray_id, yaw)
        if hit is not None:
            self._last.remember(scene, hit)
            return hit
        region = self.compute_region(scene, tray_id, yaw)
        self._store(scene, region)
        return region

    def compute_region(self, scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
        """The region of one tray computed now (no region cache), through the planner's
        memo of refinements and cell answers across tray positions (:attr:`reuse`), or from
        scratch without :attr:`across_layouts`."""
        tray = scene.tray(tray_id)
        key = own_key(self, scene, tray, yaw)
        recall_of = MemoRecall(self.reuse) if self.across_layouts else from_scratch
        return compute_tray_region(self, scene, tray, yaw, key, recall_of)

    def regions(
        self, scene: Scene, workers: int | None = None
    ) -> dict[tuple[str, float], TrayRegion]:
        """Regions of every tray the task needs, at every yaw of the policy.

        workers: processes for the regions not in the cache (default: the planner's
        ``workers``): this one and helpers forked from it, so they share its database.
        """
        pairs = [(t, y) for t in scene.task_trays for y in scene.base_yaw.yaws]
        # The regions are a function of the layout: the same layout (a change of sigma, rule
        # or objective) takes them as they were, without checking each cached region anew.
        layout = scene.model_dump_json(
            exclude={"name", "description", "sigma", "error_model", "motion", "failure", "start",
                     "goal"}
        )  # fmt: skip
        hit = self._layouts.get(layout)
        if hit is not None:
            for region in hit.values():
                self._last.remember(scene, region)
                self._used(region)
            return dict(hit)
        workers = self.workers if workers is None else workers
        trays = list(dict.fromkeys(t for t, _ in pairs))
        snaps = dict(zip(trays, snapshots(scene, trays, self.object_solids(scene)), strict=True))
        out: dict[tuple[str, float], TrayRegion] = {}
        for t, y in pairs:
            kept = self._cached(scene, t, y, snaps[t])
            if kept is not None:
                self._last.remember(scene, kept)
                out[t, y] = kept
        todo = [p for p in pairs if p not in out]
        computed = (
            self._pool(workers).regions(scene, todo)
            if workers > 1 and todo
            else [self.compute_region(scene, t, y) for t, y in todo]
        )
        for (t, y), region in zip(todo, computed, strict=True):
            self._store(scene, region, snaps[t])
            out[t, y] = region
        out = {p: out[p] for p in pairs}
        self._layouts.put(layout, out)
        return dict(out)

    def _cached(
        self, scene: Scene, tray_id: str, yaw: float, snap: Snapshot | None = None
    ) -> TrayRegion | None:
        """The cached region of the tray still valid in ``scene`` (``snap``: its
        :func:`~pickstop.speedups.validity.snapshot`, if made already), or None."""
        tray = scene.tray(tray_id)
        entries = self.cache.get(own_key(self, scene, tray, yaw), [])
        if not entries:
            return None  # never computed with the tray here: nothing to snapshot for
        snap = snapshot(scene, tray.id, self.object_solids(scene)) if snap is None else snap
        for entry in entries:
            if still_valid(self, entry, snap):
                self._used(entry.region)
                return entry.region
        return None

    def _used(self, region: TrayRegion) -> None:
        """``region`` served a layout: its cache entry is the last its tray (and of all
        trays, its key) lets go, so a layout edited away from and back to keeps its regions
        however many layouts were tried meanwhile."""
        entries = self.cache.get(region.key)
        if entries is None:
            return
        self.cache[region.key] = self.cache.pop(region.key)
        for i, entry in enumerate(entries):
            if entry.region is region:
                entries.insert(0, entries.pop(i))
                return

    def known_regions(
        self, scene: Scene, pairs: list[tuple[str, float]]
    ) -> dict[tuple[str, float], TrayRegion]:
        """For each ``(tray id, yaw)`` planned before: its cached region if it still holds in
        ``scene`` (exact), else the region computed for the tray nearest to where it stands
        now, carried there rigidly and clipped to the cells where the base footprint fits (for
        a preview: nothing is checked but the footprint)."""
        exact = {p: r for p in pairs if (r := self._cached(scene, *p)) is not None}
        rest = [p for p in pairs if p not in exact]
        return {**exact, **self._last.carried(self.robot, scene, rest)} if rest else exact

    def forget(self) -> None:
        """Drop every region kept (layouts, cache, last regions); grasps and other memos of
        the kit stay. The next request computes its regions afresh."""
        self._layouts.clear()
        self.cache.clear()
        self._last.clear()

    def _store(self, scene: Scene, region: TrayRegion, snap: Snapshot | None = None) -> None:
        self._last.remember(scene, region)
        entries = self.cache.setdefault(region.key, [])
        snap = snapshot(scene, region.tray_id, self.object_solids(scene)) if snap is None else snap
        entries.insert(0, CacheEntry(region, snap))
        del entries[LAYOUTS_PER_TRAY:]
        if len(self.cache) > self.cache_size:
            self.cache.pop(next(iter(self.cache)))

    def _pool(self, workers: int) -> RegionProcesses:
        if self._processes is None or self._processes.processes != workers:
            self.close()
            self._processes = RegionProcesses(self, workers, self.compute_region)
        return self._processes

    def close(self) -> None:
        """Stop the helper processes, if any (started again when next needed)."""
        if self._processes is not None:
            self._processes.close()
            self._processes = None
