"""Orders of a product mix: checked against their scene, read from a file or a request.

An order names the trays it needs, or its parts (each brings its tray); ``weight`` says how
often it is made. The scene may carry its orders (``orders``); a list given beside it (the
CLI's ``--orders FILE``, a request's ``orders``) replaces them.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Any

from pydantic import TypeAdapter, ValidationError

from pickstop.errors import InputError
from pickstop.scene.model import Order, Scene, SceneError

_ORDERS = TypeAdapter(list[Order])


def order_problems(scene: Scene, orders: list[Order], loc: str = "orders") -> list[tuple[str, str]]:
    """(field, message) for every order of ``orders`` naming a tray or part ``scene`` lacks,
    listing one twice, or sharing its id with another order."""
    out: list[tuple[str, str]] = []
    trays = {t.id for t in scene.trays}
    parts = {p.id for t in scene.trays for p in t.parts}
    for d in sorted(k for k, v in Counter(o.id for o in orders).items() if v > 1):
        out.append((loc, f"duplicate order id {d!r}"))
    for i, order in enumerate(orders):
        for name, ids, known in (("trays", order.trays, trays), ("parts", order.parts, parts)):
            for j, x in enumerate(ids or []):
                if x not in known:
                    msg = f"order {order.id!r}: unknown {name[:-1]} {x!r}"
                    out.append((f"{loc}.{i}.{name}.{j}", msg))
            for d in sorted(k for k, v in Counter(ids or []).items() if v > 1):
                out.append((f"{loc}.{i}.{name}", f"order {order.id!r} lists {d!r} twice"))
    return out


def parse_orders(data: Any, scene: Scene, source: str = "orders") -> list[Order]:
    """A decoded JSON list of orders, validated against ``scene``; raises
    :class:`~pickstop.scene.model.SceneError` naming each problem's field (``orders.2.trays.0``)."""
    try:
        orders = _ORDERS.validate_python(data)
    except ValidationError as e:
        problems = [
            (".".join(["orders", *(str(p) for p in err["loc"])]), err["msg"]) for err in e.errors()
        ]
        raise SceneError(problems, source) from None
    if not orders:
        raise SceneError([("orders", "give at least one order")], source)
    problems = order_problems(scene, orders)
    if problems:
        raise SceneError(problems, source)
    return orders


def load_orders(path: str | Path, scene: Scene) -> list[Order]:
    """The orders of a JSON file (a list of ``{id, trays | parts, weight}``) for ``scene``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: orders file not found", field="orders")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not valid JSON: {e}", field="orders") from None
    if isinstance(data, dict) and "orders" in data:  # a scene document, or {"orders": [...]}
        data = data["orders"]
    return parse_orders(data, scene, str(path))


def scene_orders(scene: Scene) -> list[Order]:
    """The scene's own orders; refused (naming ``orders``) if it has none."""
    if not scene.orders:
        raise InputError(
            "the scene has no orders: add them to its 'orders' or give a file of them",
            field="orders",
        )
    return list(scene.orders)
