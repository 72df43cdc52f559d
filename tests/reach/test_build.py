"""Building, storing and loading reachability databases."""

from __future__ import annotations

import numpy as np
import pytest

from pickstop.errors import (
    CorruptShardError,
    DatabaseMismatchError,
    DatabaseNotFoundError,
    InputError,
)
from pickstop.reach.build import BuildParams, dequantise
from pickstop.robot.kinematics import Chain, fk
from pickstop.store.reach_build import build
from pickstop.store.reach_catalog import list_databases, open_database
from pickstop.store.shards import read_shard


def test_catalog_records_complete_build(small_db):
    folder, row, params = small_db
    assert row["state"] == "complete"
    info = list_databases(folder)[0]
    assert len(info["shards"]) == params.n_chunks
    assert all(len(s["sha256"]) == 64 and s["bytes"] > 0 for s in info["shards"])
    assert 0 < row["stored"] <= params.samples
    assert row["rejected_floor"] > 0 and row["floor_clearance"] == params.floor_clearance
    rejected = row["rejected_self_collision"] + row["rejected_floor"]
    assert row["stored"] + rejected == params.samples
    assert row["robot_hash"] and row["code_version"] and row["build_seconds"] > 0


def test_every_stored_configuration_lies_in_its_voxel(small_loaded, tiago):
    db = small_loaded
    rows = np.random.default_rng(0).choice(len(db), 20_000, replace=False)
    Rs, ps = fk(Chain.from_robot(tiago), db.thetas(rows))
    assert (db.voxel.keys_from_matrices(ps, Rs) == db.keys[rows]).all()
    lo, hi = db.voxel.cell_bounds(db.keys[rows])
    assert ((lo - 1e-9 <= ps) & (ps < hi + 1e-9)).all()
    assert (np.diff(db.keys) >= 0).all()


def test_shards_sorted_by_voxel_key(small_db, tiago):
    folder, row, _ = small_db
    chain = Chain.from_robot(tiago)
    db = open_database(folder, tiago, row["id"])
    shard = list_databases(folder)[0]["shards"][0]
    data = read_shard(folder / shard["path"], shard["sha256"], tiago.dof)
    Rs, ps = fk(chain, dequantise(data.joints, db.lower, db.upper))
    keys = db.voxel.keys_from_matrices(ps, Rs)
    assert (np.diff(keys) >= 0).all()


def test_stored_configurations_are_free_of_self_collision(small_db, small_loaded, tiago):
    from pickstop.robot.artifacts import self_collision
    from pickstop.robot.selfcollision import ExactSelfCollision
    from pickstop.settings import cache_dir

    disabled, _ = self_collision(tiago, cache_dir(small_db[0]))
    exact = ExactSelfCollision(tiago, disabled)
    rows = np.random.default_rng(1).choice(len(small_loaded), 500, replace=False)
    assert not exact.colliding(small_loaded.thetas(rows)).any()


def test_stored_configurations_keep_every_link_above_the_floor(small_db, small_loaded, tiago):
    """The exact check (coal, every moving link, the hand's too) on stored configurations."""
    from pickstop.robot.floor import ExactFloor

    rows = np.random.default_rng(2).choice(len(small_loaded), 500, replace=False)
    clearance = small_db[2].floor_clearance
    assert not ExactFloor(tiago).colliding(small_loaded.thetas(rows), clearance).any()


def test_floor_clearance_is_part_of_the_database_identity(tiago):
    from pickstop.reach.build import database_id

    a = database_id(tiago.robot_hash, BuildParams(samples=10_000))
    b = database_id(tiago.robot_hash, BuildParams(samples=10_000, floor_clearance=0.05))
    assert a != b


def test_a_larger_floor_clearance_drops_more(tmp_path, tiago):
    low = build(tiago, BuildParams(samples=20_000, chunk_size=20_000), tmp_path, workers=1)
    high = build(
        tiago,
        BuildParams(samples=20_000, chunk_size=20_000, floor_clearance=0.3),
        tmp_path,
        workers=1,
    )
    assert high["rejected_floor"] > low["rejected_floor"] > 0
    assert high["stored"] < low["stored"]


def _shas(folder):
    return [s["sha256"] for s in list_databases(folder)[0]["shards"]]


def test_resumed_build_equals_uninterrupted(tmp_path, tiago):
    params = BuildParams(samples=60_000, chunk_size=20_000, seed=3)
    whole = build(tiago, params, tmp_path / "a", workers=1)
    part = build(tiago, params, tmp_path / "b", workers=1, max_chunks=1)
    assert part["state"] == "interrupted"  # stopped before completing: resumable
    # A crash can leave a temp file and a shard whose catalog row was never written.
    (tmp_path / "b" / "reach" / part["id"] / "chunk-000002.parquet.tmp99").write_bytes(b"junk")
    resumed = build(tiago, params, tmp_path / "b", workers=2)
    assert resumed["state"] == whole["state"] == "complete"
    assert resumed["id"] == whole["id"]
    assert _shas(tmp_path / "a") == _shas(tmp_path / "b")
    index = [
        [f["sha256"] for f in list_databases(d)[0]["index"]]
        for d in (tmp_path / "a", tmp_path / "b")
    ]
    assert index[0] == index[1] and len(index[0]) == 6
    assert resumed["stored"] == whole["stored"]


def test_corrupted_shard_is_detected(tmp_path, tiago, capsys):
    from pickstop.cli import main

    params = BuildParams(samples=20_000, chunk_size=10_000, seed=1)
    row = build(tiago, params, tmp_path, workers=1)
    shard = tmp_path / list_databases(tmp_path)[0]["shards"][1]["path"]
    raw = bytearray(shard.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    shard.write_bytes(bytes(raw))
    # Plans read the index, not the shards; `reach verify` checks both.
    assert main(["--data-dir", str(tmp_path), "reach", "verify"]) == CorruptShardError.exit_code
    assert "chunk-000001.parquet is corrupt" in capsys.readouterr().out
    shard.unlink()
    assert main(["--data-dir", str(tmp_path), "reach", "verify"]) == CorruptShardError.exit_code
    assert "shard missing" in capsys.readouterr().out
    # Building again repairs it: the missing chunk is recomputed, identical to before.
    build(tiago, params, tmp_path, workers=1)
    assert main(["--data-dir", str(tmp_path), "reach", "verify"]) == 0
    assert len(open_database(tmp_path, tiago, row["id"])) == row["stored"]


def test_database_of_another_robot_is_refused(small_db, pr2):
    folder, row, _ = small_db
    with pytest.raises(DatabaseMismatchError, match="built for robot 'tiago'"):
        open_database(folder, pr2, row["id"])
    with pytest.raises(DatabaseNotFoundError, match="no complete reachability database"):
        open_database(folder, pr2)


def test_changed_config_is_another_robot(small_db, tmp_path):
    from pickstop.robot.model import load
    from tests.utils import TIAGO_CONFIG, TIAGO_URDF, write_config

    folder, row, _ = small_db
    text = TIAGO_CONFIG.format(urdf=TIAGO_URDF).replace("mytiago", "tiago")
    other = load(str(write_config(tmp_path, text + "locked_joints: {head_2_joint: 0.3}\n")))
    with pytest.raises(DatabaseMismatchError, match="config hash"):
        open_database(folder, other, row["id"])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"samples": 10}, "samples"),
        ({"samples": 10_000, "resolution": 0.0}, "resolution"),
        ({"samples": 10_000, "orientation": 0}, "orientation"),
        ({"samples": 10_000, "thinning": -1.0}, "thinning"),
        ({"samples": 10_000, "floor_clearance": -0.01}, "floor_clearance"),
        ({"samples": 10_000, "floor_clearance": float("nan")}, "floor_clearance"),
    ],
)
def test_bad_build_parameters(tmp_path, tiago, kwargs, field):
    with pytest.raises(InputError) as e:
        build(tiago, BuildParams(**kwargs), tmp_path)
    assert e.value.field == field
    assert not (tmp_path / "reach").exists()


def test_thinning_drops_low_manipulability(tmp_path, tiago):
    plain = build(tiago, BuildParams(samples=20_000, chunk_size=20_000), tmp_path, workers=1)
    thin = build(
        tiago, BuildParams(samples=20_000, chunk_size=20_000, thinning=0.1), tmp_path, workers=1
    )
    assert thin["rejected_thinning"] > 0 and thin["stored"] < plain["stored"]
    a = open_database(tmp_path, tiago, plain["id"])
    b = open_database(tmp_path, tiago, thin["id"])
    assert np.median(b.manip) > np.median(a.manip)
