"""The memory-mapped voxel index: as recomputing at open was, cheap to open, checked, shared."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pickstop.cli import main
from pickstop.errors import CorruptShardError, DatabaseError
from pickstop.reach.build import BuildParams, dequantise
from pickstop.reach.database import ReachDatabase
from pickstop.reach.so3 import matrices_to_quats
from pickstop.robot.kinematics import Chain, fk
from pickstop.store.catalog import Catalog
from pickstop.store.reach_build import build
from pickstop.store.reach_catalog import list_databases, open_database
from pickstop.store.shards import read_shard

ROOT = Path(__file__).resolve().parents[2]


def _legacy(folder: Path, row: dict, tiago) -> ReachDatabase:
    """The database as opening it computed before the index existed: every shard read, the
    FK of every row, a stable sort of the concatenated shards by voxel key, all in memory."""
    info = next(r for r in list_databases(folder) if r["id"] == row["id"])
    parts = [read_shard(folder / s["path"], s["sha256"], tiago.dof) for s in info["shards"]]
    joints = np.concatenate([p.joints for p in parts])
    manip = np.concatenate([p.manip for p in parts])
    lower, upper = (
        np.array(json.loads(info["joint_lower"])),
        np.array(json.loads(info["joint_upper"])),
    )
    R, p = fk(Chain.from_robot(tiago), dequantise(joints, lower, upper))
    q = matrices_to_quats(R)
    probe = open_database(folder, tiago, row["id"])
    keys = probe.voxel.keys(p, q)
    order = np.argsort(keys, kind="stable")
    unique, first = np.unique(keys[order], return_index=True)
    return ReachDatabase(
        info,
        unique_keys=unique,
        offsets=np.append(first, len(keys)).astype(np.int64),
        joints=joints[order],
        manip=manip[order],
        positions=p[order].astype(np.float32),
        quats=q[order].astype(np.float32),
    )


def test_index_equals_recomputing_at_open(small_db, tiago):
    folder, row, _ = small_db
    db = open_database(folder, tiago, row["id"])
    ref = _legacy(folder, row, tiago)
    for name in ("unique_keys", "offsets", "joints", "manip", "positions", "quats"):
        assert np.array_equal(getattr(db, name), getattr(ref, name)), name
    assert db.reach_xy == ref.reach_xy
    # Candidates and their ranking, target by target, on a fixed seed.
    rng = np.random.default_rng(5)
    rows = rng.choice(len(db), 400, replace=False)
    ps = db.positions[rows].astype(float) + rng.normal(0, 0.02, (400, 3))
    qs = db.quats[rows].astype(float)
    a, b = db.query_many(ps, qs), ref.query_many(ps, qs)
    assert np.array_equal(a.offsets, b.offsets) and np.array_equal(a.rows, b.rows)
    for i in range(0, 400, 40):
        x, y = db.query(ps[i], qs[i], neighbours=True), ref.query(ps[i], qs[i], neighbours=True)
        assert np.array_equal(x.rows, y.rows) and np.array_equal(x.keys, y.keys)
        assert np.array_equal(x.pos_err, y.pos_err) and np.array_equal(x.rot_err, y.rot_err)


def _rchar() -> int:
    with open("/proc/self/io") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("rchar:"))


def test_open_reads_no_rows(small_db, tmp_path, tiago):
    """Opening reads the catalog and the index headers, whatever the number of rows."""
    tiny = build(tiago, BuildParams(samples=20_000, chunk_size=10_000, seed=2), tmp_path, workers=1)
    read = {}
    for folder, db_id in ((tmp_path, tiny["id"]), (small_db[0], small_db[1]["id"])):
        open_database(folder, tiago, db_id)  # the catalog is migrated, the files verified
        before = _rchar()
        db = open_database(folder, tiago, db_id)
        read[len(db)] = _rchar() - before
        assert db.stats.bytes_hashed == 0 and not db.stats.files_hashed
        assert isinstance(db.positions, np.memmap) and isinstance(db.joints, np.memmap)
        assert "keys" not in db.__dict__  # per-row keys are expanded only if asked for
    small, large = sorted(read)
    assert large > 10 * small
    # Bytes read by read() calls (catalog, headers): tiny, and the same for 15x the rows.
    assert read[large] < 200_000 and read[small] < 200_000
    assert abs(read[large] - read[small]) < 20_000, read


def _flip(path: Path, keep_mtime: bool = False) -> None:
    st = path.stat()
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    path.write_bytes(bytes(raw))
    if keep_mtime:
        os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))


def _verify(capsys, folder: Path) -> tuple[int, list]:
    capsys.readouterr()
    code = main(["--data-dir", str(folder), "reach", "verify"])
    return code, json.loads(capsys.readouterr().out)


def test_altered_index_is_refused_until_repaired(tmp_path, tiago, capsys):
    params = BuildParams(samples=20_000, chunk_size=10_000, seed=1)
    row = build(tiago, params, tmp_path, workers=1)
    index = tmp_path / "reach" / row["id"] / "index"
    assert _verify(capsys, tmp_path)[0] == 0
    # A flipped byte changes the file's time: the next open hashes it and refuses it.
    _flip(index / "positions.npy")
    with pytest.raises(CorruptShardError, match=r"positions\.npy is corrupt"):
        open_database(tmp_path, tiago, row["id"])
    code, report = _verify(capsys, tmp_path)
    assert code == CorruptShardError.exit_code and not report[0]["ok"]
    assert [f["path"].rsplit("/", 1)[1] for f in report[0]["files"] if not f["ok"]] == [
        "positions.npy"
    ]
    # Put back: verified once at the new time, then opened without hashing.
    _flip(index / "positions.npy")
    assert open_database(tmp_path, tiago, row["id"]).stats.files_hashed == [
        f"reach/{row['id']}/index/positions.npy"
    ]
    assert open_database(tmp_path, tiago, row["id"]).stats.bytes_hashed == 0
    # Altered behind the open's back (time restored): `reach verify` still finds it.
    _flip(index / "joints.npy", keep_mtime=True)
    assert _verify(capsys, tmp_path)[0] == CorruptShardError.exit_code
    # A truncated or missing file is refused without hashing.
    (index / "quats.npy").write_bytes(b"\x93NUMPY")
    with pytest.raises(CorruptShardError, match=r"quats\.npy is corrupt: 6 bytes"):
        open_database(tmp_path, tiago, row["id"])
    (index / "starts.npy").unlink()
    with pytest.raises(CorruptShardError, match="shard missing"):
        open_database(tmp_path, tiago, row["id"])
    # The same build command repairs it: indexed again from the intact shards, identical.
    before = {f["name"]: f["sha256"] for f in list_databases(tmp_path)[0]["index"]}
    build(tiago, params, tmp_path, workers=1)
    assert {f["name"]: f["sha256"] for f in list_databases(tmp_path)[0]["index"]} == before
    assert len(open_database(tmp_path, tiago, row["id"])) == row["stored"]
    assert _verify(capsys, tmp_path)[0] == 0


def test_database_without_index_asks_to_index_then_is_indexed(tmp_path, tiago):
    """A database built before indices existed (catalog migrated, no index) is never misread."""
    params = BuildParams(samples=20_000, chunk_size=10_000, seed=4)
    row = build(tiago, params, tmp_path, workers=1)
    first = open_database(tmp_path, tiago, row["id"])
    positions = np.array(first.positions)
    del first
    cat = Catalog(tmp_path)
    cat.db.execute("DELETE FROM reach_arrays")
    cat.db.execute("UPDATE reach_databases SET index_format = NULL, reach_xy = NULL")
    cat.close()
    import shutil

    shutil.rmtree(tmp_path / "reach" / row["id"] / "index")
    with pytest.raises(DatabaseError, match="no voxel index") as e:
        open_database(tmp_path, tiago, row["id"])
    assert (
        f"pickstop --data-dir {tmp_path.resolve()} reach build --robot tiago --samples 20000"
        in (e.value.message)
    )
    assert "--seed 4 --chunk-size 10000" in e.value.message
    again = build(tiago, params, tmp_path, workers=1)
    assert again["state"] == "complete" and again["index_format"] == 1
    assert np.array_equal(open_database(tmp_path, tiago, row["id"]).positions, positions)


SHARER = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    from pickstop.store.reach_catalog import open_database
    from pickstop.robot.model import load

    db = open_database(Path(sys.argv[1]), load("tiago"), sys.argv[2])
    total = float(db.positions.sum())  # touch every page of the positions
    print("ready", flush=True)
    sys.stdin.readline()
    rss = pss = 0
    inside = False
    with open("/proc/self/smaps") as f:
        for line in f:
            parts = line.split()
            if "-" in parts[0] and len(parts) >= 5:
                inside = line.rstrip().endswith("positions.npy")
            elif inside and parts[0] == "Rss:":
                rss += int(parts[1])
            elif inside and parts[0] == "Pss:":
                pss += int(parts[1])
    print(rss, pss, total, flush=True)
    """
)


def test_two_processes_share_the_mapped_index(small_db):
    folder, row, _ = small_db
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "backend"), str(ROOT)]))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", SHARER, str(folder), row["id"]],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )
        for _ in range(2)
    ]
    try:
        for p in procs:
            assert p.stdout is not None and p.stdout.readline().strip() == "ready"
        for p in procs:  # both hold the pages now
            assert p.stdin is not None
            p.stdin.write("\n")
            p.stdin.flush()
        figures = [p.stdout.readline().split() for p in procs if p.stdout is not None]
    finally:
        for p in procs:
            p.wait(timeout=60)
    size_kb = row["stored"] * 12 / 1024
    for rss, pss, _ in figures:
        # Each process has the whole positions array resident, but shares it: PSS ~ RSS / 2.
        assert int(rss) >= 0.9 * size_kb
        assert int(pss) <= 0.6 * int(rss)
