"""Request and response bodies of the REST API (pydantic): the OpenAPI document shows these.

Scene and robot documents stay plain mappings in the request models (they are validated by
:func:`pickstop.scene.load.parse_scene` and :func:`pickstop.robot.config.parse_config`, after
the size limits), but the OpenAPI document types them by the scene and robot schemas.
"""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, WithJsonSchema, model_validator

from pickstop.api.limits import Limits
from pickstop.robot.floor import FLOOR_CLEARANCE, MAX_CLEARANCE
from pickstop.scene.model import Order
from pickstop.sequence.mix_model import Mix
from pickstop.sequence.plan_model import Plan, PlanOptions

API_PREFIX = "/api/v1"
# A scene document in a schema: the OpenAPI document turns this marker into a $ref to the
# Scene component (a $ref here would send pydantic looking for a definition of its own).
SCENE = {"x-component": "Scene"}
SceneDoc = Annotated[dict[str, Any], WithJsonSchema(SCENE)]
OptionalSceneDoc = Annotated[
    dict[str, Any] | None, WithJsonSchema({"anyOf": [SCENE, {"type": "null"}]})
]

EXAMPLE_SCENE = {
    "name": "two trays",
    "floor": {"min": [-1, -1], "max": [4, 3]},
    "obstacles": [
        {
            "id": "table",
            "geometry": {"shape": "box", "size": [1.6, 0.6, 0.72]},
            "pose": {"x": 1.4, "y": 1.6},
        }
    ],
    "trays": [
        {
            "id": "tray_1",
            "pose": {"x": 0.95, "y": 1.5, "z": 0.725},
            "inner_size": [0.3, 0.2],
            "parts": [
                {"id": "bolt", "geometry": {"shape": "cylinder", "radius": 0.01, "height": 0.05}}
            ],
        }
    ],
    "base_yaw": {"fixed": 1.5707963},
    "start": {"x": 0, "y": 0},
    "goal": {"x": 3, "y": 0},
}


# -- problems -------------------------------------------------------------------------------------
class FieldError(BaseModel):
    field: str
    message: str


class ProblemDetails(BaseModel):
    """RFC 9457 problem details; ``field`` is the first offending field (dotted), or ``body``."""

    type: str
    title: str
    status: int
    detail: str
    instance: str | None = None
    field: str | None = None
    errors: list[FieldError] | None = None


# -- service --------------------------------------------------------------------------------------
class LoadedPlanner(BaseModel):
    robot: str
    database: str


class Health(BaseModel):
    status: Literal["ok"]
    version: str
    process: int = Field(description="id of the API process that answered")
    loaded: list[LoadedPlanner]
    interrupted_jobs_at_start: int
    limits: Limits


# -- robots ---------------------------------------------------------------------------------------
class RobotInfo(BaseModel):
    name: str
    kind: Literal["preset", "registered"]
    created: str | None = None


class RegisteredRobot(BaseModel):
    name: str
    kind: Literal["registered"] = "registered"
    dof: int
    robot_hash: str


# -- databases ------------------------------------------------------------------------------------
class DatabaseInfo(BaseModel):
    id: str
    robot: str | None = None
    robot_hash: str | None = None
    state: str | None = None
    samples: int | None = None
    stored: int | None = None
    resolution: float | None = None
    orientation: int | None = None
    seed: int | None = None
    chunk_size: int | None = None
    thinning: float | None = None
    code_version: str | None = None
    created: str | None = None
    completed: str | None = None
    build_seconds: float | None = None
    rejected_self_collision: int | None = None
    rejected_thinning: int | None = None
    floor_clearance: float | None = None
    rejected_floor: int | None = None
    shards: int | None = None
    bytes: int | None = None
    screen_false_rejection: float | None = Field(
        default=None, description="valid configurations the self-collision screen dropped"
    )
    screen_bound: float | None = Field(default=None, description="the bound it is held to")
    screen_meets_bound: bool | None = Field(
        default=None,
        description="whether the screen meets its bound (false: the database lacks that share "
        "of the robot's reachable configurations)",
    )

    @classmethod
    def of(cls, row: dict[str, Any]) -> DatabaseInfo:
        derived = ("shards", "bytes", "screen_bound", "screen_meets_bound")
        out = {k: row.get(k) for k in cls.model_fields if k not in derived}
        shards = row.get("shards")
        if shards is not None:
            out["shards"], out["bytes"] = len(shards), sum(s["bytes"] for s in shards)
        if row.get("screen_false_rejection") is not None:
            from pickstop.robot.artifacts import FALSE_REJECTION_BOUND

            out["screen_bound"] = FALSE_REJECTION_BOUND
            out["screen_meets_bound"] = row["screen_false_rejection"] <= FALSE_REJECTION_BOUND
        return cls.model_validate(out)


class BuildRequest(BaseModel):
    """A reachability database build; every value is checked before the job is queued."""

    model_config = ConfigDict(extra="forbid")
    robot: str = Field(default="tiago", description="a preset or a registered robot")
    samples: int = Field(default=2_000_000, ge=1000, description="joint-space samples")
    resolution: float = Field(
        default=0.05, ge=0.005, le=0.5, allow_inf_nan=False, description="voxel edge [m]"
    )
    orientation: int = Field(default=6, ge=1, le=32, description="SO(3) grid divisions")
    seed: int = Field(default=0, ge=0, le=2**63 - 1)
    chunk_size: int = Field(default=250_000, ge=1000, le=5_000_000)
    thinning: float = Field(
        default=0.0, ge=0, lt=10, allow_inf_nan=False, description="thinning distance [rad]"
    )
    floor_clearance: float = Field(
        default=FLOOR_CLEARANCE,
        ge=0,
        le=MAX_CLEARANCE,
        allow_inf_nan=False,
        description="configurations with a moving link this close to the floor are dropped [m]",
    )


# -- scenes ---------------------------------------------------------------------------------------
class SceneRecord(BaseModel):
    id: str
    name: str
    etag: str
    revision: int
    created: str
    updated: str
    scene: SceneDoc | None = None

    @classmethod
    def of(cls, row: dict[str, Any], with_doc: bool) -> SceneRecord:
        return cls(
            **{k: row[k] for k in cls.model_fields if k in row and k != "scene"},
            scene=json.loads(row["doc"]) if with_doc else None,
        )


class Feature(BaseModel):
    type: Literal["Feature"] = "Feature"
    geometry: dict[str, Any] | None
    properties: dict[str, Any]


class FeatureCollection(BaseModel):
    type: Literal["FeatureCollection"] = "FeatureCollection"
    features: list[Feature]


class Regions(BaseModel):
    """A scene's base regions and their intersections (candidate stops) as GeoJSON."""

    database: str
    sigma: float
    rule: Literal["sigma", "success"] = "sigma"
    target: float = 0.95
    regions: FeatureCollection
    intersections: FeatureCollection


# -- plans ----------------------------------------------------------------------------------------
class BatchItem(BaseModel):
    """A stored scene by id, or an inline scene document: exactly one of them."""

    model_config = ConfigDict(extra="forbid")
    scene_id: str | None = Field(default=None, description="a stored scene")
    scene: OptionalSceneDoc = Field(default=None, description="or an inline scene document")

    @model_validator(mode="after")
    def _one(self) -> BatchItem:
        if (self.scene_id is None) == (self.scene is None):
            raise ValueError("give exactly one of scene_id and scene")
        return self


class PlanRequest(BatchItem):
    options: PlanOptions = PlanOptions()
    database: str | None = Field(default=None, description="reachability database id")
    mode: Literal["sync", "job", "preview"] = Field(
        default="sync",
        description="'job': run as a batch job; 'preview': a quick unverified plan to draw "
        "while a layout is edited (known regions carried with the moved trays, no witnesses, no "
        "Monte Carlo; the plan says verified: false); never stored, so send store: false",
    )
    store: bool = Field(
        default=True, description="keep the plan as a record (false: answered, not stored)"
    )
    orders: list[Order] | Literal["scene"] | None = Field(
        default=None,
        description="plan a product mix on the scene's layout: every order (a list of {id, "
        "trays | parts, weight}, or 'scene' for the scene's own orders) planned, each tray's "
        "region computed once; answered with a mix record, each order's plan stored as a plan "
        "(mode 'sync' or 'job'; at most `max_orders` orders, see /limits)",
    )


class PlanRecord(BaseModel):
    id: str | None  # None for a preview that was not stored
    scene_id: str | None
    scene_revision: int | None
    created: str
    options: dict[str, Any]
    plan: Plan | None = None
    scene: SceneDoc | None = None


class PlanSummary(BaseModel):
    id: str
    scene_id: str | None
    scene_revision: int | None
    options: dict[str, Any]
    created: str
    stops: int | None
    time: float | None

    @classmethod
    def of(cls, row: dict[str, Any]) -> PlanSummary:
        return cls(**{**row, "options": json.loads(row["options"])})


# -- mixes ----------------------------------------------------------------------------------------
class MixRecord(BaseModel):
    """A stored mix: its document names each order's stored plan by id (``orders[].plan``)."""

    id: str | None  # None if not stored
    scene_id: str | None
    scene_revision: int | None
    created: str
    options: dict[str, Any]
    mix: Mix


class MixSummary(BaseModel):
    id: str
    scene_id: str | None
    scene_revision: int | None
    options: dict[str, Any]
    created: str
    orders: int | None
    time: float | None

    @classmethod
    def of(cls, row: dict[str, Any]) -> MixSummary:
        return cls(**{**row, "options": json.loads(row["options"])})


# -- jobs -----------------------------------------------------------------------------------------
class BatchRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    scenes: list[BatchItem] = Field(min_length=1)
    options: PlanOptions = PlanOptions()
    database: str | None = None


class Job(BaseModel):
    id: str
    kind: Literal["build", "batch", "dispatch", "mix", "layout"]
    state: Literal["queued", "running", "done", "failed", "cancelled", "interrupted"]
    progress: float
    params: dict[str, Any]
    result: dict[str, Any] | None
    error: str | None
    created: str
    updated: str

    @classmethod
    def of(cls, row: dict[str, Any]) -> Job:
        return cls(
            **{
                **row,
                "params": json.loads(row["params"]),
                "result": json.loads(row["result"]) if row["result"] else None,
            }
        )


# -- placement -------------------------------------------------------------------------------------
Coordinate = Annotated[float, Field(ge=-1e4, le=1e4, allow_inf_nan=False)]


class PlacementRequest(BatchItem):
    """Where a tray of the scene would stand with its footprint at ``(x, y, yaw)``."""

    tray: str = Field(description="a tray of the scene (its own place does not count)")
    x: Coordinate
    y: Coordinate
    yaw: Coordinate = 0.0
    z_hint: Coordinate | None = Field(
        default=None, description="the tray's pose height now [m]: of the supports under the "
        "footprint, the free one nearest this height (a tray dragged along a shelf stays on it)"
    )  # fmt: skip


class PlacementAnswer(BaseModel):
    """The support under the footprint (an obstacle id, ``floor``, or null), the pose height
    that rests the tray there [m] and whether it stands free (else ``problem`` says why);
    ``top``: the support's top face height [m]."""

    tray: str
    x: float
    y: float
    yaw: float
    z: float | None
    support: str | None
    free: bool
    problem: str | None = None
    top: float | None = None


class CopyRequest(BatchItem):
    tray: str = Field(description="the tray to copy onto a free spot of its support")


class CopyAnswer(BaseModel):
    tray: dict[str, Any] | None = Field(
        description="the copy (new ids for it and its parts) on the nearest free spot of the "
        "same support, as a tray document; null if the support has no free spot"
    )


# -- guidance -------------------------------------------------------------------------------------
class GuidanceRequest(BatchItem):
    """Where a tray of the scene could go, and what that does to its order's stops."""

    tray: str = Field(description="a tray of the scene")
    order: str | None = Field(
        default=None, description="judge it with this order's trays (default: the task's)"
    )
    mix: bool = Field(default=False, description="with the trays of every order that needs it")
    sigma: float | None = Field(
        default=None, ge=0, le=1, allow_inf_nan=False, description="default: the scene's [m]"
    )
    database: str | None = Field(default=None, description="reachability database id")


class GuidanceInfo(BaseModel):
    tray: str
    sigma: float
    groups: list[list[str]] = Field(description="the partner trays, one list per order shown")
    here: Literal["shares", "own", "unreachable", "unknown"] = Field(
        description="the zone the tray stands in now"
    )
    seconds: float


class Guidance(BaseModel):
    """Zones of positions of the tray's centre (world x, y [m]) on the supports it may stand
    on, as GeoJSON: ``kind`` 'shares' (it shares a stop of inscribed radius >= sigma with the
    feature's ``trays``), 'own' (it needs a stop of its own), 'unreachable', or 'unknown' (a
    support at another height: drop it there to know). Predicted from known regions (carried
    with the tray); the exact plan decides once the tray is dropped."""

    type: Literal["FeatureCollection"] = "FeatureCollection"
    properties: GuidanceInfo
    features: list[Feature]


# -- layouts --------------------------------------------------------------------------------------
class LayoutRequest(BatchItem):
    """Suggested moves of trays for the mix (a job: progress, result, cancel)."""

    orders: list[Order] | Literal["scene"] | None = Field(
        default=None, description="the mix (default: the scene's orders, else its task)"
    )
    movable: list[str] | None = Field(
        default=None, max_length=6, description="trays that may move (default: every tray an "
        "order needs, at most 6)"
    )  # fmt: skip
    options: PlanOptions = PlanOptions()
    database: str | None = Field(default=None, description="reachability database id")
    step: float = Field(default=0.1, ge=0.025, le=1.0, allow_inf_nan=False,
                        description="slot spacing [m]")  # fmt: skip
    turns: list[Literal[0, 90, 180, 270]] = Field(
        default=[0, 90, 180, 270], min_length=1, max_length=4, description="turns tried [deg]"
    )
    suggestions: int = Field(default=3, ge=1, le=10)
    shortlist: int = Field(default=12, ge=1, le=64,
                           description="best predicted layouts planned exactly")  # fmt: skip
