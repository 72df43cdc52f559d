"""Exported orders of every example plan: the models, the official schemas, the standard's
constraints; and the guaranteed radius and picks they carry."""

from __future__ import annotations

import copy
import math

import jsonschema
import pytest

from pickstop.errors import InputError
from pickstop.fleet import order as od
from pickstop.fleet import published
from pickstop.fleet import route as rt
from pickstop.fleet import vda5050 as v
from pickstop.frames import wrap_angle
from tests.fleet.conftest import SCENES


def schema(kind: str, version: str) -> dict:
    return published.schema(kind, version)


@pytest.mark.parametrize("version", ["2.0", "2.1", "3.0"])
@pytest.mark.parametrize("name", SCENES)
def test_orders_of_every_example_validate_and_keep_the_rules(example_plans, name, version):
    scene, plan = example_plans[name]
    opts = od.OrderOptions(version=version, start_yaw=scene.start.yaw, goal_yaw=scene.goal.yaw)
    order = od.build_order(plan, opts)
    doc = v.dump(order)
    jsonschema.validate(doc, schema("order", v.VERSIONS[version]))
    assert od.check_order(order) == []
    assert type(order).model_validate(doc) == order  # the wire form reads back the same
    seq_nodes = [n.sequence_id for n in order.nodes]
    seq_edges = [e.sequence_id for e in order.edges]
    assert all(s % 2 == 0 for s in seq_nodes) and all(s % 2 == 1 for s in seq_edges)
    assert seq_nodes == sorted(seq_nodes) and seq_edges == sorted(seq_edges)
    assert order.nodes[0].node_id == "start" and order.nodes[-1].node_id == "goal"
    assert all(n.released for n in order.nodes) and all(e.released for e in order.edges)
    stops = [n for n in order.nodes if n.actions]
    assert len(stops) == len(plan.stops)
    for n, s in zip(stops, plan.stops, strict=True):
        p = n.node_position
        assert (p.x, p.y) == (s.x, s.y) and p.theta == pytest.approx(wrap_angle(s.yaw))
        dev = p.allowed_deviation_xy
        radius = dev.a if version == "3.0" else dev
        assert radius == s.inscribed_radius >= plan.parameters.sigma > 0
        assert p.allowed_deviation_theta >= 0
        picks = {(a.action_parameters[1].value, a.action_parameters[2].value) for a in n.actions}
        assert picks == {(t, part.id) for t in s.trays for part in scene.tray(t).parts}
        for a in n.actions:
            assert a.action_type == "pick" and a.blocking_type == "HARD"
            params = {q.key: q.value for q in a.action_parameters}
            assert params["jointNames"] == plan.joints
            assert len(params["jointPositions"]) == len(plan.joints)


def test_release_stops_puts_the_rest_in_the_horizon(example_plans):
    _, plan = example_plans["five_trays"]
    order = od.build_order(plan, od.OrderOptions(release_stops=1))
    assert od.check_order(order) == []
    released = [n.node_id for n in order.nodes if n.released]
    assert released[-1] == "stop0" and not order.nodes[-1].released
    order0 = od.build_order(plan, od.OrderOptions(release_stops=0))
    assert [n.released for n in order0.nodes].count(True) == 1
    assert not any(e.released for e in order0.edges)


def test_check_order_names_each_broken_rule(example_plans):
    _, plan = example_plans["paper_experiment"]
    good = v.dump(od.build_order(plan))

    def broken(change) -> list[str]:
        doc = copy.deepcopy(good)
        change(doc)
        return od.check_order(v.Order21.model_validate(doc))

    assert "node ids are not unique" in broken(
        lambda d: d["nodes"][1].update(nodeId=d["nodes"][0]["nodeId"])
    )
    assert "a node's sequenceId is odd" in broken(lambda d: d["nodes"][1].update(sequenceId=3))
    assert any("released" in p for p in broken(lambda d: d["nodes"][1].update(released=False)))
    assert any("does not join" in p for p in broken(lambda d: d["edges"][0].update(endNodeId="x")))
    with pytest.raises(Exception, match="greater than or equal to 0"):
        broken(lambda d: d["nodes"][1]["nodePosition"].update(allowedDeviationXY=-0.1))


def test_theta_stays_in_the_schema_range():
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert abs(wrap_angle(math.pi)) <= v.PI_THETA


@pytest.mark.parametrize(
    ("opts", "field"),
    [
        (od.OrderOptions(version="4.0"), "vda_version"),
        (od.OrderOptions(manufacturer="a/b"), "manufacturer"),
        (od.OrderOptions(serial_number=""), "serial_number"),
        (od.OrderOptions(release_stops=-1), "release_stops"),
    ],
)
def test_bad_options_name_the_field(example_plans, opts, field):
    _, plan = example_plans["paper_experiment"]
    with pytest.raises(InputError) as e:
        od.build_order(plan, opts)
    assert e.value.field == field


def test_a_bad_plan_document_names_the_field(example_plans):
    _, plan = example_plans["paper_experiment"]
    doc = plan.model_dump(mode="json")
    doc["stops"][0]["x"] = "far"
    with pytest.raises(InputError, match=r"stops\.0\.x"):
        rt.load_plan(doc)


def test_floor_path_corners_become_via_nodes_the_vehicle_passes(example_plans, planner):
    from pickstop.fleet.execution import vehicle_for
    from pickstop.fleet.pickcheck import PickChecker
    from pickstop.fleet.tracker import OrderTracker

    scene, plan = example_plans["paper_experiment"]
    legs = [leg.model_copy(deep=True) for leg in plan.legs]
    (x0, y0), (x1, y1) = legs[0].polyline[0], legs[0].polyline[-1]
    corner = (x0 + 0.3, 0.5 * (y0 + y1))  # a detour, as around an obstacle
    legs[0].polyline = [legs[0].polyline[0], corner, legs[0].polyline[-1]]
    bent = plan.model_copy(update={"legs": legs})
    order = od.build_order(bent)
    assert od.check_order(order) == []
    ids = [n.node_id for n in order.nodes]
    assert ids[:3] == ["start", "leg0-via1", "stop0"]
    via = order.nodes[1]
    assert (via.node_position.x, via.node_position.y) == corner and not via.actions
    assert via.node_position.allowed_deviation_xy == rt.VIA_TOLERANCE
    veh = vehicle_for(bent, PickChecker(planner, scene), seed=0)
    veh.forced_error = (0.0, 0.0, 0.0)
    tracker = OrderTracker(order)
    veh.accept(v.dump(order))
    passed_via_while_driving = False
    while veh.busy:
        veh.advance(min(0.5, veh.next_event()))
        tracker.update(veh.state())
        if "leg0-via1" in tracker.reached and "stop0" not in tracker.reached:
            passed_via_while_driving = True
    assert passed_via_while_driving and tracker.done
    longer = (
        math.dist((x0, y0), corner) + math.dist(corner, (x1, y1)) - math.dist((x0, y0), (x1, y1))
    )
    assert (
        veh.finished_at - veh.started_at
        > plan.totals.time.total + 0.9 * longer / plan.parameters.max_speed
    )


@pytest.mark.parametrize("version", ["2.0", "2.1", "3.0"])
def test_a_docking_leg_holds_the_stops_yaw_in_the_order_nav2_and_the_vehicle(
    example_plans, planner, version
):
    """A plan whose first stop is docked: a straight leg from a staging point 0.2 m back,
    driven at the stop's yaw. The order's staging node and the stop carry that theta, the edge
    between them its GLOBAL orientation without rotation; Nav2's poses hold the yaw; the
    simulated vehicle halts at the staging point as the time model does."""
    from pickstop.fleet import nav2
    from pickstop.fleet.execution import vehicle_for
    from pickstop.fleet.pickcheck import PickChecker
    from pickstop.sequence.timing import pieces_time, plan_time, rest_pieces

    scene, plan = example_plans["paper_experiment"]
    s0 = plan.stops[0]
    back = (s0.x - 0.2 * math.cos(s0.yaw), s0.y - 0.2 * math.sin(s0.yaw))
    legs = [leg.model_copy(deep=True) for leg in plan.legs]
    legs[0].polyline = [legs[0].polyline[0], back, (s0.x, s0.y)]
    legs[0].segment_yaws = [None, s0.yaw]
    legs[1].polyline = [(s0.x, s0.y), back, *legs[1].polyline[1:]]
    legs[1].segment_yaws = [s0.yaw] + [None] * (len(legs[1].polyline) - 2)
    m = plan.parameters
    for leg in legs:
        leg.time = pieces_time(
            rest_pieces(leg.polyline, leg.segment_yaws or []), m.max_speed, m.max_acceleration
        )
    n_parts = sum(len(scene.tray(t).parts) for t in plan.trays)
    tb = plan_time(
        [rest_pieces(leg.polyline, leg.segment_yaws or []) for leg in legs],
        len(plan.stops), n_parts, m.max_speed, m.max_acceleration, m.stop_time, m.pick_time,
    )  # fmt: skip
    docked = plan.model_copy(update={"legs": legs})

    order = od.build_order(docked, od.OrderOptions(version=version))
    jsonschema.validate(v.dump(order), schema("order", v.VERSIONS[version]))
    assert od.check_order(order) == []
    ids = [n.node_id for n in order.nodes]
    assert ids[:4] == ["start", "leg0-via1", "stop0", "leg1-via1"]
    for k in (1, 3):
        p = order.nodes[k].node_position
        assert (p.x, p.y) == pytest.approx(back) and p.theta == pytest.approx(s0.yaw)
        assert p.allowed_deviation_theta is not None
        dev = p.allowed_deviation_xy
        assert (dev.a if version == "3.0" else dev) == rt.DOCK_TOLERANCE
    for e in (order.edges[1], order.edges[2]):  # staging -> stop, stop -> staging
        assert e.orientation == pytest.approx(s0.yaw) and e.orientation_type == "GLOBAL"
        if version != "3.0":
            assert e.rotation_allowed is False
        else:
            assert e.reach_orientation_before_entering is True
    assert order.edges[0].orientation is None and order.edges[3].orientation is None

    doc = nav2.build_nav2(docked)
    poses = nav2.goal_poses(doc)
    assert poses[0][2] == pytest.approx(s0.yaw) and poses[1][2] == pytest.approx(s0.yaw)
    assert doc["segments"][0]["docking"] == [1] and doc["segments"][1]["docking"] == [2]

    veh = vehicle_for(docked, PickChecker(planner, scene), seed=0, version=v.VERSIONS[version])
    veh.forced_error = (0.0, 0.0, 0.0)
    assert veh.accept(v.dump(order))
    while veh.busy:
        veh.advance(min(0.5, veh.next_event()))
    assert veh.finished_at - veh.started_at == pytest.approx(tb.total, abs=0.1)
    # halting at the staging point costs time against driving through it
    assert tb.travel > plan_time([leg.length for leg in legs], 0, 0, m.max_speed,
                                 m.max_acceleration, 0, 0).travel  # fmt: skip
