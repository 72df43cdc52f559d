from __future__ import annotations

import pytest

from pickstop.reach.build import BuildParams
from pickstop.store.reach_build import build
from tests.once import built_once, own_copy

SMALL = BuildParams(samples=300_000, chunk_size=50_000, seed=7)


@pytest.fixture(scope="session")
def small_db(tmp_path_factory, tiago):
    """A 300k-sample TIAGo database in its own data folder: (folder, catalog row, params). Built
    once per run (tests/once.py); this worker's own copy of the data folder."""
    shared, row = built_once(
        tmp_path_factory, "reachdata", lambda folder: build(tiago, SMALL, folder, workers=2)
    )
    return own_copy(tmp_path_factory, shared, "reachdata"), row, SMALL


@pytest.fixture(scope="session")
def small_loaded(small_db, tiago):
    from pickstop.store.reach_catalog import open_database

    folder, row, _ = small_db
    return open_database(folder, tiago, row["id"])
