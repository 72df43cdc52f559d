"""``/plans/{id}/report`` and ``/plans/{id}/stops.csv``: a stored plan as a document to hand
on (an HTML report with its top-view drawing) and its stops as CSV."""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Response

from pickstop.api.deps import ReadKey, ServiceDep
from pickstop.api.problems import Problem
from pickstop.report.html import ReportIds, report_html
from pickstop.report.stops_csv import stops_csv
from pickstop.sequence.plan_model import Plan

router = APIRouter(tags=["plans"])

IMMUTABLE = "public, max-age=31536000, immutable"


def _stored(service: Any, plan_id: str) -> tuple[Plan, dict[str, Any], dict[str, Any]]:
    """The stored plan, the scene document it was planned from, and its row (404 if none)."""
    row = service.store.plan(plan_id)
    if row is None:
        raise Problem(404, "Not found", f"no plan {plan_id!r}", field="plan_id")
    return Plan.model_validate_json(row["doc"]), json.loads(row["scene_doc"]), row


@router.get(
    "/plans/{plan_id}/report",
    dependencies=[ReadKey],
    response_class=Response,
    responses={200: {"content": {"text/html": {}}, "description": "a self-contained page"}},
)
def plan_report(service: ServiceDep, plan_id: str) -> Response:
    """The plan as one HTML page: top-view drawing, figures, stops, rejections, ids, notes."""
    plan, scene, row = _stored(service, plan_id)
    ids = ReportIds(row["id"], row["scene_id"], row["scene_revision"], row["created"])
    # The store's id (its own characters), never the path's text, names the file.
    headers = {"Cache-Control": IMMUTABLE,
               "Content-Disposition": f'inline; filename="pickstop-{row["id"]}.html"'}  # fmt: skip
    return Response(report_html(plan, scene, ids), media_type="text/html; charset=utf-8",
                    headers=headers)  # fmt: skip


@router.get(
    "/plans/{plan_id}/stops.csv",
    dependencies=[ReadKey],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}, "description": "one row per stop"}},
)
def plan_stops_csv(service: ServiceDep, plan_id: str) -> Response:
    """The plan's stops in visiting order, one row each (position, yaw, trays, radius,
    success with its interval)."""
    plan, scene, row = _stored(service, plan_id)
    name = f"pickstop-{row['id']}-stops.csv"
    headers = {"Cache-Control": IMMUTABLE,
               "Content-Disposition": f'attachment; filename="{name}"'}  # fmt: skip
    return Response(stops_csv(plan, scene), media_type="text/csv; charset=utf-8",
                    headers=headers)  # fmt: skip
