"""The reachability databases in the catalog: their rows, shards and index files.

Every read and write of ``reach_databases``, ``reach_shards`` and ``reach_arrays`` is here;
opening a database by id reads its row and index files here and hands the mapped arrays to
:class:`pickstop.reach.database.ReachDatabase`, which knows nothing of the catalog.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path
from typing import Any

from pickstop.errors import (
    CorruptShardError,
    DatabaseBusyError,
    DatabaseError,
    DatabaseMismatchError,
    DatabaseNotFoundError,
)
from pickstop.reach.database import ReachDatabase, build_command
from pickstop.robot.model import RobotModel
from pickstop.store.catalog import Catalog
from pickstop.store.reach_index import (
    INDEX_FORMAT,
    ArrayFile,
    check_file,
    map_index,
    verify_one,
)

# -- who builds a database ---------------------------------------------------------------------


def builder_tag() -> str:
    """``"host pid"`` of this process, recorded on a database while it builds it."""
    return f"{socket.gethostname()} {os.getpid()}"


def builder_alive(tag: str | None) -> bool:
    """Is the process of a builder tag still running? (Another host's: assumed so.)"""
    if not tag:
        return False
    host, _, pid = tag.rpartition(" ")
    if host != socket.gethostname():
        return True
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError):
        return True
    return True


# -- database rows -----------------------------------------------------------------------------


def database_row(catalog: Catalog, db_id: str) -> dict[str, Any] | None:
    """The catalog row of database ``db_id`` (exact id), or None."""
    return catalog.one("SELECT * FROM reach_databases WHERE id = ?", [db_id])


def insert_database(catalog: Catalog, row: dict[str, Any]) -> None:
    """Add the row of a new database (its columns as the ``reach_databases`` table names them)."""
    catalog.insert("reach_databases", row)


def claim_build(catalog: Catalog, row: dict[str, Any]) -> None:
    """Name this process the builder of database ``row["id"]`` in one transaction: its row
    set 'building' with this process's tag, or made again from ``row`` (state 'building') if
    it is gone (deleted since it was read). A delete judges the builder in a transaction too,
    so it either comes first (and the row is made again here) or is refused."""
    fields = {"state": "building", "completed": None, "builder": builder_tag()}
    with catalog.transaction() as conn:
        if conn.execute("SELECT 1 FROM reach_databases WHERE id = ?", [row["id"]]).fetchone():
            sets = ", ".join(f"{k} = :{k}" for k in fields)
            conn.execute(
                f"UPDATE reach_databases SET {sets} WHERE id = :_id", {**fields, "_id": row["id"]}
            )
        else:
            new = {**row, **fields}
            names = ", ".join(new)
            conn.execute(
                f"INSERT INTO reach_databases ({names}) VALUES ({', '.join(':' + k for k in new)})",
                new,
            )


def update_database(catalog: Catalog, db_id: str, fields: dict[str, Any]) -> None:
    """Set columns ``fields`` of database ``db_id``."""
    sets = ", ".join(f"{k} = :{k}" for k in fields)
    catalog.conn.execute(
        f"UPDATE reach_databases SET {sets} WHERE id = :_id", {**fields, "_id": db_id}
    )


def end_build(catalog: Catalog, db_id: str, seconds: float) -> None:
    """A build run of ``db_id`` ended after ``seconds`` [s]: add them to its build time, clear
    its builder and, unless it completed, mark it 'interrupted' (the same build resumes it)."""
    catalog.conn.execute(
        "UPDATE reach_databases SET build_seconds = build_seconds + ?, builder = NULL, "
        "state = CASE WHEN state = 'building' THEN 'interrupted' ELSE state END "
        "WHERE id = ?",
        [seconds, db_id],
    )


def shard_totals(catalog: Catalog, db_id: str) -> dict[str, int]:
    """Sums over the shards of ``db_id``: ``stored`` rows and ``rejected_self_collision``,
    ``rejected_thinning``, ``rejected_floor`` samples."""
    row = catalog.query(
        "SELECT SUM(rows) stored, SUM(rejected_self_collision) rejected_self_collision, "
        "SUM(rejected_thinning) rejected_thinning, SUM(rejected_floor) rejected_floor "
        "FROM reach_shards WHERE db_id = ?",
        [db_id],
    )[0]
    return {k: int(v or 0) for k, v in row.items()}


def delete_database(catalog: Catalog, db_id: str) -> bool:
    """Forget database ``db_id`` (its row, shards and index files) in one transaction; False
    if the catalog has no such database. Its files are the caller's to remove. One a running
    build names is refused (:class:`DatabaseBusyError`), judged in the same transaction as
    the build's claim (:func:`claim_build`), so that no build writes into a deleted row."""
    with catalog.transaction() as conn:
        found = conn.execute(
            "SELECT state, builder FROM reach_databases WHERE id = ?", [db_id]
        ).fetchone()
        if found is not None and found[0] == "building" and builder_alive(found[1]):
            raise DatabaseBusyError(f"database {db_id} is being built: cancel its build job first")
        if found is not None:
            conn.execute("DELETE FROM reach_shards WHERE db_id = ?", [db_id])
            conn.execute("DELETE FROM reach_arrays WHERE db_id = ?", [db_id])
            conn.execute("DELETE FROM reach_databases WHERE id = ?", [db_id])
    return found is not None


# -- shards ------------------------------------------------------------------------------------


def shards(catalog: Catalog, db_id: str) -> list[dict[str, Any]]:
    """The shards recorded for ``db_id`` in chunk order: ``chunk, path, sha256, bytes, rows``."""
    return catalog.query(
        "SELECT chunk, path, sha256, bytes, rows FROM reach_shards WHERE db_id = ? ORDER BY chunk",
        [db_id],
    )


def record_shard(catalog: Catalog, db_id: str, shard: dict[str, Any]) -> None:
    """Record (or replace) the shard of chunk ``shard["chunk"]`` of ``db_id`` with its figures
    (``path, sha256, bytes, rows, samples, rejected_*, seconds``)."""
    catalog.insert("reach_shards", {"db_id": db_id, **shard}, replace=True)


def forget_shard(catalog: Catalog, db_id: str, chunk: int) -> None:
    """Drop the record of one shard (it vanished or was altered: the build computes it again)."""
    catalog.conn.execute("DELETE FROM reach_shards WHERE db_id = ? AND chunk = ?", [db_id, chunk])


# -- index files -------------------------------------------------------------------------------


def index_files(catalog: Catalog, db_id: str) -> list[ArrayFile]:
    """The index files the catalog records for ``db_id`` (empty if it has none)."""
    rows = catalog.query("SELECT * FROM reach_arrays WHERE db_id = ? ORDER BY name", [db_id])
    return [ArrayFile.of_row(r) for r in rows]


def record_index(
    catalog: Catalog, db_id: str, files: list[ArrayFile], figures: dict[str, Any]
) -> None:
    """Record a new index of ``db_id`` (replacing any older one) with its ``figures``."""
    with catalog.transaction() as conn:
        conn.execute("DELETE FROM reach_arrays WHERE db_id = ?", [db_id])
        for f in files:
            conn.execute(
                "INSERT INTO reach_arrays (db_id, name, path, dtype, shape, sha256, bytes, "
                "mtime_ns) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [db_id, f.name, f.path, f.dtype, json.dumps(list(f.shape)), f.sha256, f.bytes,
                 f.mtime_ns],
            )  # fmt: skip
        conn.execute(
            "UPDATE reach_databases SET index_format = ?, voxels = ?, reach_xy = ?, "
            "index_seconds = ? WHERE id = ?",
            [INDEX_FORMAT, figures["voxels"], figures["reach_xy"], figures["seconds"], db_id],
        )


def index_intact(catalog: Catalog, row: dict[str, Any], data_dir: Path) -> bool:
    """Is the database's voxel index of this format, present and unaltered?"""
    files = index_files(catalog, row["id"])
    if row.get("index_format") != INDEX_FORMAT or not files:
        return False
    try:
        for f in files:
            check_file(data_dir, f, full=False)
    except CorruptShardError:
        return False
    return True


def mark_verified(data_dir: Path, db_id: str, verified: dict[str, int]) -> None:
    """Record the modification times ``{name: mtime_ns}`` at which files were verified.

    Best effort: on a read-only data folder the next open verifies them again."""
    try:
        cat = Catalog(data_dir)
    except Exception:
        return
    try:
        for name, mtime_ns in verified.items():
            cat.conn.execute(
                "UPDATE reach_arrays SET mtime_ns = ? WHERE db_id = ? AND name = ?",
                [mtime_ns, db_id, name],
            )
    except Exception:  # read-only catalog: verified again next time
        pass
    finally:
        cat.close()


def verify_files(data_dir: Path, db_id: str, catalog: Catalog) -> list[dict[str, Any]]:
    """Hash every file of a database (its shards and its index): one report row a file."""
    out: list[dict[str, Any]] = []
    verified: dict[str, int] = {}
    for r in shards(catalog, db_id):
        f = ArrayFile("shard", r["path"], "", (), r["sha256"], r["bytes"], -1)
        out.append(verify_one(data_dir, f, None))
    for f in index_files(catalog, db_id):
        out.append(verify_one(data_dir, f, verified))
    if verified:
        mark_verified(data_dir, db_id, verified)
    return out


# -- finding and opening databases -------------------------------------------------------------


def list_databases(data_dir: Path, robot: str | None = None) -> list[dict[str, Any]]:
    """Catalog rows of every database (of ``robot`` if given), newest first."""
    cat = Catalog(data_dir)
    try:
        sql = "SELECT * FROM reach_databases"
        args: list[Any] = []
        if robot:
            sql += " WHERE robot = ?"
            args.append(robot)
        rows = cat.query(sql + " ORDER BY created DESC, id", args)
        for r in rows:
            if r["state"] == "building" and not builder_alive(r.get("builder")):
                # Its process was killed before it could say so.
                cat.conn.execute(
                    "UPDATE reach_databases SET state = 'interrupted', builder = NULL "
                    "WHERE id = ? AND state = 'building'",
                    [r["id"]],
                )
                r["state"], r["builder"] = "interrupted", None
            r["shards"] = shards(cat, r["id"])
            r["index"] = cat.query(
                "SELECT name, path, dtype, shape, sha256, bytes FROM reach_arrays "
                "WHERE db_id = ? ORDER BY name",
                [r["id"]],
            )
        return rows
    finally:
        cat.close()


def verify_databases(data_dir: Path, db_id: str | None = None) -> list[dict[str, Any]]:
    """Hash every shard and index file of every database (or of ``db_id``, an id or prefix).

    One report a database: ``{"id", "state", "ok", "files": [{"path", "ok", ...}]}``; a file
    that passes is recorded as verified at its current modification time."""
    data_dir = Path(data_dir)
    rows = list_databases(data_dir)
    if db_id is not None:
        rows = [r for r in rows if r["id"].startswith(db_id)]
        if not rows:
            raise DatabaseNotFoundError(f"no reachability database with id {db_id!r} in {data_dir}")
    cat = Catalog(data_dir)
    try:
        out = []
        for r in rows:
            files = verify_files(data_dir, r["id"], cat)
            indexed = r.get("index_format") == INDEX_FORMAT
            out.append({"id": r["id"], "state": r["state"], "indexed": indexed,
                        "ok": all(f["ok"] for f in files), "files": files})  # fmt: skip
        return out
    finally:
        cat.close()


def folder_flag(data_dir: Path) -> Path | None:
    """``data_dir`` as a command's ``--data-dir`` names it: None for the default data folder
    (``$PICKSTOP_DATA_DIR`` or the built-in one), which a command finds without it."""
    from pickstop.settings import Settings

    data_dir = Path(data_dir).resolve()
    return None if data_dir == Path(Settings().data_dir).resolve() else data_dir


def find_database(
    data_dir: Path, robot: RobotModel, db_id: str | None = None, default: str | None = None
) -> dict[str, Any]:
    """The catalog row to use for ``robot``: ``db_id`` if given (checked), else its default:
    ``default`` if given (the service's setting, checked as a named one), else
    :func:`default_row`."""
    rows = list_databases(data_dir)
    if db_id is None and default is not None:
        db_id = default
    if db_id is not None:
        match = [r for r in rows if r["id"] == db_id or r["id"].startswith(db_id)]
        if not match:
            raise DatabaseNotFoundError(f"no reachability database with id {db_id!r} in {data_dir}")
        if len(match) > 1:
            raise DatabaseNotFoundError(f"database id prefix {db_id!r} is ambiguous")
        row = match[0]
        if row["robot_hash"] != robot.robot_hash:
            raise DatabaseMismatchError(
                f"database {row['id']} was built for robot {row['robot']!r} (config hash "
                f"{row['robot_hash'][:12]}), not for {robot.name!r} (config hash "
                f"{robot.robot_hash[:12]}); build one with "
                f"`{build_command(None, robot, folder_flag(data_dir))}`"
            )
        if row["state"] != "complete":
            raise DatabaseNotFoundError(
                f"database {row['id']} is {row['state']}, not complete: resume it with "
                f"`{build_command(row, robot, folder_flag(data_dir))}`"
            )
        return row
    row = default_row(rows, robot.robot_hash)
    if row is None:
        same_name = [r["id"] for r in rows if r["robot"] == robot.name]
        hint = (
            f" (databases {', '.join(same_name)} are named {robot.name!r} but were built for "
            "another config or are incomplete)"
            if same_name
            else ""
        )
        raise DatabaseNotFoundError(
            f"no complete reachability database for robot {robot.name!r} in {data_dir}{hint}; "
            f"build one with `{build_command(None, robot, folder_flag(data_dir))}`"
        )
    return row


def default_params(row: dict[str, Any]) -> bool:
    """Whether a database was built with the default build parameters (any sample count)."""
    from pickstop.reach.build import BuildParams

    base = BuildParams(samples=1000)
    return all(
        row.get(k) == getattr(base, k)
        for k in ("resolution", "orientation", "seed", "chunk_size", "thinning", "floor_clearance")
    )


def default_row(rows: list[dict[str, Any]], robot_hash: str) -> dict[str, Any] | None:
    """The database a robot's plans use when they name none: the first one completed with the
    default build parameters, else the first completed at all. Later builds never take its
    place, whatever they hold: a default changes only by deleting it or by the setting."""
    ok = [r for r in rows if r["robot_hash"] == robot_hash and r["state"] == "complete"]
    preferred = [r for r in ok if default_params(r)] or ok
    if not preferred:
        return None
    return min(preferred, key=lambda r: (r.get("completed") or r.get("created") or "", r["id"]))


def open_database(
    data_dir: Path, robot: RobotModel, db_id: str | None = None, default: str | None = None
) -> ReachDatabase:
    """Open a complete database of ``robot`` (``db_id``, else its default: ``default`` if
    given, see :func:`find_database`): map its voxel index read-only.

    Nothing is decoded or recomputed; only files whose size or modification time changed
    since they were last verified are hashed (a corrupted one is refused)."""
    data_dir = Path(data_dir)
    row = find_database(data_dir, robot, db_id, default)
    if row.get("index_format") != INDEX_FORMAT:
        raise DatabaseNotFoundError(
            f"database {row['id']} has no voxel index of the format this PickStop reads "
            f"(it was built by {row['code_version']}); index it from its shards with "
            f"`{build_command(row, robot, folder_flag(data_dir))}` (about a second per "
            "million configurations)"
        )
    cat = Catalog(data_dir)
    try:
        files = index_files(cat, row["id"])
    finally:
        cat.close()
    try:
        arrays, stats = map_index(data_dir, row["id"], files)
    except CorruptShardError as e:
        raise CorruptShardError(
            f"{e.message}; for this database: `{build_command(row, robot, folder_flag(data_dir))}`"
        ) from None
    if stats.verified:
        mark_verified(data_dir, row["id"], stats.verified)
    if len(arrays["manip"]) != row["stored"]:
        raise DatabaseError(
            f"database {row['id']}: its index holds {len(arrays['manip'])} configurations, "
            f"the catalog records {row['stored']}; index it again with "
            f"`{build_command(row, robot, folder_flag(data_dir))}`"
        )
    return ReachDatabase(
        row,
        unique_keys=arrays["keys"],
        offsets=arrays["starts"],
        joints=arrays["joints"],
        manip=arrays["manip"],
        positions=arrays["positions"],
        quats=arrays["quats"],
        reach_xy=row["reach_xy"],
        stats=stats,
    )
