"""The reachability catalog's functions on rows alone (no build): what builds and the service
rely on to resume, total and forget databases."""

from __future__ import annotations

import json

import pytest

from pickstop.store import reach_catalog as rc
from pickstop.store.catalog import Catalog


def _row(db_id: str, **over):
    row = {"id": db_id, "robot": "tiago", "robot_hash": "h" * 64, "dof": 8, "resolution": 0.05,
           "orientation": 6, "samples": 2000, "seed": 0, "chunk_size": 1000, "thinning": 0.0,
           "code_version": "test", "joint_lower": json.dumps([0.0] * 8),
           "joint_upper": json.dumps([1.0] * 8), "state": "building",
           "created": "2026-01-01T00:00:00+00:00"}  # fmt: skip
    return {**row, **over}


def _shard(chunk: int, rows: int):
    return {"chunk": chunk, "path": f"reach/x/chunk-{chunk:06d}.parquet", "sha256": "0" * 64,
            "bytes": 10, "rows": rows, "samples": 1000, "rejected_self_collision": 3,
            "rejected_thinning": 0, "rejected_floor": 2, "seconds": 0.5}  # fmt: skip


@pytest.fixture
def cat(tmp_path):
    c = Catalog(tmp_path)
    yield c
    c.close()


def test_shards_are_recorded_replaced_totalled_and_forgotten(cat):
    rc.insert_database(cat, _row("a"))
    rc.record_shard(cat, "a", _shard(1, 700))
    rc.record_shard(cat, "a", _shard(0, 500))
    rc.record_shard(cat, "a", _shard(0, 600))  # a chunk computed again replaces its record
    assert [(s["chunk"], s["rows"]) for s in rc.shards(cat, "a")] == [(0, 600), (1, 700)]
    assert rc.shard_totals(cat, "a") == {"stored": 1300, "rejected_self_collision": 6,
                                         "rejected_thinning": 0, "rejected_floor": 4}  # fmt: skip
    rc.forget_shard(cat, "a", 0)
    assert [s["chunk"] for s in rc.shards(cat, "a")] == [1]


def test_an_ended_build_is_interrupted_unless_complete(cat):
    rc.insert_database(cat, _row("a", builder="host 1"))
    rc.insert_database(cat, _row("b", state="complete"))
    rc.end_build(cat, "a", 2.5)
    rc.end_build(cat, "a", 1.0)
    rc.end_build(cat, "b", 4.0)
    a, b = rc.database_row(cat, "a"), rc.database_row(cat, "b")
    assert a is not None and b is not None
    assert (a["state"], a["builder"], a["build_seconds"]) == ("interrupted", None, 3.5)
    assert (b["state"], b["build_seconds"]) == ("complete", 4.0)
    assert rc.database_row(cat, "c") is None


def test_a_dead_builder_is_found_out_when_listing(tmp_path, cat):
    rc.insert_database(cat, _row("a", builder=rc.builder_tag()))  # this process: alive
    rc.insert_database(cat, _row("b", builder="nohost-that-exists-here 1"))  # another host
    dead = rc.builder_tag().rpartition(" ")[0] + " 999999999"
    rc.insert_database(cat, _row("c", builder=dead))
    states = {r["id"]: r["state"] for r in rc.list_databases(tmp_path)}
    assert states == {"a": "building", "b": "building", "c": "interrupted"}
    row = rc.database_row(cat, "c")
    assert row is not None and row["builder"] is None


def test_deleting_a_database_forgets_only_its_rows(cat):
    rc.insert_database(cat, _row("a"))
    rc.insert_database(cat, _row("b"))
    for db in ("a", "b"):
        rc.record_shard(cat, db, _shard(0, 10))
    assert rc.delete_database(cat, "a") is True
    assert rc.database_row(cat, "a") is None and rc.shards(cat, "a") == []
    assert rc.database_row(cat, "b") is not None and len(rc.shards(cat, "b")) == 1
    assert rc.delete_database(cat, "a") is False


def test_a_database_a_live_build_names_is_not_deleted(cat):
    from pickstop.errors import DatabaseBusyError

    rc.insert_database(cat, _row("a", builder=rc.builder_tag()))  # this process: alive
    rc.insert_database(cat, _row("b", builder="elsewhere-host-gone 999999", state="interrupted"))
    with pytest.raises(DatabaseBusyError, match="being built"):
        rc.delete_database(cat, "a")
    assert rc.database_row(cat, "a") is not None
    assert rc.delete_database(cat, "b") is True


def test_a_build_claims_its_row_again_after_a_delete(cat):
    """A delete that comes between a build's read of its row and its claim: the claim makes
    the row again, so the build's shards have a row to belong to."""
    row = _row("a", state="complete", completed="2026-01-02T00:00:00+00:00")
    rc.insert_database(cat, row)
    assert rc.delete_database(cat, "a") is True
    rc.claim_build(cat, row)
    again = rc.database_row(cat, "a")
    assert again["state"] == "building" and again["builder"] == rc.builder_tag()
    rc.record_shard(cat, "a", _shard(0, 10))  # no foreign key error
    assert len(rc.shards(cat, "a")) == 1
    with pytest.raises(Exception, match="being built"):
        rc.delete_database(cat, "a")


def _complete(db_id: str, completed: str, stored: int, **over):
    """A complete database row; default build parameters unless ``over`` changes them."""
    over = {"chunk_size": 250_000, "floor_clearance": 0.01, **over}
    return _row(db_id, state="complete", completed=completed, stored=stored, **over)


@pytest.fixture
def robot():
    from types import SimpleNamespace

    return SimpleNamespace(robot_hash="h" * 64, name="tiago", source="tiago")


def test_a_later_build_never_becomes_the_default_database(cat, tmp_path, robot):
    """The default is the first database completed with the default build parameters: a later
    one with more configurations (default parameters or not) never takes its place."""
    rc.insert_database(cat, _complete("first", "2026-01-01T00:00:00+00:00", 100))
    rc.insert_database(cat, _complete("thin", "2026-01-02T00:00:00+00:00", 900,
                                      floor_clearance=1e-38))  # fmt: skip
    rc.insert_database(cat, _complete("bigger", "2026-01-03T00:00:00+00:00", 500))
    assert rc.find_database(tmp_path, robot)["id"] == "first"
    assert rc.find_database(tmp_path, robot, "thin")["id"] == "thin"  # named: used


def test_without_default_parameters_the_first_completed_is_the_default(cat, tmp_path, robot):
    rc.insert_database(cat, _complete("b", "2026-01-02T00:00:00+00:00", 900, seed=3))
    rc.insert_database(cat, _complete("a", "2026-01-01T00:00:00+00:00", 100, seed=11))
    assert rc.find_database(tmp_path, robot)["id"] == "a"


def test_a_configured_default_database_is_used_and_checked(cat, tmp_path, robot):
    from pickstop.errors import DatabaseNotFoundError

    rc.insert_database(cat, _complete("first", "2026-01-01T00:00:00+00:00", 100))
    rc.insert_database(cat, _complete("chosen", "2026-01-02T00:00:00+00:00", 50, seed=4))
    assert rc.find_database(tmp_path, robot, default="chosen")["id"] == "chosen"
    with pytest.raises(DatabaseNotFoundError):
        rc.find_database(tmp_path, robot, default="gone")
