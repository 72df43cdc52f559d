"""A scene's orders in the planner: which trays an order needs, the document planned for it,
and the mix's weighted figures in words (pure functions of documents)."""

from __future__ import annotations

import copy
from typing import Any

TASK = "task"  # the order selector's entry for the scene's own task


def order_ids(doc: dict[str, Any]) -> list[str]:
    return [str(o["id"]) for o in doc.get("orders") or []]


def order_trays(doc: dict[str, Any], oid: str) -> list[str]:
    """The trays order ``oid`` needs: its trays, then the tray of each of its parts, each once
    (as the scene model resolves them; unknown ids left out)."""
    order = next((o for o in doc.get("orders") or [] if o["id"] == oid), None)
    if order is None:
        return []
    of_part = {p["id"]: t["id"] for t in doc["trays"] for p in t.get("parts", [])}
    known = {t["id"] for t in doc["trays"]}
    listed = [t for t in order.get("trays") or [] if t in known]
    listed += [of_part[p] for p in order.get("parts") or [] if p in of_part]
    return list(dict.fromkeys(listed))


def with_order(doc: dict[str, Any], oid: str) -> dict[str, Any]:
    """A copy of ``doc`` whose task is order ``oid``'s trays (:data:`TASK`, an unknown order or
    one whose trays are all gone: the document's own task)."""
    out = copy.deepcopy(doc)
    trays = [] if oid == TASK else order_trays(doc, oid)
    if trays:
        out["task"] = trays
    return out


def _fig(v: float | None, fmt: str, unit: str = "") -> str:
    return "—" if v is None else f"{format(v, fmt)}{unit}"


def mix_summary(mix: dict[str, Any]) -> str:
    """The mix's weighted means per order, then each order's stops and time."""
    t = mix["totals"]
    lines = [
        f"**Mix of {t['orders']} orders** (weighted per order, {t['planned']} planned)",
        f"- Stops: **{_fig(t.get('stops'), '.2f')}** · time **{_fig(t.get('time'), '.1f', ' s')}**"
        f" · success {_fig(t.get('success'), '.1%')}",
    ]
    for o in mix.get("orders", []):
        lines.append(f"- {o['id']} (×{o['weight']:g}): {_fig(o.get('stops'), 'd')} stops, "
                     f"{_fig(o.get('time'), '.1f', ' s')}")  # fmt: skip
    if t.get("failed"):
        lines.append(f"- ⚠ no plan: {', '.join(t['failed'])}")
    return "\n".join(lines)
