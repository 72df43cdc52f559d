"""The simulated vehicle and the tracker without a broker: the order runs to the end on
simulated time, states validate against the official schemas, and a stop outside the
guaranteed radius fails its pick (exact check) with the reason."""

from __future__ import annotations

import math

import jsonschema
import numpy as np
import pytest

from pickstop.fleet import order as od
from pickstop.fleet import published
from pickstop.fleet import vda5050 as v
from pickstop.fleet.execution import vehicle_for
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.tracker import OrderTracker
from pickstop.scene.positioning import YAW_LATTICE


@pytest.fixture(scope="module")
def paper(example_plans, planner):
    scene, plan = example_plans["paper_experiment"]
    return scene, plan, PickChecker(planner, scene)


def drive(veh, order, tracker, schema=None, max_dt=2.0):
    assert veh.accept(v.dump(order))
    tracker.update(veh.state())
    states = 0
    while veh.busy:
        veh.advance(min(max_dt, veh.next_event()))
        st = veh.state()
        if schema is not None:
            jsonschema.validate(st, schema)
        tracker.update(st)
        states += 1
    return states


@pytest.mark.parametrize("version", ["2.0.0", "2.1.0", "3.0.0"])
def test_an_order_runs_to_the_end_and_every_state_is_valid(paper, version):
    scene, plan, check = paper
    veh = vehicle_for(plan, check, seed=1, version=version)
    veh.forced_error = (0.0, 0.0, 0.0)  # exactly at the stops: every pick is feasible
    order = od.build_order(plan, od.OrderOptions(version=version))
    tracker = OrderTracker(order)
    schema = published.schema("state", version)
    drive(veh, order, tracker, schema)
    s = tracker.summary()
    assert s["done"] and s["nodes_reached"] == len(order.nodes)
    assert s["reached"] == [n.node_id for n in order.nodes]
    assert s["actions_finished"] == s["actions"] == sum(len(st.witnesses) for st in plan.stops)
    assert all(st["status"] == "finished" for st in s["stops"])
    assert s["position"]["x"] == pytest.approx(scene.goal.x)
    # Exactly at the stops the executed time is the predicted one.
    assert veh.finished_at - veh.started_at == pytest.approx(plan.totals.time.total, rel=1e-6)


def test_a_stop_outside_the_guaranteed_radius_fails_its_pick_with_the_reason(paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=1)
    veh.failure = None  # no failure model: a failed pick fails its action, no retry
    r = plan.stops[0].inscribed_radius
    veh.forced_error = (0.0, -(r + 0.35), 0.0)  # far outside, away from the table
    order = od.build_order(plan)
    tracker = OrderTracker(order)
    drive(veh, order, tracker)
    s = tracker.summary()
    assert s["done"] and s["actions_failed"] == s["actions"]  # every stop landed too far
    first = s["stops"][0]
    assert first["status"] == "failed" and first["failed"]
    reason = first["failed"][0]["result"]
    assert "not graspable" in reason and "outside its guaranteed radius" in reason
    assert f"{r:.3f} m" in reason
    assert any(e["errorType"] == "pickFailed" for e in s["errors"])


def test_the_tracker_ignores_other_orders_and_stale_states(paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=2)
    order = od.build_order(plan, od.OrderOptions(order_id="mine"))
    tracker = OrderTracker(order)
    veh.accept(v.dump(od.build_order(plan, od.OrderOptions(order_id="other"))))
    assert not tracker.update(veh.state()) and tracker.states == 0
    veh.accept(v.dump(order))
    st = veh.state()
    assert tracker.update(st) and not tracker.update(st)  # the same headerId again: stale
    assert not tracker.update({"garbage": 1})
    assert tracker.ignored == 3


def test_errors_are_drawn_from_the_scene_model(paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=3)
    d = np.array([veh.error(veh.rng, 0.0, 0.0, 0.0, ())[:2] for _ in range(4000)])
    mean = np.linalg.norm(d, axis=1).mean()
    assert mean == pytest.approx(plan.parameters.sigma, rel=0.05)  # gaussian: mean error sigma


def test_a_malformed_order_is_refused_with_an_error_in_the_state(paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=4)
    doc = v.dump(od.build_order(plan))
    doc["nodes"][1]["sequenceId"] = 3
    assert not veh.accept(doc)
    assert veh.state()["errors"][0]["errorType"] == "orderError"


def test_the_vehicle_lands_by_the_model_of_each_stops_station(paper):
    """A biased, anisotropic model in the base frame for the first stop's trays: the vehicle
    lands off by it turned to the stop's heading; the other stops by the global model."""
    from pickstop.scene.positioning import ErrorDist, Positioning, Station, rot

    _, plan, check = paper
    s0 = plan.stops[0]
    cov = ((4e-4, 1e-4), (1e-4, 1e-4))
    biased = ErrorDist("gaussian", mean=(0.05, -0.02), covariance=cov, yaw_mean=0.02)
    pos = Positioning(ErrorDist("gaussian", 0.0), (Station("s0", biased, frozenset(s0.trays)),))
    veh = vehicle_for(plan, check, seed=3, positioning=pos)
    d = np.array([veh.error(veh.rng, s0.x, s0.y, s0.yaw, tuple(s0.trays)) for _ in range(20_000)])
    R = rot(s0.yaw)
    assert d[:, :2].mean(0) == pytest.approx(R @ np.array(biased.mean), abs=1e-3)
    assert np.cov(d[:, :2].T) == pytest.approx(R @ np.array(cov) @ R.T, abs=2e-5)
    assert d[:, 2].mean() == pytest.approx(0.02, abs=YAW_LATTICE)
    assert veh.error(veh.rng, s0.x, s0.y, s0.yaw, ("elsewhere",)) == (0.0, 0.0, 0.0)
    order = od.build_order(plan)
    drive(veh, order, OrderTracker(order))
    x, y, _ = veh.stopped_at["stop0"]
    assert math.dist((x, y), (s0.x, s0.y)) > 0.01  # it drew from the station's model
    if len(plan.stops) > 1:
        x1, y1, _ = veh.stopped_at["stop1"]
        assert (x1, y1) == pytest.approx((plan.stops[1].x, plan.stops[1].y))


def test_a_missed_landing_re_docks_then_calls_an_operator_as_the_model_says(paper):
    """Every landing misses: each stop re-docks ``retries`` times, then an operator sets the
    base at the node; its picks then finish, and the time adds up to the model's worst case."""
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=1)
    fm = veh.failure
    assert fm is not None and fm.retries == plan.parameters.failure.retries
    r = plan.stops[0].inscribed_radius
    veh.forced_error = (0.0, -(r + 0.35), 0.0)  # far outside, away from the table
    order = od.build_order(plan)
    tracker = OrderTracker(order)
    schema = published.schema("state", "2.1.0")
    drive(veh, order, tracker, schema)
    s = tracker.summary()
    assert s["done"] and s["actions_finished"] == s["actions"]  # the operator saved each stop
    assert [(a.first_ok, a.retries, a.operator) for a in veh.arrivals] == [
        (False, fm.retries, True)
    ] * len(plan.stops)
    worst = len(plan.stops) * (fm.retries * fm.retry_time + fm.operator_time)
    # the drives leave from where the operator set the base, the node: as planned
    assert veh.finished_at - veh.started_at == pytest.approx(
        plan.totals.time.total + worst, rel=1e-6
    )
    kinds = [i["infoType"] for i in veh.state()["information"]]
    assert kinds.count("operatorCall") == len(plan.stops)


def test_executed_time_matches_the_expected_time_of_a_known_success_rate(paper):
    """A check that passes within 0.12 m of the node: the success rate is known in closed
    form, so the mean executed time over many runs must match the model's expected time."""
    from pickstop.sequence.failure import failure_time
    from pickstop.sequence.success import disc_probability

    _, plan, _ = paper
    stops = {(round(s.x, 9), round(s.y, 9)) for s in plan.stops}
    R = 0.12

    def near(tray, x, y, yaw):
        return (min(np.hypot(x - a, y - b) for a, b in stops) <= R, "outside the disc")

    veh = vehicle_for(plan, near, seed=5)
    times = []
    for r in range(400):
        order = od.build_order(plan, od.OrderOptions(order_id=f"run{r}"))
        drive(veh, order, OrderTracker(order), max_dt=1e9)
        times.append(veh.finished_at - veh.started_at)
    p = disc_probability("gaussian", plan.parameters.sigma, R)
    expected = plan.totals.time.total + len(plan.stops) * float(failure_time(p, veh.failure))
    times = np.array(times)
    # drives leave from where the base landed, not the node: a few cm either way
    assert abs(times.mean() - expected) < 4 * times.std() / np.sqrt(len(times)) + 0.5
