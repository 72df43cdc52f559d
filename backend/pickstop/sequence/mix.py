"""A product mix on one layout: every order planned, each tray's region computed once.

An order's plan is the plan of the scene whose task is the order's trays (the same document
a single plan gives). The regions of every tray any order needs are computed first, once, in
one call (several processes at once if the region planner has helpers); each order's plan then
finds them in the region planner's cache, and its exact stop checks in the stop planner's
(orders sharing a stop share its check).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from pickstop.reach.database import ReachDatabase
from pickstop.regions.cells import TrayRegion
from pickstop.scene.model import Order, Scene
from pickstop.sequence import mix_model as mm
from pickstop.sequence.cover import InfeasiblePlanError
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.request import scene_hash


@dataclass(frozen=True)
class OrderPlan:
    """An order and its plan, or why it has none."""

    order: Order
    trays: tuple[str, ...]
    plan: Plan | None
    error: str | None = None


@dataclass(frozen=True)
class MixPlans:
    """Every order's plan on one layout, with the time the regions and the plans took [s]."""

    scene: Scene
    options: PlanOptions
    database: str
    orders: list[OrderPlan]
    regions_seconds: float
    plans_seconds: float

    def __add__(self, other: MixPlans) -> MixPlans:
        """The orders of both (of one scene, options and database), their times summed."""
        return dataclasses.replace(
            self,
            orders=self.orders + other.orders,
            regions_seconds=self.regions_seconds + other.regions_seconds,
            plans_seconds=self.plans_seconds + other.plans_seconds,
        )


def order_scene(scene: Scene, trays: list[str] | tuple[str, ...]) -> Scene:
    """``scene`` with the task of one order: its ``trays``."""
    return scene.model_copy(update={"task": list(trays)})


def mix_trays(scene: Scene, orders: list[Order]) -> list[str]:
    """Every tray some order needs, each once, in order of first need."""
    return list(dict.fromkeys(t for o in orders for t in scene.order_trays(o)))


class MixRegions(Protocol):
    """What a mix asks of a region planner (:class:`~pickstop.speedups.region_planner.RegionPlanner`
    is one): every task tray's regions at once, and the database's id."""

    @property
    def db(self) -> ReachDatabase: ...

    def regions(
        self, scene: Scene, workers: int | None = None
    ) -> dict[tuple[str, float], TrayRegion]: ...


class MixPlanner(Protocol):
    """What a mix asks of a stop planner (:class:`~pickstop.speedups.stop_planner.StopPlanner`
    is one): its region planner, and a scene's plan."""

    @property
    def regions(self) -> MixRegions: ...

    def plan(self, scene: Scene, options: PlanOptions) -> Plan: ...


def plan_mix(
    sp: MixPlanner,
    scene: Scene,
    orders: list[Order],
    options: PlanOptions | None = None,
    workers: int | None = None,
    step: Callable[[int, int], None] | None = None,
    prepare: list[Order] | None = None,
) -> MixPlans:
    """The plan of every order of ``orders`` on the layout of ``scene``.

    workers: processes for the regions (default: the region planner's). step: called with
    (orders planned, orders) after each order (a job's progress; it may raise to stop).
    prepare: the orders whose trays' regions to compute first (default ``orders``; a mix
    planned a few orders at a time gives them all at the first call).
    An order that cannot be planned keeps its reason; any other error stops the mix.
    """
    opts = options or PlanOptions()
    t0 = time.perf_counter()
    needed = mix_trays(scene, orders if prepare is None else prepare)
    sp.regions.regions(order_scene(scene, needed), workers=workers)
    t1 = time.perf_counter()
    out = []
    for k, order in enumerate(orders):
        trays = tuple(scene.order_trays(order))
        try:
            out.append(OrderPlan(order, trays, sp.plan(order_scene(scene, trays), opts)))
        except InfeasiblePlanError as e:
            out.append(OrderPlan(order, trays, None, e.message))
        if step is not None:
            step(k + 1, len(orders))
    return MixPlans(scene, opts, sp.regions.db.id, out, t1 - t0, time.perf_counter() - t1)


def order_figures(op: OrderPlan, plan_ref: str | None = None) -> mm.OrderFigures:
    """The figures of one order's plan; ``plan_ref``: where its plan document is kept."""
    o, p = op.order, op.plan
    base = {"id": o.id, "name": o.name, "weight": o.weight, "trays": list(op.trays)}
    if p is None:
        return mm.OrderFigures(**base, error=op.error)
    return mm.OrderFigures(
        **base,
        plan=plan_ref,
        stops=p.totals.stops,
        time=p.totals.time.total,
        route_length=p.totals.route_length,
        success=p.totals.success,
        naive_stops=len(p.naive.stops),
        naive_time=p.naive.time.total,
    )


def mix_totals(figures: list[mm.OrderFigures]) -> mm.MixTotals:
    """Weighted means per order over the orders planned."""
    done = [f for f in figures if f.error is None]
    weight = sum(f.weight for f in done)

    def mean(field: str) -> float | None:
        vals = [(f.weight, getattr(f, field)) for f in done]
        if not done or any(v is None for _, v in vals):
            return None
        return sum(w * v for w, v in vals) / weight

    time_, naive = mean("time"), mean("naive_time")
    saving = None if time_ is None or naive is None else naive - time_
    return mm.MixTotals(
        orders=len(figures),
        planned=len(done),
        failed=[f.id for f in figures if f.error is not None],
        weight=weight,
        stops=mean("stops"),
        time=time_,
        route_length=mean("route_length"),
        success=mean("success"),
        naive_stops=mean("naive_stops"),
        naive_time=naive,
        saving_time=saving,
        saving_fraction=None if saving is None or not naive else saving / naive,
    )


def mix_document(mix: MixPlans, plan_refs: list[str | None] | None = None) -> mm.Mix:
    """The mix document of ``mix``; ``plan_refs``: where each order's plan is kept."""
    refs = plan_refs or [None] * len(mix.orders)
    figures = [order_figures(op, ref) for op, ref in zip(mix.orders, refs, strict=True)]
    n = max(len(mix.orders), 1)
    return mm.Mix(
        scene=mix.scene.name,
        scene_hash=scene_hash(mix.scene),
        database=mix.database,
        options=mix.options,
        totals=mix_totals(figures),
        orders=figures,
        timings=mm.MixTimings(
            regions=mix.regions_seconds,
            plans=mix.plans_seconds,
            per_order=mix.plans_seconds / n,
            total=mix.regions_seconds + mix.plans_seconds,
        ),
    )
