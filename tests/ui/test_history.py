"""The edit history: undo, redo, revert and dirty as pure operations on documents."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop_ui import edits
from pickstop_ui.history import History, restore, snapshot

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture
def doc():
    return json.loads(SCENE.read_text())


def test_undo_puts_a_moved_tray_back_exactly_and_redo_moves_it_again(doc):
    h = History.start(doc)
    assert not h.dirty and h.undo_label is None and h.redo_label is None
    original = copy.deepcopy(doc)
    edits.move(doc, "trays", "tray_4", 3.6 + 0.1 / 3, 1.5, 0.3, snap=False)
    h = h.record("move tray_4", doc)
    assert h.dirty and h.undo_label == "move tray_4"
    h = h.undo()
    assert h.doc() == original and not h.dirty and h.redo_label == "move tray_4"
    h = h.redo()
    assert h.doc()["trays"][3]["pose"]["x"] == 3.6 + 0.1 / 3 and h.undo_label == "move tray_4"


def test_a_removed_tray_comes_back_with_its_place_in_the_task(doc):
    doc["task"] = ["tray_1", "tray_2", "tray_3", "tray_4"]
    h = History.start(doc)
    edits.remove_tray(doc, "tray_2")
    h = h.record("remove tray_2", doc)
    back = h.undo().doc()
    assert [t["id"] for t in back["trays"]] == ["tray_1", "tray_2", "tray_3", "tray_4"]
    assert back["task"] == ["tray_1", "tray_2", "tray_3", "tray_4"]


def test_a_new_edit_drops_what_was_undone_and_a_no_op_is_no_step(doc):
    h = History.start(doc)
    edits.rename_tray(doc, "tray_1", "bolts")
    h = h.record("rename tray_1", doc)
    h = h.undo()
    doc = h.doc()
    edits.set_needed(doc, "tray_2", False)
    h = h.record("task tray_2", doc)
    assert h.redo_label is None and h.undo_label == "task tray_2"
    assert h.record("nothing", h.doc()) is h


def test_revert_to_saved_is_one_undoable_step(doc):
    h = History.start(doc)
    for k in range(3):
        edits.move(doc, "obstacles", "table_b", 3.6 + 0.1 * (k + 1), 1.6, 0.0)
        h = h.record(f"move table_b {k}", doc)
    h = h.revert()
    assert h.current == h.saved and h.undo_label == "revert to saved"
    assert h.undo().doc()["obstacles"][1]["pose"]["x"] == pytest.approx(3.9)


def test_saving_clears_dirty_and_keeps_the_steps(doc):
    h = History.start(doc)
    edits.rename_tray(doc, "tray_1", "bolts")
    h = h.record("rename tray_1", doc).mark_saved()
    assert not h.dirty and h.undo_label == "rename tray_1"
    assert h.undo().dirty  # the saved scene has the new name
    stored = dict(h.doc(), description="as the store answered it")
    h2 = h.mark_saved(stored)
    assert not h2.dirty and h2.doc() == stored


def test_the_oldest_steps_go_past_the_limit(doc):
    h = History.start(doc, limit=3)
    for k in range(5):
        edits.rename_tray(doc, "tray_1", f"name {k}")
        h = h.record(f"rename {k}", doc)
    assert [s.label for s in h.done] == ["rename 2", "rename 3", "rename 4"]
    for _ in range(5):
        h = h.undo()
    assert h.doc()["trays"][0]["name"] == "name 1" and len(h.undone) == 3
    with pytest.raises(ValueError, match="at least one step"):
        History.start(doc, limit=0)


def test_a_snapshot_is_canonical_and_restores_a_fresh_copy(doc):
    s = snapshot(doc)
    assert s == snapshot(json.loads(json.dumps(doc, indent=2)))
    a, b = restore(s), restore(s)
    a["trays"][0]["pose"]["x"] = 99.0
    assert b["trays"][0]["pose"]["x"] != 99.0


# -- against a reference model: a list of documents and a cursor -----------------------------

OPS = st.lists(
    st.one_of(
        st.tuples(st.just("edit"), st.integers(0, 3), st.integers(-5, 5)),
        st.tuples(st.just("undo")),
        st.tuples(st.just("redo")),
        st.tuples(st.just("revert")),
        st.tuples(st.just("save")),
    ),
    max_size=40,
)


@settings(max_examples=150, deadline=None)
@given(OPS)
def test_any_sequence_of_edits_undos_and_redos_matches_a_list_with_a_cursor(ops):
    base = {"trays": [{"id": f"t{k}", "pose": {"x": 0.0}} for k in range(4)]}
    h = History.start(base)
    docs, cursor, saved = [copy.deepcopy(base)], 0, copy.deepcopy(base)
    for op in ops:
        if op[0] == "edit" or op[0] == "revert":
            if op[0] == "edit":
                new = copy.deepcopy(docs[cursor])
                new["trays"][op[1]]["pose"]["x"] += op[2] * 0.025
                h = h.record("edit", new)
            else:
                new = copy.deepcopy(saved)
                h = h.revert()
            if new != docs[cursor]:
                docs, cursor = [*docs[: cursor + 1], new], cursor + 1
        elif op[0] == "undo":
            h, cursor = h.undo(), max(cursor - 1, 0)
        elif op[0] == "redo":
            h, cursor = h.redo(), min(cursor + 1, len(docs) - 1)
        else:
            h, saved = h.mark_saved(), copy.deepcopy(docs[cursor])
        assert h.doc() == docs[cursor]
        assert len(h.done) == cursor and len(h.undone) == len(docs) - 1 - cursor
        assert h.dirty == (docs[cursor] != saved)
