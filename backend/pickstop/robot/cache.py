"""The on-disk cache of robots' derived data: one folder for every data folder and process.

What depends on a robot alone (its disabled pairs, self-collision screen, covers, outline) is
kept per robot hash in ``<cache>/robots/`` (:func:`pickstop.settings.cache_dir`). A file is
written atomically (temporary file, then rename) and made under a lock, so processes asking
for the same entry at once make it once: the others wait, then read it. :data:`COMPUTED`
counts what this process made rather than read.
"""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

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
