"""``pickstop regions`` and ``pickstop plan``: plans of one scene, a folder of them and a mix's
orders; bad options exit 2, an infeasible plan 3 with its explanation; ``--robot`` overrides
the scene's robot, and the missing-database hint runs as printed."""

from __future__ import annotations

import json
import shutil

import pytest

from pickstop.cli import main
from tests.cli.conftest import EXAMPLES, exit_code, run


def _scene_naming(folder, robot_block):
    """The paper-like scene in ``folder``, naming its robot by ``robot_block``."""
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["robot"] = robot_block
    path = folder / "scene.json"
    path.write_text(json.dumps(doc))
    return path, doc["trays"][0]["id"]


def _hint(err):
    import re

    (command,) = re.findall(r"`(pickstop [^`]+)`", err)
    return command


def test_missing_database_hint_for_a_config_robot_runs_as_printed(tmp_path, capsys, monkeypatch):
    import shlex

    import pickstop.cli.reach
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)  # the hint names the config relative to the working folder
    scene, tray = _scene_naming(tmp_path, {"config": "robot/dense_amr.yaml"})
    data = ["--data-dir", str(tmp_path / "data")]
    code, _, err = run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 5, err
    command = _hint(err)
    assert "--robot robot/dense_amr.yaml" in command and "dense_amr.yaml" in str(config)
    # Run as printed (the default sample count made small for a test).
    monkeypatch.setattr(pickstop.cli.reach, "DEFAULT_SAMPLES", 20_000)
    code, out, err = run(capsys, *shlex.split(command)[1:], "--quiet")
    assert code == 0, err
    assert json.loads(out)["state"] == "complete"
    code, out, err = run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 0, err
    assert json.loads(out)["database"]


def test_robot_option_overrides_the_scenes_robot(tmp_path, capsys, monkeypatch):
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)
    scene, tray = _scene_naming(tmp_path, {"preset": "tiago"})
    data = ["--data-dir", str(tmp_path / "data")]
    for argv in (["plan", str(scene)], ["regions", str(scene), "--tray", tray]):
        code, _, err = run(capsys, *data, *argv, "--robot", str(config))
        assert code == 5, err  # the config robot has no database: it, not TIAGo, was asked for
        assert "robot 'dense_amr'" in err and "--robot robot/dense_amr.yaml" in _hint(err)
        code, _, err = run(capsys, *data, *argv, "--robot", "tiago")
        assert code == 5 and "--robot tiago" in _hint(err)
        code, _, err = run(capsys, *data, *argv, "--robot", "nowhere.yaml")
        assert code == 2 and "nowhere.yaml: robot config file not found" in err


def test_plan_one_scene_to_a_file(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--samples", "200", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    summary = json.loads(stdout)
    plan = json.loads(out.read_text())
    assert plan["format"] == "pickstop.plan" and plan["database"] == db.id
    assert summary["stops"] == len(plan["stops"]) and summary["naive_stops"] == 3
    assert plan["parameters"]["samples"] == 200


def test_plan_a_folder_with_one_bad_scene(region_db, tmp_path, capsys):
    folder, db = region_db
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(EXAMPLES / "paper_experiment.json", scenes / "a.json")
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["sigma"] = 0.5
    (scenes / "b_wide_sigma.json").write_text(json.dumps(doc))
    (scenes / "c_broken.json").write_text("{not json")
    code, stdout, _ = run(
        capsys, "--data-dir", str(folder), "plan", str(scenes), "--samples", "0",
        "--out", str(tmp_path / "plans"), "--db", db.id,
    )  # fmt: skip
    assert code == 2  # the worst failure: an invalid file
    lines = stdout.splitlines()
    assert lines[0].split()[:4] == ["scene", "status", "trays", "stops"]
    assert lines[1].startswith("a.json") and " ok " in lines[1]
    assert "b_wide_sigma.json: no plan with sigma = 0.500 m" in stdout
    assert "c_broken.json:" in stdout and "not valid JSON" in stdout
    assert "1 of 3 scenes planned" in stdout
    assert sorted(p.name for p in (tmp_path / "plans").iterdir()) == ["a.plan.json"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--sigma", "-0.1"], "--sigma: Input should be greater than or equal to 0"),
        (["--target", "1.5"], "--target: Input should be less than 1"),
        (["--samples", "-3"], "--samples: Input should be greater than or equal to 0"),
        (["--rule", "luck"], "invalid choice: 'luck'"),
    ],
)
def test_bad_plan_options_exit_2(tmp_path, capsys, extra, message):
    scene = str(EXAMPLES / "paper_experiment.json")
    assert exit_code("--data-dir", str(tmp_path), "plan", scene, *extra) == 2
    assert message in capsys.readouterr().err


def test_infeasible_plan_exits_3_with_its_explanation(region_db, capsys):
    folder, db = region_db
    code, stdout, err = run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--sigma", "0.6", "--samples", "0", "--db", db.id,
    )  # fmt: skip
    assert code == 3 and stdout == ""
    assert "no plan with sigma = 0.600 m: tray tray_1:" in err


def test_expected_time_objective_carries_its_trade_off(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "five_trays.json"),
        "--objective", "expected-time", "--samples", "100", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    plan = json.loads(out.read_text())
    assert plan["parameters"]["objective"] == "expected-time"
    rows = plan["tradeoff"]
    assert [r["stops"] for r in rows] == sorted(r["stops"] for r in rows)
    assert [r["stops"] for r in rows if r["chosen"]] == [len(plan["stops"])]
    summary = json.loads(stdout)
    assert summary["expected_s"] == round(plan["totals"]["time"]["expected"], 1)
    assert summary["expected_s"] >= summary["time_s"]


def test_plan_every_order_of_a_mix_to_a_folder(region_db, tmp_path, capsys):
    folder, db = region_db
    orders = tmp_path / "orders.json"
    orders.write_text(json.dumps([{"id": "a", "trays": ["tray_1", "tray_2"], "weight": 2},
                                  {"id": "b", "parts": ["p4a"]}]))  # fmt: skip
    out = tmp_path / "mix"
    code, stdout, _ = run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--orders", str(orders), "--samples", "0", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    mix = json.loads(stdout)
    assert mix == json.loads((out / "mix.json").read_text())
    assert mix["format"] == "pickstop.mix" and mix["totals"]["planned"] == 2
    assert sorted(p.name for p in out.iterdir()) == ["a.plan.json", "b.plan.json", "mix.json"]
    b = json.loads((out / "b.plan.json").read_text())
    assert b["format"] == "pickstop.plan" and b["trays"] == ["tray_4"]
    assert mix["orders"][1] == {**mix["orders"][1], "plan": "b.plan.json", "trays": ["tray_4"],
                                "stops": 1, "naive_stops": 1}  # fmt: skip


def test_orders_the_scene_lacks_or_a_tray_in_mid_air_exit_2(tmp_path, capsys):
    scene = str(EXAMPLES / "paper_experiment.json")
    code = main(["--data-dir", str(tmp_path), "plan", scene, "--orders"])
    assert code == 2 and "the scene has no orders" in capsys.readouterr().err
    bad = tmp_path / "orders.json"
    bad.write_text(json.dumps([{"id": "a", "trays": ["tray_7"]}]))
    code = main(["--data-dir", str(tmp_path), "plan", scene, "--orders", str(bad)])
    assert code == 2 and "orders.0.trays.0: order 'a': unknown tray 'tray_7'" in (
        capsys.readouterr().err
    )
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["trays"][3]["pose"]["y"] = 1.1  # beside its table
    (tmp_path / "air.json").write_text(json.dumps(doc))
    code = main(["--data-dir", str(tmp_path), "plan", str(tmp_path / "air.json")])
    err = capsys.readouterr().err
    assert code == 2 and "tray 'tray_4' stands on nothing: its bottom is 0.720 m" in err
