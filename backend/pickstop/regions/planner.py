"""The region planner: a region kit with its region caches and its worker processes.

:meth:`RegionPlanner.regions` answers every task tray at every yaw of a scene: from the memo of
the last layouts, from the per-tray cache while :mod:`pickstop.regions.validity` says a region
still holds, else computed by :mod:`pickstop.regions.pipeline` (several at once in forked
processes). The last region of each tray is kept for previews (:mod:`pickstop.regions.carry`).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

from pickstop.regions.cells import TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import compute_tray_region
from pickstop.regions.validity import CacheEntry, own_key, snapshot, still_valid
from pickstop.scene.model import Scene, Tray


@dataclass
class RegionPlanner(RegionKit):
    """The regions of scenes for one robot and database, cached (see the module)."""

    cache: dict[str, list[CacheEntry]] = field(default_factory=dict)
    _layouts: dict[str, dict[tuple[str, float], TrayRegion]] = field(
        default_factory=dict, repr=False
    )  # the regions of the last layouts
    _last: dict[tuple[str, float, str], tuple[Tray, TrayRegion]] = field(
        default_factory=dict, repr=False
    )  # per tray id, yaw and what the tray is (pose aside): the tray as it stood, its region
    cache_size: int = 256
    workers: int = 1  # processes for several regions at once (forked: they share the database)
    _workers_pool: Any = field(default=None, repr=False)

    def tray_region(self, scene: Scene, tray_id: str, yaw: float | None = None) -> TrayRegion:
        """The region of one tray, reused from the cache while nothing it looked at changed."""
        tray = scene.tray(tray_id)
        yaw = scene.base_yaw.yaws[0] if yaw is None else yaw
        hit = self._cached(scene, tray_id, yaw)
        if hit is not None:
            self._remember(scene, hit)
            return hit
        region = compute_tray_region(self, scene, tray, yaw, own_key(self, scene, tray, yaw))
        self._store(scene, region)
        return region

    def regions(
        self, scene: Scene, workers: int | None = None
    ) -> dict[tuple[str, float], TrayRegion]:
        """Regions of every tray the task needs, at every yaw of the policy.

        workers: processes for the regions not in the cache (default: the planner's
        ``workers``); they are forked from this process, so they share its database.
        """
        pairs = [(t, y) for t in scene.task_trays for y in scene.base_yaw.yaws]
        # The regions are a function of the layout: the same layout (a change of sigma, rule
        # or objective) takes them as they were, without checking each cached region anew.
        layout = scene.model_dump_json(
            exclude={"name", "description", "sigma", "error_model", "motion", "start", "goal"}
        )
        hit = self._layouts.get(layout)
        if hit is not None:
            for region in hit.values():
                self._remember(scene, region)
            return dict(hit)
        workers = self.workers if workers is None else workers
        todo = [(t, y) for t, y in pairs if self._cached(scene, t, y) is None]
        if workers > 1 and len(todo) > 1:
            pool = self._pool(workers)
            for region in pool.starmap(_pool_region, [(scene, t, y) for t, y in todo]):
                self._store(scene, region)
        out = {(t, y): self.tray_region(scene, t, y) for t, y in pairs}
        self._layouts[layout] = out
        while len(self._layouts) > 8:
            self._layouts.pop(next(iter(self._layouts)))
        return dict(out)

    def _cached(self, scene: Scene, tray_id: str, yaw: float) -> TrayRegion | None:
        tray = scene.tray(tray_id)
        snap = snapshot(scene, tray.id)
        for entry in self.cache.get(own_key(self, scene, tray, yaw), []):
            if still_valid(self, entry, snap):
                return entry.region
        return None

    def known_regions(
        self, scene: Scene, pairs: list[tuple[str, float]]
    ) -> dict[tuple[str, float], TrayRegion]:
        """For each ``(tray id, yaw)`` planned before: the last region computed for the tray
        wherever it stood, carried rigidly to where it stands now and clipped to the cells
        where the base footprint fits (for a preview: nothing is checked but the footprint)."""
        from pickstop.regions.carry import carried_regions

        known = []
        for p in pairs:
            hit = self._last.get((*p, _carry_key(scene, p[0])))
            if hit is not None:
                known.append((p, hit))
        carried = carried_regions(self.robot, scene, [k for _, k in known])
        return {p: r for (p, _), r in zip(known, carried, strict=True)}

    def _remember(self, scene: Scene, region: TrayRegion) -> None:
        """Keep ``region`` as its tray's last (what a preview carries), the newest last."""
        key = (region.tray_id, region.yaw, _carry_key(scene, region.tray_id))
        self._last.pop(key, None)
        self._last[key] = (scene.tray(region.tray_id), region)
        if len(self._last) > 4 * self.cache_size:
            self._last.pop(next(iter(self._last)))

    def _store(self, scene: Scene, region: TrayRegion) -> None:
        self._remember(scene, region)
        entries = self.cache.setdefault(region.key, [])
        entries.insert(0, CacheEntry(region, snapshot(scene, region.tray_id)))
        del entries[4:]  # a few layouts per tray and yaw
        if len(self.cache) > self.cache_size:
            self.cache.pop(next(iter(self.cache)))

    def _pool(self, workers: int) -> Any:
        if self._workers_pool is None or self._workers_pool[0] != workers:
            import multiprocessing

            global _POOL_PLANNER
            _POOL_PLANNER = self
            ctx = multiprocessing.get_context("fork")
            self._workers_pool = (workers, ctx.Pool(workers))
        return self._workers_pool[1]

    def close(self) -> None:
        """Stop the worker processes, if any."""
        if self._workers_pool is not None:
            self._workers_pool[1].terminate()
            self._workers_pool = None


_POOL_PLANNER: RegionPlanner | None = None  # the planner the forked workers inherited


def _pool_region(scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
    assert _POOL_PLANNER is not None
    planner = _POOL_PLANNER
    tray = scene.tray(tray_id)
    return compute_tray_region(planner, scene, tray, yaw, own_key(planner, scene, tray, yaw))


def _carry_key(scene: Scene, tray_id: str) -> str:
    """What a region carried with its tray must share with the region it was computed as: the
    tray itself but for its pose, and the scene's settings every region depends on. A tray of
    the same id in another scene, or with other parts, is another tray."""
    tray = scene.tray(tray_id).model_dump(mode="json", exclude={"pose"})
    blob = [
        tray,
        *(
            scene.model_dump(
                mode="json", include={"robot", "gripper", "base_grid", "floor_clearance"}
            ).values()
        ),
    ]
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()
