"""The HTML report: self-contained, a drawing, one table row per stop with the plan's numbers,
rejections with their trays, the ids, and names escaped."""

from __future__ import annotations

import copy
import re

from pickstop.report.html import ReportIds, report_html


def _cells(html: str) -> list[list[str]]:
    rows = re.findall(r"<tr class='stop'>(.*?)</tr>", html)
    return [re.findall(r"<td[^>]*>(.*?)</td>", r) for r in rows]


def test_the_report_holds_a_drawing_and_one_row_per_stop_with_the_plans_numbers(
    paper_plan, paper_scene
):
    ids = ReportIds("pln_1", "scn_1", 3, "2024-01-01T00:00:00Z")
    html = report_html(paper_plan, paper_scene, ids)
    assert html.startswith("<!doctype html>") and html.count("<svg") == 1
    assert "<script" not in html and " src=" not in html and "<link" not in html
    rows = _cells(html)
    assert len(rows) == len(paper_plan.stops)
    for k, (cells, s) in enumerate(zip(rows, paper_plan.stops, strict=True)):
        assert cells[0] == str(k + 1)
        assert (cells[1], cells[2]) == (f"{s.x:.3f}", f"{s.y:.3f}")
        assert cells[5] == f"{s.inscribed_radius:.3f}"
        assert cells[6].startswith(f"{100 * s.success.rate:.1f}%")
    t = paper_plan.totals
    assert f"<b>{t.stops}</b>" in html and f"{t.route_length:.2f} m" in html
    assert f"{t.time.total:.1f} s" in html and f"{100 * t.success:.1f}%" in html
    for text in ("pln_1", "scn_1", "revision 3", paper_plan.database, paper_plan.scene_hash):
        assert text in html


def test_rejections_are_listed_with_their_trays_and_names_are_escaped(paper_plan, paper_scene):
    scene = copy.deepcopy(paper_scene)
    scene["trays"][0]["name"] = "<script>alert(1)</script>"
    html = report_html(paper_plan, scene)
    assert "<script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    rejected = [c for c in paper_plan.candidates if c.status == "rejected"]
    if rejected:
        c = rejected[0]
        line = next(li for li in re.findall(r"<li>(.*?)</li>", html) if c.reason in li)
        assert all(t in line or t == "tray_1" for t in c.trays)
    assert "not stored" in html  # no ids given
