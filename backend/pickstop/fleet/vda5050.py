"""VDA 5050 messages (order, state, connection, instant actions), versions 2.0.0, 2.1.0 and
3.0.0, as pydantic models.

Written from the published JSON schemas (vendored in ``schemas/``; a test compares every
field, required set, enum and number range with them). Attributes are snake_case, the wire
names are the schema's camelCase aliases: dump with ``by_alias=True, exclude_none=True``.
Units: metres, seconds, radians, in the map frame of ``mapId``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.alias_generators import to_camel

PI_THETA = 3.14159265359  # the schemas' bound on theta and orientation
PI_DEV = 3.141592654  # the schemas' bound on allowedDeviationTheta
HALF_PI = 1.570796327

VersionName = Literal["2.0.0", "2.1.0", "3.0.0"]
VERSIONS: dict[str, VersionName] = {
    "2.0": "2.0.0",
    "2.0.0": "2.0.0",
    "2.1": "2.1.0",
    "2.1.0": "2.1.0",
    "3.0": "3.0.0",
    "3.0.0": "3.0.0",
}

Theta = Annotated[float, Field(ge=-PI_THETA, le=PI_THETA)]
NonNeg = Annotated[float, Field(ge=0)]
SeqId = Annotated[int, Field(ge=0)]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]


class _Msg(BaseModel):
    """Wire names are camelCase; unknown fields are refused (orders we write must be exact)."""

    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True, extra="forbid")


class _In(_Msg):
    """Messages we read from vehicles: fields newer than ours are ignored, not refused."""

    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True, extra="ignore")


# -- shared by every version --------------------------------------------------------------------
class ActionParameter(_Msg):
    key: str
    value: list[Any] | bool | int | float | str | dict[str, Any]


class ControlPoint21(_Msg):
    x: float
    y: float
    weight: NonNeg | None = None


class ControlPoint(_Msg):
    x: float
    y: float
    weight: float | None = None


class Corridor21(_Msg):
    left_width: NonNeg
    right_width: NonNeg
    corridor_ref_point: Literal["KINEMATICCENTER", "CONTOUR"] | None = None


class Header(_Msg):
    header_id: int
    timestamp: str  # ISO 8601, UTC, "YYYY-MM-DDTHH:mm:ss.fffZ"
    version: str
    manufacturer: str
    serial_number: str


# -- 2.1.0 order -----------------------------------------------------------------------------------
class Action21(_Msg):
    action_type: str
    action_id: str
    action_description: str | None = None
    blocking_type: Literal["NONE", "SOFT", "HARD"]
    action_parameters: list[ActionParameter] | None = None


class NodePosition21(_Msg):
    x: float
    y: float
    theta: Theta | None = None
    allowed_deviation_xy: NonNeg | None = Field(default=None, alias="allowedDeviationXY")
    allowed_deviation_theta: Annotated[float, Field(ge=-PI_DEV, le=PI_DEV)] | None = None
    map_id: str
    map_description: str | None = None


class Node21(_Msg):
    node_id: str
    sequence_id: SeqId
    node_description: str | None = None
    released: bool
    node_position: NodePosition21 | None = None
    actions: list[Action21]


class Trajectory21(_Msg):
    degree: Annotated[int, Field(ge=1)]
    knot_vector: list[Unit]
    control_points: list[ControlPoint21]


class Edge21(_Msg):
    edge_id: str
    sequence_id: SeqId
    edge_description: str | None = None
    released: bool
    start_node_id: str
    end_node_id: str
    max_speed: float | None = None
    max_height: float | None = None
    min_height: float | None = None
    orientation: Theta | None = None
    orientation_type: str | None = None  # "GLOBAL" or "TANGENTIAL" (not an enum in 2.1)
    direction: str | None = None
    rotation_allowed: bool | None = None
    max_rotation_speed: float | None = None
    length: float | None = None
    trajectory: Trajectory21 | None = None
    corridor: Corridor21 | None = None
    actions: list[Action21]


class Order21(Header):
    order_id: str
    order_update_id: SeqId
    zone_set_id: str | None = None
    nodes: list[Node21]
    edges: list[Edge21]


# -- 2.0.0 order (2.1.0 less the corridor; allowedDeviationTheta >= 0; an orientationType enum) --
class NodePosition20(_Msg):
    x: float
    y: float
    theta: Theta | None = None
    allowed_deviation_xy: NonNeg | None = Field(default=None, alias="allowedDeviationXY")
    allowed_deviation_theta: Annotated[float, Field(ge=0, le=PI_DEV)] | None = None
    map_id: str
    map_description: str | None = None


class Node20(_Msg):
    node_id: str
    sequence_id: SeqId
    node_description: str | None = None
    released: bool
    node_position: NodePosition20 | None = None
    actions: list[Action21]


class Trajectory20(_Msg):
    degree: int
    knot_vector: list[Unit]
    control_points: list[ControlPoint21]


class Edge20(_Msg):
    edge_id: str
    sequence_id: SeqId
    edge_description: str | None = None
    released: bool
    start_node_id: str
    end_node_id: str
    max_speed: float | None = None
    max_height: float | None = None
    min_height: float | None = None
    orientation: Theta | None = None
    orientation_type: Literal["GLOBAL", "TANGENTIAL"] | None = None
    direction: str | None = None
    rotation_allowed: bool | None = None
    max_rotation_speed: float | None = None
    length: float | None = None
    trajectory: Trajectory20 | None = None
    actions: list[Action21]


class Order20(Header):
    order_id: str
    order_update_id: SeqId
    zone_set_id: str | None = None
    nodes: list[Node20]
    edges: list[Edge20]


# -- 3.0.0 order -----------------------------------------------------------------------------------
BlockingType30 = Literal["NONE", "SOFT", "SINGLE", "HARD"]


class Action30(_Msg):
    action_type: str
    action_id: str
    action_descriptor: str | None = None
    blocking_type: BlockingType30
    action_parameters: list[ActionParameter] | None = None
    retriable: bool | None = None


class DeviationEllipse(_Msg):
    """3.0's allowed deviation: an ellipse with half axes a, b [m] turned by theta [rad]."""

    a: NonNeg
    b: NonNeg
    theta: Annotated[float, Field(ge=-HALF_PI, le=HALF_PI)]


class NodePosition30(_Msg):
    x: float
    y: float
    theta: Theta | None = None
    allowed_deviation_xy: DeviationEllipse | None = Field(default=None, alias="allowedDeviationXY")
    allowed_deviation_theta: Annotated[float, Field(ge=0, le=PI_DEV)] | None = None
    map_id: str


class Node30(_Msg):
    node_id: str
    sequence_id: SeqId
    node_descriptor: str | None = None
    released: bool
    node_position: NodePosition30 | None = None
    actions: list[Action30]


class Trajectory30(_Msg):
    degree: Annotated[int, Field(ge=1)] | None = None
    knot_vector: list[Unit] | None = None
    control_points: list[ControlPoint]


class Corridor30(_Msg):
    left_width: NonNeg
    right_width: NonNeg
    corridor_reference_point: Literal["KINEMATIC_CENTER", "CONTOUR"] | None = None
    release_required: bool | None = None
    release_loss_behavior: Literal["STOP", "RETURN"] | None = None


class Edge30(_Msg):
    edge_id: str
    sequence_id: SeqId
    edge_descriptor: str | None = None
    released: bool
    maximum_speed: float | None = None
    maximum_mobile_robot_height: float | None = None
    minimum_load_handling_device_height: float | None = None
    orientation: Theta | None = None
    orientation_type: Literal["GLOBAL", "TANGENTIAL"] | None = None
    direction: str | None = None
    reach_orientation_before_entering: bool | None = None
    max_rotation_speed: float | None = None
    trajectory: Trajectory30 | None = None
    length: float | None = None
    corridor: Corridor30 | None = None
    actions: list[Action30]


class Order30(Header):
    order_id: str
    order_update_id: SeqId
    order_description: str | None = None
    nodes: list[Node30]
    edges: list[Edge30]


# -- 2.1.0 state -----------------------------------------------------------------------------------
ActionStatus21 = Literal["WAITING", "INITIALIZING", "RUNNING", "FINISHED", "FAILED"]


class MapState21(_In):
    map_id: str
    map_version: str
    map_description: str | None = None
    map_status: Literal["ENABLED", "DISABLED"]


class NodeStatePosition(_In):
    x: float
    y: float
    theta: float | None = None
    map_id: str


class NodeState21(_In):
    node_id: str
    sequence_id: int
    node_description: str | None = None
    released: bool
    node_position: NodeStatePosition | None = None


class StateTrajectory21(_In):
    degree: int
    knot_vector: list[Unit]
    control_points: list[ControlPoint]


class EdgeState21(_In):
    edge_id: str
    sequence_id: int
    edge_description: str | None = None
    released: bool
    trajectory: StateTrajectory21 | None = None


class AgvPosition(_In):
    x: float
    y: float
    theta: float
    map_id: str
    map_description: str | None = None
    position_initialized: bool
    localization_score: Unit | None = None
    deviation_range: float | None = None


class Velocity(_In):
    vx: float | None = None
    vy: float | None = None
    omega: float | None = None


class BoundingBoxReference(_In):
    x: float
    y: float
    z: float
    theta: float | None = None


class LoadDimensions21(_In):
    length: float
    width: float
    height: float | None = None


class Load21(_In):
    load_id: str | None = None
    load_type: str | None = None
    load_position: str | None = None
    bounding_box_reference: BoundingBoxReference | None = None
    load_dimensions: LoadDimensions21 | None = None
    weight: NonNeg | None = None


class ActionState21(_In):
    action_id: str
    action_type: str | None = None
    action_description: str | None = None
    action_status: ActionStatus21
    result_description: str | None = None


class BatteryState(_In):
    battery_charge: float
    battery_voltage: float | None = None
    battery_health: Annotated[float, Field(ge=0, le=100)] | None = None
    charging: bool
    reach: NonNeg | None = None


class Reference(_In):
    reference_key: str
    reference_value: str


class Error21(_In):
    error_type: str
    error_references: list[Reference] | None = None
    error_description: str | None = None
    error_hint: str | None = None
    error_level: Literal["WARNING", "FATAL"]


class InfoReference(_In):
    reference_key: str
    reference_value: str


class Info21(_In):
    info_type: str
    info_references: list[InfoReference] | None = None
    info_description: str | None = None
    info_level: Literal["INFO", "DEBUG"]


class SafetyState21(_In):
    e_stop: Literal["AUTOACK", "MANUAL", "REMOTE", "NONE"]
    field_violation: bool


class State21(Header, _In):
    model_config = _In.model_config
    maps: list[MapState21] | None = None
    order_id: str
    order_update_id: int
    zone_set_id: str | None = None
    last_node_id: str
    last_node_sequence_id: int
    driving: bool
    paused: bool | None = None
    new_base_request: bool | None = None
    distance_since_last_node: float | None = None
    operating_mode: Literal["AUTOMATIC", "SEMIAUTOMATIC", "MANUAL", "SERVICE", "TEACHIN"]
    node_states: list[NodeState21]
    edge_states: list[EdgeState21]
    agv_position: AgvPosition | None = None
    velocity: Velocity | None = None
    loads: list[Load21] | None = None
    action_states: list[ActionState21]
    battery_state: BatteryState
    errors: list[Error21]
    information: list[Info21] | None = None
    safety_state: SafetyState21


# -- 2.0.0 state -----------------------------------------------------------------------------------
ActionStatus20 = Literal["WAITING", "INITIALIZING", "RUNNING", "PAUSED", "FINISHED", "FAILED"]


class NodeStatePosition20(_In):
    x: float
    y: float
    theta: float | None = None
    allowed_deviation_xy: float | None = Field(default=None, alias="allowedDeviationXY")
    allowed_deviation_theta: float | None = None
    map_id: str
    map_description: str | None = None


class NodeState20(_In):
    node_id: str
    sequence_id: int
    node_description: str | None = None
    node_position: NodeStatePosition20 | None = None
    released: bool


class StateTrajectory20(_In):
    degree: Annotated[float, Field(ge=1)] | None = None
    knot_vector: list[Unit]
    control_points: list[ControlPoint]


class EdgeState20(_In):
    edge_id: str
    sequence_id: int
    edge_description: str | None = None
    released: bool
    trajectory: StateTrajectory20 | None = None


class ActionState20(_In):
    action_id: str
    action_type: str | None = None
    action_description: str | None = None
    action_status: ActionStatus20
    result_description: str | None = None


class BatteryState20(_In):
    battery_charge: float
    battery_voltage: float | None = None
    battery_health: Annotated[int, Field(ge=0, le=100)] | None = None
    charging: bool
    reach: NonNeg | None = None


class Error20(_In):
    error_type: str
    error_references: list[Reference] | None = None
    error_description: str | None = None
    error_level: Literal["WARNING", "FATAL"]


class State20(Header, _In):
    model_config = _In.model_config
    order_id: str
    order_update_id: int
    zone_set_id: str | None = None
    last_node_id: str
    last_node_sequence_id: int
    driving: bool
    paused: bool | None = None
    new_base_request: bool | None = None
    distance_since_last_node: float | None = None
    operating_mode: Literal["AUTOMATIC", "SEMIAUTOMATIC", "MANUAL", "SERVICE", "TEACHIN"]
    node_states: list[NodeState20]
    edge_states: list[EdgeState20]
    agv_position: AgvPosition | None = None
    velocity: Velocity | None = None
    loads: list[Load21] | None = None
    action_states: list[ActionState20]
    battery_state: BatteryState20
    errors: list[Error20]
    information: list[Info21] | None = None
    safety_state: SafetyState21


# -- 3.0.0 state -----------------------------------------------------------------------------------
ActionStatus30 = Literal[
    "WAITING", "INITIALIZING", "RUNNING", "PAUSED", "RETRIABLE", "FINISHED", "FAILED"
]
RequestStatus = Literal["REQUESTED", "GRANTED", "REVOKED", "EXPIRED"]


class MapState30(_In):
    map_id: str
    map_version: str
    map_descriptor: str | None = None
    map_status: Literal["ENABLED", "DISABLED"]


class ZoneSetState(_In):
    zone_set_id: str
    map_id: str
    zone_set_status: Literal["ENABLED", "DISABLED"]


class NodeStatePosition30(_In):
    x: float
    y: float
    theta: Theta | None = None
    map_id: str


class NodeState30(_In):
    node_id: str
    sequence_id: int
    node_descriptor: str | None = None
    released: bool
    node_position: NodeStatePosition30 | None = None


class EdgeState30(_In):
    edge_id: str
    sequence_id: int
    edge_descriptor: str | None = None
    released: bool
    trajectory: Trajectory30 | None = None


class PlannedPath(_In):
    trajectory: Trajectory30
    traversed_nodes: list[str] | None = None


class PolylinePoint(_In):
    x: float
    y: float
    theta: Theta | None = None
    eta: str


class IntermediatePath(_In):
    polyline: list[PolylinePoint]


class MobileRobotPosition(_In):
    x: float
    y: float
    theta: Theta
    map_id: str
    localized: bool
    localization_score: Unit | None = None
    deviation_range: NonNeg | None = None


class LoadDimensions30(_In):
    length: NonNeg
    width: NonNeg
    height: NonNeg | None = None


class Load30(_In):
    load_id: str | None = None
    load_type: str | None = None
    load_position: str | None = None
    bounding_box_reference: BoundingBoxReference | None = None
    load_dimensions: LoadDimensions30 | None = None
    weight: NonNeg | None = None


class ZoneRequest(_In):
    request_id: str
    request_type: Literal["ACCESS", "REPLANNING"]
    zone_id: str
    zone_set_id: str
    request_status: RequestStatus
    trajectory: Trajectory30 | None = None


class EdgeRequest(_In):
    request_id: str
    request_type: Literal["CORRIDOR"]
    edge_id: str
    sequence_id: int
    request_status: RequestStatus


class ActionState30(_In):
    action_id: str
    action_type: str | None = None
    action_descriptor: str | None = None
    action_status: ActionStatus30
    action_result: str | None = None


Percent = Annotated[float, Field(ge=0, le=100)]


class PowerSupply(_In):
    state_of_charge: Percent
    battery_voltage: float | None = None
    battery_current: float | None = None
    battery_health: Percent | None = None
    charging: bool
    range: NonNeg | None = None


class Translation(_In):
    translation_key: str
    translation_value: str


class Error30(_In):
    error_type: str
    error_references: list[Reference] | None = None
    error_description: str | None = None
    error_description_translations: list[Translation] | None = None
    error_hint: str | None = None
    error_hint_translations: list[Translation] | None = None
    error_level: Literal["WARNING", "URGENT", "CRITICAL", "FATAL"]


class Info30(_In):
    info_type: str
    info_references: list[InfoReference] | None = None
    info_descriptor: str | None = None
    info_level: Literal["INFO", "DEBUG"]


class SafetyState30(_In):
    active_emergency_stop: Literal["MANUAL", "REMOTE", "NONE"]
    field_violation: bool


class State30(Header, _In):
    model_config = _In.model_config
    maps: list[MapState30] | None = None
    zone_sets: list[ZoneSetState] | None = None
    order_id: str
    order_update_id: int
    last_node_id: str
    last_node_sequence_id: int
    node_states: list[NodeState30]
    edge_states: list[EdgeState30]
    planned_path: PlannedPath | None = None
    intermediate_path: IntermediatePath | None = None
    mobile_robot_position: MobileRobotPosition | None = None
    velocity: Velocity | None = None
    loads: list[Load30] | None = None
    driving: bool
    paused: bool | None = None
    new_base_request: bool | None = None
    zone_requests: list[ZoneRequest] | None = None
    edge_requests: list[EdgeRequest] | None = None
    distance_since_last_node: float | None = None
    action_states: list[ActionState30]
    instant_action_states: list[ActionState30]
    zone_action_states: list[ActionState30] | None = None
    power_supply: PowerSupply
    operating_mode: Literal[
        "STARTUP", "AUTOMATIC", "SEMIAUTOMATIC", "INTERVENED", "MANUAL", "SERVICE", "TEACH_IN"
    ]
    errors: list[Error30]
    information: list[Info30] | None = None
    safety_state: SafetyState30


# -- connection (every version) --------------------------------------------------------------------
# -- instant actions (the factsheet request) ----------------------------------------------------
class InstantActions2(Header):
    """2.0.0 and 2.1.0 (the same message)."""

    actions: list[Action21]


class InstantAction30(_Msg):
    action_type: str
    action_id: str
    action_descriptor: str | None = None
    blocking_type: Literal["NONE"]
    action_parameters: list[ActionParameter] | None = None


class InstantActions30(Header):
    actions: list[InstantAction30]


class Connection21(Header):
    connection_state: Literal["ONLINE", "OFFLINE", "CONNECTIONBROKEN"]


class Connection30(Header):
    connection_state: Literal["ONLINE", "OFFLINE", "HIBERNATING", "CONNECTION_BROKEN"]


#: the last-will state of each version (the broker publishes it when the vehicle drops)
BROKEN = {"2.0.0": "CONNECTIONBROKEN", "2.1.0": "CONNECTIONBROKEN", "3.0.0": "CONNECTION_BROKEN"}

Order = Order20 | Order21 | Order30
State = State20 | State21 | State30
ORDER_MODELS: dict[str, type[Order20] | type[Order21] | type[Order30]] = {
    "2.0.0": Order20,
    "2.1.0": Order21,
    "3.0.0": Order30,
}
STATE_MODELS: dict[str, type[State20] | type[State21] | type[State30]] = {
    "2.0.0": State20,
    "2.1.0": State21,
    "3.0.0": State30,
}
CONNECTION_MODELS: dict[str, type[Connection21] | type[Connection30]] = {
    "2.0.0": Connection21,  # the same message as 2.1.0
    "2.1.0": Connection21,
    "3.0.0": Connection30,
}
INSTANT_MODELS: dict[str, type[InstantActions2] | type[InstantActions30]] = {
    "2.0.0": InstantActions2,
    "2.1.0": InstantActions2,
    "3.0.0": InstantActions30,
}


def v3(version: str) -> bool:
    """3.x names (``actionDescriptor``, ``maximumSpeed``, an ellipse for ``allowedDeviationXY``)."""
    return version.startswith("3.")


def minor(version: str) -> tuple[int, int]:
    """``"2.1.0" -> (2, 1)``; a version that is not ``MAJOR.MINOR[.PATCH]`` gives ``(0, 0)``."""
    try:
        a, b = version.split(".")[:2]
        return int(a), int(b)
    except ValueError:
        return (0, 0)


def major(version: str) -> str:
    """The topic's version level: ``"2.1.0" -> "v2"``."""
    return "v" + version.split(".")[0]


def dump(msg: BaseModel) -> dict[str, Any]:
    """The wire form of a message (camelCase, unset optional fields left out)."""
    return msg.model_dump(mode="json", by_alias=True, exclude_none=True)
