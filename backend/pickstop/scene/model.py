"""The scene file format (JSON, versioned): floor, obstacles, trays with parts, robot, task.

Pydantic at the boundary: :func:`parse_scene` turns a decoded JSON document into a validated
:class:`Scene` or raises :class:`SceneError` listing every problem with its field path.
Poses are ``(x, y, z, yaw)`` [m, rad]: a position and a rotation about the vertical.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    field_validator,
    model_serializer,
    model_validator,
)
from shapely.geometry import Polygon

from pickstop.errors import InputError
from pickstop.frames import R_axis
from pickstop.robot.floor import FLOOR_CLEARANCE, MAX_CLEARANCE
from pickstop.scene import defaults

FORMAT = "pickstop.scene"
VERSION = 1

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Ident = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$")]
# Bounds that keep a scene's geometry well-conditioned in floating point: every size at least
# 0.1 mm and every coordinate within 10 km, so that no outline collapses to a point or a line.
MIN_SIZE, MAX_SIZE, MAX_COORD = 1e-4, 1e3, 1e4  # [m]
MAX_YAW = 4 * math.pi  # [rad]: two turns either way; more is a unit mistake (degrees)
Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD, allow_inf_nan=False)]
Size = Annotated[float, Field(ge=MIN_SIZE, le=MAX_SIZE, allow_inf_nan=False)]
Yaw = Annotated[float, Field(ge=-MAX_YAW, le=MAX_YAW, allow_inf_nan=False)]
# Names are shown to people: no control characters, no bidirectional overrides (which make a
# name read as another); a description may break lines.
_HIDDEN = r"\u202a-\u202e\u2066-\u2069"
Name = Annotated[str, Field(max_length=200, pattern=f"^[^\\x00-\\x1f\\x7f{_HIDDEN}]*$")]
Text = Annotated[str, Field(pattern=f"^[^\\x00-\\x08\\x0b\\x0c\\x0e-\\x1f\\x7f{_HIDDEN}]*$")]
FilePath = Annotated[str, Field(min_length=1, max_length=1024, pattern=r"^[^\x00-\x1f\x7f]+$")]


class SceneError(InputError):
    """A scene document is invalid; ``problems`` lists (field path, message) pairs."""

    def __init__(self, problems: list[tuple[str, str]], source: str = "scene") -> None:
        self.problems = problems
        text = "; ".join(f"{loc}: {msg}" for loc, msg in problems)
        super().__init__(
            f"{source}: invalid scene: {text}", field=problems[0][0] if problems else None
        )


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Pose(_Strict):
    """Position [m] and yaw about the vertical [rad]."""

    x: Coord = 0.0
    y: Coord = 0.0
    z: Coord = 0.0
    yaw: Yaw = 0.0


class BasePose(_Strict):
    """A base pose on the floor: ``(x, y)`` [m] and yaw [rad]."""

    x: Coord
    y: Coord
    yaw: Yaw = 0.0


class Box(_Strict):
    shape: Literal["box"] = "box"
    size: tuple[Size, Size, Size]  # full extents along x, y, z [m]


class Cylinder(_Strict):
    shape: Literal["cylinder"] = "cylinder"
    radius: Size
    height: Size


class Mesh(_Strict):
    shape: Literal["mesh"] = "mesh"
    path: FilePath  # relative to the scene file
    scale: Annotated[float, Field(ge=1e-4, le=1e4, allow_inf_nan=False)] = 1.0


Shape = Annotated[Box | Cylinder | Mesh, Field(discriminator="shape")]


class Obstacle(_Strict):
    """A static obstacle; its pose is the centre of its base face on the floor-up axis."""

    id: Ident
    name: Name = ""
    geometry: Shape
    pose: Pose  # centre of the bounding box bottom [m], yaw [rad]


class Grasp(_Strict):
    """A user-given grasp: the hand's grasp point (TCP) pose in the part frame
    (``T_part_tcp``; the TCP is the tool frame moved by the robot's ``hand.tool_offset``)."""

    position: tuple[Finite, Finite, Finite]
    quaternion_wxyz: tuple[Finite, Finite, Finite, Finite]

    @field_validator("quaternion_wxyz")
    @classmethod
    def _unit(cls, q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        n = math.sqrt(sum(v * v for v in q))
        if abs(n - 1.0) > 1e-3:
            raise ValueError(f"must be a unit quaternion (norm {n:.4f})")
        return q


class Part(_Strict):
    """A part lying in its tray; ``pose`` is its bottom centre in the tray frame."""

    id: Ident
    name: Name = ""
    geometry: Shape
    pose: Pose = Pose()
    grasps: list[Grasp] | None = None  # override generated grasps


MAX_TILT = 0.8  # [rad], about 46 degrees


class Tilt(_Strict):
    """A rotation of a tray about its own x or y axis [rad], as on a flow rack's slanted
    shelf (10-20 degrees); positive turns y towards z (axis x) or z towards x (axis y)."""

    axis: Literal["x", "y"]
    angle: Annotated[float, Field(ge=-MAX_TILT, le=MAX_TILT, allow_inf_nan=False)]

    def matrix(self) -> np.ndarray:
        """``R_yawed_tray`` (3, 3): the tilt, applied after the tray's yaw."""
        return R_axis(self.axis, self.angle)


class Tray(_Strict):
    """An open box on a table or shelf. Its frame: centre of the inner floor, x along
    ``inner_size[0]``, z along the floor's normal (tilted with the tray)."""

    id: Ident
    name: Name = ""
    pose: Pose  # inner floor centre in the world [m], yaw [rad]
    tilt: Tilt | None = None  # about the tray's own x or y axis, after the yaw
    inner_size: tuple[Size, Size]  # [m]
    wall_height: Size = defaults.TRAY_WALL_HEIGHT
    wall_thickness: Size = defaults.TRAY_WALL_THICKNESS
    floor_thickness: Annotated[NonNegative, Field(le=MAX_SIZE)] = defaults.TRAY_FLOOR_THICKNESS
    parts: list[Part] = Field(default_factory=list)
    color: str | None = None

    @property
    def outer_size(self) -> tuple[float, float]:
        t = 2 * self.wall_thickness
        return (self.inner_size[0] + t, self.inner_size[1] + t)


#: Fields of the scene's ``gripper`` block from when the scene described the hand's geometry;
#: the robot config owns the hand now, so they are read and ignored (see ``gripper_notes``).
HAND_GEOMETRY_FIELDS = (
    "max_opening",
    "finger_length",
    "tip_offset",
    "finger_thickness",
    "hand_width",
    "palm_depth",
)


class Gripper(_Strict):
    """How grasps are generated for this scene: which kinds, at how many angles.

    The hand itself (its links, open posture, grasp point, opening) is the robot's: see the
    robot config's ``hand`` block. The geometry fields older scenes carry here are accepted and
    ignored, with a note (:func:`gripper_notes`).
    """

    kinds: tuple[Literal["top", "side"], ...] = ("top", "side")
    symmetric: bool = False  # a parallel gripper looks the same turned 180 degrees about x
    top_down_angles: Annotated[int, Field(ge=1, le=36)] = 8  # about the vertical, over 360 deg
    side_directions: Annotated[int, Field(ge=0, le=36)] = 8  # horizontal approach directions
    max_opening: Positive | None = None  # ignored: the robot's hand.max_opening
    finger_length: Positive | None = None  # ignored: the robot's hand geometry
    tip_offset: NonNegative | None = None  # ignored: from the robot's hand geometry
    finger_thickness: Positive | None = None  # ignored
    hand_width: Positive | None = None  # ignored
    palm_depth: Positive | None = None  # ignored


def gripper_notes(scene: Scene) -> list[str]:
    """Notes on ``gripper`` fields an older scene gives that no longer apply."""
    given = [f for f in HAND_GEOMETRY_FIELDS if getattr(scene.gripper, f) is not None]
    if not given:
        return []
    return [
        f"gripper.{f}: no longer applies (the hand's geometry comes from the robot: its "
        "links at the pre-grasp joint values, tool_offset and max_opening in the robot "
        "config's hand block)"
        for f in given
    ]


class YawPolicy(_Strict):
    """One fixed base yaw (the paper) or a small set to search [rad]."""

    fixed: Yaw | None = 0.0
    candidates: list[Yaw] | None = None

    @model_validator(mode="after")
    def _one(self) -> YawPolicy:
        if self.candidates is not None and not 1 <= len(self.candidates) <= 16:
            raise ValueError("candidates must hold 1 to 16 yaws")
        return self

    @property
    def yaws(self) -> list[float]:
        if self.candidates is not None:
            return list(self.candidates)
        return [self.fixed if self.fixed is not None else 0.0]


class Extent(_Strict):
    """A rectangle on the floor [m]: ``min`` below ``max`` in x and in y."""

    min: tuple[Coord, Coord]
    max: tuple[Coord, Coord]

    @model_validator(mode="after")
    def _ordered(self) -> Extent:
        if not (self.min[0] < self.max[0] and self.min[1] < self.max[1]):
            raise ValueError("min must be below max in x and y")
        return self


class BaseGrid(_Strict):
    """Where base positions are sampled: resolution [m] and the extent (default: the floor)."""

    resolution: Annotated[float, Field(ge=0.005, le=0.5)] = defaults.GRID_RESOLUTION
    extent: Extent | None = None


class RobotRef(_Strict):
    """A preset name or a robot config file (relative to the scene file)."""

    preset: str | None = "tiago"
    config: str | None = None

    @model_validator(mode="after")
    def _one(self) -> RobotRef:
        if self.config is not None and self.preset not in (None, "tiago"):
            raise ValueError("give either preset or config, not both")
        return self

    @property
    def ref(self) -> str:
        return self.config if self.config is not None else (self.preset or "tiago")


class Motion(_Strict):
    """Time model parameters of the base and the arm."""

    max_speed: Annotated[float, Field(ge=0.01, le=10)] = 0.5  # [m/s]
    max_acceleration: Annotated[float, Field(ge=0.01, le=50)] = 0.5  # [m/s^2]
    stop_time: Annotated[float, Field(ge=0, le=3600)] = 8.0  # decelerate, dock, relocalise [s]
    pick_time: Annotated[float, Field(ge=0, le=3600)] = 6.0  # per part [s]


Offset = Annotated[float, Field(ge=-1.0, le=1.0, allow_inf_nan=False)]  # [m]
Variance = Annotated[float, Field(ge=-1.0, le=1.0, allow_inf_nan=False)]  # [m^2]
YawOffset = Annotated[float, Field(ge=-math.pi, le=math.pi, allow_inf_nan=False)]  # [rad]
Covariance = tuple[tuple[Variance, Variance], tuple[Variance, Variance]]
#: the fields an error model added to its first form (kind, yaw_sigma), left out of the
#: scene's dump while they hold their defaults, so that a scene's hash stays what it was
_ADDED: Mapping[str, Any] = MappingProxyType(
    {"mean": (0.0, 0.0), "covariance": None, "yaw_mean": 0.0, "frame": "base", "stations": ()}
)


def _check_covariance(c: Covariance | None) -> Covariance | None:
    """Symmetric and positive definite, or None."""
    if c is None:
        return c
    (a, b), (b2, d) = c
    if abs(b - b2) > 1e-12:
        raise ValueError("covariance must be symmetric")
    if not (a > 0 and d > 0 and a * d - b * b > 0):
        raise ValueError("covariance must be positive definite (variances > 0, |correlation| < 1)")
    return c


class _Positioning(_Strict):
    """What an error model adds to an isotropic sigma: a mean offset [m] and a covariance
    [m^2] in ``frame`` (``base``: x along the planned heading, y to its left; or ``map``), and
    a yaw bias [rad]. See :mod:`pickstop.scene.positioning`."""

    mean: tuple[Offset, Offset] = (0.0, 0.0)
    covariance: Covariance | None = None  # gaussian only; None: isotropic from sigma
    yaw_mean: YawOffset = 0.0
    frame: Literal["base", "map"] = "base"

    @field_validator("covariance")
    @classmethod
    def _pd(cls, c: Covariance | None) -> Covariance | None:
        return _check_covariance(c)


class StationError(_Positioning):
    """A station's own error model: for stops whose centre lies in ``zone`` (a polygon, map
    frame [m]) or that pick from any of ``trays`` (a tray group). Unset fields take the
    scene's (kind, sigma, yaw_sigma)."""

    name: Ident
    trays: list[Ident] | None = Field(default=None, min_length=1, max_length=1000)
    zone: list[tuple[Finite, Finite]] | None = Field(default=None, min_length=3, max_length=256)
    kind: Literal["bounded", "gaussian"] | None = None
    sigma: Annotated[float, Field(ge=0, le=1.0)] | None = None  # [m]
    yaw_sigma: Annotated[float, Field(ge=0, le=math.pi)] | None = None  # [rad]
    arrivals: Annotated[int, Field(ge=0)] | None = Field(
        default=None, description="recorded arrivals a fitted model rests on"
    )

    @model_validator(mode="after")
    def _where(self) -> StationError:
        if (self.trays is None) == (self.zone is None):
            raise ValueError("give either trays (a tray group) or zone (a polygon), not both")
        if self.zone is not None and not Polygon(self.zone).is_valid:
            raise ValueError("zone must be a simple polygon")
        if self.covariance is not None and self.kind == "bounded":
            raise ValueError("a covariance needs kind 'gaussian'")
        return self


class ErrorModel(_Positioning):
    """Base positioning error: bounded disc of radius sigma, or Gaussian with mean error sigma
    (or the given covariance), offset by ``mean``; per station where ``stations`` says so."""

    kind: Literal["bounded", "gaussian"] = "gaussian"
    yaw_sigma: Annotated[float, Field(ge=0, le=math.pi)] = 0.0  # [rad]
    stations: list[StationError] = Field(default_factory=list, max_length=256)

    @model_validator(mode="after")
    def _kinds(self) -> ErrorModel:
        if self.covariance is not None and self.kind == "bounded":
            raise ValueError("a covariance needs kind 'gaussian'")
        names = [s.name for s in self.stations]
        if len(set(names)) != len(names):
            raise ValueError("station names must be unique")
        for i, st in enumerate(self.stations):
            if st.covariance is not None and (st.kind or self.kind) == "bounded":
                raise ValueError(f"stations.{i}: a covariance needs kind 'gaussian'")
        return self

    @model_serializer(mode="wrap")
    def _compact(self, handler: Any) -> dict[str, Any]:
        out = handler(self)
        for k, default in _ADDED.items():
            if k in out and _same(out[k], default):
                del out[k]
        return out


def _same(value: Any, default: Any) -> bool:
    if isinstance(value, list | tuple) and isinstance(default, list | tuple):
        return list(value) == list(default)
    return bool(value == default)


class FailureModel(_Strict):
    """What a failed arrival costs (a stop where some pick is impossible from where the base
    landed): the base re-localises and re-docks, landing anew, up to ``retries`` times, then
    an operator is called, who sets the base where it picks (:mod:`pickstop.sequence.failure`)."""

    relocalise_time: NonNegative = 5.0  # [s] per retry
    redock_time: NonNegative = 10.0  # [s] per retry: back off and dock again
    retries: Annotated[int, Field(ge=0, le=10)] = 2
    operator_time: NonNegative = 300.0  # [s] an operator's call after the last retry


MAX_ORDERS = 1000  # orders a scene document may carry (the API's limit is lower)


class Order(_Strict):
    """One product of a mix: the trays it needs (or the parts: each brings its tray) and
    how often it is made (``weight``, e.g. per shift). The scene's ``task`` is the one-order
    case."""

    id: Ident
    name: str = ""
    trays: list[Ident] | None = None
    parts: list[Ident] | None = None
    weight: Annotated[float, Field(gt=0, allow_inf_nan=False)] = 1.0

    @model_validator(mode="after")
    def _needs_something(self) -> Order:
        if not (self.trays or self.parts):
            raise ValueError("an order needs at least one tray or part")
        return self


class LayoutZone(_Strict):
    """An area of the floor plane where trays may be placed when a layout is searched: a
    tray that may move goes only where its outline lies within a zone that admits it."""

    id: Ident
    name: str = ""
    outline: Annotated[list[tuple[Finite, Finite]], Field(min_length=3, max_length=256)]
    trays: list[Ident] | None = None  # the trays it admits (default: every tray)


class Scene(_Strict):
    format: Literal["pickstop.scene"] = "pickstop.scene"
    version: Literal[1] = 1
    name: Name = ""
    description: Text = ""
    floor: Extent
    # Every robot link, the hand's included, keeps this far above the floor [m].
    floor_clearance: Annotated[float, Field(ge=0, le=MAX_CLEARANCE)] = FLOOR_CLEARANCE
    robot: RobotRef = RobotRef()
    gripper: Gripper = Gripper()
    obstacles: list[Obstacle] = Field(default_factory=list)
    trays: list[Tray] = Field(min_length=1)
    task: list[Ident] | None = None  # trays the task needs (default: all)
    base_yaw: YawPolicy = YawPolicy()
    base_grid: BaseGrid = BaseGrid()
    start: BasePose
    goal: BasePose
    sigma: Annotated[float, Field(ge=0, le=1.0)] = defaults.SIGMA  # base positioning error [m]
    error_model: ErrorModel = ErrorModel()
    motion: Motion = Motion()
    failure: FailureModel = FailureModel()
    # the product mix: each order's trays planned on this one layout
    orders: Annotated[list[Order], Field(max_length=MAX_ORDERS)] | None = None
    # where trays may go when a layout is searched (default: anywhere on their supports)
    zones: Annotated[list[LayoutZone], Field(max_length=64)] | None = None

    @model_validator(mode="after")
    def _station_trays(self) -> Scene:
        known = {t.id for t in self.trays}
        for i, st in enumerate(self.error_model.stations):
            missing = [t for t in st.trays or [] if t not in known]
            if missing:
                raise ValueError(
                    f"error_model.stations.{i}.trays: no tray {', '.join(missing)} in the scene"
                )
        return self

    @property
    def grid_extent(self) -> Extent:
        return self.base_grid.extent or self.floor

    def tray(self, tray_id: str) -> Tray:
        for t in self.trays:
            if t.id == tray_id:
                return t
        raise KeyError(tray_id)

    @property
    def task_trays(self) -> list[str]:
        return list(self.task) if self.task is not None else [t.id for t in self.trays]

    def order_trays(self, order: Order) -> list[str]:
        """The trays ``order`` needs: its trays, then the tray of each of its parts, each once
        (unknown ids are left out: the scene checks name them)."""
        of_part = {p.id: t.id for t in self.trays for p in t.parts}
        known = {t.id for t in self.trays}
        listed = [t for t in order.trays or [] if t in known]
        listed += [of_part[p] for p in order.parts or [] if p in of_part]
        return list(dict.fromkeys(listed))


def resolve_mesh_paths(
    data: Any, root: Path, allowed: list[Path] | None = None, source: str = "scene"
) -> Any:
    """A copy of a scene document whose mesh paths are absolute (relative ones start at
    ``root``); with ``allowed``, a mesh outside those folders is refused, as is a missing one."""
    if not isinstance(data, dict):
        return data
    out = json.loads(json.dumps(data))
    problems: list[tuple[str, str]] = []

    def fix(geom: Any, loc: str) -> None:
        if not isinstance(geom, dict) or geom.get("shape") != "mesh":
            return
        ref = geom.get("path")
        if not isinstance(ref, str) or not ref:
            return  # the schema check names it
        p = Path(ref)
        p = (p if p.is_absolute() else root / p).resolve()
        if allowed is not None and not any(p.is_relative_to(a.resolve()) for a in allowed):
            problems.append((f"{loc}.path", f"mesh {ref!r} lies outside the allowed folders"))
        elif not p.is_file():
            problems.append((f"{loc}.path", f"mesh file {ref!r} not found"))
        geom["path"] = str(p)

    for i, ob in enumerate(out.get("obstacles") or []):
        if isinstance(ob, dict):
            fix(ob.get("geometry"), f"obstacles.{i}.geometry")
    for i, tray in enumerate(out.get("trays") or []):
        for k, part in enumerate((tray or {}).get("parts") or [] if isinstance(tray, dict) else []):
            if isinstance(part, dict):
                fix(part.get("geometry"), f"trays.{i}.parts.{k}.geometry")
    if problems:
        raise SceneError(problems, source)
    return out


def scene_json_schema() -> dict[str, Any]:
    """The published JSON Schema of the scene format."""
    schema = Scene.model_json_schema()
    schema["$id"] = f"https://pickstop.dev/schema/scene-v{VERSION}.json"
    schema["title"] = "PickStop scene"
    return schema
