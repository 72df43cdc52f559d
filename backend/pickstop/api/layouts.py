"""Layout suggestions over REST: a request checked when submitted, the search run as a job
(progress as it goes, cancel stops it), the layout document as the job's result."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from pickstop.api.limits import Limits
from pickstop.api.mixes import request_orders
from pickstop.errors import InputError
from pickstop.layout.search import SearchSettings, check_request
from pickstop.scene.model import Order, Scene
from pickstop.sequence.mix import mix_trays
from pickstop.sequence.plan_model import PlanOptions
from pickstop.store.records import ServiceStore


def layout_orders(orders: Any, scene: Scene, limits: Limits) -> list[Order]:
    """A request's orders (a list, ``"scene"``), or by default the scene's, else its task."""
    if orders is not None:
        return request_orders(orders, scene, limits)
    if scene.orders:
        return request_orders("scene", scene, limits)
    return [Order(id="task", trays=scene.task_trays)]


def layout_params(body: Any, scene: Scene, limits: Limits) -> dict[str, Any]:
    """A layout request's job parameters, every check a search would meet made now."""
    orders = layout_orders(body.orders, scene, limits)
    movable = body.movable if body.movable is not None else mix_trays(scene, orders)
    check_request(scene, orders, movable)
    return {
        "scene_id": body.scene_id,
        "scene": body.scene,
        "orders": [o.model_dump() for o in orders],
        "movable": movable,
        "options": body.options.model_dump(),
        "database": body.database,
        "settings": {"step": body.step, "turns": list(dict.fromkeys(body.turns)),
                     "suggestions": body.suggestions, "shortlist": body.shortlist},
    }  # fmt: skip


def layout_job(
    parse: Callable[[Any], Scene], layout: Callable[..., dict[str, Any]]
) -> Callable[[Any, str, dict[str, Any]], dict[str, Any]]:
    """A layout search as a job: ``layout_params``'s parameters -> the layout document;
    progress as the search reports it."""

    def run(runner: Any, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        store: ServiceStore = runner.store
        doc = params.get("scene")
        if params.get("scene_id") is not None:
            row = store.scene(params["scene_id"])
            if row is None:
                raise InputError(f"scene {params['scene_id']} does not exist", field="scene_id")
            doc = json.loads(row["doc"])
        scene = parse(doc)
        orders = [Order(**o) for o in params["orders"]]
        s = params["settings"]
        settings = SearchSettings(
            step=s["step"], turns=tuple(s["turns"]), suggestions=s["suggestions"],
            shortlist=s["shortlist"],
        )  # fmt: skip
        last = [0.0]

        def progress(fraction: float, message: str) -> None:
            if fraction - last[0] >= 0.01 or fraction >= 1.0:
                last[0] = fraction
                store.set_job(job_id, progress=min(fraction, 0.99))

        return layout(scene, orders, params["movable"], PlanOptions(**params["options"]),
                      settings, params.get("database"), progress)  # fmt: skip

    return run
