"""Arrivals: the tracker notes where the vehicle stood at each stop and how its picks ended;
logs are written line by line and read back, a bad line named."""

from __future__ import annotations

import json

import pytest

from pickstop.errors import InputError
from pickstop.fleet import order as od
from pickstop.fleet import vda5050 as v
from pickstop.fleet.arrivals import Recorder, read_log
from pickstop.fleet.execution import vehicle_for
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.tracker import OrderTracker
from pickstop.fleet.vehicle_types import PickAction
from pickstop.frames import wrap_angle


@pytest.fixture(scope="module")
def paper(example_plans, planner):
    scene, plan = example_plans["paper_experiment"]
    return scene, plan, PickChecker(planner, scene)


def run(veh, order, tracker, until=None):
    assert veh.accept(v.dump(order))
    tracker.update(veh.state())
    while veh.busy and not (until and until(tracker)):
        veh.advance(veh.next_event())
        tracker.update(veh.state())


@pytest.mark.parametrize("version", ["2.0.0", "3.0.0"])
def test_every_stop_is_an_arrival_with_the_reported_pose_and_its_picks(paper, version):
    scene, plan, check = paper
    veh = vehicle_for(plan, check, seed=0, version=version)
    veh.forced_error = (0.012, -0.008, 0.01)
    order = od.build_order(plan, od.OrderOptions(version=version, order_id="o1"))
    tracker = OrderTracker(order)
    run(veh, order, tracker)
    arrivals = tracker.arrivals()
    assert [a.node_id for a in arrivals] == [f"stop{k}" for k in range(len(plan.stops))]
    for a, s in zip(arrivals, plan.stops, strict=True):
        assert (a.order_id, a.stop, a.trays) == ("o1", a.stop, sorted(s.trays))
        assert (a.planned.x, a.planned.y) == (s.x, s.y)
        assert a.planned.theta == pytest.approx(wrap_angle(s.yaw))
        assert a.reported.x - a.planned.x == pytest.approx(0.012)
        assert a.reported.y - a.planned.y == pytest.approx(-0.008)
        assert wrap_angle(a.reported.theta - a.planned.theta) == pytest.approx(0.01)
        parts = {(p.tray_id, p.part_id) for p in a.picks}
        assert parts == {(t, part.id) for t in s.trays for part in scene.tray(t).parts}
        assert a.ok == all(p.status == "FINISHED" for p in a.picks)
        assert a.manufacturer == "pickstop" and a.map_id == "map" and a.time.endswith("Z")
    assert tracker.summary()["arrivals"][0]["node_id"] == "stop0"


def test_an_arrival_waits_for_its_picks_unless_final(paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    veh.forced_error = (0.0, 0.0, 0.0)
    order = od.build_order(plan)
    tracker = OrderTracker(order)
    run(veh, order, tracker, until=lambda t: "stop0" in t.landed)
    assert tracker.arrivals() == []
    (open_,) = tracker.arrivals(final=True)
    assert open_.node_id == "stop0" and not open_.ok
    assert {p.status for p in open_.picks} <= {"WAITING", "RUNNING", "INITIALIZING", "FINISHED"}


def test_a_mapped_pick_still_names_its_tray_and_part(paper):
    _, plan, check = paper
    pick = PickAction(action_type="pickPart", parameters={"station": "trayId", "load": "partId"})
    veh = vehicle_for(plan, check, seed=0)
    veh.pick, veh.forced_error = pick, (0.0, 0.0, 0.0)
    order = od.build_order(plan, od.OrderOptions(pick=pick))
    tracker = OrderTracker(order, pick=pick)
    run(veh, order, tracker)
    assert tracker.arrivals()[0].trays == sorted(plan.stops[0].trays)
    assert all(p.part_id for a in tracker.arrivals() for p in a.picks)


def test_a_log_is_written_line_by_line_and_read_back(paper, tmp_path):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    veh.forced_error = (0.0, 0.0, 0.0)
    order = od.build_order(plan)
    tracker = OrderTracker(order)
    run(veh, order, tracker)
    log = tmp_path / "runs" / "arrivals.jsonl"
    rec = Recorder(log)
    for a in tracker.arrivals():
        rec(a)
    rec(tracker.arrivals()[0])
    assert rec.written == len(plan.stops) + 1
    back = read_log(log)
    assert back == [*tracker.arrivals(), tracker.arrivals()[0]]
    text = log.read_text().splitlines()
    bad = json.loads(text[0])
    del bad["reported"]
    log.write_text(text[0] + "\n\n" + json.dumps(bad) + "\n")
    with pytest.raises(InputError, match=r"line 3: reported: Field required"):
        read_log(log)
    log.write_text("{not json\n")
    with pytest.raises(InputError, match="line 1: not JSON"):
        read_log(log)
    with pytest.raises(InputError, match="no such file"):
        read_log(tmp_path / "none.jsonl")
