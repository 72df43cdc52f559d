"""A simulated VDA 5050 vehicle: drives an order's edges, stops with a positioning error,
performs its picks, and reports it all as state messages.

The core (:class:`SimVehicle`) runs on simulated time: ``advance(dt)`` moves it forward, and
``state()`` is the state message at that instant. Between stops it drives rest to rest along
the nodes it passes at the scene's speed and acceleration (the plan's time model); at a node
with actions it lands at the node plus an error drawn from the scene's error model, docks
(``stop_time``), then runs each ``pick`` (``pick_time``) after checking, from where it really
stopped, that the part is graspable (``check``: the exact pipeline in :mod:`pickstop.fleet.
pickcheck`). A failed pick fails its action with the reason; the order goes on.

With a failure model (``failure``, the scene's, :mod:`pickstop.sequence.failure`) it checks
every pick of a stop when it has docked: if any is impossible from where it landed it
re-localises and re-docks (``retry_time``), landing anew, up to ``retries`` times, then calls an
operator (``operator_time``), who sets it at the node; its picks follow. Each arrival is
recorded (:class:`Arrival`) and reported in the state's ``information``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pickstop.fleet import factsheet as fs
from pickstop.fleet import order as orders
from pickstop.fleet import vda5050 as v
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction
from pickstop.frames import wrap_angle
from pickstop.scene.positioning import ErrorDist, Kind, Positioning
from pickstop.sequence.failure import FailureCosts
from pickstop.sequence.timing import leg_time

REFUSAL_TYPES = ("validationError", "orderError")
INFO_KEPT = 20  # the latest re-docks and operator calls a state reports

#: ``check(tray_id, x, y, yaw) -> (ok, reason)`` at an actual base pose [m, m, rad].
Check = Callable[[str, float, float, float], tuple[bool, str]]
#: ``error(rng, x, y, yaw, trays) -> (dx, dy, dyaw)``: where the base lands relative to a
#: node at ``(x, y, yaw)`` [m, m, rad] whose picks are from ``trays`` (map frame).
ErrorDraw = Callable[
    [np.random.Generator, float, float, float, tuple[str, ...]], tuple[float, float, float]
]


def error_model(positioning: Positioning) -> ErrorDraw:
    """Draws from the model of the node's station (the sampler of the plan's Monte Carlo)."""

    def draw(
        rng: np.random.Generator, x: float, y: float, yaw: float, trays: tuple[str, ...]
    ) -> tuple[float, float, float]:
        dxy, dyaw = positioning.at((x, y), trays).sample(1, rng, yaw)
        return float(dxy[0, 0]), float(dxy[0, 1]), float(dyaw[0])

    return draw


def isotropic(kind: Kind, sigma: float, yaw_sigma: float) -> Positioning:
    """The one model of a plan's parameters: isotropic, unbiased, everywhere."""
    return Positioning(ErrorDist(kind, sigma, yaw_sigma=yaw_sigma))


@dataclass(frozen=True)
class Motion:
    max_speed: float = 0.5  # [m/s]
    max_acceleration: float = 0.5  # [m/s^2]
    stop_time: float = 8.0  # [s]
    pick_time: float = 6.0  # [s]


@dataclass
class Arrival:
    """How a stop's arrival went: did the first landing serve every pick, how many re-docks
    followed, was an operator called."""

    node: str
    first_ok: bool
    retries: int = 0
    operator: bool = False


@dataclass
class _Action:
    id: str
    type: str
    params: dict[str, Any]
    status: str = "WAITING"
    result: str | None = None


@dataclass
class _Node:
    id: str
    seq: int
    x: float
    y: float
    theta: float | None
    deviation: float
    actions: list[_Action]


def _node_of(n: Any) -> _Node:
    """An order's node as the vehicle runs it: position [m] (0 without one), heading [rad] if
    given, allowed deviation [m] (an ellipse's semi-major axis) and its actions, waiting."""
    p = n.node_position
    dev = 0.0 if p is None else p.allowed_deviation_xy
    dev = dev.a if isinstance(dev, v.DeviationEllipse) else float(dev or 0.0)
    return _Node(
        n.node_id,
        n.sequence_id,
        0.0 if p is None else p.x,
        0.0 if p is None else p.y,
        None if p is None else p.theta,
        dev,
        [
            _Action(
                a.action_id,
                a.action_type,
                {q.key: q.value for q in a.action_parameters or []},
            )
            for a in n.actions
        ],
    )


@dataclass
class _Phase:
    kind: str  # "drive", "dock", "redock", "operator", "pick"
    duration: float
    node: int  # the node it ends at / works at
    path: list[tuple[float, float]] = field(default_factory=list)  # drive: from, vias, to
    nodes: list[int] = field(default_factory=list)  # drive: the nodes it passes, in order
    action: int = -1


@dataclass
class SimVehicle:
    manufacturer: str
    serial_number: str
    motion: Motion
    error: ErrorDraw
    check: Check
    rng: np.random.Generator
    version: str = "2.1.0"
    pick: PickAction = DEFAULT_PICK  # how its controller names a pick and its parameters
    body: fs.Body = field(default_factory=fs.Body)
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    map_id: str = "map"
    teleport_to_first_node: bool = True  # place the vehicle at a new order's first node
    #: the node pose error, or None to draw it; tests use it to force a bad stop
    forced_error: tuple[float, float, float] | None = None
    clock: float = 0.0  # [s] simulated
    order_id: str = ""
    order_update_id: int = 0
    header_id: int = 0
    nodes: list[_Node] = field(default_factory=list)
    edges: list[tuple[str, int]] = field(default_factory=list)  # (edgeId, sequenceId)
    last_node: int = -1
    phases: list[_Phase] = field(default_factory=list)
    elapsed: float = 0.0  # [s] into the current phase
    errors: list[dict[str, Any]] = field(default_factory=list)
    started_at: float = 0.0
    finished_at: float | None = None
    stopped_at: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    failure: FailureCosts | None = None  # None: no retries, a failed pick fails its action
    arrivals: list[Arrival] = field(default_factory=list)  # this order's, in visiting order
    info: list[dict[str, Any]] = field(default_factory=list)  # the state's information

    # -- the factsheet -----------------------------------------------------------------------------
    def factsheet(self, header_id: int = 0) -> dict[str, Any]:
        """Its factsheet message: the pick as its controller names it, its body and drive."""
        return fs.describe(
            self.version, self.manufacturer, self.serial_number, [fs.pick_spec(self.pick)],
            self.body, header_id, orders.timestamp(),
        )  # fmt: skip

    # -- orders ----------------------------------------------------------------------------------
    def accept(self, doc: dict[str, Any]) -> bool:
        """Take an order message; False (with an error in the state) if it is refused: an
        order of a newer protocol version, one the version's schema or the standard's rules
        refuse, or one asking for an action or parameter its factsheet does not list."""
        oid = str(doc.get("orderId", "")) if isinstance(doc, dict) else ""
        refs = (("orderId", oid),)
        # an earlier refusal is history once a new order arrives
        self.errors = [e for e in self.errors if e["errorType"] not in REFUSAL_TYPES]
        o = self._validated(doc, refs)
        if o is None:
            return False
        if o.order_id == self.order_id and o.order_update_id <= self.order_update_id:
            return True  # a repeat of the order we run
        self._start(o)
        return True

    def _validated(self, doc: dict[str, Any], refs: tuple[tuple[str, str], ...]) -> v.Order | None:
        """The order model of ``doc``, or None with the refusal in ``errors``: a newer protocol
        version, a schema error, an action its factsheet does not list, or a broken rule of
        the standard (an order without nodes among them)."""
        theirs = str(doc.get("version", "")) if isinstance(doc, dict) else ""
        if v.minor(theirs) > v.minor(self.version):
            text = f"order version {theirs} is not compatible with vehicle version {self.version}"
            self._error("validationError", text, "FATAL", refs)
            return None
        try:
            o = v.ORDER_MODELS[self.version].model_validate(doc)
        except Exception as e:
            text = f"order refused: {e}".splitlines()[0]
            self._error("validationError", text, "FATAL", refs)
            return None
        unable = fs.check_order(o, fs.read(self.factsheet()))
        if unable:
            self._error("orderError", "order action is not executable: " + "; ".join(unable),
                        "WARNING", refs)  # fmt: skip
            return None
        problems = orders.check_order(o)
        if problems or not o.nodes:
            text = "order refused: " + "; ".join(problems or ["no nodes"])
            self._error("orderError", text, "WARNING", refs)
            return None
        return o

    def _start(self, o: v.Order) -> None:
        """Run the validated order ``o`` from its first node (placed there if
        ``teleport_to_first_node``), its phases planned and nothing done yet."""
        self.errors = []
        self.order_id, self.order_update_id = o.order_id, o.order_update_id
        self.nodes = [_node_of(n) for n in o.nodes]
        self.edges = [(e.edge_id, e.sequence_id) for e in o.edges]
        first = self.nodes[0]
        if self.teleport_to_first_node:
            self.x, self.y = first.x, first.y
            if first.theta is not None:
                self.theta = first.theta
        self.last_node = 0
        self.started_at, self.finished_at = self.clock, None
        self.stopped_at = {}
        self.arrivals = []
        self.info = []
        self.phases = self._plan_phases()
        self.elapsed = 0.0
        if not self.phases:
            self.finished_at = self.clock

    def _plan_phases(self) -> list[_Phase]:
        """Rest-to-rest drives between the nodes it halts at (those with actions or an
        orientation: a docking leg's ends, where it turns); docking and picks at stops."""
        out: list[_Phase] = []
        stops = [i for i, n in enumerate(self.nodes) if n.actions or n.theta is not None]
        stops.append(len(self.nodes) - 1)
        prev = 0
        for s in sorted(set(stops)):
            if s == 0:
                continue
            passed = list(range(prev + 1, s + 1))
            out.append(_Phase("drive", 0.0, s, nodes=passed))
            if self.nodes[s].actions:
                out.append(_Phase("dock", self.motion.stop_time, s))
                out += [
                    _Phase("pick", self.motion.pick_time, s, action=k)
                    for k in range(len(self.nodes[s].actions))
                ]
            prev = s
        return out

    # -- simulated time ----------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        return bool(self.phases)

    def next_event(self) -> float:
        """Simulated seconds until the current phase ends (inf when idle)."""
        if not self.phases:
            return math.inf
        self._begin(self.phases[0])
        return max(0.0, self.phases[0].duration - self.elapsed)

    def advance(self, dt: float) -> bool:
        """Move ``dt`` [s] forward; True if anything a state reports changed (besides pose)."""
        changed = False
        while self.phases:
            ph = self.phases[0]
            self._begin(ph)
            left = ph.duration - self.elapsed
            if dt < left - 1e-12:
                self.elapsed += dt
                self.clock += dt
                if ph.kind == "drive":
                    self._drive_pose(ph)
                return changed
            dt -= max(left, 0.0)
            self.clock += max(left, 0.0)
            self._end(ph)
            self.phases.pop(0)
            self.elapsed = 0.0
            changed = True
        self.clock += dt
        return changed

    def _begin(self, ph: _Phase) -> None:
        if ph.kind == "drive" and not ph.path:
            ph.path = [(self.x, self.y)] + [(self.nodes[i].x, self.nodes[i].y) for i in ph.nodes]
            length = sum(math.dist(a, b) for a, b in zip(ph.path, ph.path[1:], strict=False))
            m = self.motion
            ph.duration = float(leg_time(length, m.max_speed, m.max_acceleration))
        elif ph.kind == "pick":
            a = self.nodes[ph.node].actions[ph.action]
            if a.status == "WAITING":
                self._pick(ph.node, a)

    def _drive_pose(self, ph: _Phase) -> None:
        m = self.motion
        t, T = self.elapsed, ph.duration
        length = sum(math.dist(a, b) for a, b in zip(ph.path, ph.path[1:], strict=False))
        v_, a_ = m.max_speed, m.max_acceleration
        # distance travelled at time t of a rest-to-rest trapezoid (or triangle) of length L
        ta = min(v_ / a_, T / 2.0)
        vp = a_ * ta
        if t < ta:
            s = 0.5 * a_ * t * t
        elif t < T - ta:
            s = 0.5 * a_ * ta * ta + vp * (t - ta)
        else:
            s = length - 0.5 * a_ * (T - t) ** 2
        s = travelled = min(max(s, 0.0), length)
        for (ax, ay), (bx, by) in zip(ph.path, ph.path[1:], strict=False):
            d = math.hypot(bx - ax, by - ay)
            if d == 0.0:
                continue
            if s <= d:
                self.x, self.y = ax + s / d * (bx - ax), ay + s / d * (by - ay)
                self.theta = math.atan2(by - ay, bx - ax)
                break
            s -= d
        # the nodes passed so far count as traversed (not the one it drives to)
        acc = 0.0
        for k, (a, b) in enumerate(zip(ph.path, ph.path[1:], strict=False)):
            acc += math.dist(a, b)
            if acc <= travelled and k < len(ph.nodes) - 1:
                self.last_node = max(self.last_node, ph.nodes[k])

    def _end(self, ph: _Phase) -> None:
        node = self.nodes[ph.node]
        if ph.kind == "drive":
            dx, dy, dyaw = (0.0, 0.0, 0.0)
            if node.actions:  # it stops here: the base lands off by the error model
                yaw = self.theta if node.theta is None else node.theta
                dx, dy, dyaw = self.forced_error or self.error(
                    self.rng, node.x, node.y, yaw, self._trays(node)
                )
            self.x, self.y = node.x + dx, node.y + dy
            if node.theta is not None:
                self.theta = wrap_angle(node.theta + dyaw)
            self.last_node = ph.node
            self.stopped_at[node.id] = (self.x, self.y, self.theta)
        elif ph.kind in ("dock", "redock", "operator") and self.failure is not None:
            self._arrived(ph)
        elif ph.kind == "pick":
            a = node.actions[ph.action]
            if a.status == "RUNNING":
                a.status = "FINISHED"
        if len(self.phases) == 1:
            self.finished_at = self.clock

    def _trays(self, node: _Node) -> tuple[str, ...]:
        """The trays a node's picks are from (as its pick's parameters name them)."""
        found = (self.pick.ours(a.params).get("trayId") for a in node.actions
                 if a.type == self.pick.action_type)  # fmt: skip
        return tuple(sorted({str(t) for t in found if t is not None}))

    def _arrived(self, ph: _Phase) -> None:
        """After docking, a re-dock or an operator's call: go on to the picks if every one is
        possible from here, else re-dock (landing anew) or, after the last retry, call an
        operator, who sets the base at the node."""
        fm, node = self.failure, self.nodes[ph.node]
        assert fm is not None
        if ph.kind == "operator":
            self.x, self.y = node.x, node.y
            if node.theta is not None:
                self.theta = node.theta
            self.arrivals[-1].operator = True
            self.stopped_at[node.id] = (self.x, self.y, self.theta)
            return
        if ph.kind == "redock":
            yaw = self.theta if node.theta is None else node.theta
            dx, dy, dyaw = self.forced_error or self.error(
                self.rng, node.x, node.y, yaw, self._trays(node)
            )
            self.x, self.y = node.x + dx, node.y + dy
            if node.theta is not None:
                self.theta = wrap_angle(node.theta + dyaw)
            self.arrivals[-1].retries += 1
            self.stopped_at[node.id] = (self.x, self.y, self.theta)
        ok = all(self.check(t, self.x, self.y, self.theta)[0] for t in self._trays(node))
        if ph.kind == "dock":
            self.arrivals.append(Arrival(node.id, ok))
        if ok:
            return
        if self.arrivals[-1].retries < fm.retries:
            nxt = _Phase("redock", fm.retry_time, ph.node)
        else:
            nxt = _Phase("operator", fm.operator_time, ph.node)
        self.phases.insert(1, nxt)
        where = f"({self.x:.3f}, {self.y:.3f}, {math.degrees(self.theta):.1f} deg)"
        self.info.append(
            {
                "infoType": "retry" if nxt.kind == "redock" else "operatorCall",
                "infoDescription": f"not every pick at node {node.id} is possible from {where}: "
                + ("re-docking" if nxt.kind == "redock" else "calling an operator"),
                "infoLevel": "INFO",
                "infoReferences": [{"referenceKey": "nodeId", "referenceValue": node.id}],
            }
        )

    def _pick(self, k: int, a: _Action) -> None:
        node = self.nodes[k]
        if a.type != self.pick.action_type:
            a.status, a.result = "FINISHED", f"{a.type}: nothing to do in simulation"
            return
        ours = self.pick.ours(a.params)
        tray = str(ours.get("trayId", ""))
        off = math.hypot(self.x - node.x, self.y - node.y)
        ok, why = self.check(tray, self.x, self.y, self.theta)
        where = (
            f"stopped at ({self.x:.3f}, {self.y:.3f}, {math.degrees(self.theta):.1f} deg), "
            f"{off:.3f} m from node {node.id}"
            + (
                f" (outside its guaranteed radius {node.deviation:.3f} m)"
                if off > node.deviation
                else f" (within its guaranteed radius {node.deviation:.3f} m)"
            )
        )
        if ok:
            a.status, a.result = "RUNNING", f"part {ours.get('partId')} graspable; {where}"
        else:
            a.status = "FAILED"
            a.result = f"part {ours.get('partId')} of tray {tray} not graspable: {why}; {where}"
            self._error(
                "pickFailed", a.result, "WARNING", (("actionId", a.id), ("nodeId", node.id))
            )

    def _error(
        self, kind: str, text: str, level: str = "WARNING", refs: tuple[tuple[str, str], ...] = ()
    ) -> None:
        e: dict[str, Any] = {"errorType": kind, "errorDescription": text, "errorLevel": level}
        if refs:
            e["errorReferences"] = [{"referenceKey": k, "referenceValue": x} for k, x in refs]
        self.errors.append(e)

    # -- the state message ----------------------------------------------------------------------
    def state(self, stamp: str | None = None) -> dict[str, Any]:
        """The VDA 5050 state message now (validated by the version's model)."""
        v3 = v.v3(self.version)
        desc = "actionDescriptor" if v3 else "actionDescription"
        result = "actionResult" if v3 else "resultDescription"
        upcoming = self.nodes[self.last_node + 1 :] if self.last_node >= 0 else []
        last = self.nodes[self.last_node] if self.nodes and self.last_node >= 0 else None
        edges = [e for e in self.edges if last is not None and e[1] > last.seq]
        self.header_id += 1
        actions = []
        for n in self.nodes:
            for a in n.actions:
                s = {"actionId": a.id, "actionType": a.type, "actionStatus": a.status}
                if a.result:
                    s[result] = a.result
                s[desc] = f"{a.type} at {n.id}"
                actions.append(s)
        if v3:
            errors = [
                {**e, "errorLevel": "URGENT" if e["errorLevel"] == "FATAL" else e["errorLevel"]}
                for e in self.errors
            ]
        else:
            errors = self.errors
        pos = {"x": self.x, "y": self.y, "theta": wrap_angle(self.theta), "mapId": self.map_id}
        driving = bool(self.phases) and self.phases[0].kind == "drive"
        doc: dict[str, Any] = {
            "headerId": self.header_id,
            "timestamp": stamp or orders.timestamp(),
            "version": self.version,
            "manufacturer": self.manufacturer,
            "serialNumber": self.serial_number,
            "orderId": self.order_id,
            "orderUpdateId": self.order_update_id,
            "lastNodeId": last.id if last else "",
            "lastNodeSequenceId": last.seq if last else 0,
            "nodeStates": [
                {"nodeId": n.id, "sequenceId": n.seq, "released": True} for n in upcoming
            ],
            "edgeStates": [{"edgeId": e, "sequenceId": s, "released": True} for e, s in edges],
            "driving": driving,
            "actionStates": actions,
            "operatingMode": "AUTOMATIC",
            "errors": errors,
            "information": self.info[-INFO_KEPT:],
            "safetyState": {
                ("activeEmergencyStop" if v3 else "eStop"): "NONE",
                "fieldViolation": False,
            },
        }
        if v3:
            doc["mobileRobotPosition"] = {**pos, "localized": True}
            doc["instantActionStates"] = []
            doc["powerSupply"] = {"stateOfCharge": 100.0, "charging": False}
        else:
            doc["agvPosition"] = {**pos, "positionInitialized": True}
            doc["batteryState"] = {"batteryCharge": 100.0, "charging": False}
        return v.dump(v.STATE_MODELS[self.version].model_validate(doc))
