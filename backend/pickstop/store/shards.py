"""Parquet shards of a reachability database: written atomically, read only if intact.

A shard holds one sample chunk, rows sorted by voxel key: ``j0..j{n-1}`` (uint16 quantised
joints) and ``manip`` (float16 manipulability). The key itself is not stored: it follows from
the joints by FK, which loading computes anyway to rank candidates (storing it would cost
~5 bytes a row, a quarter of the budget).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pickstop.errors import CorruptShardError


@dataclass(frozen=True)
class ShardData:
    joints: np.ndarray  # (m, dof) uint16
    manip: np.ndarray  # (m,) float16


def write_shard(path: Path, data: ShardData) -> tuple[str, int]:
    """Write ``data`` to ``path`` atomically (tmp file, fsync, rename); return (sha256, bytes)."""
    m, dof = data.joints.shape
    assert data.manip.shape == (m,)
    cols: dict[str, pa.Array] = {}
    for i in range(dof):
        cols[f"j{i}"] = pa.array(np.ascontiguousarray(data.joints[:, i]), pa.uint16())
    cols["manip"] = pa.array(data.manip.astype(np.float16), pa.float16())
    table = pa.table(cols)
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(
        table,
        tmp,
        compression="zstd",
        compression_level=3,
        use_dictionary=False,
        # Parquet stores uint16 as INT32: splitting byte streams lets zstd drop the zero bytes.
        column_encoding=dict.fromkeys(cols, "BYTE_STREAM_SPLIT"),
        row_group_size=1 << 20,
    )
    with open(tmp, "rb+") as f:
        raw = f.read()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return hashlib.sha256(raw).hexdigest(), len(raw)


def read_shard(path: Path, sha256: str, dof: int) -> ShardData:
    """Read a shard, refusing one that is missing, altered or malformed."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise CorruptShardError(f"shard missing: {path}") from None
    digest = hashlib.sha256(raw).hexdigest()
    if digest != sha256:
        raise CorruptShardError(
            f"shard {path} is corrupt: sha256 {digest[:12]}... does not match the catalog's "
            f"{sha256[:12]}...; rebuild the database (`pickstop reach build` resumes it)"
        )
    try:
        table = pq.read_table(pa.BufferReader(raw))
        joints = np.stack([table.column(f"j{i}").to_numpy() for i in range(dof)], axis=1)
        manip = table.column("manip").to_numpy()
    except (pa.ArrowException, KeyError, ValueError) as e:
        raise CorruptShardError(f"shard {path} is unreadable: {e}") from None
    if joints.dtype != np.uint16 or manip.dtype != np.float16:
        raise CorruptShardError(f"shard {path} has unexpected column types")
    return ShardData(joints=joints.reshape(len(manip), dof), manip=manip)
