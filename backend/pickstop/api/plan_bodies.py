"""Stored plans as the JSON bytes the API answers with, kept in memory once read.

Stored plans are immutable and never deleted, so a body never goes stale: the cache only
forgets the oldest bodies past :data:`MAX_BODIES`.
"""

from __future__ import annotations

import json

from pickstop.api.schemas import PlanRecord
from pickstop.caching import Cache
from pickstop.store.records import ServiceStore

MAX_BODIES = 512  # plan bodies kept in memory


def record_body(record: PlanRecord, plan_json: bytes) -> bytes:
    """``record`` (without plan or scene) with the plan's JSON as it came from the planner:
    the bytes ``record.model_copy(update={"plan": plan}).model_dump_json()`` would give,
    without parsing the plan or serialising it again."""
    if record.plan is not None or record.scene is not None:
        raise ValueError("record_body takes a record without plan and scene")
    head = record.model_dump_json(exclude={"plan", "scene"}).encode()
    return head[:-1] + b',"plan":' + plan_json + b',"scene":null}'


class PlanBodies:
    """The bodies of stored plans: ``{"id", "scene_id", "scene_revision", "created",
    "options", "plan"}`` as bytes, assembled from the stored JSON without parsing it."""

    def __init__(self, store: ServiceStore) -> None:
        self.store = store
        self._bodies: Cache[str, bytes] = Cache("plan_bodies", max_items=MAX_BODIES)

    def cached(self, plan_id: str) -> bytes | None:
        """A stored plan's body if it is in memory already (no database access)."""
        return self._bodies.peek(plan_id)

    def body(self, plan_id: str, with_scene: bool = False) -> bytes | None:
        """A stored plan record as JSON bytes (``with_scene``: plus the exact scene it was
        planned from); None if there is no such plan."""
        hit = self._bodies.get(plan_id)
        if hit is not None and not with_scene:
            return hit
        row = self.store.plan(plan_id)
        if row is None:
            return None
        body = (
            f'{{"id":"{row["id"]}","scene_id":{json.dumps(row["scene_id"])},'
            f'"scene_revision":{json.dumps(row["scene_revision"])},"created":"{row["created"]}",'
            f'"options":{row["options"]},"plan":{row["doc"]}}}'
        ).encode()
        self._bodies.put(plan_id, body)
        if with_scene:
            return body[:-1] + b',"scene":' + row["scene_doc"].encode() + b"}"
        return body
