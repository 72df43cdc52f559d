"""Undo and redo of the planner's edits: a pure history of scene documents.

Every edit the engineer makes to the scene (a tray or obstacle moved or turned, a tray added,
removed or renamed, a task ticked, a whole suggested layout accepted) is one :class:`Step`:
what it is called and the document before and after it. Documents are kept as canonical JSON
text (:func:`snapshot`): immutable, compact, compared by equality, and restored exactly, so an
undo puts every coordinate back to the bit.

A :class:`History` is a frozen value; every operation returns a new one. It knows nothing of
what an edit does: the caller changes its working document however it likes and then
records the result under a label (:meth:`History.record`), so any future edit (a layout
suggestion accepted as a whole) is one step without a new kind of edit here. The document
as last saved is kept too: :meth:`History.revert` is a step like any other (undoable), and
:attr:`History.dirty` says whether the scene differs from what is stored.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Any

Snapshot = str  # a scene document as canonical JSON text
MAX_STEPS = 200  # steps kept for undo; the oldest go first


def snapshot(doc: dict[str, Any]) -> Snapshot:
    """``doc`` as canonical JSON text (keys sorted, no spaces): equal documents, equal text."""
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)


def restore(snap: Snapshot) -> dict[str, Any]:
    """A fresh document from ``snap`` (the caller may change it freely)."""
    doc: dict[str, Any] = json.loads(snap)
    return doc


@dataclass(frozen=True)
class Step:
    """One undoable edit: its label (e.g. "move tray_4") and the document around it."""

    label: str
    before: Snapshot
    after: Snapshot


@dataclass(frozen=True)
class History:
    """The edits of one planner window. ``current``: the document as it stands; ``saved``: as
    it was last loaded or saved; ``done``: steps to undo (newest last); ``undone``: steps to
    redo (the next one last)."""

    current: Snapshot
    saved: Snapshot
    done: tuple[Step, ...] = ()
    undone: tuple[Step, ...] = ()
    limit: int = MAX_STEPS

    @classmethod
    def start(cls, doc: dict[str, Any], limit: int = MAX_STEPS) -> History:
        """A history with nothing to undo, ``doc`` as saved and current."""
        if limit < 1:
            raise ValueError(f"a history keeps at least one step, got limit {limit}")
        s = snapshot(doc)
        return cls(current=s, saved=s, limit=limit)

    # -- reading ------------------------------------------------------------------------------
    def doc(self) -> dict[str, Any]:
        """A fresh copy of the current document."""
        return restore(self.current)

    @property
    def dirty(self) -> bool:
        """The current document differs from the saved one."""
        return self.current != self.saved

    @property
    def undo_label(self) -> str | None:
        """What :meth:`undo` would take back (None: nothing)."""
        return self.done[-1].label if self.done else None

    @property
    def redo_label(self) -> str | None:
        """What :meth:`redo` would do again (None: nothing)."""
        return self.undone[-1].label if self.undone else None

    # -- changing -----------------------------------------------------------------------------
    def record(self, label: str, doc: dict[str, Any] | Snapshot) -> History:
        """The edit from the current document to ``doc`` as one step called ``label``; the
        steps undone before it can no longer be redone. An edit that changes nothing is no
        step (the history is returned as it is)."""
        after = doc if isinstance(doc, str) else snapshot(doc)
        if after == self.current:
            return self
        done = (*self.done, Step(label, self.current, after))[-self.limit :]
        return replace(self, current=after, done=done, undone=())

    def undo(self) -> History:
        """The last step taken back (the history as it is when there is none)."""
        if not self.done:
            return self
        step = self.done[-1]
        return replace(self, current=step.before, done=self.done[:-1],
                       undone=(*self.undone, step))  # fmt: skip

    def redo(self) -> History:
        """The last undone step done again (the history as it is when there is none)."""
        if not self.undone:
            return self
        step = self.undone[-1]
        return replace(self, current=step.after, done=(*self.done, step)[-self.limit :],
                       undone=self.undone[:-1])  # fmt: skip

    def revert(self) -> History:
        """Back to the saved document, as one undoable step."""
        return self.record("revert to saved", self.saved)

    def mark_saved(self, doc: dict[str, Any] | None = None) -> History:
        """The current document (or ``doc``, as the store answered it) is what is stored now;
        a stored document that differs from the current one becomes the current one, and
        the steps stay undoable."""
        if doc is None:
            return replace(self, saved=self.current)
        s = snapshot(doc)
        return replace(self, saved=s, current=s) if s != self.current else replace(self, saved=s)
