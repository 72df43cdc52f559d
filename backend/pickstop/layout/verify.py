"""Exact plans of candidate layouts: ranked quickly with the working planner, verified from
scratch.

A layout's verified figures must not depend on which layouts were tried before it. The working
planner's regions may (a region computed after a move keeps refinements remembered from other
places: every cell verified, but more cells than from scratch); so a suggestion is verified by a
planner of its own whose regions are computed by the from-scratch pipeline, no refinement
carried between computations. Its cache keeps a region only while the validity rules say the
region is the one the pipeline would compute in the layout at hand, so what it reuses between
layouts changes no answer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from pickstop.scene.model import Order, Scene
from pickstop.sequence.mix import MixPlans, plan_mix
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.region_planner import RegionPlanner
from pickstop.speedups.stop_planner import StopPlanner


def scratch_planner(rp: RegionPlanner) -> StopPlanner:
    """A stop planner over a region planner of its own for ``rp``'s robot and database whose
    regions are computed from scratch (nothing reused across layouts); close its ``regions``
    after use."""
    kit = RegionPlanner(rp.robot, rp.db, cache_dir=rp.cache_dir, across_layouts=False,
                        workers=rp.workers)  # fmt: skip
    return StopPlanner(kit)


class Evaluator(Protocol):
    """Plans every order of layouts: ``rank`` exactly without Monte Carlo (the working planner,
    to rank them), ``verify`` exactly with the request's options (from scratch)."""

    def rank(self, scenes: list[Scene]) -> list[MixPlans]: ...

    def verify(self, scenes: list[Scene]) -> list[MixPlans]: ...

    def close(self) -> None: ...


@dataclass
class LocalEvaluator:
    """:class:`Evaluator` in this process: the working stop planner and a scratch one."""

    working: StopPlanner
    orders: list[Order]
    options: PlanOptions
    scratch: StopPlanner | None = None

    def rank(self, scenes: list[Scene]) -> list[MixPlans]:
        quick = self.options.model_copy(update={"samples": 0})
        return [plan_mix(self.working, s, self.orders, quick) for s in scenes]

    def verify(self, scenes: list[Scene]) -> list[MixPlans]:
        if self.scratch is None:
            self.scratch = scratch_planner(self.working.regions)
        return [plan_mix(self.scratch, s, self.orders, self.options) for s in scenes]

    def close(self) -> None:
        if self.scratch is not None:
            self.scratch.regions.close()
