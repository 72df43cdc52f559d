"""The example scenes' plans against their stored documents (``tests/sequence/expected/``).

Each example is planned from scratch (:func:`~pickstop.sequence.request.plan_from_scratch`:
the algorithm alone, so the plan depends on the scene, the options and the session's database,
never on what was planned before) and compared with the stored plan, timings aside, floats to
1e-9. A change that moves a stop, a route point, a witness or a success figure of an example
shows here. After a change meant to alter plans, write them anew and review the diff::

    PICKSTOP_WRITE_EXPECTED=1 python -m pytest tests/sequence/test_examples.py
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop.sequence.plan_model import PlanOptions
from pickstop.sequence.request import plan_from_scratch
from tests.utils import same_document

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
EXPECTED = Path(__file__).parent / "expected"
NAMES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]
OPTIONS = PlanOptions(samples=200)


@pytest.mark.parametrize("name", NAMES)
def test_the_example_plans_are_the_stored_ones(planner, name):
    scene = parse_scene(json.loads((EXAMPLES / f"{name}.json").read_text()))
    plan = plan_from_scratch(planner.scratch(), scene, OPTIONS)
    doc = json.loads(plan.model_dump_json(exclude={"timings"}))
    path = EXPECTED / f"{name}.json"
    if os.environ.get("PICKSTOP_WRITE_EXPECTED"):
        path.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    assert path.exists(), f"no stored plan {path}: write it with PICKSTOP_WRITE_EXPECTED=1"
    same_document(doc, json.loads(path.read_text()))


def test_a_moved_stop_is_told(planner):
    """The comparison is strict enough to see one stop moved by a millimetre."""
    doc = json.loads((EXPECTED / "paper_experiment.json").read_text())
    moved = json.loads(json.dumps(doc))
    moved["stops"][0]["x"] += 0.001
    with pytest.raises(AssertionError, match=r"stops\[0\]\.x"):
        same_document(moved, doc)
