"""A plan as one self-contained HTML page to hand to a colleague: the top-view drawing, the
figures, the stops table, the rejected candidates with their reasons, the ids that identify
what was planned (scene, revision, robot, database, plan), and the plan's notes.

No scripts, no external files: the drawing is inline SVG and the style is in the page, so
the file opens anywhere and prints as it looks (the browser's *Print to PDF* gives a PDF).
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from html import escape
from typing import Any

from pickstop.report.drawing import top_view_svg, tray_names
from pickstop.report.stops_csv import stop_row
from pickstop.sequence.plan_model import Plan

STYLE = """
body { font: 14px/1.45 Helvetica, Arial, sans-serif; color: #222; margin: 24px auto;
       max-width: 960px; padding: 0 16px; }
h1 { font-size: 22px; margin: 0 0 4px; } h2 { font-size: 17px; margin: 24px 0 8px; }
.sub { color: #666; margin-bottom: 16px; }
table { border-collapse: collapse; width: 100%; font-size: 13px; }
th, td { border-bottom: 1px solid #ddd; padding: 4px 6px; text-align: left; }
th { background: #f3f3f3; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
.figs { display: grid; grid-template-columns: repeat(3, 1fr); gap: 8px; }
.fig { border: 1px solid #ddd; border-radius: 4px; padding: 6px 10px; }
.fig b { display: block; font-size: 18px; } .fig span { color: #666; font-size: 12px; }
svg { max-width: 100%; height: auto; border: 1px solid #ddd; }
@media print { body { margin: 0; } h2 { break-after: avoid; } table { break-inside: auto; } }
"""


@dataclass(frozen=True)
class ReportIds:
    """What identifies the plan outside of it (the store's ids; None where not stored)."""

    plan_id: str | None = None
    scene_id: str | None = None
    scene_revision: int | None = None
    created: str | None = None


def pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f}%"


def _figures(plan: Plan) -> str:
    t, n = plan.totals, plan.naive
    success = pct(t.success)
    if t.success_interval is not None:
        lo, hi = t.success_interval
        success += f" <span>(95%: {pct(lo)} to {pct(hi)})</span>"
    figs = [
        ("Stops", f"{t.stops}", f"one per tray: {len(n.stops)}"),
        ("Route", f"{t.route_length:.2f} m", f"one per tray: {n.route_length:.2f} m"),
        ("Predicted time", f"{t.time.total:.1f} s",
         f"travel {t.time.travel:.1f} s, stops {t.time.stops:.1f} s, picks {t.time.picks:.1f} s"),
        ("Saving", f"{100 * n.saving_fraction:.1f}%",
         f"{n.saving_time:.1f} s against one stop per tray ({n.time.total:.1f} s)"),
        ("Success", success, f"{plan.parameters.samples} Monte Carlo samples per stop"),
        ("Rule", f"σ = {plan.parameters.sigma:.3f} m",
         f"rule {plan.parameters.rule}, {plan.parameters.error_model} error, objective "
         f"{plan.parameters.objective}{', proven optimal' if plan.optimal else ''}"),
    ]  # fmt: skip
    cells = "".join(f"<div class='fig'><span>{a}</span><b>{b}</b><span>{c}</span></div>"
                    for a, b, c in figs)  # fmt: skip
    return f"<div class='figs'>{cells}</div>"


def _stops_table(plan: Plan, names: dict[str, str]) -> str:
    head = ("<tr><th>Stop</th><th>x [m]</th><th>y [m]</th><th>yaw [°]</th><th>Trays</th>"
            "<th>Inscribed r [m]</th><th>Success (95% interval)</th></tr>")  # fmt: skip
    rows = []
    for k, s in enumerate(plan.stops):
        r = stop_row(k, s, names)
        rate = "—" if s.success is None else (
            f"{pct(s.success.rate)} ({pct(s.success.interval[0])} to "
            f"{pct(s.success.interval[1])})")  # fmt: skip
        trays = ", ".join(escape(names.get(t, t)) for t in s.trays)
        rows.append(f"<tr class='stop'><td class='n'>{k + 1}</td><td class='n'>{s.x:.3f}</td>"
                    f"<td class='n'>{s.y:.3f}</td><td class='n'>{r['yaw_deg']}</td>"
                    f"<td>{trays}</td><td class='n'>{s.inscribed_radius:.3f}</td>"
                    f"<td class='n'>{rate}</td></tr>")  # fmt: skip
    return f"<table id='stops'>{head}{''.join(rows)}</table>"


def _rejections(plan: Plan, names: dict[str, str]) -> str:
    """Each reason once, with the candidates (their trays) it rejected."""
    by_reason: dict[str, list[str]] = defaultdict(list)
    for c in plan.candidates:
        if c.status == "rejected":
            by_reason[c.reason or "rejected"].append(
                f"{', '.join(names.get(t, t) for t in c.trays)} (r = {c.inscribed_radius:.3f} m)"
            )
    if not by_reason:
        return "<p>No candidate stop was rejected.</p>"
    items = "".join(f"<li>{escape(why)}: {escape('; '.join(whom))}</li>"
                    for why, whom in sorted(by_reason.items()))  # fmt: skip
    return f"<ul>{items}</ul>"


def _ids(plan: Plan, ids: ReportIds) -> str:
    rows = [
        ("Plan", ids.plan_id or "not stored"),
        ("Created", ids.created or "—"),
        ("Scene", f"{plan.scene} (id {ids.scene_id or 'inline'}, revision "
                  f"{ids.scene_revision if ids.scene_revision is not None else '—'})"),
        ("Scene hash", plan.scene_hash),
        ("Robot", f"{plan.robot} (hash {plan.robot_hash[:16]})"),
        ("Database", plan.database),
        ("Trays of the task", ", ".join(plan.trays)),
        ("Base yaws", ", ".join(f"{math.degrees(y):.0f}°" for y in plan.parameters.base_yaws)),
    ]  # fmt: skip
    return "<table>" + "".join(f"<tr><th>{a}</th><td>{escape(str(b))}</td></tr>"
                               for a, b in rows) + "</table>"  # fmt: skip


def report_html(plan: Plan, scene: dict[str, Any], ids: ReportIds | None = None) -> str:
    """The report of ``plan``, planned from the scene document ``scene``."""
    ids = ids or ReportIds()
    names = tray_names(scene)
    notes = "".join(f"<li>{escape(n)}</li>" for n in plan.notes) or "<li>None.</li>"
    title = f"Stops plan: {escape(plan.scene or ids.scene_id or 'scene')}"
    verified = "" if plan.verified else "<p><b>Preview: not verified.</b></p>"
    return "\n".join([
        "<!doctype html>",
        "<html lang='en'><head><meta charset='utf-8'>",
        f"<title>{title}</title><style>{STYLE}</style></head><body>",
        f"<h1>{title}</h1>",
        f"<div class='sub'>{len(plan.stops)} stops for {len(plan.trays)} trays · plan "
        f"{escape(ids.plan_id or 'not stored')} · {escape(ids.created or '')}</div>",
        verified,
        _figures(plan),
        "<h2>Top view</h2>",
        top_view_svg(plan, scene),
        "<h2>Stops</h2>",
        _stops_table(plan, names),
        "<h2>Rejected candidate stops</h2>",
        _rejections(plan, names),
        "<h2>What was planned</h2>",
        _ids(plan, ids),
        "<h2>Notes</h2>",
        f"<ul>{notes}</ul>",
        "</body></html>",
    ])  # fmt: skip
