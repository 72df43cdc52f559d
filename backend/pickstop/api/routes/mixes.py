"""``/mixes``: stored mixes (planned through ``POST /plans`` with ``orders``), immutable."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Query, Response

from pickstop.api.deps import ReadKey, ServiceDep
from pickstop.api.problems import Problem
from pickstop.api.schemas import MixRecord, MixSummary

router = APIRouter(tags=["plans"])

IMMUTABLE = {"Cache-Control": "public, max-age=31536000, immutable"}


@router.get("/mixes", dependencies=[ReadKey])
def mixes(
    service: ServiceDep,
    scene_id: str | None = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
    offset: Annotated[int, Query(ge=0, le=10**9, description="records to skip")] = 0,
) -> list[MixSummary]:
    return [MixSummary.of(x) for x in service.store.mixes(scene_id, limit, offset)]


@router.get("/mixes/{mix_id}", dependencies=[ReadKey], response_model=MixRecord)
def get_mix(service: ServiceDep, mix_id: str) -> Response:
    """A stored mix: the mix document, each order's plan named by its plan id
    (``GET /plans/{id}``)."""
    row = service.store.mix(mix_id)
    if row is None:
        raise Problem(404, "Not found", f"no mix {mix_id!r}", field="mix_id")
    record = MixRecord(
        id=row["id"],
        scene_id=row["scene_id"],
        scene_revision=row["scene_revision"],
        created=row["created"],
        options=json.loads(row["options"]),
        mix=json.loads(row["doc"]),
    )
    return Response(record.model_dump_json(), media_type="application/json", headers=IMMUTABLE)
