"""Product mixes over REST: a request's orders checked, a mix planned (at once or as a job, a
few orders at a time), each order's plan stored as a plan record and the mix document naming
them stored as a mix record."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from pickstop.api.limits import Limits
from pickstop.errors import InputError
from pickstop.runtime.cancel import checkpoint
from pickstop.scene.model import Order, Scene
from pickstop.scene.orders import parse_orders, scene_orders
from pickstop.sequence.mix import MixPlans, mix_document
from pickstop.sequence.plan_model import PlanOptions
from pickstop.store.records import ServiceStore, now

CHUNK = 10  # orders a mix job plans per call (its progress steps between them)


def request_orders(
    orders: list[Order] | list[dict[str, Any]] | str, scene: Scene, limits: Limits
) -> list[Order]:
    """A request's ``orders`` (a list, or ``"scene"``: the scene's own) checked against the
    scene and the limit on their number."""
    if orders == "scene":
        out = scene_orders(scene)
    else:
        docs = [o.model_dump() if isinstance(o, Order) else o for o in orders]
        out = parse_orders(docs, scene)
    if len(out) > limits.max_orders:
        raise InputError(f"orders: {len(out)} orders exceed the limit of {limits.max_orders}",
                         field="orders")  # fmt: skip
    return out


def store_mix(
    store: ServiceStore,
    scene_id: str | None,
    revision: int | None,
    scene_doc: dict[str, Any],
    mix: MixPlans,
    keep: bool = True,
) -> dict[str, Any]:
    """The mix record of ``mix`` (a dict as :class:`~pickstop.api.schemas.MixRecord`): with
    ``keep``, each order's plan stored as a plan record (its scene document with the order's
    trays as task) and the mix document, naming them, as a mix record."""
    options = mix.options.model_dump()
    refs: list[str | None] = [None] * len(mix.orders)
    if keep:
        for k, op in enumerate(mix.orders):
            if op.plan is not None:
                doc = {**scene_doc, "task": list(op.trays)}
                rec = store.add_plan(scene_id, revision, doc, options,
                                     op.plan.model_dump_json().encode())  # fmt: skip
                refs[k] = str(rec["id"])
    doc = mix_document(mix, refs).model_dump(mode="json")
    row = {"id": None, "created": now()}
    if keep:
        row = store.add_mix(scene_id, revision, options, doc)
    return {"id": row["id"], "scene_id": scene_id, "scene_revision": revision,
            "created": row["created"], "options": options, "mix": doc}  # fmt: skip


def mix_job(
    parse: Callable[[Any], Scene],
    plan_mix: Callable[..., MixPlans],
    limits: Limits,
) -> Callable[[Any, str, dict[str, Any]], dict[str, Any]]:
    """A mix as a job: ``{"scene_id" | "scene", "orders", "options", "database"}`` -> the mix
    record's id with the totals; progress after every :data:`CHUNK` orders."""

    def run(runner: Any, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        store: ServiceStore = runner.store
        scene_id, doc, revision = params.get("scene_id"), params.get("scene"), None
        if scene_id is not None:
            row = store.scene(scene_id)
            if row is None:
                raise InputError(f"scene {scene_id} does not exist", field="scene_id")
            doc, revision = json.loads(row["doc"]), row["revision"]
        scene = parse(doc)
        orders = request_orders(params["orders"], scene, limits)
        options = PlanOptions(**params.get("options", {}))
        mix: MixPlans | None = None
        for start in range(0, len(orders), CHUNK):
            checkpoint()
            part = plan_mix(scene, orders[start : start + CHUNK], options,
                            params.get("database"), orders if start == 0 else None)  # fmt: skip
            mix = part if mix is None else mix + part
            store.set_job(job_id, progress=min(start + CHUNK, len(orders)) / len(orders))
        assert mix is not None
        record = store_mix(store, scene_id, revision, doc, mix)
        totals = record["mix"]["totals"]
        return {"mix": record["id"], "orders": totals["orders"], "planned": totals["planned"],
                "failed": totals["failed"]}  # fmt: skip

    return run
