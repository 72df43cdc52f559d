"""``pickstop errors fit``: the fit of arrivals logged by a simulated vehicle with a known error
model holds the truth, is written into the scene, and a re-plan says what changed."""

from __future__ import annotations

import json

import pytest

from pickstop.cli import main
from tests.cli.conftest import EXAMPLES


@pytest.mark.slow
def test_simulate_500_runs_with_a_known_model_and_fit_it_back(
    plan_file, example_plans, region_db, tmp_path, capsys
):
    """The loop end to end: 500 executions of the paper plan over MQTT, the vehicle landing
    off by a known anisotropic, biased model per stop (in its base frame) and recording every
    arrival; the fit of the log holds the truth within its 95% intervals, is written into the
    scene, and a re-plan with it says what changed."""
    import yaml

    from pickstop.fleet.arrivals import read_log
    from pickstop.fleet.fit import group_name

    _, plan = example_plans["paper_experiment"]
    folder, db = region_db
    truths = [
        {"mean": [0.02, -0.01], "covariance": [[4e-4, 1e-4], [1e-4, 1e-4]], "yaw_mean": 0.006,
         "yaw_sigma": 0.012},
        {"mean": [-0.015, 0.004], "covariance": [[1e-4, -5e-5], [-5e-5, 2.5e-4]],
         "yaw_mean": -0.004, "yaw_sigma": 0.008},
    ]  # fmt: skip
    stations = [{"name": f"s{k}", "trays": s.trays, **truths[k % 2]}
                for k, s in enumerate(plan.stops)]  # fmt: skip
    truth = tmp_path / "truth.yaml"
    truth.write_text(yaml.safe_dump({"format": "pickstop.error_model", "version": 1,
                                     "error_model": {"stations": stations}}))  # fmt: skip
    log, model = tmp_path / "arrivals.jsonl", tmp_path / "fitted.json"
    scene_file = str(EXAMPLES / "paper_experiment.json")
    common = ["--data-dir", str(folder)]
    assert main([*common, "execute-sim", str(plan_file), "--scene", scene_file, "--runs", "500",
                 "--seed", "3", "--db", db.id, "--error-model", str(truth),
                 "--record", str(log)]) == 0  # fmt: skip
    arrivals = read_log(log)
    assert len(arrivals) == 500 * len(plan.stops)
    assert len({a.order_id for a in arrivals}) == 500
    # the scene's stations: one per stop's trays, with the scene's model until fitted
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["error_model"] = {**doc.get("error_model", {}), "stations": [
        {"name": st["name"], "trays": st["trays"]} for st in stations]}  # fmt: skip
    with_stations, fitted_scene = tmp_path / "stations.json", tmp_path / "fitted_scene.json"
    with_stations.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main([*common, "errors", "fit", str(log), "--out", str(model), "--scene",
                 str(with_stations), "--write-scene", str(fitted_scene), "--replan",
                 str(plan_file), "--db", db.id]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "re-plan:" in printed and "(model s0)" in printed
    fit = json.loads(model.read_text())["fit"]
    assert fit["arrivals"] == 500 * len(plan.stops)
    assert fit["written"] == [st["name"] for st in stations]
    by_name = {s["station"]: s for s in fit["stations"]}
    for st in stations:
        f = by_name[st["name"]]
        assert f["arrivals"] == 500
        C = st["covariance"]
        for i in range(2):
            lo, hi = f["mean_interval"][i]
            assert lo <= st["mean"][i] <= hi, (st["name"], "mean", i, f)
            lo, hi = f["variance_interval"][i]
            assert lo <= C[i][i] <= hi, (st["name"], "variance", i, f)
        lo, hi = f["covariance_interval"]
        assert lo <= C[0][1] <= hi, (st["name"], "covariance", f)
        lo, hi = f["yaw_mean_interval"]
        assert lo <= st["yaw_mean"] <= hi, (st["name"], "yaw mean", f)
        lo, hi = f["yaw_sigma_interval"]
        assert lo <= st["yaw_sigma"] <= hi, (st["name"], "yaw sd", f)
    written = json.loads(fitted_scene.read_text())["error_model"]["stations"]
    assert [(w["name"], w["trays"], w["arrivals"]) for w in written] == [
        (st["name"], st["trays"], 500) for st in stations
    ]
    # without a scene: one station per tray group, the same estimates
    assert main(["errors", "fit", str(log)]) == 0
    assert group_name(plan.stops[0].trays) in capsys.readouterr().out
