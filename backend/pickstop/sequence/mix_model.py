"""The mix document (JSON, versioned): every order of a product mix planned on one layout.

Each order's plan is the plan document of :mod:`pickstop.sequence.plan_model` (kept beside
this one: a file or a stored plan, named by ``plan``); this document sums them up, weighted
by how often each order is made. Units: metres, seconds.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from pickstop.sequence.plan_model import PlanOptions

FORMAT = "pickstop.mix"
VERSION = 1


class OrderFigures(BaseModel):
    """One order's plan in figures (or why it has none)."""

    id: str
    name: str = ""
    weight: float
    trays: list[str]
    plan: str | None = Field(
        default=None, description="where its plan document is: a file name, or a stored plan id"
    )
    stops: int | None = None
    time: float | None = Field(default=None, description="predicted operation time [s]")
    route_length: float | None = None  # [m]
    success: float | None = None  # the whole plan's, under the error model (Monte Carlo)
    naive_stops: int | None = None
    naive_time: float | None = None  # [s]
    error: str | None = Field(default=None, description="why the order has no plan")


class MixTotals(BaseModel):
    """The weighted means per order over the orders planned (weights: how often each is made)."""

    orders: int
    planned: int
    failed: list[str] = Field(description="ids of the orders without a plan")
    weight: float = Field(description="sum of the planned orders' weights")
    stops: float | None = None
    time: float | None = None  # [s]
    route_length: float | None = None  # [m]
    success: float | None = Field(
        default=None, description="weighted mean of the plans' success rates (none without MC)"
    )
    naive_stops: float | None = None
    naive_time: float | None = None  # [s]
    saving_time: float | None = None  # naive - plan [s]
    saving_fraction: float | None = None


class MixTimings(BaseModel):
    regions: float = Field(description="every tray's region for the mix, once [s]")
    plans: float = Field(description="the orders' plans once the regions are known [s]")
    per_order: float = Field(description="plans / orders [s]")
    total: float


class Mix(BaseModel):
    format: Literal["pickstop.mix"] = "pickstop.mix"
    version: Literal[1] = 1
    scene: str
    scene_hash: str
    database: str
    options: PlanOptions
    totals: MixTotals
    orders: list[OrderFigures]
    timings: MixTimings
