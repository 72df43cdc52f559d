from __future__ import annotations

import pytest

from pickstop.reach.build import BuildParams
from pickstop.store.reach_build import build


@pytest.fixture(scope="session")
def small_db(tmp_path_factory, tiago):
    """A 300k-sample TIAGo database in its own data folder: (folder, catalog row, params)."""
    folder = tmp_path_factory.mktemp("reachdata")
    params = BuildParams(samples=300_000, chunk_size=50_000, seed=7)
    row = build(tiago, params, folder, workers=2)
    return folder, row, params


@pytest.fixture(scope="session")
def small_loaded(small_db, tiago):
    from pickstop.store.reach_catalog import open_database

    folder, row, _ = small_db
    return open_database(folder, tiago, row["id"])
