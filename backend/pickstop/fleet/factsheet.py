"""A vehicle's factsheet (VDA 5050 2.0.0 and later): what it says it executes, and whether an
order asks for anything else.

Read leniently (only what is checked; 3.0's names ``mobileRobotActions`` and
``maximumArrayLengths`` as well as 2.x's ``agvActions`` and ``maxArrayLens``) into
:class:`Capabilities`. :func:`check_order` lists every reason the vehicle cannot run an order:
an action type it does not list (or not on nodes), a parameter the order sends that the action
does not list, one it requires that the order lacks, a value of another data type, a blocking
type it does not list, more nodes, edges, actions or parameters than its protocol limits, an
order of a newer protocol version than the vehicle's. Empty: the order may be sent.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError
from pydantic.alias_generators import to_camel

from pickstop.errors import InputError
from pickstop.fleet import vda5050 as v


class _In(BaseModel):
    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True, extra="ignore")


class _Param(_In):
    key: str
    value_data_type: str
    is_optional: bool | None = None


class _Action(_In):
    action_type: str
    action_scopes: list[str]
    action_parameters: list[_Param] | None = None
    blocking_types: list[str] | None = None


class _Optional(_In):
    parameter: str
    support: str


class _Features(_In):
    optional_parameters: list[_Optional] = Field(default_factory=list)
    agv_actions: list[_Action] | None = None  # 2.x
    mobile_robot_actions: list[_Action] | None = None  # 3.0


class _Type(_In):
    series_name: str | None = None


class _Limits(_In):
    max_array_lens: dict[str, Any] | None = None  # 2.x
    maximum_array_lengths: dict[str, Any] | None = None  # 3.0


class _Factsheet(_In):
    version: str
    manufacturer: str
    serial_number: str
    type_specification: _Type = _Type()
    protocol_limits: _Limits = _Limits()
    protocol_features: _Features


@dataclass(frozen=True)
class ActionSpec:
    scopes: frozenset[str]
    parameters: dict[str, tuple[str, bool]]  # key -> (valueDataType, optional)
    blocking_types: frozenset[str] | None  # None: not stated


@dataclass(frozen=True)
class Capabilities:
    """What a factsheet says, as checked here."""

    version: str
    manufacturer: str
    serial_number: str
    series_name: str | None
    actions: dict[str, ActionSpec]
    limits: dict[str, int]  # "order.nodes", "node.actions", ...: 0 or absent means no limit
    required: tuple[str, ...]  # optional parameters the vehicle needs (support REQUIRED)


def read(doc: Any) -> Capabilities:
    """A factsheet message -> :class:`Capabilities`; InputError naming the field if unusable."""
    try:
        fs = _Factsheet.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        loc = ".".join(str(p) for p in err["loc"])
        raise InputError(f"factsheet: {loc}: {err['msg']}", field=f"factsheet.{loc}") from None
    feats = fs.protocol_features
    acts = feats.agv_actions if feats.mobile_robot_actions is None else feats.mobile_robot_actions
    lims = fs.protocol_limits.maximum_array_lengths or fs.protocol_limits.max_array_lens or {}
    return Capabilities(
        version=fs.version,
        manufacturer=fs.manufacturer,
        serial_number=fs.serial_number,
        series_name=fs.type_specification.series_name,
        actions={
            a.action_type: ActionSpec(
                frozenset(a.action_scopes),
                {
                    p.key: (p.value_data_type, bool(p.is_optional))
                    for p in a.action_parameters or []
                },
                None if a.blocking_types is None else frozenset(a.blocking_types),
            )
            for a in acts or []
        },
        limits={k: int(n) for k, n in lims.items() if isinstance(n, int) and n > 0},
        required=tuple(o.parameter for o in feats.optional_parameters if o.support == "REQUIRED"),
    )


def _fits(value: Any, dtype: str) -> bool:
    """Does ``value`` have the factsheet's ``valueDataType``?"""
    if dtype == "BOOL":
        return isinstance(value, bool)
    if dtype == "INTEGER":
        return isinstance(value, int) and not isinstance(value, bool)
    if dtype in ("NUMBER", "FLOAT"):
        return isinstance(value, int | float) and not isinstance(value, bool)
    kinds = {"STRING": str, "ARRAY": list, "OBJECT": dict}
    return isinstance(value, kinds[dtype]) if dtype in kinds else True


def _action_problems(caps: Capabilities, a: Any, scope: str) -> list[str]:
    spec = caps.actions.get(a.action_type)
    if spec is None:
        listed = ", ".join(sorted(caps.actions)) or "none"
        return [f"the vehicle's factsheet lists no action {a.action_type!r} (it lists: {listed})"]
    out = []
    if scope not in spec.scopes:
        out.append(
            f"action {a.action_type!r} is not allowed on {scope.lower()}s "
            f"(scopes: {', '.join(sorted(spec.scopes))})"
        )
    if spec.blocking_types is not None and a.blocking_type not in spec.blocking_types:
        out.append(
            f"action {a.action_type!r}: blocking type {a.blocking_type} is not one of "
            f"{', '.join(sorted(spec.blocking_types))}"
        )
    sent = {p.key: p.value for p in a.action_parameters or []}
    for key, value in sent.items():
        if key not in spec.parameters:
            listed = ", ".join(spec.parameters) or "none"
            out.append(
                f"action {a.action_type!r} has no parameter {key!r} in the vehicle's "
                f"factsheet (it lists: {listed})"
            )
        elif not _fits(value, spec.parameters[key][0]):
            out.append(
                f"parameter {key!r} of action {a.action_type!r} must be "
                f"{spec.parameters[key][0]}, the order sends {type(value).__name__}"
            )
    for key, (_, optional) in spec.parameters.items():
        if not optional and key not in sent:
            out.append(
                f"action {a.action_type!r} requires parameter {key!r}, which the order "
                "does not send"
            )
    return out


def check_order(order: v.Order, caps: Capabilities) -> list[str]:
    """Every reason the vehicle of ``caps`` cannot run ``order`` (each named once)."""
    problems: list[str] = []
    if v.minor(order.version) > v.minor(caps.version):
        problems.append(
            f"the order is VDA 5050 {order.version}, the vehicle speaks "
            f"{caps.version} (its factsheet)"
        )
    counts = {
        "order.nodes": len(order.nodes),
        "order.edges": len(order.edges),
        "node.actions": max((len(n.actions) for n in order.nodes), default=0),
        "edge.actions": max((len(e.actions) for e in order.edges), default=0),
        "actions.actionsParameters": max(
            (len(a.action_parameters or []) for n in order.nodes for a in n.actions), default=0
        ),
    }
    for key, n in counts.items():
        if key in caps.limits and n > caps.limits[key]:
            problems.append(
                f"{key}: the order has {n}, the vehicle takes at most {caps.limits[key]}"
            )
    for scope, items in (("NODE", order.nodes), ("EDGE", order.edges)):
        for item in items:
            for a in item.actions:
                problems += _action_problems(caps, a, scope)
    for name in caps.required:
        if not _carries(order, name):
            problems.append(f"the vehicle requires {name}, which the order does not carry")
    return list(dict.fromkeys(problems))


def _carries(order: v.Order, path: str) -> bool:
    """Does the order set the optional field ``path`` (``order.edges.trajectory``) anywhere?"""
    doc: Any = v.dump(order)
    parts = path.split(".")
    if parts and parts[0] == "order":
        parts = parts[1:]
    level = [doc]
    for p in parts:
        nxt = []
        for d in level:
            if isinstance(d, dict) and p in d:
                x = d[p]
                nxt += x if isinstance(x, list) else [x]
        level = nxt
    return bool(level)


# -- a factsheet to publish (the simulated vehicle's) ----------------------------------------------
#: data types of PickStop's pick values, as a factsheet names them
VALUE_TYPES = {
    "stopIndex": "INTEGER",
    "trayId": "STRING",
    "partId": "STRING",
    "graspIndex": "INTEGER",
    "jointNames": "ARRAY",
    "jointPositions": "ARRAY",
}
OPTIONAL_SENT = (
    "order.nodes.nodePosition.theta",
    "order.nodes.nodePosition.allowedDeviationXY",
    "order.nodes.nodePosition.allowedDeviationTheta",
    "order.edges.orientation",
    "order.edges.length",
)


def _dtype(value: Any) -> str:
    if isinstance(value, bool):
        return "BOOL"
    if isinstance(value, int):
        return "INTEGER"
    return "NUMBER" if isinstance(value, float) else "STRING"


def pick_spec(pick: Any) -> dict[str, Any]:
    """A factsheet action entry of a :class:`~pickstop.fleet.vehicle_types.PickAction`."""
    params = [{"key": k, "valueDataType": VALUE_TYPES[val]} for k, val in pick.parameters.items()]
    params += [{"key": k, "valueDataType": _dtype(c)} for k, c in pick.constants.items()]
    return {"actionType": pick.action_type, "actionScopes": ["NODE"],
            "actionParameters": params}  # fmt: skip


@dataclass(frozen=True)
class Body:
    """What a factsheet states of the vehicle's body and drive [m, m/s, m/s^2]."""

    series_name: str = "pickstop-sim"
    max_speed: float = 0.5
    max_acceleration: float = 0.5
    width: float = 0.6
    length: float = 0.6
    height: float = 1.5
    omnidirectional: bool = False


def describe(
    version: str, manufacturer: str, serial: str, actions: list[dict[str, Any]], body: Body,
    header_id: int = 0, stamp: str = "1970-01-01T00:00:00.000Z",
) -> dict[str, Any]:  # fmt: skip
    """A factsheet message of ``version`` listing ``actions`` (node actions as
    :func:`pick_spec` makes them) and the instant ``factsheetRequest``."""
    request = {"actionType": "factsheetRequest", "actionScopes": ["INSTANT"]}
    optional = [{"parameter": p, "support": "SUPPORTED"} for p in OPTIONAL_SENT]
    head = {"headerId": header_id, "timestamp": stamp, "version": version,
            "manufacturer": manufacturer, "serialNumber": serial}  # fmt: skip
    b = body
    if v.v3(version):
        acts = [{**a, "pauseAllowed": False, "cancelAllowed": False} for a in [*actions, request]]
        return head | {
            "typeSpecification": {
                "seriesName": b.series_name, "mobileRobotKinematics":
                "OMNI" if b.omnidirectional else "DIFF", "mobileRobotClass": "CARRIER",
                "maximumLoadMass": 0.0, "localizationTypes": ["NATURAL"],
                "navigationTypes": ["AUTONOMOUS"]},
            "physicalParameters": {
                "minimumSpeed": 0.0, "maximumSpeed": b.max_speed,
                "maximumAcceleration": b.max_acceleration,
                "maximumDeceleration": b.max_acceleration, "minimumHeight": b.height,
                "maximumHeight": b.height, "width": b.width, "length": b.length},
            "protocolLimits": {"maximumStringLengths": {}, "maximumArrayLengths": {},
                               "timing": {"minimumOrderInterval": 0.0,
                                          "minimumStateInterval": 0.0}},
            "protocolFeatures": {"optionalParameters": optional, "mobileRobotActions": acts},
            "mobileRobotGeometry": {},
            "loadSpecification": {},
        }  # fmt: skip
    return head | {
        "typeSpecification": {
            "seriesName": b.series_name, "agvKinematic": "OMNI" if b.omnidirectional else "DIFF",
            "agvClass": "CARRIER", "maxLoadMass": 0.0, "localizationTypes": ["NATURAL"],
            "navigationTypes": ["AUTONOMOUS"]},
        "physicalParameters": {
            "speedMin": 0.0, "speedMax": b.max_speed, "accelerationMax": b.max_acceleration,
            "decelerationMax": b.max_acceleration, "heightMin": b.height, "heightMax": b.height,
            "width": b.width, "length": b.length},
        "protocolLimits": {"maxStringLens": {}, "maxArrayLens": {},
                           "timing": {"minOrderInterval": 0.0, "minStateInterval": 0.0}},
        "protocolFeatures": {"optionalParameters": optional, "agvActions": [*actions, request]},
        "agvGeometry": {},
        "loadSpecification": {},
    }  # fmt: skip
