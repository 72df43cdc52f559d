"""The 3D planner in real headless Chromium (Debian's), driven by Playwright with the mouse.

The API runs under uvicorn on 127.0.0.1; the planner runs in this process so the test can
read the camera it set and project world points to the pixels to drag. Screenshots are kept
in tests/artifacts/ui/. Times from mouse release to the redrawn panel are measured in the
page (pointerup and a MutationObserver, both on performance.now()) and printed.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pickstop_ui.app import SIGMA_MAX
from tests.conftest import LIVE_KEY, free_port
from tests.ui import browser

playwright = pytest.importorskip("playwright.sync_api")

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]  # fmt: skip
ARTIFACTS = Path(__file__).parents[1] / "artifacts" / "ui"
SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"
ROUTE = np.array([231, 205, 71])  # (255, 200, 0) as lit and shaded in the view
REJECTED = np.array([222, 38, 40])
KEPT = np.array([40, 200, 90])
STALE = np.array([140, 140, 175])
TRAY4_PATCH = np.array([251, 227, 197])  # tray_4 orange, translucent over the floor (flat light)

pytestmark = pytest.mark.skipif(
    shutil.which("chromium") is None, reason="Debian's chromium is not installed"
)


@pytest.fixture(scope="module")
def planner_app(live_api):
    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient

    client = PickStopClient(live_api, LIVE_KEY)
    doc = json.loads(SCENE.read_text())
    stored = client.create_scene(doc)
    app = PlannerApp(client, stored.id, port=free_port())
    yield app
    app.close()


@pytest.fixture(scope="module")
def ui_page(planner_app):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with playwright.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        pg = browser.new_page(viewport={"width": 1280, "height": 800})
        pg.goto(f"http://127.0.0.1:{planner_app.port}/")
        pg.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=120_000)
        _close_notifications(pg)
        time.sleep(3)  # let the software renderer finish the first frames
        yield pg
        browser.close()


def _close_notifications(pg) -> None:
    for button in pg.locator(".mantine-Notification-closeButton").all():
        button.click()


def _shot(pg, name: str) -> np.ndarray:
    import imageio.v3 as iio

    path = ARTIFACTS / f"{name}.png"
    pg.screenshot(path=str(path))
    return iio.imread(path)[..., :3].astype(int)


def _read(name: str) -> np.ndarray:
    import imageio.v3 as iio

    return iio.imread(ARTIFACTS / f"{name}.png")[..., :3].astype(int)


def _pixels(img: np.ndarray, rgb: np.ndarray, tol: int = 40) -> np.ndarray:
    """(N, 2) pixel coordinates (x, y) of the 3D view (left of the panel) close to ``rgb``."""
    view = img[:, :860]
    hit = np.all(np.abs(view - rgb) <= tol, axis=-1)
    ys, xs = np.nonzero(hit)
    return np.column_stack([xs, ys])


def _arm_timer(pg) -> None:
    """In the page: note the next pointerup and every text change after it, with times."""
    pg.evaluate(
        """() => {
            window.__t = {up: null, move: null, changes: []};
            addEventListener('pointerup', () => { window.__t.up = performance.now(); },
                             {capture: true, once: true});
            addEventListener('pointermove', () => {
                if (window.__t.up === null) { window.__t.move = performance.now(); }
            }, {capture: true});
            const obs = new MutationObserver(() => {
                window.__t.changes.push([performance.now(), document.body.innerText]);
            });
            obs.observe(document.body, {subtree: true, childList: true, characterData: true});
        }"""
    )


def _elapsed_ms(pg, marker: str) -> float:
    """Milliseconds from the end of the gesture (the last pointer move before the release)
    to the first page text that shows ``marker`` after it."""
    pg.wait_for_function(
        "m => window.__t.up !== null && window.__t.changes.some(c => c[1].includes(m))",
        arg=marker,
        timeout=60_000,
    )
    t = pg.evaluate("window.__t")
    start = t["move"] if t["move"] is not None else t["up"]
    done = next(c[0] for c in t["changes"] if marker in c[1] and c[0] >= start)
    return float(done - start)


def _settled_sigma(app) -> float:
    """The slider's value once the drag's last update has reached the planner."""
    time.sleep(0.5)
    return round(float(app.sigma.value), 3)


def _robots_checkbox(pg):
    return pg.get_by_label("ghost robots at stops")


def _wait_for(cond, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)


def _project(cam, p, size=(1280, 800)) -> tuple[float, float]:
    """World point -> page pixel (CSS), from the camera the browser reported (OpenCV frame,
    vertical fov), the canvas filling the page of ``size``: the camera's own image size is in
    drawing-buffer pixels, which the draft resolution makes smaller."""
    from viser import transforms as tf

    R = tf.SO3(np.asarray(cam.wxyz)).as_matrix()
    pc = R.T @ (np.asarray(p, float) - np.asarray(cam.position))
    w, h = size
    f = (h / 2) / math.tan(cam.fov / 2)
    return w / 2 + f * pc[0] / pc[2], h / 2 + f * pc[1] / pc[2]


def _drag(pg, a, b, steps: int = 12) -> None:
    pg.mouse.move(*a)
    pg.mouse.down()
    for k in range(1, steps + 1):
        pg.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        time.sleep(0.03)
    pg.mouse.up()


def _set_slider(pg, index: int, value: float, lo: float, hi: float) -> None:
    """Drag slider ``index`` of the panel from its thumb to ``value``."""
    root = pg.locator(".mantine-Slider-root").nth(index)
    root.scroll_into_view_if_needed()
    box = root.bounding_box()
    thumb = root.locator("[role=slider]").bounding_box()
    start = (thumb["x"] + thumb["width"] / 2, thumb["y"] + thumb["height"] / 2)
    end = (box["x"] + (value - lo) / (hi - lo) * box["width"], start[1])
    _drag(pg, start, end)


def test_page_connects_and_draws_the_scene_and_plan(ui_page, planner_app):
    text = ui_page.inner_text("body")
    assert f"Stops: {len(planner_app.state.plan.stops)} (naive 3)" in text
    assert "σ = 0.100 m" in text
    img = _shot(ui_page, "01-initial")
    route = _pixels(img, ROUTE)
    assert len(route) > 300, "the route is drawn in its colour"
    # Route pixels lie between the start and the goal on screen.
    cam = next(iter(planner_app.server.get_clients().values())).camera
    sx, _ = _project(cam, (0.0, 0.0, 0.0))
    assert route[:, 0].min() < sx + 80
    # tray_4's region patch shows in its colour (orange, translucent).
    assert len(_pixels(img, TRAY4_PATCH, tol=8)) > 200


def _sigma_splitting_a_stop(plan) -> float:
    """A sigma just above a shared stop's radius, below every tray's widest candidate:
    that stop is rejected, the plan stays feasible with one stop more."""
    shared = min(s.inscribed_radius for s in plan.stops if len(s.trays) >= 2)
    widest = min(
        max(c.inscribed_radius for c in plan.candidates if c.trays == [t]) for t in plan.trays
    )
    target = math.ceil((shared + 1e-3) / 0.005) * 0.005  # the slider's step is 5 mm
    assert shared < target < widest, "the example must have a stop serving two trays"
    return target


@pytest.fixture
def close_oblique_view(planner_app):
    """A camera nearer the floor than the presets, looking a little right of its centre: the
    circles fill more of the view, so a vanished one shows in the pixel counts. The first
    view again afterwards."""
    doc = planner_app.state.doc
    (x0, y0), (x1, y1) = doc["floor"]["min"], doc["floor"]["max"]
    cx, cy, span = 0.5 * (x0 + x1), 0.5 * (y0 + y1), max(x1 - x0, y1 - y0)
    client = next(iter(planner_app.server.get_clients().values()))
    x = cx + 0.12 * span
    pose = SimpleNamespace(position=(x, cy - 0.45 * span, 0.6 * span),
                           look_at=(x, cy + 0.1 * span, 0.0))  # fmt: skip

    def aim() -> SimpleNamespace:
        with client.atomic():
            client.camera.fov = math.radians(75.0)
            client.camera.position = pose.position
            client.camera.look_at = pose.look_at
        return pose

    browser.hold_camera(client, aim)
    yield
    browser.reset_camera(planner_app)


def test_sigma_slider_changes_circles_and_numbers(ui_page, planner_app, close_oblique_view):
    plan = planner_app.state.plan
    n_stops = len(plan.stops)
    target = _sigma_splitting_a_stop(plan)
    # The ghost robots would stand on their circles: they are off until asked for.
    assert not planner_app.show_robots.value
    _wait_for(lambda: not any(frame.visible for frame, _ in planner_app.layer.ghosts))
    time.sleep(1.5)
    before = _shot(ui_page, "02-sigma-before")
    green_before = len(_pixels(before, KEPT, tol=35))
    red_before = len(_pixels(before, REJECTED))
    _arm_timer(ui_page)
    _set_slider(ui_page, 0, target, 0.0, SIGMA_MAX)
    sigma = _settled_sigma(planner_app)
    assert sigma == pytest.approx(target, abs=1e-6)
    ms = _elapsed_ms(ui_page, f"σ = {sigma:.3f} m")
    print(f"\nslider gesture end -> redrawn plan (sigma {sigma:.3f}): {ms:.0f} ms")
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    text = ui_page.inner_text("body")
    assert f"Stops: {n_stops + 1} (naive" in text  # the shared stop's circle is now too small
    assert f"below sigma {sigma:.3f} m" in text
    time.sleep(1.5)
    after = _shot(ui_page, "03-sigma-raised")
    # The shared stop's solid green centre and circle are gone (now red, the circle dashed):
    # at least a marker's worth of green less (how much of the markers the route and the
    # labels cover depends on the pixel ratio and where the labels settle).
    assert green_before > 40 and len(_pixels(after, KEPT, tol=35)) < green_before - 40
    assert len(_pixels(after, REJECTED)) > red_before + 25
    _robots_checkbox(ui_page).click()
    _wait_for(lambda: planner_app.show_robots.value)
    _arm_timer(ui_page)
    _set_slider(ui_page, 0, 0.10, 0.0, SIGMA_MAX)
    sigma = _settled_sigma(planner_app)
    ms = _elapsed_ms(ui_page, f"σ = {sigma:.3f} m")
    print(f"slider gesture end -> redrawn plan (sigma {sigma:.3f}): {ms:.0f} ms")
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    assert f"Stops: {n_stops} (naive" in ui_page.inner_text("body")


def test_dragging_a_tray_replans_and_moves_its_region(ui_page, planner_app):
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    tray = next(t for t in planner_app.state.doc["trays"] if t["id"] == "tray_4")
    x0 = tray["pose"]["x"]
    stop = next(s for s in planner_app.state.plan.stops if "tray_4" in s.trays)
    before = _shot(ui_page, "04-drag-before")
    base = np.array([tray["pose"]["x"], tray["pose"]["y"], tray["pose"]["z"]])
    # Select the tray, grab its gizmo's x arrow and pull it 0.2 m along +x (to near the
    # table's end: further, the tray would overhang it).
    a, b = browser.grab_x_arrow(ui_page, planner_app, "tray_4", base, 0.2)
    _arm_timer(ui_page)
    _drag(ui_page, a, b)
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    seq = planner_app.state.seq  # previews while dragging, then the exact plan on release
    assert planner_app.state.plan.verified and planner_app.state.drawn_seq == seq
    ms = _elapsed_ms(ui_page, f"plan #{seq} in")
    print(f"\ndrag release -> redrawn plan: {ms:.0f} ms")
    moved = next(t for t in planner_app.state.doc["trays"] if t["id"] == "tray_4")
    assert moved["pose"]["x"] == pytest.approx(x0 + 0.2, abs=0.05)
    assert moved["pose"]["z"] == tray["pose"]["z"] and abs(moved["pose"]["yaw"]) < 1e-6
    # tray_4's stop follows it: a new stop, within the arm's reach of the tray's new place.
    new = next(s for s in planner_app.state.plan.stops if "tray_4" in s.trays)
    assert math.hypot(new.x - stop.x, new.y - stop.y) > 0.1
    assert math.hypot(new.x - moved["pose"]["x"], new.y - moved["pose"]["y"]) < 1.2
    time.sleep(1.5)
    after = _shot(ui_page, "05-drag-after")
    px0, px1 = _pixels(before, TRAY4_PATCH, 8), _pixels(after, TRAY4_PATCH, 8)
    assert px1[:, 0].mean() > px0[:, 0].mean() + 10, "tray_4's region moved right on screen"


def test_infeasible_layout_shows_the_explanation(ui_page, planner_app):
    planner_app.deselect()  # the dragged tray's guidance zones would colour the floor
    _wait_for(lambda: planner_app.selection.key is None)
    time.sleep(1.0)
    _set_slider(ui_page, 0, SIGMA_MAX, 0.0, SIGMA_MAX)
    sigma = _settled_sigma(planner_app)
    assert sigma == pytest.approx(SIGMA_MAX)
    marker = f"no plan with sigma = {sigma:.3f} m"
    ui_page.wait_for_function("m => document.body.innerText.includes(m)", arg=marker,
                              timeout=60_000)  # fmt: skip
    text = ui_page.inner_text("body")
    assert (
        "Status: no plan — ⚠ Infeasible plan" in text and "last valid plan is shown greyed" in text
    )
    assert "tray tray_1:" in text  # the explanation names the trays and their numbers
    time.sleep(1.5)
    img = _shot(ui_page, "06-infeasible")
    initial = _pixels(_read("01-initial"), ROUTE)
    assert len(_pixels(img, ROUTE)) < len(initial) / 2, "the route is no longer yellow"
    assert len(_pixels(img, STALE, tol=25)) > 200, "the last plan is drawn greyed out"
    _set_slider(ui_page, 0, 0.10, 0.0, SIGMA_MAX)
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)


def test_save_conflict_is_reported(ui_page, planner_app, live_api):
    from pickstop_ui.client import PickStopClient

    other = PickStopClient(live_api, LIVE_KEY)
    sid = planner_app.state.stored.id
    theirs = other.scene(sid)
    doc = dict(theirs.doc, description="changed by someone else")
    other.save_scene(sid, doc, theirs.etag)
    ui_page.get_by_role("button", name="Save scene").click()
    ui_page.wait_for_function("document.body.innerText.includes('Save conflict')", timeout=30_000)
    assert other.scene(sid).doc["description"] == "changed by someone else"  # not overwritten
    _shot(ui_page, "07-save-conflict")


PREVIEW_ROUTE = np.array([150, 60, 255])  # the preview's dashed violet route
# The 3D view's drawing-buffer width and its width on the page [px].
CANVAS = "() => [window.__viserMutable.canvas.width, window.__viserMutable.canvas.clientWidth]"


def _count_meshes(app):
    """Count the mesh messages the planner sends from now on (robot and ghost meshes)."""
    iface = app.server.scene._websock_interface
    sent = {"meshes": 0}
    original = iface.queue_message

    def counting(message):
        if type(message).__name__ in {"GlbMessage", "MeshMessage", "BatchedMeshesMessage"}:
            sent["meshes"] += 1
        return original(message)

    iface.queue_message = counting
    return sent, lambda: setattr(iface, "queue_message", original)


def test_dragging_slowly_previews_the_plan_then_draws_the_exact_one(
    ui_page, planner_app, close_oblique_view
):
    """Region and stop follow the tray during the drag, drawn as a preview and said so; on
    release the verified plan replaces it and the preview style is gone."""
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    tray = next(t for t in planner_app.state.doc["trays"] if t["id"] == "tray_4")
    cam = next(iter(planner_app.server.get_clients().values())).camera
    base = np.array([tray["pose"]["x"], tray["pose"]["y"], tray["pose"]["z"]])
    a, b = browser.grab_x_arrow(ui_page, planner_app, "tray_4", base, -0.2)  # back along -x
    ui_page.evaluate(
        """() => {
            window.__f = [];
            new MutationObserver(() => {
                const m = document.body.innerText
                    .match(/preview \\(not verified\\) · plan #(\\d+)/);
                if (m) { window.__f.push([performance.now(), +m[1]]); }
            }).observe(document.body, {subtree: true, childList: true, characterData: true});
        }"""
    )
    _arm_timer(ui_page)
    steps, shots, stops = 40, {}, {}
    ui_page.mouse.move(*a)
    ui_page.mouse.down()
    for k in range(1, steps + 1):
        ui_page.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        time.sleep(0.08)
        if k in (15, 35):
            # let a preview of the tray where it is now be drawn (a loaded machine may
            # still be drawing the last exact plan), then look
            _wait_for(lambda: not planner_app.state.plan.verified)
            time.sleep(0.6)
            shots[k] = _shot(ui_page, f"08-drag-preview-{k}")
            plan = planner_app.state.plan
            assert not plan.verified
            stops[k] = next((s.x, s.y) for s in plan.stops if "tray_4" in s.trays)
            text = ui_page.inner_text("body")
            assert "PREVIEW — not verified" in text and "preview (not verified)" in text
            # Software WebGL: drawn at draft resolution (half the pixel ratio) while editing.
            width, css = ui_page.evaluate(CANVAS)
            assert width <= 0.5 * css + 1, "previews are drawn at draft resolution"
    ui_page.mouse.up()
    frames = ui_page.evaluate("window.__f")
    ui_page.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=60_000)
    seq = planner_app.state.seq
    ms = _elapsed_ms(ui_page, f"plan #{seq} in")
    plans = sorted({n for _, n in frames})
    span = (frames[-1][0] - frames[0][0]) / 1e3 if len(frames) > 1 else float("nan")
    print(f"\npreview during a slow drag: {len(plans)} previews drawn in {span:.1f} s "
          f"({(len(plans) - 1) / span:.1f} per second, with two 0.6 s pauses)")  # fmt: skip
    print(f"drag release -> exact plan drawn: {ms:.0f} ms")
    # The stop marker moved with the tray between the two moments, and the picture changed
    # around it (the region patch and the marker).
    (x1, y1), (x2, y2) = stops[15], stops[35]
    assert math.hypot(x2 - x1, y2 - y1) > 0.05
    diff = np.abs(shots[15] - shots[35]).sum(axis=-1)[:, :860] > 30
    for x, y in (stops[15], stops[35]):
        u, v = _project(cam, (x, y, 0.0))
        win = diff[max(int(v) - 60, 0) : int(v) + 60, max(int(u) - 60, 0) : int(u) + 60]
        assert win.sum() > 200, "the drawing changed where the region and its stop are"
    assert len(_pixels(shots[35], PREVIEW_ROUTE, tol=45)) > 40, "the dashed preview route"
    # Released: the verified plan, the preview's style and words gone.
    assert planner_app.state.plan.verified and planner_app.state.drawn_seq == seq
    text = ui_page.inner_text("body")
    assert "PREVIEW" not in text and "preview (not verified)" not in text
    # Full resolution again (viser's own adaptive ratio may take it down to 0.75).
    ui_page.wait_for_function(f"() => {{ const [w, css] = ({CANVAS})(); return w >= 0.75 * css; }}",
                              timeout=10_000)  # fmt: skip
    time.sleep(1.5)
    after = _shot(ui_page, "09-drag-released")
    assert len(_pixels(after, PREVIEW_ROUTE, tol=45)) < 10
    assert len(_pixels(after, ROUTE)) > 300


def test_a_sigma_change_updates_nodes_and_sends_no_robot_meshes(ui_page, planner_app):
    plan = planner_app.state.plan
    target = _sigma_splitting_a_stop(plan)
    # Once there and back, so that a ghost exists for each stop count.
    for value in (target, 0.10):
        _set_slider(ui_page, 0, value, 0.0, SIGMA_MAX)
        _settled_sigma(planner_app)
        ui_page.wait_for_function("document.body.innerText.includes('Status: ready')",
                                  timeout=60_000)  # fmt: skip
    sent, restore = _count_meshes(planner_app)
    try:
        times = []
        for value in (target, 0.10):
            _arm_timer(ui_page)
            _set_slider(ui_page, 0, value, 0.0, SIGMA_MAX)
            sigma = _settled_sigma(planner_app)
            times.append(_elapsed_ms(ui_page, f"σ = {sigma:.3f} m"))
            ui_page.wait_for_function("document.body.innerText.includes('Status: ready')",
                                      timeout=60_000)  # fmt: skip
    finally:
        restore()
    print(f"\nslider gesture end -> redrawn: {', '.join(f'{t:.0f}' for t in times)} ms")
    assert sent["meshes"] == 0, "a re-plan sent robot meshes again"
