"""Shared fixtures: robots load once per session; small databases build once per session."""

from __future__ import annotations

import os
import warnings

import pytest

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def pytest_configure(config):
    # Per-robot derived data (disabled pairs, screen) is shared by every test of a run.
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


@pytest.fixture(scope="session", params=["tiago", "pr2"])
def robot(request, tiago, pr2):
    return tiago if request.param == "tiago" else pr2
