"""Execute a plan many times on a simulated vehicle and set the outcome beside the prediction.

Each run dispatches the plan's VDA 5050 order over MQTT to a :class:`SimVehicle` that lands at
each stop off by the scene's error model and checks every pick with the exact pipeline. A stop
succeeds in a run when all its picks do, the plan when every stop does. Rates carry 95% Wilson
intervals; the prediction is the plan's Monte Carlo (per stop) and its product (per plan).

A plan that carries a failure model (``parameters.failure``) runs with it: a stop succeeds when
its first landing serves every pick; one that does not is re-docked and, after the last retry,
served by an operator, as the model says, and the executed time (failures included) is set
beside the plan's expected time.
"""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pickstop.errors import InputError
from pickstop.fleet import order as orders
from pickstop.fleet.arrivals import Arrival
from pickstop.fleet.broker import LocalMosquitto
from pickstop.fleet.dispatch import Dispatcher
from pickstop.fleet.mqtt import Broker
from pickstop.fleet.route import guaranteed_radius
from pickstop.fleet.sim_node import VehicleNode
from pickstop.fleet.vehicle import Check, Motion, SimVehicle, error_model, isotropic
from pickstop.scene.positioning import Positioning
from pickstop.sequence import plan_model as pm
from pickstop.sequence.failure import FailureCosts
from pickstop.sequence.success import Rate

MAX_RUNS = 100_000


@dataclass(frozen=True)
class RunOutcome:
    stops_ok: tuple[bool, ...]
    time: float  # [s] simulated, order accepted to goal reached
    failures: tuple[str, ...]  # results of failed picks
    latency: float | None  # [s] publish to the first state naming the order
    retries: tuple[int, ...] = ()  # per stop: re-docks (with a failure model)
    operator: tuple[bool, ...] = ()  # per stop: an operator was called (with a failure model)


def vehicle_for(
    plan: pm.Plan,
    check: Check,
    seed: int,
    version: str = "2.1.0",
    kind: str | None = None,
    positioning: Positioning | None = None,
) -> SimVehicle:
    """A simulated vehicle with the plan's time model and failure model, landing by
    ``positioning`` (default: the plan's isotropic error model; pass the scene's for
    per-station, biased, anisotropic ones)."""
    p = plan.parameters
    pos = positioning or isotropic(kind or p.error_model, p.sigma, p.yaw_sigma)  # type: ignore[arg-type]
    return SimVehicle(
        manufacturer="pickstop",
        serial_number="sim-1",
        motion=Motion(p.max_speed, p.max_acceleration, p.stop_time, p.pick_time),
        error=error_model(pos),
        check=check,
        rng=np.random.default_rng(seed),
        version=version,
        failure=None if p.failure is None else FailureCosts.of(p.failure),
    )


def execute(
    plan: pm.Plan,
    check: Check,
    runs: int,
    seed: int = 0,
    version: str = "2.1.0",
    broker: Broker | None = None,
    positioning: Positioning | None = None,
    record: Callable[[Arrival], None] | None = None,
) -> list[RunOutcome]:
    """``runs`` executions of the plan (a local Mosquitto unless ``broker`` is given), the
    vehicle landing off by ``positioning`` (default: the plan's isotropic model); ``record``
    takes every arrival at a stop."""
    if not 1 <= runs <= MAX_RUNS:
        raise InputError(f"runs: must be in 1..{MAX_RUNS}, got {runs}", field="runs")
    version = orders.version_of(version)
    local = LocalMosquitto().start() if broker is None else None
    try:
        where = broker or local.broker  # type: ignore[union-attr]
        veh = vehicle_for(plan, check, seed, version, positioning=positioning)
        node = VehicleNode(veh, where, time_scale=0).start()
        disp = Dispatcher(where, veh.manufacturer, veh.serial_number, version).start()
        try:
            base = orders.order_id_of(plan)
            out = []
            for r in range(runs):
                order = orders.build_order(
                    plan,
                    orders.OrderOptions(
                        version=version,
                        manufacturer=veh.manufacturer,
                        serial_number=veh.serial_number,
                        order_id=f"{base}-run{r}",
                        header_id=r,
                    ),
                )
                s = disp.run(order, timeout=120.0, record=record)
                out.append(_outcome(veh, s))
            return out
        finally:
            disp.stop()
            node.stop()
    finally:
        if local is not None:
            local.stop()


def _outcome(veh: SimVehicle, s: dict[str, Any]) -> RunOutcome:
    """A run's outcome from the tracker's summary ``s`` and the vehicle's arrivals."""
    stops = s["stops"]
    ok = tuple(st["status"] == "finished" for st in stops)
    arrivals = veh.arrivals if veh.failure is not None else []
    if arrivals:
        if len(arrivals) != len(stops):
            raise AssertionError(f"{len(arrivals)} arrivals recorded for {len(stops)} stops")
        ok = tuple(a.first_ok for a in arrivals)
    return RunOutcome(
        ok,
        float((veh.finished_at or veh.clock) - veh.started_at),
        tuple(f["result"] or "" for st in stops for f in st["failed"]),
        s["latency"],
        tuple(a.retries for a in arrivals),
        tuple(a.operator for a in arrivals),
    )


def report(plan: pm.Plan, outcomes: list[RunOutcome]) -> dict[str, Any]:
    """Executed success per stop and per plan (95% Wilson intervals) beside the prediction,
    and the executed time beside the predicted one."""
    n = len(outcomes)
    stops = []
    for k, s in enumerate(plan.stops):
        rate = Rate(n, sum(o.stops_ok[k] for o in outcomes))
        pred = s.success
        stops.append(
            {
                "stop": k,
                "trays": s.trays,
                "guaranteed_radius": guaranteed_radius(s),
                "executed": rate.rate,
                "executed_interval": list(rate.interval),
                "predicted": None if pred is None else pred.rate,
                "predicted_interval": None if pred is None else list(pred.interval),
                "predicted_samples": None if pred is None else pred.samples,
            }
        )
    whole = Rate(n, sum(all(o.stops_ok) for o in outcomes))
    times = [o.time for o in outcomes]
    lat = [o.latency for o in outcomes if o.latency is not None]
    reasons = Counter(f.split(";")[0] for o in outcomes for f in o.failures)
    t = plan.totals
    return {
        "scene": plan.scene,
        "rule": plan.parameters.rule,
        "sigma": plan.parameters.sigma,
        "error_model": plan.parameters.error_model,
        "runs": n,
        "stops": stops,
        "plan": {
            "executed": whole.rate,
            "executed_interval": list(whole.interval),
            "predicted": t.success,
            "predicted_interval": None if t.success_interval is None else list(t.success_interval),
        },
        "time": {
            "executed_mean": statistics.fmean(times),
            "executed_sd": statistics.pstdev(times) if n > 1 else 0.0,
            "executed_min": min(times),
            "executed_max": max(times),
            "predicted": t.time.total,
            "expected": t.time.expected,
        },
        "recovery": _recovery(plan, outcomes),
        "dispatch_latency": {
            "median": statistics.median(lat) if lat else None,
            "max": max(lat) if lat else None,
        },
        "failures": [{"reason": r, "count": c} for r, c in reasons.most_common(5)],
    }


def _recovery(plan: pm.Plan, outcomes: list[RunOutcome]) -> dict[str, Any] | None:
    """Re-docks and operator calls per run, executed (mean) beside expected (None without a
    failure model)."""
    runs = [o for o in outcomes if len(o.retries) == len(plan.stops)]
    if not runs or plan.parameters.failure is None:
        return None
    t = plan.totals
    return {
        "retries_mean": statistics.fmean(sum(o.retries) for o in runs),
        "retries_expected": t.retries,
        "operator_calls_mean": statistics.fmean(sum(o.operator) for o in runs),
        "operator_calls_expected": t.operator_calls,
    }


def _pct(x: float | None) -> str:
    return "    -" if x is None else f"{x:6.1%}"


def _iv(iv: list[float] | None) -> str:
    return "        -        " if iv is None else f"[{iv[0]:6.1%}, {iv[1]:6.1%}]"


def table(rep: dict[str, Any]) -> str:
    """The report as text."""
    lines = [
        f"{rep['scene']}: rule {rep['rule']}, sigma {rep['sigma']:.3f} m ({rep['error_model']}), "
        f"{rep['runs']} runs",
        f"{'':10} {'executed':>8} {'95% interval':>18}   {'predicted':>9} {'95% interval':>18}",
    ]
    for s in rep["stops"]:
        lines.append(
            f"stop {s['stop']:<5} {_pct(s['executed']):>8} {_iv(s['executed_interval']):>18}   "
            f"{_pct(s['predicted']):>9} {_iv(s['predicted_interval']):>18}"
        )
    p = rep["plan"]
    lines.append(
        f"{'plan':10} {_pct(p['executed']):>8} {_iv(p['executed_interval']):>18}   "
        f"{_pct(p['predicted']):>9} {_iv(p['predicted_interval']):>18}"
    )
    t = rep["time"]
    expected = "" if t.get("expected") is None else f", expected {t['expected']:.1f} s"
    lines.append(
        f"time: executed {t['executed_mean']:.1f} s (sd {t['executed_sd']:.2f}, "
        f"{t['executed_min']:.1f} to {t['executed_max']:.1f}), predicted {t['predicted']:.1f} s"
        + expected
    )
    r = rep.get("recovery")
    if r is not None:
        exp_r, exp_o = r["retries_expected"], r["operator_calls_expected"]
        lines.append(
            f"re-docks per run: executed {r['retries_mean']:.3f}"
            + ("" if exp_r is None else f", expected {exp_r:.3f}")
            + f"; operator calls: executed {r['operator_calls_mean']:.4f}"
            + ("" if exp_o is None else f", expected {exp_o:.4f}")
        )
    for f in rep["failures"]:
        lines.append(f"  {f['count']} x {f['reason']}")
    return "\n".join(lines)
