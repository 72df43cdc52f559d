"""Shared helpers of the planner's browser tests: Debian's headless Chromium under Playwright,
a planner started in the test's process over the live API on 127.0.0.1, mouse gestures at
projected world points, waits on the page and on the planner."""

from __future__ import annotations

import contextlib
import json
import math
import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import LIVE_KEY, free_port

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]  # fmt: skip
ARTIFACTS = Path(__file__).parents[1] / "artifacts" / "ui"
SCENES = Path(__file__).parents[2] / "examples" / "scenes"
PAPER = SCENES / "paper_experiment.json"
SIZE = (1280, 800)  # the page's viewport [CSS px]

needs_chromium = pytest.mark.skipif(
    shutil.which("chromium") is None, reason="Debian's chromium is not installed"
)


@contextlib.contextmanager
def planner(live_api: str, scene: Path = PAPER, **kwargs: Any) -> Iterator[Any]:
    """A planner window of ``scene`` (stored anew in the API) on a free port."""
    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient

    client = PickStopClient(live_api, LIVE_KEY)
    stored = client.create_scene(json.loads(scene.read_text()))
    app = PlannerApp(client, stored.id, port=free_port(), **kwargs)
    try:
        yield app
    finally:
        app.close()


@contextlib.contextmanager
def page(app: Any) -> Iterator[Any]:
    """A headless Chromium page on ``app``, its first plan ready and drawn."""
    playwright = pytest.importorskip("playwright.sync_api")
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with playwright.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            pg = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]},
                                  accept_downloads=True)  # fmt: skip
            pg.goto(f"http://127.0.0.1:{app.port}/")
            ready(pg, 180_000)
            for button in pg.locator(".mantine-Notification-closeButton").all():
                button.click()
            time.sleep(2)  # let the software renderer finish the first frames
            yield pg
        finally:
            browser.close()


def ready(pg: Any, timeout: float = 60_000) -> None:
    """Wait until the panel says the plan is ready (success rates in)."""
    pg.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=timeout)


def camera(app: Any) -> Any:
    return next(iter(app.server.get_clients().values())).camera


def project(cam: Any, p: Any, size: tuple[int, int] = SIZE) -> tuple[float, float]:
    """World point -> page pixel (CSS), from the camera the browser reported (OpenCV frame,
    vertical fov), the canvas filling the page of ``size``."""
    from viser import transforms as tf

    R = tf.SO3(np.asarray(cam.wxyz)).as_matrix()
    pc = R.T @ (np.asarray(p, float) - np.asarray(cam.position))
    w, h = size
    f = (h / 2) / math.tan(cam.fov / 2)
    return w / 2 + f * pc[0] / pc[2], h / 2 + f * pc[1] / pc[2]


def drag(pg: Any, a: Any, b: Any, steps: int = 12, button: str = "left") -> None:
    """Press ``button`` at ``a``, move to ``b`` in ``steps`` moves, release."""
    pg.mouse.move(*a)
    pg.mouse.down(button=button)
    for k in range(1, steps + 1):
        pg.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        time.sleep(0.03)
    pg.mouse.up(button=button)


def wait_for(cond: Callable[[], bool], timeout: float = 30.0, what: str = "condition") -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        time.sleep(0.05)


def settled(app: Any, timeout: float = 60.0, since: int | None = None) -> None:
    """Wait until the newest request's plan, with its success rates, is drawn (``since``: and
    a request newer than plan number ``since`` was made)."""
    if since is not None:
        wait_for(lambda: app.state.seq > since, timeout, "a new request")
    wait_for(lambda: not app.state.busy and app.state.drawn_seq == app.state.seq
             and app.replanner.drawn_seq == app.state.seq, timeout, "the plan")  # fmt: skip


def node_position(pg: Any, name: str) -> list[float] | None:
    """The position of scene node ``name`` as the browser holds it (None: not there)."""
    return pg.evaluate(
        """n => { const m = window.__viserMutable, o = m.nodeRefFromName[n];
                  if (!o) return null;
                  const p = m.nodePoseData[n];
                  return p && p.position ? [...p.position]
                                         : [o.position.x, o.position.y, o.position.z]; }""",
        name,
    )


def shot(pg: Any, name: str) -> np.ndarray:
    import imageio.v3 as iio

    path = ARTIFACTS / f"{name}.png"
    pg.screenshot(path=str(path))
    return iio.imread(path)[..., :3].astype(int)


def tray(app: Any, tid: str) -> dict[str, Any]:
    return next(t for t in app.state.doc["trays"] if t["id"] == tid)


def stops(plan: Any) -> list[tuple[float, float, float, tuple[str, ...]]]:
    return [(s.x, s.y, s.yaw, tuple(s.trays)) for s in plan.stops]


def hold_camera(client: Any, aim: Callable[[], Any], tries: int = 4) -> None:
    """Point ``client``'s camera with ``aim`` (which sets it and returns the pose it set:
    ``position``, ``look_at``) and wait until the camera the browser reports has stayed
    there for 0.5 s. A report the browser sent before it received the new pose can land
    after it and put the old camera back into the server's state (then the tests would
    project with a camera the page no longer shows): the pose is set again."""

    def there(pose: Any) -> bool:
        cam = client.camera
        return bool(np.allclose(cam.position, pose.position, atol=1e-3)
                    and np.allclose(cam.look_at, pose.look_at, atol=1e-3))  # fmt: skip

    for _ in range(tries):
        pose = aim()
        end, since = time.monotonic() + 3.0, None
        while time.monotonic() < end:
            if not there(pose):
                since = None
            elif since is None:
                since = time.monotonic()
            elif time.monotonic() - since >= 0.5:
                return
            time.sleep(0.05)
    raise AssertionError("the browser's camera did not stay where it was pointed")


def reset_camera(app: Any) -> None:
    """Back to the planner's first view of the scene (a test that moved the camera)."""
    client = next(iter(app.server.get_clients().values()))
    hold_camera(client, lambda: app.show_view(client, "iso"))


def ray_at(cam: Any, px: Any, size: tuple[int, int] = SIZE) -> tuple[np.ndarray, np.ndarray]:
    """The world ray (origin, unit direction) through page pixel ``px`` [CSS px]."""
    from viser import transforms as tf

    w, h = size
    f = (h / 2) / math.tan(cam.fov / 2)
    d = tf.SO3(np.asarray(cam.wxyz)).as_matrix() @ np.array([(px[0] - w / 2) / f,
                                                             (px[1] - h / 2) / f, 1.0])  # fmt: skip
    return np.asarray(cam.position, float), d / np.linalg.norm(d)


def item_point(app: Any, kind: str, oid: str, timeout: float = 3.0) -> tuple[float, float]:
    """A pixel on the top of tray or obstacle ``oid`` where a click picks it: the top face's
    points tried from its centre outwards, each kept only if the rays through it and through
    the pixels 8 px around it meet this item first, and it lies clear of the gizmo's centre
    and of the panel. Looked for again until ``timeout`` [s] while the camera, the scene or
    the gizmo may still be settling."""
    end = time.monotonic() + timeout
    while (px := _item_point(app, kind, oid)) is None:
        assert time.monotonic() < end, f"no clear point to click on {oid}"
        time.sleep(0.2)
    return px


def _item_point(app: Any, kind: str, oid: str) -> tuple[float, float] | None:
    from pickstop_ui.picking import item_box, pick

    boxes = [x for x in map(item_box, app.scene.drawn_items()) if x is not None]
    box = next(x for x in boxes if (x.kind, x.id) == (kind, oid))
    cam = camera(app)
    gizmo = project(cam, app.selection.gizmo.position) if app.selection.gizmo.visible else None
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    grid = [(u, v) for u in np.linspace(-0.8, 0.8, 9) for v in np.linspace(-0.8, 0.8, 9)]
    for u, v in sorted(grid, key=lambda uv: abs(uv[0]) + abs(uv[1])):
        lx, ly = u * box.half[0], v * box.half[1]
        p = np.array([box.centre[0] + c * lx - s * ly, box.centre[1] + s * lx + c * ly,
                      box.centre[2] + box.half[2]])  # fmt: skip
        px = project(cam, p)
        around = [(px[0] + a, px[1] + b) for a, b in ((0, 0), (8, 0), (-8, 0), (0, 8), (0, -8))]
        hits = all(pick(boxes, *ray_at(cam, q)) is box for q in around)
        clear = gizmo is None or math.dist(px, gizmo) > 60
        if hits and clear and 0 < px[0] < 820 and 0 < px[1] < SIZE[1]:
            return px
    return None


def click_item(pg: Any, app: Any, kind: str, oid: str) -> None:
    """Click the top of tray or obstacle ``oid`` and wait until it is selected (a click in
    the moment the gizmo leaves the page can be lost: clicked again, up to three times)."""
    for attempt in range(3):
        pg.mouse.click(*item_point(app, kind, oid))
        try:
            wait_for(lambda: app.selection.key == (kind, oid), 4, f"{oid} to be selected")
            break
        except AssertionError:
            if attempt == 2:
                raise
    time.sleep(0.3)  # the gizmo reaches the page


def gizmo_length(app: Any, at: Any) -> float:
    """The world length [m] of the gizmo's arrows at point ``at``: they are drawn a fixed
    number of pixels long."""
    from pickstop_ui.selection import GIZMO_PX

    cam = camera(app)
    dist = float(np.linalg.norm(np.asarray(at, float) - np.asarray(cam.position)))
    return GIZMO_PX * dist * 2 * math.tan(cam.fov / 2) / SIZE[1]


def grab_x_arrow(pg: Any, app: Any, tid: str, base: Any, dx: float) -> tuple[Any, Any]:
    """Select tray ``tid`` (a click), then where to press on its gizmo's x arrow and where to
    release to pull it ``dx`` [m] along x (the arrow grabbed at 55% of its length, or nearer
    its root where that lies under the panel)."""
    if app.selection.key != ("trays", tid):
        click_item(pg, app, "trays", tid)
    cam = camera(app)
    for frac in (0.55, 0.45, 0.35, 0.28):  # the arrow's end may lie under the panel
        grab = frac * gizmo_length(app, base)
        a = project(cam, np.asarray(base) + np.array([grab, 0.0, 0.0]))
        if a[0] < 820:
            break
    return a, project(cam, np.asarray(base) + np.array([grab + dx, 0.0, 0.0]))
