"""Reports in the browser, one click each: the HTML report of the paper-like scene holds a
drawing and one row per stop with the plan's numbers; the stops CSV one row per stop; the PNG
a title and a legend around a render without the gizmo. Prints the time from the click on
*Download report* to the file, and the factory cell's report size."""

from __future__ import annotations

import csv
import io
import re
import time

import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium


def _download(pg, button: str) -> tuple[bytes, str, float]:
    t0 = time.perf_counter()
    with pg.expect_download(timeout=120_000) as dl:
        pg.get_by_role("button", name=button, exact=True).click()
    path = dl.value.path()
    return path.read_bytes(), dl.value.suggested_filename, time.perf_counter() - t0


def _stored_plan(app):
    from pickstop.sequence.plan_model import Plan

    body = app.api.http.get(f"/api/v1/plans/{app.state.plan_id}").json()
    return Plan.model_validate(body["plan"])


def test_the_report_holds_a_drawing_and_one_row_per_stop_equal_to_the_plan(pg, app):
    b.settled(app)
    html, name, seconds = _download(pg, "Download report")
    print(f"\nclick on Download report -> file: {seconds * 1e3:.0f} ms, {len(html)} bytes")
    text = html.decode()
    assert name == f"pickstop-report-{app.state.plan_id}.html"
    assert text.count("<svg") == 1 and "<script" not in text
    plan = _stored_plan(app)
    assert b.stops(plan) == b.stops(app.state.plan)  # the plan on screen, stored
    rows = re.findall(r"<tr class='stop'>(.*?)</tr>", text)
    assert len(rows) == len(plan.stops)
    for row, s in zip(rows, plan.stops, strict=True):
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
        assert (cells[1], cells[2]) == (f"{s.x:.3f}", f"{s.y:.3f}")
        assert cells[6].startswith(f"{100 * s.success.rate:.1f}%")
    assert f"{plan.totals.time.total:.1f} s" in text and app.state.plan_id in text


def test_the_stops_csv_has_one_row_per_stop(pg, app):
    body, name, _ = _download(pg, "Download stops CSV")
    rows = list(csv.DictReader(io.StringIO(body.decode())))
    plan = app.state.plan
    assert name.endswith(".csv") and len(rows) == len(plan.stops)
    for row, s in zip(rows, plan.stops, strict=True):
        assert float(row["x_m"]) == pytest.approx(s.x, abs=1e-4)
        assert row["trays"].split(";") == s.trays


def test_the_png_has_a_title_and_legend_around_a_render_without_the_gizmo(pg, app):
    import imageio.v3 as iio

    from pickstop_ui.app import RENDER
    from pickstop_ui.exports import LEGEND_W, TITLE_H

    b.click_item(pg, app, "trays", "tray_1")
    body, name, _ = _download(pg, "Download PNG snapshot")
    img = iio.imread(body)
    assert name == "pickstop.png" and img.shape[:2] == (RENDER[1] + TITLE_H, RENDER[0] + LEGEND_W)
    margin = img[TITLE_H + 40 :, RENDER[0] + 10 :, :3]
    assert (margin < 100).all(axis=-1).sum() > 500  # dark text: figures and legend
    title = img[10 : TITLE_H - 10, :600, :3]
    assert (title < 100).all(axis=-1).sum() > 100
    assert app.selection.gizmo.visible  # back after the render


def test_the_factory_cells_report_size(live_api, pg):
    # A second page in the same browser (one Playwright per process at a time).
    with b.planner(live_api, b.SCENES / "factory_cell.json") as f:
        fp = pg.context.browser.new_page(viewport={"width": b.SIZE[0], "height": b.SIZE[1]},
                                         accept_downloads=True)  # fmt: skip
        fp.goto(f"http://127.0.0.1:{f.port}/")
        b.ready(fp, 180_000)
        b.settled(f, 180)
        html, _, seconds = _download(fp, "Download report")
        print(f"\nfactory cell: click on Download report -> file {seconds * 1e3:.0f} ms, "
              f"report {len(html) / 1e3:.0f} kB")  # fmt: skip
        assert html.count(b"<tr class='stop'>") == len(f.state.plan.stops)
        assert len(html) < 2_000_000
        fp.close()
