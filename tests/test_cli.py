"""The ``pickstop`` command: JSON out, clear errors, exit code 2 for bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from pickstop.cli import main


def _run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def cli_data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clidata")
    code = main(
        [
            "--data-dir",
            str(folder),
            "reach",
            "build",
            "--samples",
            "40000",
            "--chunk-size",
            "20000",
            "--workers",
            "1",
            "--quiet",
        ]
    )
    assert code == 0
    return folder


def test_build_info_query(cli_data, capsys):
    code, out, _ = _run(capsys, "--data-dir", str(cli_data), "reach", "info")
    assert code == 0
    info = json.loads(out)
    assert info[0]["state"] == "complete" and info[0]["shards"] == 2
    assert info[0]["indexed"] and info[0]["index_bytes"] > 0 and info[0]["voxels"] > 0
    code, out, _ = _run(
        capsys,
        "--data-dir",
        str(cli_data),
        "reach",
        "query",
        "--pose",
        "0.6",
        "-0.2",
        "0.8",
        "0.7071068",
        "0",
        "0.7071068",
        "0",
        "--neighbours",
        "--refine",
    )
    assert code == 0
    res = json.loads(out)
    assert res["voxel"]["resolution_m"] == 0.05
    assert res["count"] >= len(res["candidates"]) and len(res["candidates"]) <= 10
    assert res["count"] > 0 and res["candidates"][0]["theta"]
    assert "refined" in res and isinstance(res["refined"]["success"], bool)


def test_build_again_is_a_no_op(cli_data, capsys):
    code, out, _ = _run(
        capsys,
        "--data-dir",
        str(cli_data),
        "reach",
        "build",
        "--samples",
        "40000",
        "--chunk-size",
        "20000",
        "--workers",
        "1",
        "--quiet",
    )
    assert code == 0 and json.loads(out)["state"] == "complete"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["reach", "query", "--pose", "1", "2", "3"], "expected 7 arguments"),
        (["reach", "query", "--pose", "1", "2", "x", "1", "0", "0", "0"], "not a number: 'x'"),
        (["reach", "build", "--samples", "-5"], "must be positive"),
        (["reach", "build", "--robot", "fetchy"], "unknown robot 'fetchy'"),
        (["reach", "build", "--resolution", "0", "--samples", "5000"], "resolution must be"),
        (
            ["reach", "query", "--pose", "0.5", "0", "0.7", "1", "1", "0", "0"],
            "unit quaternion",
        ),
        (["ui", "--draft-scale", "0"], "--draft-scale: must be in (0, 1], got 0"),
        (["ui", "--draft-scale", "1.5"], "must be in (0, 1], got 1.5"),
        (["ui", "--lighting", "dark"], "--lighting: invalid choice: 'dark'"),
        (["nonsense"], "invalid choice"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    try:
        code = main(["--data-dir", str(tmp_path), *argv])
    except SystemExit as e:  # argparse
        code = e.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err


def test_query_without_database_explains(tmp_path, capsys):
    code, _, err = _run(
        capsys,
        "--data-dir",
        str(tmp_path),
        "reach",
        "query",
        "--pose",
        "0.5",
        "0",
        "0.7",
        "1",
        "0",
        "0",
        "0",
    )
    assert code == 5  # no database: its own exit code, documented in docs/cli.md
    assert "no complete reachability database for robot 'tiago'" in err
    assert f"`pickstop --data-dir {tmp_path.resolve()} reach build --robot tiago`" in err


def test_console_script_installed(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "pickstop.cli", "--data-dir", str(tmp_path), "reach", "info"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0 and json.loads(proc.stdout) == []


def _scene_naming(folder, robot_block):
    """The paper-like scene in ``folder``, naming its robot by ``robot_block``."""
    from pathlib import Path

    src = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"
    doc = json.loads(src.read_text())
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

    import pickstop.cli
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)  # the hint names the config relative to the working folder
    scene, tray = _scene_naming(tmp_path, {"config": "robot/dense_amr.yaml"})
    data = ["--data-dir", str(tmp_path / "data")]
    code, _, err = _run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 5, err
    command = _hint(err)
    assert "--robot robot/dense_amr.yaml" in command and "dense_amr.yaml" in str(config)
    # Run as printed (the default sample count made small for a test).
    monkeypatch.setattr(pickstop.cli, "DEFAULT_SAMPLES", 20_000)
    code, out, err = _run(capsys, *shlex.split(command)[1:], "--quiet")
    assert code == 0, err
    assert json.loads(out)["state"] == "complete"
    code, out, err = _run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 0, err
    assert json.loads(out)["database"]


def test_robot_option_overrides_the_scenes_robot(tmp_path, capsys, monkeypatch):
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)
    scene, tray = _scene_naming(tmp_path, {"preset": "tiago"})
    data = ["--data-dir", str(tmp_path / "data")]
    for argv in (["plan", str(scene)], ["regions", str(scene), "--tray", tray]):
        code, _, err = _run(capsys, *data, *argv, "--robot", str(config))
        assert code == 5, err  # the config robot has no database: it, not TIAGo, was asked for
        assert "robot 'dense_amr'" in err and "--robot robot/dense_amr.yaml" in _hint(err)
        code, _, err = _run(capsys, *data, *argv, "--robot", "tiago")
        assert code == 5 and "--robot tiago" in _hint(err)
        code, _, err = _run(capsys, *data, *argv, "--robot", "nowhere.yaml")
        assert code == 2 and "nowhere.yaml: robot config file not found" in err


def test_ui_robot_option_registers_a_config_with_the_api(tmp_path):
    import httpx

    from pickstop.cli import _api_robot
    from pickstop_ui.client import PickStopClient
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path, triangles=500, arm_mesh=False)
    posted = []

    def api(request: httpx.Request) -> httpx.Response:
        if request.method == "GET":
            return httpx.Response(200, json=[{"name": "tiago"}])
        posted.append((request.headers["content-type"], request.content))
        return httpx.Response(201, json={"name": "dense_amr"})

    client = PickStopClient("http://api")
    client.http = httpx.Client(base_url="http://api", transport=httpx.MockTransport(api))
    assert _api_robot(client, "tiago") == "tiago" and not posted  # a preset: as it is
    assert _api_robot(client, str(config)) == "dense_amr"
    assert posted == [("application/yaml", config.read_bytes())]
