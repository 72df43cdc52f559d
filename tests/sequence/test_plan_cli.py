"""``pickstop plan``: one scene to a plan file, a folder to a summary table, clear errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from pickstop.cli import main

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def _run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_plan_one_scene_to_a_file(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = _run(
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
    code, stdout, _ = _run(
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
    try:
        code = main(
            ["--data-dir", str(tmp_path), "plan", str(EXAMPLES / "paper_experiment.json"), *extra]
        )
    except SystemExit as e:
        code = e.code
    assert code == 2
    assert message in capsys.readouterr().err


def test_infeasible_plan_exits_3_with_its_explanation(region_db, capsys):
    folder, db = region_db
    code, stdout, err = _run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--sigma", "0.6", "--samples", "0", "--db", db.id,
    )  # fmt: skip
    assert code == 3 and stdout == ""
    assert "no plan with sigma = 0.600 m: tray tray_1:" in err


def test_expected_time_objective_carries_its_trade_off(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = _run(
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
