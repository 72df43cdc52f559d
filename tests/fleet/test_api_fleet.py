"""The fleet routes: export of a stored plan, dispatch as a job over a live Mosquitto to a
simulated vehicle; the job record and the planner's fleet panel show every node reached and
every pick finished."""

from __future__ import annotations

import json
import time

import jsonschema
import pytest
import yaml
from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.fleet import nav2
from pickstop.fleet.execution import vehicle_for
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.route import guaranteed_radius, load_plan
from pickstop.fleet.sim_node import VehicleNode
from pickstop.settings import Settings, hash_key
from tests.fleet.conftest import EXAMPLES, scene_of
from tests.fleet.test_order import schema

KEY = "fleet-test-key-0123456789"
AUTH = {"Authorization": f"Bearer {KEY}"}

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def mosquitto():
    """One Mosquitto for this module's service and vehicles (each test's vehicle has a serial
    number of its own)."""
    from pickstop.fleet.broker import LocalMosquitto

    with LocalMosquitto() as m:
        yield m


@pytest.fixture(scope="module")
def fleet_client(region_db, mosquitto):
    """One service for the module (its planner warm after the first plan); each test stores
    plans of its own."""
    folder, _ = region_db
    settings = Settings(data_dir=folder, api_keys=[hash_key(KEY)], mqtt_broker=mosquitto.broker.url)
    with TestClient(create_app(settings)) as c:
        yield c


@pytest.fixture()
def stored_plan(fleet_client):
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    r = fleet_client.post(
        "/api/v1/plans",
        headers=AUTH,
        json={"scene": doc, "options": {"sigma": 0.1, "samples": 200}},
    )
    assert r.status_code == 201, r.text
    return r.json()["id"], load_plan(r.json()["plan"])


def test_export_of_a_stored_plan(fleet_client, stored_plan):
    plan_id, plan = stored_plan
    r = fleet_client.get(f"/api/v1/plans/{plan_id}/export?format=vda5050&vda_version=3.0")
    assert r.status_code == 200
    order = r.json()
    jsonschema.validate(order, schema("order", "3.0.0"))
    assert order["orderId"] == plan_id and order["version"] == "3.0.0"
    r = fleet_client.get(f"/api/v1/plans/{plan_id}/export?format=nav2&nav2_format=yaml")
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/yaml")
    doc = yaml.safe_load(r.text)
    assert len(doc["segments"]) == len(plan.stops) + 1
    assert nav2.goal_poses(doc)[-1][:2] == pytest.approx(plan.route[-1])
    r = fleet_client.get(f"/api/v1/plans/{plan_id}/export?format=lif")
    assert r.status_code == 200
    jsonschema.validate(r.json(), schema("lif", "2.0.0"))
    assert r.json()["layouts"][0]["layoutId"] == plan_id
    assert len(r.json()["layouts"][0]["stations"]) == len(plan.stops)
    bad = fleet_client.get(f"/api/v1/plans/{plan_id}/export?format=pdf")
    assert bad.status_code == 422
    assert fleet_client.get("/api/v1/plans/pln_nope/export").status_code == 404


def test_dispatch_job_follows_the_order_to_the_end(fleet_client, stored_plan, mosquitto, planner):
    """Dispatched from the planner's fleet panel, as a user does: the panel starts the job
    through the API and follows it; the job record and the panel end with every node reached
    and every pick finished."""
    import viser

    from pickstop_ui.client import PickStopClient
    from pickstop_ui.fleet_view import COLOURS, FleetView, panel

    plan_id, plan = stored_plan
    veh = vehicle_for(plan, PickChecker(planner, scene_of("paper_experiment")), seed=0)
    veh.serial_number = "agv-7"
    veh.forced_error = (0.0, 0.0, 0.0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=100).start()
    server = viser.ViserServer(port=0, verbose=False)
    api = PickStopClient("http://testserver")
    api.http = fleet_client  # the app in process (TestClient is an httpx client)
    fleet_client.headers.update(AUTH)
    try:
        view = FleetView(server, api, lambda: plan_id)
        view.serial.value = "agv-7"
        view._dispatch()
        t_end = time.monotonic() + 60
        while time.monotonic() < t_end and (view.job is None or view.job["state"] != "done"):
            time.sleep(0.1)
        job = fleet_client.get(f"/api/v1/jobs/{view.job['id']}").json()
        assert job["kind"] == "dispatch" and job["state"] == "done", job
        res = job["result"]
        assert res["done"] and res["nodes_reached"] == res["nodes"]
        assert res["actions_finished"] == res["actions"] > 0
        assert [s["status"] for s in res["stops"]] == ["finished"] * len(plan.stops)
        # the panel: the vehicle at the goal, every stop green, the text says so
        assert tuple(view.vehicle.position[:2]) == pytest.approx(plan.route[-1])
        assert len(view.stops) == len(plan.stops)
        assert all(h.color == COLOURS["finished"] for h in view.stops.values())
        text = view.md.content
        assert text == panel(view.job) and text.count("**finished**") == len(plan.stops)
        assert f"nodes reached {res['nodes']}/{res['nodes']}" in text
    finally:
        for k in AUTH:
            fleet_client.headers.pop(k, None)
        server.stop()
        node.stop()


def test_dispatch_bad_input_and_no_broker(fleet_client, stored_plan, region_db):
    plan_id, _ = stored_plan
    url = f"/api/v1/plans/{plan_id}/dispatch"
    assert fleet_client.post(url, json={}).status_code == 401
    r = fleet_client.post(url, headers=AUTH, json={"serial_number": "a/b"})
    assert r.status_code == 422 and r.json()["field"].endswith("serial_number")
    r = fleet_client.post(url, headers=AUTH, json={"timeout": -1})
    assert r.status_code == 422
    assert (
        fleet_client.post("/api/v1/plans/pln_x/dispatch", headers=AUTH, json={}).status_code == 404
    )
    folder, _ = region_db
    with TestClient(create_app(Settings(data_dir=folder, api_keys=[hash_key(KEY)]))) as c:
        r = c.post(url, headers=AUTH, json={})
        assert r.status_code == 409 and "PICKSTOP_MQTT_BROKER" in r.json()["detail"]


def test_a_dispatch_job_can_be_cancelled(fleet_client, stored_plan, mosquitto, planner):
    plan_id, plan = stored_plan
    veh = vehicle_for(plan, PickChecker(planner, scene_of("paper_experiment")), seed=0)
    veh.serial_number = "agv-8"
    node = VehicleNode(veh, mosquitto.broker, rate_hz=5, time_scale=1).start()  # ~60 s order
    try:
        r = fleet_client.post(
            f"/api/v1/plans/{plan_id}/dispatch", headers=AUTH, json={"serial_number": "agv-8"}
        )
        job_id = r.json()["id"]
        t_end = time.monotonic() + 20
        job = r.json()
        while time.monotonic() < t_end and not (job["result"] or {}).get("states"):
            time.sleep(0.1)
            job = fleet_client.get(f"/api/v1/jobs/{job_id}").json()
        assert job["state"] == "running" and job["result"]["nodes_reached"] >= 1
        assert fleet_client.post(f"/api/v1/jobs/{job_id}/cancel", headers=AUTH).status_code == 200
        while time.monotonic() < t_end and job["state"] == "running":
            time.sleep(0.1)
            job = fleet_client.get(f"/api/v1/jobs/{job_id}").json()
        assert job["state"] == "cancelled" and "cancelled" in job["error"]
    finally:
        node.stop()


def test_a_dispatch_job_is_refused_by_the_factsheet_and_mapped_by_the_vehicle_types(
    region_db, mosquitto, planner, tmp_path
):
    """A 2.0.0 vehicle calling a pick ``pickPart``: without a vehicle type the job fails naming
    the missing action and the vehicle receives nothing; with the service's vehicle types the
    export renames the pick and the job runs to the end."""
    from pickstop.fleet.factsheet import Body
    from pickstop.fleet.vehicle_types import parse_vehicle_types
    from tests.fleet.test_vehicle_types import TYPES

    folder, _ = region_db
    types = tmp_path / "vehicles.yaml"
    types.write_text(yaml.safe_dump(TYPES))
    settings = Settings(data_dir=folder, api_keys=[hash_key(KEY)],
                        mqtt_broker=mosquitto.broker.url, vehicle_types=types)  # fmt: skip
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    with TestClient(create_app(settings)) as c:
        r = c.post("/api/v1/plans", headers=AUTH,
                   json={"scene": doc, "options": {"sigma": 0.1, "samples": 0}})  # fmt: skip
        plan_id, plan = r.json()["id"], load_plan(r.json()["plan"])
        r = c.get(f"/api/v1/plans/{plan_id}/export?vda_version=2.0&vehicle_type=mm1")
        assert r.status_code == 200
        jsonschema.validate(r.json(), schema("order", "2.0.0"))
        assert {a["actionType"] for n in r.json()["nodes"] for a in n["actions"]} == {"pickPart"}
        assert c.get(f"/api/v1/plans/{plan_id}/export?vehicle_type=nope").status_code == 422

        veh = vehicle_for(plan, PickChecker(planner, scene_of("paper_experiment")), seed=0,
                          version="2.0.0")  # fmt: skip
        veh.manufacturer, veh.serial_number = "other", "mm-5"
        veh.pick = parse_vehicle_types(TYPES).vehicle_types[0].pick
        veh.body = Body(series_name="MM-1")
        veh.forced_error = (0.0, 0.0, 0.0)
        node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
        try:

            def dispatch(**extra) -> dict:
                body = {"manufacturer": "other", "serial_number": "mm-5", "vda_version": "2.0"}
                r = c.post(f"/api/v1/plans/{plan_id}/dispatch", headers=AUTH,
                           json=body | extra)  # fmt: skip
                assert r.status_code == 202, r.text
                job = r.json()
                t_end = time.monotonic() + 60
                while time.monotonic() < t_end and job["state"] in ("queued", "running"):
                    time.sleep(0.1)
                    job = c.get(f"/api/v1/jobs/{job['id']}").json()
                return job

            job = dispatch()  # "other" matches no type: PickStop's own pick
            assert job["state"] == "failed", job
            assert "cannot run order" in job["error"] and "no action 'pick'" in job["error"]
            assert veh.order_id == ""
            job = dispatch(vehicle_type="mm1")
            assert job["state"] == "done", job
            assert job["result"]["actions_finished"] == job["result"]["actions"] > 0
        finally:
            node.stop()


def test_a_dispatch_jobs_arrivals_fit_and_write_a_stored_scene(fleet_client, mosquitto, planner):
    """Three dispatches of a stored scene's plan: each job keeps its arrivals (JSON lines);
    the fit of them, written into the scene with its ETag, gives it a fitted global model."""
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    r = fleet_client.post("/api/v1/scenes", headers=AUTH, json=doc)
    assert r.status_code == 201, r.text
    scene_id, etag = r.json()["id"], r.headers["ETag"]
    r = fleet_client.post("/api/v1/plans", headers=AUTH,
                          json={"scene_id": scene_id, "options": {"samples": 0}})  # fmt: skip
    assert r.status_code == 201, r.text
    plan_id, plan = r.json()["id"], load_plan(r.json()["plan"])
    veh = vehicle_for(plan, PickChecker(planner, scene_of("paper_experiment")), seed=2)
    veh.serial_number = "fit-1"
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
    jobs = []
    try:
        for _ in range(3):
            r = fleet_client.post(f"/api/v1/plans/{plan_id}/dispatch", headers=AUTH,
                                  json={"serial_number": "fit-1"})  # fmt: skip
            job = r.json()
            t_end = time.monotonic() + 60
            while time.monotonic() < t_end and job["state"] in ("queued", "running"):
                time.sleep(0.1)
                job = fleet_client.get(f"/api/v1/jobs/{job['id']}").json()
            assert job["state"] == "done", job
            jobs.append(job["id"])
    finally:
        node.stop()
    r = fleet_client.get(f"/api/v1/jobs/{jobs[0]}/arrivals")
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/x-ndjson")
    lines = [json.loads(x) for x in r.text.splitlines()]
    assert [a["node_id"] for a in lines] == [f"stop{k}" for k in range(len(plan.stops))]
    assert fleet_client.get("/api/v1/jobs/job_nope/arrivals").status_code == 404

    body = {"jobs": jobs, "scene_id": scene_id, "min_arrivals": 3, "write": True}
    r = fleet_client.post("/api/v1/errors/fit", headers=AUTH, json=body)
    assert r.status_code == 428  # no If-Match
    r = fleet_client.post("/api/v1/errors/fit", headers=AUTH | {"If-Match": '"stale"'}, json=body)
    assert r.status_code == 412
    r = fleet_client.post("/api/v1/errors/fit", headers=AUTH | {"If-Match": etag}, json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["format"] == "pickstop.error_model"
    (g,) = out["fit"]["stations"]
    assert g["station"] == "(global)" and g["arrivals"] == 3 * len(plan.stops)
    assert out["fit"]["written"] == ["(global)"]
    stored = fleet_client.get(f"/api/v1/scenes/{scene_id}").json()
    assert stored["etag"] != etag.strip('"') and stored["revision"] == 2
    assert stored["scene"]["error_model"]["covariance"] == out["error_model"]["covariance"]
    r = fleet_client.post("/api/v1/errors/fit", headers=AUTH,
                          json={"arrivals": [{"order_id": "x"}]})  # fmt: skip
    assert r.status_code == 422 and r.json()["field"].startswith("node_id")


def _stop_positions(order: dict) -> list[dict]:
    return [n["nodePosition"] for n in order["nodes"] if n["actions"]]


def _cli_order(plan, region_db, tmp_path, version: str) -> dict:
    """The order ``pickstop export --verify-xy --verify-yaw`` writes for ``plan``."""
    from pickstop.cli import main

    folder, db = region_db
    path, out = tmp_path / "plan.json", tmp_path / f"order-{version}.json"
    path.write_text(plan.model_dump_json())
    args = ["--data-dir", str(folder), "export", str(path), "--format", "vda5050",
            "--vda-version", version, "--scene", str(EXAMPLES / "paper_experiment.json"),
            "--verify-xy", "--verify-yaw", "--db", db.id, "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    return json.loads(out.read_text())


def test_verified_export_carries_what_the_command_proves_once_per_plan(
    fleet_client, stored_plan, region_db, tmp_path, monkeypatch
):
    """``tolerances=verified``: a 3.0 order's stops carry the ellipse and yaw window the
    command proves for the same plan, a 2.1 order the proven circle and the same window, a LIF
    layout the ellipse; proven on the first export only (the planning's ``prove`` is called
    once), kept for the others."""
    plan_id, plan = stored_plan
    service = fleet_client.app.state.service
    calls = []
    prove = service.planning.prove
    monkeypatch.setattr(service.planning, "prove", lambda *a: calls.append(a) or prove(*a))
    url = f"/api/v1/plans/{plan_id}/export"
    r = fleet_client.get(url, params={"vda_version": "3.0", "tolerances": "verified"})
    assert r.status_code == 200, r.text
    assert len(calls) == 1
    jsonschema.validate(r.json(), schema("order", "3.0.0"))
    cli = _stop_positions(_cli_order(plan, region_db, tmp_path, "3.0"))
    api = _stop_positions(r.json())
    assert len(api) == len(plan.stops) > 0
    assert [p["allowedDeviationXY"] for p in api] == [p["allowedDeviationXY"] for p in cli]
    assert [p["allowedDeviationTheta"] for p in api] == [p["allowedDeviationTheta"] for p in cli]
    assert all(p["allowedDeviationXY"]["a"] > p["allowedDeviationXY"]["b"] for p in api)

    kept = service.proofs.kept(plan_id)
    v2 = _stop_positions(fleet_client.get(url).json())  # 2.1, verified by default
    assert [p["allowedDeviationXY"] for p in v2] == [s.radius for s in kept.shapes]
    assert [p["allowedDeviationTheta"] for p in v2] == [p["allowedDeviationTheta"] for p in cli]
    layout = fleet_client.get(url, params={"format": "lif"}).json()["layouts"][0]
    dev = [e["vehicleTypeEdgeProperties"][0].get("allowedDeviationXY") for e in layout["edges"]]
    assert [d for d in dev if d] == [p["allowedDeviationXY"] for p in cli]
    assert fleet_client.get(url, params={"format": "nav2"}).status_code == 200
    assert len(calls) == 1  # every later export read the kept proof

    radius = _stop_positions(fleet_client.get(url, params={"tolerances": "radius"}).json())
    assert [p["allowedDeviationTheta"] for p in radius] != [p["allowedDeviationTheta"] for p in v2]
    assert [p["allowedDeviationXY"] for p in radius] == [guaranteed_radius(s) for s in plan.stops]
    assert fleet_client.get(url, params={"tolerances": "exact"}).status_code == 422


def test_dispatch_sends_the_proven_tolerances(fleet_client, stored_plan, mosquitto, planner):
    """A dispatch asks for verified tolerances by default: the order the vehicle receives
    carries each stop's proven circle and yaw window."""
    plan_id, plan = stored_plan
    veh = vehicle_for(plan, PickChecker(planner, scene_of("paper_experiment")), seed=0)
    veh.serial_number, veh.forced_error = "agv-9", (0.0, 0.0, 0.0)
    received = []
    accept = veh.accept
    veh.accept = lambda doc: received.append(doc) or accept(doc)  # type: ignore[method-assign]
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
    try:
        r = fleet_client.post(f"/api/v1/plans/{plan_id}/dispatch", headers=AUTH,
                              json={"serial_number": "agv-9"})  # fmt: skip
        assert r.status_code == 202, r.text
        job = r.json()
        assert job["params"]["tolerances"] == "verified"
        t_end = time.monotonic() + 60
        while time.monotonic() < t_end and job["state"] in ("queued", "running"):
            time.sleep(0.1)
            job = fleet_client.get(f"/api/v1/jobs/{job['id']}").json()
        assert job["state"] == "done", job
    finally:
        node.stop()
    kept = fleet_client.app.state.service.proofs.kept(plan_id)
    stops = _stop_positions(received[0])
    assert [p["allowedDeviationXY"] for p in stops] == [s.radius for s in kept.shapes]
    assert [p["allowedDeviationTheta"] for p in stops] == list(kept.yaw)
