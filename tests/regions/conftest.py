from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickstop.reach.build import BuildParams, build
from pickstop.reach.database import open_database

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


@pytest.fixture(scope="session")
def region_db(tmp_path_factory, tiago):
    """A 600k-sample TIAGo database for region tests: (data folder, database)."""
    folder = tmp_path_factory.mktemp("regiondata")
    row = build(tiago, BuildParams(samples=600_000, chunk_size=150_000, seed=11), folder, workers=2)
    return folder, open_database(folder, tiago, row["id"])


@pytest.fixture(scope="session")
def planner(region_db, tiago):
    from pickstop.regions.base_region import RegionPlanner
    from pickstop.settings import cache_dir

    folder, db = region_db
    return RegionPlanner(tiago, db, cache_dir=cache_dir(folder))


@pytest.fixture()
def paper_doc():
    return json.loads((EXAMPLES / "paper_experiment.json").read_text())
