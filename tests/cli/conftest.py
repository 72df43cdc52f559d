"""Running ``pickstop`` in this process; a plan file of the paper scene for the fleet commands."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickstop.cli import main
from tests.fleet.conftest import example_plans, fleet_stop_planner, mosquitto  # noqa: F401 (fixtures)

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def run(capsys, *argv):
    """``pickstop argv``: its exit code, stdout and stderr."""
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def exit_code(*argv) -> int:
    """The exit code of ``pickstop argv``, argparse's own refusals (SystemExit) included."""
    try:
        return main(list(argv))
    except SystemExit as e:
        return e.code


@pytest.fixture(scope="module")
def plan_file(example_plans, tmp_path_factory):  # noqa: F811 (the fixture, imported above)
    _, plan = example_plans["paper_experiment"]
    path = tmp_path_factory.mktemp("fleetcli") / "plan.json"
    path.write_text(json.dumps(plan.model_dump(mode="json")))
    return path
