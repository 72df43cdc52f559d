"""The layout document (JSON, versioned): suggested moves of trays and what they gain.

Every figure in a suggestion comes from exact, verified plans of every order in the moved
layout (the same plans ``pickstop plan --orders`` makes of the moved scene), never from the
search's predictions. Units: metres, seconds, degrees for turns.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from pickstop.scene.model import Pose
from pickstop.sequence.mix_model import MixTotals, OrderFigures
from pickstop.sequence.plan_model import PlanOptions

FORMAT = "pickstop.layout"
VERSION = 1


class Move(BaseModel):
    """One tray moved: where it stood, where it goes, and how far it turns [deg]."""

    model_config = ConfigDict(populate_by_name=True, serialize_by_alias=True)

    tray: str
    was: Pose = Field(alias="from")
    to: Pose
    turn: float = Field(description="[deg], about the vertical")


class Figures(BaseModel):
    """A layout's mix, from exact verified plans: the weighted totals and each order's."""

    totals: MixTotals
    orders: list[OrderFigures]


class Gain(BaseModel):
    """Before minus after (positive: better), in weighted means per order."""

    time: float | None = None  # [s]
    stops: float | None = None
    success: float | None = None  # after minus before


class Suggestion(BaseModel):
    rank: int
    moves: list[Move]
    scene: dict[str, Any] = Field(description="the whole moved scene, a valid scene document")
    after: Figures
    gain: Gain
    predicted: dict[str, float] = Field(
        description="what the search predicted (weighted stops and time), for comparison"
    )
    ranked: dict[str, float] = Field(
        description="what the exact plans it was ranked by gave (weighted stops and time; no "
        "Monte Carlo, the working planner's regions)"
    )
    verified: Literal[True] = True


class SearchStats(BaseModel):
    slots: dict[str, int] = Field(description="slots tried per movable tray")
    predicted: int = Field(description="layouts whose plans were predicted")
    planned: int = Field(description="layouts planned exactly (no Monte Carlo) to rank them")
    verified: int = Field(description="layouts verified (exact plans, Monte Carlo included)")
    seconds: dict[str, float] = Field(
        description="regions (the turned trays'), predict, plan, verify, total; first: time "
        "to the first verified suggestion"
    )


class Layout(BaseModel):
    format: Literal["pickstop.layout"] = "pickstop.layout"
    version: Literal[1] = 1
    scene: str
    options: PlanOptions
    orders: list[str]
    movable: list[str]
    before: Figures
    suggestions: list[Suggestion]
    notes: list[str] = Field(default_factory=list)
    search: SearchStats
