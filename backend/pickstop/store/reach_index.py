"""The memory-mapped voxel index of a reachability database: its files and their checksums.

The catalog rows that describe the files are :mod:`pickstop.store.reach_catalog`'s. A
database's index lives in ``reach/<id>/index/``, one uncompressed ``.npy`` file an array, rows
sorted by voxel key. The files are mapped read-only (``np.load(mmap_mode="r")``): every process
on a machine shares one copy in the page cache, opening reads only the headers, and a query
reads only the pages of the voxels it touches.

- ``keys (V,) int64``: the occupied voxel keys, ascending;
- ``starts (V + 1,) int64``: voxel ``i`` owns rows ``starts[i]:starts[i + 1]``;
- ``joints (N, dof) uint16`` quantised joints, ``manip (N,) float16`` manipulability;
- ``positions (N, 3) float32`` [m] and ``quats (N, 4) float32`` (wxyz): the tool pose
  ``T_base_tool`` of every row, computed once when the index is built.

A file is hashed (sha256) when written, by ``pickstop reach verify``, and when opened after its
size or modification time differs from what the catalog recorded when it was last verified;
a file that fails is refused (:class:`CorruptShardError`) before any of its rows is used.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.errors import CorruptShardError

#: Bumped whenever the index files change meaning; an index of another format is rebuilt.
INDEX_FORMAT = 1
#: The arrays of an index and their dtypes.
ARRAYS: dict[str, str] = {
    "keys": "int64",
    "starts": "int64",
    "joints": "uint16",
    "manip": "float16",
    "positions": "float32",
    "quats": "float32",
}


def index_relpath(db_id: str) -> str:
    """Folder of a database's index, relative to the data folder."""
    return f"reach/{db_id}/index"


def file_sha256(path: Path) -> str:
    """sha256 of a file, read in 4 MB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


@dataclass(frozen=True)
class ArrayFile:
    """One index file as the catalog records it."""

    name: str
    path: str  # relative to the data folder
    dtype: str
    shape: tuple[int, ...]
    sha256: str
    bytes: int
    mtime_ns: int  # modification time when last verified

    @classmethod
    def of_row(cls, r: dict[str, Any]) -> ArrayFile:
        return cls(
            name=r["name"],
            path=r["path"],
            dtype=r["dtype"],
            shape=tuple(json.loads(r["shape"])),
            sha256=r["sha256"],
            bytes=r["bytes"],
            mtime_ns=r["mtime_ns"],
        )


def create_array(path: Path, dtype: str, shape: tuple[int, ...]) -> np.memmap:
    """A new ``.npy`` file of ``shape``, mapped for writing in place (bounded memory)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return np.lib.format.open_memmap(path, mode="w+", dtype=np.dtype(dtype), shape=shape)


def seal_array(name: str, path: Path, relpath: str) -> ArrayFile:
    """Flush a written ``.npy`` file to disk (fsync) and describe it with its checksum."""
    with open(path, "rb+") as f:
        os.fsync(f.fileno())
    arr = np.load(path, mmap_mode="r")
    dtype, shape = str(arr.dtype), tuple(int(s) for s in arr.shape)
    del arr
    st = path.stat()
    return ArrayFile(
        name=name,
        path=relpath,
        dtype=dtype,
        shape=shape,
        sha256=file_sha256(path),
        bytes=st.st_size,
        mtime_ns=st.st_mtime_ns,
    )


@dataclass
class OpenStats:
    """Work done opening an index: what was hashed because it changed since last verified."""

    bytes_hashed: int = 0
    files_hashed: list[str] = field(default_factory=list)
    #: ``{name: mtime_ns}``: the modification time each hashed file was verified at (for the
    #: catalog to record, so the next open need not hash it again).
    verified: dict[str, int] = field(default_factory=dict)


def check_file(data_dir: Path, f: ArrayFile, *, full: bool) -> int | None:
    """Refuse a missing or altered file; hash it if ``full`` or its size or time changed.

    Returns the modification time it was verified at if it was hashed, else None.
    """
    path = Path(data_dir) / f.path
    try:
        st = path.stat()
    except FileNotFoundError:
        raise CorruptShardError(f"shard missing: {f.path}") from None
    if st.st_size != f.bytes:
        raise CorruptShardError(
            f"shard {f.path} is corrupt: {st.st_size} bytes, the catalog records {f.bytes}; "
            "rebuild the database (`pickstop reach build` with the same parameters repairs it)"
        )
    if not full and st.st_mtime_ns == f.mtime_ns:
        return None
    digest = file_sha256(path)
    if digest != f.sha256:
        raise CorruptShardError(
            f"shard {f.path} is corrupt: sha256 {digest[:12]}... does not match the catalog's "
            f"{f.sha256[:12]}...; rebuild the database (`pickstop reach build` with the same "
            "parameters repairs it)"
        )
    return st.st_mtime_ns


def map_index(
    data_dir: Path, db_id: str, files: list[ArrayFile]
) -> tuple[dict[str, np.ndarray], OpenStats]:
    """Map an index read-only after checking its files (hashing those that changed; their
    verification times are in ``stats.verified`` for the catalog to record)."""
    stats = OpenStats()
    by_name = {f.name: f for f in files}
    missing = sorted(set(ARRAYS) - set(by_name))
    if missing:
        raise CorruptShardError(f"database {db_id}: the catalog lists no index file {missing}")
    arrays: dict[str, np.ndarray] = {}
    for name in ARRAYS:
        f = by_name[name]
        t = check_file(data_dir, f, full=False)
        if t is not None:
            stats.verified[name] = t
            stats.bytes_hashed += f.bytes
            stats.files_hashed.append(f.path)
        try:
            arr = np.load(Path(data_dir) / f.path, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as e:
            raise CorruptShardError(f"shard {f.path} is unreadable: {e}") from None
        if str(arr.dtype) != ARRAYS[name] or tuple(arr.shape) != f.shape:
            raise CorruptShardError(
                f"shard {f.path} holds {arr.dtype}{list(arr.shape)}, the catalog records "
                f"{ARRAYS[name]}{list(f.shape)}"
            )
        arrays[name] = arr
    n = len(arrays["manip"])
    starts = arrays["starts"]
    if len(starts) != len(arrays["keys"]) + 1 or starts[0] != 0 or starts[-1] != n:
        raise CorruptShardError(f"database {db_id}: the voxel index does not cover its {n} rows")
    if any(len(arrays[k]) != n for k in ("joints", "positions", "quats")):
        raise CorruptShardError(f"database {db_id}: index arrays of unequal length")
    return arrays, stats


def verify_one(data_dir: Path, f: ArrayFile, verified: dict[str, int] | None) -> dict[str, Any]:
    """Hash one file in full: its report row; its verification time goes into ``verified``."""
    try:
        t = check_file(data_dir, f, full=True)
    except CorruptShardError as e:
        return {"path": f.path, "ok": False, "error": e.message}
    if verified is not None and t is not None:
        verified[f.name] = t
    return {"path": f.path, "ok": True, "bytes": f.bytes}
