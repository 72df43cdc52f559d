"""Data built once per test run and shared by the xdist workers.

A session fixture that builds a database would build it in every worker, at once, on the same
cores. :func:`built_once` builds it in a folder of the run's (beside the workers' own temporary
folders), under a file lock: the first worker builds, the others wait and then take its result.
Nobody writes to that folder afterwards: each worker plans from its own copy
(:func:`own_copy`), where tests may add, change and delete what they like.
"""

from __future__ import annotations

import fcntl
import os
import pickle
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest

T = TypeVar("T")

BUILDS_LOG = "builds.log"  # one line per build in the run's folder: name, worker, seconds


def run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The temporary folder of the whole run: the workers' common parent under xdist, else the
    process's own."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def built_once(
    tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], T]
) -> tuple[Path, T]:
    """``build(folder)`` run once per test run, whatever the number of workers: (the folder it
    built in, its result, which must pickle). A build that died half way is started again."""
    root = run_folder(tmp_path_factory)
    folder, result = root / f"shared-{name}", root / f"shared-{name}.pkl"
    with open(root / f"shared-{name}.lock", "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not result.is_file():
                shutil.rmtree(folder, ignore_errors=True)
                folder.mkdir()
                t0 = time.perf_counter()
                value = build(folder)
                seconds = time.perf_counter() - t0
                result.write_bytes(pickle.dumps(value))
                worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
                with open(root / BUILDS_LOG, "a") as log:
                    log.write(f"{name} {worker} {seconds:.1f}s\n")
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return folder, pickle.loads(result.read_bytes())


def own_copy(tmp_path_factory: pytest.TempPathFactory, folder: Path, name: str) -> Path:
    """A copy of ``folder`` that this worker alone uses (a new folder each call)."""
    copy = tmp_path_factory.mktemp(name) / "data"
    shutil.copytree(folder, copy)
    return copy
