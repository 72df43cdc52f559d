"""Shared fixtures: robots load once per session; small databases build once per session."""

from __future__ import annotations

import json
import os
import warnings
from functools import partial

import pytest

from tests.once import built_once, own_copy

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def pytest_configure(config):
    # Per-robot derived data (disabled pairs, screen) is made once per run and shared by every
    # test: the xdist workers start after this runs in the controller and inherit its
    # environment; the cache's file locks keep two workers from making the same data twice.
    import tempfile

    os.environ.setdefault("PICKSTOP_CACHE_DIR", tempfile.mkdtemp(prefix="pickstop-cache-"))


warnings.filterwarnings("ignore", message="You passed package dir")

PR2_CONFIG = os.path.join(os.path.dirname(__file__), "..", "examples", "robots", "pr2.yaml")


@pytest.fixture(scope="session")
def tiago():
    from pickstop.robot.model import load

    return load("tiago")


@pytest.fixture(scope="session")
def pr2():
    from pickstop.robot.model import load

    return load(PR2_CONFIG)


def _build_region_db(tiago, folder):
    from pickstop.reach.build import BuildParams
    from pickstop.settings import cache_dir
    from pickstop.speedups.region_planner import RegionPlanner
    from pickstop.store.reach_build import build
    from pickstop.store.reach_catalog import open_database

    row = build(
        tiago, BuildParams(samples=2_000_000, chunk_size=250_000, seed=11), folder, workers=2
    )
    # A planner built here compiles the numba kernels into their on-disk cache (once per
    # checkout), before the services and workers the tests start load them from it.
    RegionPlanner(
        tiago, open_database(folder, tiago, row["id"]), cache_dir=cache_dir(folder)
    ).close()
    return row


@pytest.fixture(scope="session")
def region_db(tmp_path_factory, tiago):
    """A 2M-sample TIAGo database for region tests: (data folder, database). Built once per run
    (tests/once.py); this worker's own copy of the data folder, which its tests may write to."""
    from pickstop.store.reach_catalog import open_database

    shared, row = built_once(tmp_path_factory, "regiondata", partial(_build_region_db, tiago))
    folder = own_copy(tmp_path_factory, shared, "regiondata")
    return folder, open_database(folder, tiago, row["id"])


@pytest.fixture(scope="session")
def planner(region_db, tiago):
    from pickstop.settings import cache_dir
    from pickstop.speedups.region_planner import RegionPlanner

    folder, db = region_db
    return RegionPlanner(tiago, db, cache_dir=cache_dir(folder))


EXAMPLE_SCENES = os.path.join(os.path.dirname(__file__), "..", "examples", "scenes")


@pytest.fixture()
def paper_doc():
    """The paper-like example scene's document (a fresh copy per test)."""
    with open(os.path.join(EXAMPLE_SCENES, "paper_experiment.json")) as f:
        return json.load(f)


@pytest.fixture(scope="module")
def stop_planner(planner):
    """A stop planner per module over the session's region planner."""
    from pickstop.speedups.stop_planner import StopPlanner

    return StopPlanner(planner)


@pytest.fixture(scope="module")
def paper_plan(stop_planner):
    """The paper-like scene and its plan (300 samples a stop)."""
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.plan_model import PlanOptions

    with open(os.path.join(EXAMPLE_SCENES, "paper_experiment.json")) as f:
        scene = parse_scene(json.load(f))
    return scene, stop_planner.plan(scene, PlanOptions(samples=300))


@pytest.fixture(scope="session", params=["tiago", "pr2"])
def robot(request, tiago, pr2):
    return tiago if request.param == "tiago" else pr2


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


LIVE_KEY = "test-key-0123456789"


@pytest.fixture(scope="session")
def live_api(region_db, tmp_path_factory):
    """``pickstop serve`` under uvicorn on 127.0.0.1 over the test database: its base URL."""
    import subprocess

    from pickstop.settings import hash_key
    from pickstop.stack import spawn_api

    folder, db = region_db
    port = free_port()
    env = {
        **os.environ,
        "PICKSTOP_DATA_DIR": str(folder),
        # plans naming no database use the session's, whatever a test builds beside it
        "PICKSTOP_DEFAULT_DATABASES": json.dumps({"tiago": db.id}),
        "PICKSTOP_API_KEYS": f'["{hash_key(LIVE_KEY)}"]',
        "PICKSTOP_MAX_SAMPLES": "40000",
        "PICKSTOP_MAX_BATCH": "3",
        "PICKSTOP_MAX_BODY_BYTES": "200000",
        "PICKSTOP_REQUEST_DEADLINE": "20",
    }
    log = (tmp_path_factory.mktemp("live") / "serve.log").open("w")
    proc = spawn_api(port, env, log, timeout=120)
    url = f"http://127.0.0.1:{port}"
    yield url
    proc.terminate()
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
    log.close()
