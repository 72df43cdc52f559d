from __future__ import annotations

import json
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


@pytest.fixture()
def paper_doc():
    return json.loads((EXAMPLES / "paper_experiment.json").read_text())
