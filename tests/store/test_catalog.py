"""The catalog's transactions: committed whole or rolled back, whenever an exception comes."""

from __future__ import annotations

import pytest

from pickstop.store.catalog import Catalog


class Cancelled(BaseException):
    """A job's cancellation, raised in its thread at any bytecode."""


def _names(cat: Catalog) -> list[str]:
    return [r["id"] for r in cat.query("SELECT id FROM scenes ORDER BY id")]


def _add(conn, sid: str) -> None:
    conn.execute(
        "INSERT INTO scenes (id, name, revision, etag, doc, created, updated) "
        "VALUES (?, ?, 1, 'e', '{}', 't', 't')",
        [sid, sid],
    )


def test_a_transaction_commits_whole_or_not_at_all(tmp_path):
    cat = Catalog(tmp_path)
    with cat.transaction() as conn:
        _add(conn, "a")
    with pytest.raises(Cancelled), cat.transaction() as conn:
        _add(conn, "b")
        raise Cancelled
    assert _names(cat) == ["a"] and not cat.conn.in_transaction


def test_a_transaction_left_open_by_an_interrupted_block_does_not_block_the_next(tmp_path):
    """A cancellation that lands right after BEGIN, before any cleanup could run, leaves the
    thread's connection inside a transaction: the next transaction rolls it back and runs."""
    cat = Catalog(tmp_path)
    cat.conn.execute("BEGIN IMMEDIATE")
    _add(cat.conn, "half")
    with cat.transaction() as conn:
        _add(conn, "whole")
    assert _names(cat) == ["whole"]
