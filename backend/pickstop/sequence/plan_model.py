"""The plan document (JSON, versioned) and the options that produce it.

Both are pydantic models, so the CLI, the REST API and the 3D planner share one definition
and one JSON Schema. Units: metres, seconds, radians; positions are world ``(x, y)``.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from pickstop.scene.model import FailureModel

FORMAT = "pickstop.plan"
VERSION = 1

Point2 = tuple[float, float]


class PlanOptions(BaseModel):
    """How to plan. Unset fields come from the scene (sigma, error model)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    sigma: Annotated[float, Field(ge=0, le=1.0, allow_inf_nan=False)] | None = Field(
        default=None, description="base positioning error [m]; default: the scene's"
    )
    rule: Literal["sigma", "success"] = Field(
        default="sigma",
        description="'sigma': the paper's rule, inscribed radius >= sigma; 'success': stops "
        "must reach `target` success under the error model, confirmed by Monte Carlo",
    )
    target: Annotated[float, Field(gt=0.5, lt=1.0)] = Field(
        default=0.95, description="success rate the 'success' rule requires per stop"
    )
    objective: Literal["stops", "time", "expected-time"] = Field(
        default="stops",
        description="'stops': fewest stops, then the shortest route; 'time': least predicted "
        "operation time; 'expected-time': least expected time, failed arrivals included (the "
        "scene's failure model, each stop's fast success estimate)",
    )
    samples: Annotated[int, Field(ge=0, le=100_000)] = Field(
        default=1000, description="Monte Carlo samples per stop (0: no success estimate)"
    )
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = Field(
        default=0, description="seed of the Monte Carlo"
    )
    time_limit: Annotated[float, Field(gt=0, le=600)] = Field(
        default=10.0, description="time limit of each stop selection solve [s]"
    )
    placement: Literal["centre", "success"] = Field(
        default="centre",
        description="'centre': each stop at its intersection's inscribed circle's centre (the "
        "paper); 'success': at the point of the intersection where the fast success estimate "
        "under the stop's error model is highest, when that beats the centre (the stop then "
        "reports the centre and its rates too)",
    )


class Witness(BaseModel):
    """A verified arm configuration that grasps one part from the stop's centre."""

    tray_id: str
    part_id: str
    grasp_index: int
    theta: list[float]  # joint values in the robot's arm joint order [rad or m]
    hand: dict[str, float] = Field(
        default_factory=dict,
        description="the hand's joint values on approach (pre-grasp), by joint name [rad or m]",
    )
    T_part_tcp: list[list[float]] | None = Field(
        default=None, description="the grasp: the hand's grasp point in the part frame (4 x 4)"
    )


class Success(BaseModel):
    samples: int
    successes: int
    rate: float
    interval: Point2  # 95% Wilson score interval


class StopFailures(BaseModel):
    """A stop's failed arrivals expected per run under the scene's failure model
    (:mod:`pickstop.sequence.failure`)."""

    success: float  # the stop's success rate these follow from
    source: Literal["monte_carlo", "estimate"]  # where that rate comes from
    retries: float  # expected re-localise and re-dock rounds
    operator: float  # probability that an operator is called
    time: float  # expected extra time [s]


class Stop(BaseModel):
    index: int  # visiting order, from 0
    x: float
    y: float
    yaw: float
    trays: list[str]  # the trays picked here
    region_trays: list[str]  # every tray whose region holds this stop's component
    inscribed_radius: float
    candidate: int  # index into ``candidates``
    witnesses: list[Witness]
    success: Success | None = None
    error_model: str | None = Field(
        default=None,
        description="the station whose error model the stop's success rate uses "
        "(the scene's error_model.stations); null: the scene's global model",
    )
    estimated_success: float | None = None  # fast estimate (error density over the cells)
    failures: StopFailures | None = None
    clearance: float | None = Field(
        default=None,
        description="radius [m] of the largest circle centred at the stop inside its "
        "intersection: its guaranteed radius (the inscribed radius when the stop is at the "
        "circle's centre)",
    )
    circle_centre: Point2 | None = Field(
        default=None,
        description="placed for success: the inscribed circle's centre [m], where the paper's "
        "rule would stop; null: the stop is there",
    )
    circle_estimated_success: float | None = Field(
        default=None, description="placed for success: the fast estimate at the circle's centre"
    )
    circle_success: Success | None = Field(
        default=None, description="placed for success: the Monte Carlo at the circle's centre"
    )


class Leg(BaseModel):
    start: str  # "start", "stop 0", ...
    end: str
    length: float  # [m]
    time: float  # travel time [s], rest to rest between the halts at docking segments' ends
    polyline: list[Point2]
    segment_yaws: list[float | None] | None = Field(
        default=None,
        description="per segment of the polyline: the yaw [rad] the base holds along it (a "
        "straight docking leg to or from a pose where the base cannot turn), or null where it "
        "may turn as it likes; absent when the base may turn everywhere",
    )


class TimeTotals(BaseModel):
    travel: float
    stops: float
    picks: float
    total: float  # predicted: every arrival succeeds [s]
    failures: float | None = Field(
        default=None, description="expected time of failed arrivals per run [s]"
    )
    expected: float | None = Field(
        default=None, description="expected time per run, failures included: total + failures [s]"
    )


class Totals(BaseModel):
    stops: int
    route_length: float
    time: TimeTotals
    success: float | None = None  # whole plan: product over stops
    success_interval: Point2 | None = None
    retries: float | None = None  # expected re-docks per run
    operator_calls: float | None = None  # expected operator calls per run


class NaiveStop(BaseModel):
    tray: str
    x: float
    y: float
    inscribed_radius: float


class Naive(BaseModel):
    """One stop per tray at its region's inscribed centre, same route solver."""

    stops: list[NaiveStop]
    route_length: float
    time: TimeTotals
    saving_time: float  # naive total time - plan total time [s]
    saving_fraction: float
    saving_stops: int


class IntersectionRecord(BaseModel):
    """An intersection (a candidate stop) as the plan judged it: chosen, kept or rejected, and
    why."""

    index: int
    trays: list[str]
    yaw: float
    x: float
    y: float
    inscribed_radius: float
    area: float
    status: Literal["chosen", "kept", "rejected"]
    reason: str | None = None  # why it was rejected
    predicted_success: float | None = None  # from the region's shape ('success' rule)
    estimated_success: float | None = None  # fast estimate at its centre, for all its trays
    polygon: list[list[Point2]]  # exterior ring, then holes


class TradeoffRow(BaseModel):
    """The least expected time with exactly ``stops`` stops (expected-time objective)."""

    stops: int
    expected_time: float  # [s] per run, failures included
    time: float  # [s] predicted, every arrival succeeding
    success: float  # whole plan, from the stops' success estimates
    optimal: bool  # proven by the solver
    chosen: bool  # the plan's own row


class Parameters(BaseModel):
    sigma: float
    rule: Literal["sigma", "success"]
    target: float
    threshold_radius: float  # inscribed radius a candidate needs to be kept outright [m]
    objective: Literal["stops", "time", "expected-time"]
    placement: Literal["centre", "success"] = "centre"
    error_model: Literal["bounded", "gaussian"]
    yaw_sigma: float
    samples: int
    seed: int
    base_yaws: list[float]
    grid_resolution: float
    max_speed: float
    max_acceleration: float
    stop_time: float
    pick_time: float
    failure: FailureModel | None = None  # what a failed arrival costs


class Timings(BaseModel):
    regions: float
    intersections: float
    routing: float
    estimates: float = 0.0  # fast success estimates of every candidate [s]
    selection: float
    verification: float
    monte_carlo: float
    naive: float
    total: float


class Plan(BaseModel):
    format: Literal["pickstop.plan"] = "pickstop.plan"
    version: Literal[1] = 1
    scene: str  # scene name
    scene_hash: str  # sha256 of the scene document (canonical JSON)
    database: str
    robot: str
    robot_hash: str
    joints: list[str]
    notes: list[str] = Field(
        default_factory=list, description="scene fields that no longer apply, and why"
    )
    trays: list[str]  # the task's trays
    parameters: Parameters
    stops: list[Stop]
    route: list[Point2]  # start, stops and goal joined by the floor paths
    legs: list[Leg]
    totals: Totals
    naive: Naive
    optimal: bool  # the stop selection was proven optimal
    candidates: list[IntersectionRecord]
    tradeoff: list[TradeoffRow] | None = Field(
        default=None,
        description="expected-time objective: for each number of stops, the least expected "
        "time and its success over the same candidates (the chosen row verified, the others "
        "not)",
    )
    timings: Timings
    verified: bool = Field(
        default=True,
        description="false for a preview drawn while a layout is edited: the regions are "
        "known ones carried with the moved trays and clipped where the base no longer fits; "
        "nothing is verified, stops carry no witnesses and no success rate",
    )
