"""The on-disk cache of robots' derived data: one folder for every data folder and process.

What depends on a robot alone (its disabled pairs, self-collision screen, covers, outline) is
kept per robot hash in ``<cache>/robots/`` (:func:`pickstop.settings.cache_dir`). A file is
written atomically (temporary file, then rename) and made under a lock, so processes asking
for the same entry at once make it once: the others wait, then read it. :data:`COMPUTED`
counts what this process made rather than read.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")
_FORMAT = 2

#: Entries this process computed (rather than read from memory or the cache), by kind.
COMPUTED: Counter[str] = Counter()


def robots_folder(cache_dir: Path | str | None) -> Path | None:
    """``<cache>/robots``, where robots' derived data lives (None: no cache)."""
    return None if cache_dir is None else Path(cache_dir) / "robots"


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path``: a reader sees the old file or the new one, never half."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def making(path: Path | None) -> Iterator[None]:
    """Hold the lock of cache entry ``path`` while it is made (nothing for None): a process
    making the same entry waits here, then finds it made."""
    if path is None:
        yield
        return
    try:
        import fcntl
    except ImportError:  # no advisory locks here: entries may be made twice, never torn
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(f".{path.name}.lock"), "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def derived(robot: Any, cache_dir: Path | str | None, name: str, make: Callable[[], T]) -> T:
    """``make()``, a value that depends on nothing but ``robot`` (a loaded robot: its
    ``robot_hash``) and ``name`` (which says what and how it is made), kept on disk per robot
    hash in ``<cache>/robots/``; a cache file that does not load, or belongs to another robot
    or kind, is made again. Counted in :data:`COMPUTED` under ``name`` when made."""
    folder = robots_folder(cache_dir)
    path = None if folder is None else folder / f"{name}-{robot.robot_hash[:24]}-v{_FORMAT}.pkl"
    found, value = _read_derived(path, robot.robot_hash, name)
    if found:
        return value  # type: ignore[no-any-return]
    with making(path):  # another process making it: wait, then read it
        found, value = _read_derived(path, robot.robot_hash, name)
        if found:
            return value  # type: ignore[no-any-return]
        value = make()
        COMPUTED[name] += 1
        if path is not None:
            write_atomic(path, pickle.dumps((robot.robot_hash, name, value), protocol=5))
    return value


def _read_derived(path: Path | None, robot_hash: str, name: str) -> tuple[bool, Any]:
    if path is None or not path.is_file():
        return False, None
    try:
        with open(path, "rb") as f:
            stored_hash, stored_name, value = pickle.load(f)
    except Exception:  # an unreadable cache is rebuilt, never trusted
        return False, None
    return stored_hash == robot_hash and stored_name == name, value
