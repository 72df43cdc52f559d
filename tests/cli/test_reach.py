"""``pickstop reach``: build, info and query as JSON, a second build a no-op, bad input exits 2
naming it, a query without a database says how to build one."""

from __future__ import annotations

import json

import pytest

from pickstop.cli import main
from tests.cli.conftest import exit_code, run


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
    code, out, _ = run(capsys, "--data-dir", str(cli_data), "reach", "info")
    assert code == 0
    info = json.loads(out)
    assert info[0]["state"] == "complete" and info[0]["shards"] == 2
    assert info[0]["indexed"] and info[0]["index_bytes"] > 0 and info[0]["voxels"] > 0
    code, out, _ = run(
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
    code, out, _ = run(
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
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    assert exit_code("--data-dir", str(tmp_path), *argv) == 2
    assert message in capsys.readouterr().err


def test_query_without_database_explains(tmp_path, capsys):
    code, _, err = run(
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
