"""Regions computed in worker processes forked from the planner's.

Forked children share the parent's reachability database (its pages are copied only if
written, and they are only read) and start with its memos of grasps and refinements. The
kit reaches the children as the pool's initializer argument, which a fork hands over in
memory: nothing is pickled but the scene and the regions that come back.
"""

from __future__ import annotations

import multiprocessing
from multiprocessing.pool import Pool

from pickstop.regions.cells import TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import compute_tray_region
from pickstop.regions.validity import own_key
from pickstop.scene.model import Scene

_KIT: RegionKit | None = None  # set in each worker process, never in the parent


class RegionWorkers:
    """``processes`` forked workers computing regions with ``kit`` as it was at the fork."""

    def __init__(self, kit: RegionKit, processes: int) -> None:
        if processes < 1:
            raise ValueError(f"processes must be at least 1, got {processes}")
        self.processes = processes
        ctx = multiprocessing.get_context("fork")
        self._pool: Pool = ctx.Pool(processes, initializer=_adopt, initargs=(kit,))

    def regions(self, scene: Scene, pairs: list[tuple[str, float]]) -> list[TrayRegion]:
        """The region of each ``(tray id, yaw)`` of ``scene``, from scratch, in order."""
        return self._pool.starmap(_region, [(scene, t, y) for t, y in pairs])

    def close(self) -> None:
        """Stop the worker processes."""
        self._pool.terminate()
        self._pool.join()


def _adopt(kit: RegionKit) -> None:
    global _KIT
    _KIT = kit


def _region(scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
    kit = _KIT
    assert kit is not None, "a region worker runs only in a RegionWorkers pool"
    tray = scene.tray(tray_id)
    return compute_tray_region(kit, scene, tray, yaw, own_key(kit, scene, tray, yaw))
