from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.settings import Settings, hash_key

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
KEY = "test-key-0123456789"
AUTH = {"Authorization": f"Bearer {KEY}"}


@pytest.fixture(scope="session")
def api_settings(region_db):
    folder, db = region_db
    return Settings(data_dir=folder, api_keys=[hash_key(KEY)], max_body_bytes=300_000,
                    default_databases={"tiago": db.id})  # fmt: skip


@pytest.fixture(scope="session")
def client(api_settings):
    with TestClient(create_app(api_settings)) as c:
        yield c
