"""The SQLite catalog (sqlite-utils, WAL mode) with numbered SQL migrations."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pickstop.errors import DatabaseError

if TYPE_CHECKING:
    import sqlite_utils

MIGRATIONS = Path(__file__).parent / "migrations"


def migrations() -> list[tuple[int, Path]]:
    """Numbered migration files ``NNNN_name.sql`` in order."""
    out = []
    for f in sorted(MIGRATIONS.glob("*.sql")):
        out.append((int(f.name.split("_", 1)[0]), f))
    return out


class Catalog:
    """``catalog.sqlite`` in the data folder; one connection per instance (one per thread)."""

    def __init__(self, data_dir: Path) -> None:
        self.data_dir = Path(data_dir)
        self.path = self.data_dir / "catalog.sqlite"
        try:
            self.data_dir.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        except (sqlite3.Error, OSError) as e:
            raise DatabaseError(f"{self.path}: cannot open catalog: {e}") from None
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA foreign_keys=ON")
        conn.execute("PRAGMA busy_timeout=30000")
        self.conn = conn
        self._migrate()

    @cached_property
    def db(self) -> sqlite_utils.Database:
        """The connection as sqlite-utils sees it (imported on first use: it costs ~0.5 s and
        a reader that only queries, like opening a reachability database, never needs it)."""
        import sqlite_utils

        return sqlite_utils.Database(self.conn)

    @property
    def schema_version(self) -> int:
        return int(self.conn.execute("PRAGMA user_version").fetchone()[0])

    def _migrate(self) -> None:
        current = self.schema_version
        known = migrations()
        latest = known[-1][0] if known else 0
        if current > latest:
            raise DatabaseError(
                f"{self.path}: catalog schema version {current} is newer than this PickStop "
                f"understands ({latest}); upgrade PickStop"
            )
        for version, path in known:
            if version <= current:
                continue
            conn = self.conn
            # A migration may rebuild a table: foreign keys are off while it runs (they cannot
            # change inside a transaction), so dropping the old table cascades nowhere.
            conn.execute("PRAGMA foreign_keys=OFF")
            conn.execute("BEGIN IMMEDIATE")
            try:
                if self.schema_version < version:  # another process may have migrated meanwhile
                    for stmt in path.read_text().split(";\n"):
                        if stmt.strip():
                            conn.execute(stmt)
                    conn.execute(f"PRAGMA user_version={version}")
                conn.execute("COMMIT")
            except Exception:
                conn.execute("ROLLBACK")
                raise
            finally:
                conn.execute("PRAGMA foreign_keys=ON")

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One ``BEGIN IMMEDIATE`` transaction on this connection, committed when the block
        ends and rolled back on any exception, however early it comes (a job's cancellation
        is raised in its thread at any bytecode: right after BEGIN too). A transaction an
        interrupted block left open on this connection is rolled back first (a connection
        belongs to one thread: nothing else can be using it)."""
        conn = self.conn
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        try:
            conn.execute("BEGIN IMMEDIATE")
            yield conn
            conn.execute("COMMIT")
        except BaseException:
            if conn.in_transaction:
                conn.execute("ROLLBACK")
            raise

    def table(self, name: str) -> sqlite_utils.db.Table:
        return self.db.table(name)

    def insert(self, table: str, row: dict[str, Any], *, replace: bool = False) -> None:
        """Insert ``row`` (column: value; the columns are the code's, never a user's) into
        ``table``; ``replace``: over a row with the same primary key."""
        names = ", ".join(row)
        values = ", ".join(f":{n}" for n in row)
        verb = "INSERT OR REPLACE" if replace else "INSERT"
        self.conn.execute(f"{verb} INTO {table} ({names}) VALUES ({values})", row)

    def query(self, sql: str, params: Any = ()) -> list[dict[str, Any]]:
        cur = self.conn.execute(sql, params)
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur]

    def one(self, sql: str, params: Any = ()) -> dict[str, Any] | None:
        """The first row of a query, or None."""
        rows = self.query(sql, params)
        return rows[0] if rows else None

    def close(self) -> None:
        self.conn.close()
