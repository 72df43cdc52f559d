"""The service's records in the SQLite catalog: scenes, plans, mixes, jobs, robots.

One connection per thread (SQLite connections are not shared across threads); WAL mode lets
readers run while a writer commits. Updates that must not race (a scene's ETag check and
write) run in one ``BEGIN IMMEDIATE`` transaction.
"""

from __future__ import annotations

import json
import secrets
import threading
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pickstop.store.catalog import Catalog


def now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def new_id(prefix: str) -> str:
    return f"{prefix}_{secrets.token_hex(8)}"


class Conflict(Exception):
    """The record changed since the caller read it (ETag mismatch)."""

    def __init__(self, current: str) -> None:
        super().__init__(current)
        self.current = current


class ServiceStore:
    """The service's records in ``catalog.sqlite``: scenes, plans (and their proven
    tolerances), jobs and robots."""

    def __init__(self, data_dir: Path) -> None:
        self.data_dir = Path(data_dir)
        self._local = threading.local()
        _ = self.catalog  # migrate now, in the constructing thread

    @property
    def catalog(self) -> Catalog:
        cat = getattr(self._local, "catalog", None)
        if cat is None:
            cat = self._local.catalog = Catalog(self.data_dir)
        return cat

    @contextmanager
    def transaction(self) -> Iterator[Any]:
        with self.catalog.transaction() as conn:
            yield conn

    def rows(self, sql: str, params: Any = ()) -> list[dict[str, Any]]:
        return self.catalog.query(sql, params)

    # -- scenes ------------------------------------------------------------------------------
    def create_scene(self, doc: dict[str, Any], name: str) -> dict[str, Any]:
        t = now()
        row = {
            "id": new_id("scn"),
            "name": name,
            "doc": doc.decode() if isinstance(doc, bytes) else json.dumps(doc),
            "etag": _etag(),
            "revision": 1,
            "created": t,
            "updated": t,
        }
        self.catalog.insert("scenes", row)
        return row

    def scene(self, scene_id: str) -> dict[str, Any] | None:
        return self.catalog.one("SELECT * FROM scenes WHERE id = ?", [scene_id])

    def scenes(self, limit: int, offset: int) -> list[dict[str, Any]]:
        return self.rows(
            "SELECT id, name, etag, revision, created, updated FROM scenes "
            "ORDER BY created, id LIMIT ? OFFSET ?",
            [limit, offset],
        )

    def update_scene(
        self, scene_id: str, doc: dict[str, Any], name: str, if_match: Collection[str] | None
    ) -> dict[str, Any] | None:
        """Replace the document if its ETag is still one of ``if_match`` (None: any); None if
        the scene is gone."""
        with self.transaction() as c:
            cur = _matching_scene(c, scene_id, if_match)
            if cur is None:
                return None
            etag, rev, t = _etag(), cur[1] + 1, now()
            c.execute(
                "UPDATE scenes SET doc = ?, name = ?, etag = ?, revision = ?, updated = ? "
                "WHERE id = ?",
                [json.dumps(doc), name, etag, rev, t, scene_id],
            )
        return self.scene(scene_id)

    def delete_scene(self, scene_id: str, if_match: Collection[str] | None) -> bool:
        """Delete the scene if its ETag is one of ``if_match`` (None: any); False if gone."""
        with self.transaction() as c:
            if _matching_scene(c, scene_id, if_match) is None:
                return False
            c.execute("DELETE FROM scenes WHERE id = ?", [scene_id])
        return True

    # -- plans -------------------------------------------------------------------------------
    def add_plan(
        self,
        scene_id: str | None,
        revision: int | None,
        scene_doc: dict[str, Any],
        options: dict[str, Any],
        doc: dict[str, Any] | bytes,
    ) -> dict[str, Any]:
        """Store a plan; ``doc``: the plan as a JSON-ready mapping, or its JSON already."""
        row = {
            "id": new_id("pln"),
            "scene_id": scene_id,
            "scene_revision": revision,
            "scene_doc": json.dumps(scene_doc),
            "options": json.dumps(options),
            "doc": doc.decode() if isinstance(doc, bytes) else json.dumps(doc),
            "created": now(),
        }
        self.catalog.insert("plans", row)
        return row

    def plan(self, plan_id: str) -> dict[str, Any] | None:
        return self.catalog.one("SELECT * FROM plans WHERE id = ?", [plan_id])

    def plans(self, scene_id: str | None, limit: int, offset: int) -> list[dict[str, Any]]:
        where, params = ("WHERE scene_id = ?", [scene_id]) if scene_id else ("", [])
        return self.rows(
            "SELECT id, scene_id, scene_revision, options, created, "
            "json_extract(doc, '$.totals.stops') AS stops, "
            "json_extract(doc, '$.totals.time.total') AS time "
            f"FROM plans {where} ORDER BY created, id LIMIT ? OFFSET ?",
            [*params, limit, offset],
        )

    def plan_proof(self, plan_id: str, prover: str) -> dict[str, Any] | None:
        """A stored plan's proven tolerances (JSON) if they were proven by ``prover``."""
        row = self.catalog.one(
            "SELECT doc FROM plan_proofs WHERE plan_id = ? AND prover = ?", [plan_id, prover]
        )
        return None if row is None else json.loads(row["doc"])

    def add_plan_proof(self, plan_id: str, prover: str, doc: dict[str, Any]) -> None:
        """Keep a stored plan's proven tolerances (over any kept by another prover)."""
        row = {"plan_id": plan_id, "prover": prover, "doc": json.dumps(doc), "created": now()}
        self.catalog.insert("plan_proofs", row, replace=True)

    # -- mixes -------------------------------------------------------------------------------
    def add_mix(
        self,
        scene_id: str | None,
        revision: int | None,
        options: dict[str, Any],
        doc: dict[str, Any],
    ) -> dict[str, Any]:
        """Store a mix document (its orders' plans stored already, named by their ids)."""
        row = {
            "id": new_id("mix"),
            "scene_id": scene_id,
            "scene_revision": revision,
            "options": json.dumps(options),
            "doc": json.dumps(doc),
            "created": now(),
        }
        self.catalog.insert("mixes", row)
        return row

    def mix(self, mix_id: str) -> dict[str, Any] | None:
        return self.catalog.one("SELECT * FROM mixes WHERE id = ?", [mix_id])

    def mixes(self, scene_id: str | None, limit: int, offset: int) -> list[dict[str, Any]]:
        where, params = ("WHERE scene_id = ?", [scene_id]) if scene_id else ("", [])
        return self.rows(
            "SELECT id, scene_id, scene_revision, options, created, "
            "json_extract(doc, '$.totals.orders') AS orders, "
            "json_extract(doc, '$.totals.time') AS time "
            f"FROM mixes {where} ORDER BY created, id LIMIT ? OFFSET ?",
            [*params, limit, offset],
        )

    # -- jobs --------------------------------------------------------------------------------
    def add_job(self, kind: str, params: dict[str, Any]) -> dict[str, Any]:
        t = now()
        row = {
            "id": new_id("job"),
            "kind": kind,
            "state": "queued",
            "progress": 0.0,
            "params": json.dumps(params),
            "created": t,
            "updated": t,
        }
        self.catalog.insert("jobs", row)
        job = self.job(str(row["id"]))
        assert job is not None
        return job

    def job(self, job_id: str) -> dict[str, Any] | None:
        return self.catalog.one("SELECT * FROM jobs WHERE id = ?", [job_id])

    def jobs(self, limit: int, offset: int) -> list[dict[str, Any]]:
        return self.rows(
            "SELECT * FROM jobs ORDER BY created, id LIMIT ? OFFSET ?", [limit, offset]
        )

    def next_queued_job(self) -> str | None:
        """The oldest queued build, batch, mix or layout job, if any (dispatch jobs run on
        their own)."""
        rows = self.rows(
            "SELECT id FROM jobs WHERE state = 'queued' "
            "AND kind IN ('build', 'batch', 'mix', 'layout') ORDER BY created, id LIMIT 1"
        )
        return str(rows[0]["id"]) if rows else None

    def set_job(self, job_id: str, **fields: Any) -> None:
        fields["updated"] = now()
        for k in ("result",):
            if k in fields and not isinstance(fields[k], str | None):
                fields[k] = json.dumps(fields[k])
        sets = ", ".join(f"{k} = :{k}" for k in fields)
        with self.transaction() as c:
            c.execute(f"UPDATE jobs SET {sets} WHERE id = :id", {**fields, "id": job_id})

    def interrupt_stale_jobs(self) -> int:
        """Jobs left queued or running by a previous run of the service: mark interrupted."""
        with self.transaction() as c:
            cur = c.execute(
                "UPDATE jobs SET state = 'interrupted', error = 'the service stopped while the "
                "job was queued or running; start it again', updated = ? "
                "WHERE state IN ('queued', 'running')",
                [now()],
            )
            return int(cur.rowcount)

    # -- robots ------------------------------------------------------------------------------
    def add_robot(self, name: str, config: dict[str, Any]) -> None:
        with self.transaction() as c:
            c.execute(
                "INSERT INTO robots (name, config, created) VALUES (?, ?, ?)",
                [name, json.dumps(config), now()],
            )

    def robot(self, name: str) -> dict[str, Any] | None:
        """The registered robot ``name`` (``name, config, created``), or None."""
        return self.catalog.one("SELECT name, config, created FROM robots WHERE name = ?", [name])

    def robots(self) -> list[dict[str, Any]]:
        return self.rows("SELECT name, config, created FROM robots ORDER BY name")


def _matching_scene(
    conn: Any, scene_id: str, if_match: Collection[str] | None
) -> tuple[str, int] | None:
    """``(etag, revision)`` of a scene inside a transaction, or None if it is gone; raises
    :class:`Conflict` if its ETag is not one of ``if_match`` (None: any)."""
    cur = conn.execute("SELECT etag, revision FROM scenes WHERE id = ?", [scene_id]).fetchone()
    if cur is not None and if_match is not None and cur[0] not in if_match:
        raise Conflict(cur[0])
    return None if cur is None else (str(cur[0]), int(cur[1]))


def _etag() -> str:
    return secrets.token_hex(10)
