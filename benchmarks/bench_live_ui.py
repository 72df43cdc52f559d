"""Live layout editing in the browser: previews per second, release and slider to redrawn.

    PICKSTOP_DATA_DIR=<data with a TIAGo database> \
        python benchmarks/bench_live_ui.py [--environment-lighting] [--draft-scale X]

Starts ``pickstop serve`` on 127.0.0.1 over the data folder, the 3D planner on the paper-like
scene in this process and Debian's headless Chromium (Playwright, software WebGL). Measured in
the page (``performance.now()``): (1) previews drawn per second while tray_4 moves 2.5 cm every
50 ms, as a gizmo drag delivers poses (set from the server side, so the browser's own pointer
handling is left out); (2) a real mouse drag of the gizmo: pointer moves the page handles per
second and previews drawn; (3) release of a drag to the exact plan drawn, and (3b) the same
after holding the tray still for a second (the service plans it ahead then); (4) the end of a
sigma slider gesture to the redrawn plan. ``--environment-lighting`` runs the planner with
the environment map instead of its hemisphere light (``pickstop ui --lighting environment``);
``--draft-scale X`` sets the previews' pixel ratio (default the planner's; 1: full resolution
throughout).

"Drawn" means a canvas frame shows it: every frame the WebGL renderer draws is logged (its
animation-frame callback wrapped before the page loads); a plan counts as drawn once its
panel text appeared and the first frame that starts after the scene's nodes last changed
has ended (the text and the nodes' updates reach the viewer in order; a plan that changes
no node, e.g. a sigma step that keeps every circle, is drawn with its text), and previews
per second count the distinct previews that frames starting after their text show. The
frames' own interval, the planner's Python time per plan (drawing arrays, node updates,
panel), the API's answer time and the messages and bytes per plan are printed beside them.
"""

from __future__ import annotations

import collections
import json
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pickstop.settings import hash_key
from pickstop.stack import spawn_api
from pickstop_ui.app import SIGMA_MAX

SCENE = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"
CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]  # fmt: skip
FRAMES = """
window.__frames = [];
const raf = window.requestAnimationFrame.bind(window);
window.requestAnimationFrame = (cb) => raf((ts) => {
    const info = window.__viserTestpoints ? window.__viserTestpoints.rendererInfo : null;
    const before = info ? info.render.frame : -1;
    const t0 = performance.now();
    cb(ts);
    if (info && info.render.frame !== before) {
        window.__frames.push([t0, performance.now()]);
        if (window.__frames.length > 5000) window.__frames.splice(0, 1000);
    }
});
"""
COUNT_PREVIEWS = """() => {
    window.__f = [];
    if (window.__fObs) window.__fObs.disconnect();
    window.__fObs = new MutationObserver(() => {
        const m = document.body.innerText.match(/preview \\(not verified\\) · plan #(\\d+)/);
        if (m && (!window.__f.length || window.__f[window.__f.length - 1][1] !== +m[1])) {
            window.__f.push([performance.now(), +m[1]]);
        }
    });
    window.__fObs.observe(document.body, {subtree: true, childList: true, characterData: true});
}"""
HOLD_STILL = 1.0  # [s] a tray held still before it is let go, in (3b)
# Armed before a gesture: its last pointer move and release, every panel text after it, and
# every change of the scene's nodes (what the canvas must draw anew).
TIMER = """() => {
    window.__t = {up: null, move: null, moves: 0, changes: [], scene: []};
    addEventListener('pointerup', () => { window.__t.up = performance.now(); },
                     {capture: true, once: true});
    if (!window.__tMove) {
        window.__tMove = true;
        addEventListener('pointermove', () => {
            if (window.__t.up === null) {
                window.__t.move = performance.now();
                window.__t.moves++;
            }
        }, {capture: true});
    }
    if (window.__tObs) window.__tObs.disconnect();
    window.__tObs = new MutationObserver(() => {
        window.__t.changes.push([performance.now(), document.body.innerText]);
    });
    window.__tObs.observe(document.body, {subtree: true, childList: true, characterData: true});
    if (window.__tScene) window.__tScene();
    window.__tScene = window.__viserSceneTree.subscribe(
        () => window.__t.scene.push(performance.now()));
}"""


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _frame_after(pg, t: float) -> float:
    """The end of the first canvas frame that starts after ``t`` [ms, page time]."""
    pg.wait_for_function("t => window.__frames.some(f => f[0] > t)", arg=t, timeout=60_000)
    return float(next(f[1] for f in pg.evaluate("window.__frames") if f[0] > t))


def _since_gesture(pg, marker: str, since: str = "move") -> tuple[float, float]:
    """Gesture end (its last pointer move, or with ``since="up"`` its release) to ``marker``
    in the panel, and to the canvas frame that shows it [ms]."""
    pg.wait_for_function(
        "m => window.__t.up !== null && window.__t.changes.some(c => c[1].includes(m))",
        arg=marker,
        timeout=120_000,
    )
    t = pg.evaluate("window.__t")
    start = t["move"] if t["move"] is not None and since == "move" else t["up"]
    text = next(c[0] for c in t["changes"] if marker in c[1] and c[0] >= start)
    # The scene's nodes last changed with this text (one batch) or before it: the first
    # frame that starts after that change draws them; no change since the gesture began (a
    # sigma step that keeps every circle) leaves the canvas right as it is.
    scene = [c for c in t["scene"] if c <= text + 1.0]
    if not scene or scene[-1] < t["changes"][0][0]:
        return float(text - start), float(text - start)
    return float(text - start), max(text, _frame_after(pg, scene[-1])) - start


def _shown(frames: list, texts: list) -> list[int]:
    """The preview each canvas frame shows: the newest whose text came before it started."""
    at = np.array([t for t, _ in texts])
    shown = []
    for start, _ in frames:
        k = int(np.searchsorted(at, start)) - 1
        if k >= 0:
            shown.append(texts[k][1])
    return shown


class _Meter:
    """The planner's side of each drawn plan: Python time, API time, messages and bytes."""

    def __init__(self, app) -> None:
        import msgspec

        self.draw: list[float] = []
        self.api: list[float] = []
        self.messages = collections.Counter()
        self.bytes = 0
        iface = app.server.scene._websock_interface
        queue = iface.queue_message

        def counting(message):
            self.messages[type(message).__name__] += 1
            self.bytes += len(msgspec.msgpack.encode(message.as_serializable_dict()))
            return queue(message)

        iface.queue_message = counting
        ready, ask = app.plan_ready, app.api.plan

        def plan_ready(req, plan, final):
            t = time.perf_counter()
            ready(req, plan, final)
            self.draw.append(time.perf_counter() - t)

        def plan(scene, options, *a, **k):
            t = time.perf_counter()
            try:
                return ask(scene, options, *a, **k)
            finally:
                if not options["samples"]:  # the quick plans only, not the Monte Carlos
                    self.api.append(time.perf_counter() - t)

        app.plan_ready, app.api.plan = plan_ready, plan
        app.replanner.sink = app

    def reset(self) -> None:
        self.draw.clear()
        self.api.clear()
        self.messages.clear()
        self.bytes = 0

    def line(self) -> str:
        n = max(len(self.draw), 1)
        d, a = np.array(self.draw) * 1e3, np.array(self.api) * 1e3
        return (f"{len(self.draw)} plans drawn by the planner (quick ones asked in "
                f"{np.median(a):.0f} ms, p90 {np.percentile(a, 90):.0f}): Python "
                f"{np.median(d):.1f} ms (p90 {np.percentile(d, 90):.1f}) each, "
                f"{sum(self.messages.values()) / n:.1f} messages and "
                f"{self.bytes / n / 1e3:.1f} kB each")  # fmt: skip


def _project(cam, p, size=(1280, 800)) -> tuple[float, float]:
    """World point -> page pixel (CSS), the canvas filling the page of ``size``; the camera's
    own image size is in drawing-buffer pixels, which a draft resolution makes smaller."""
    from viser import transforms as tf

    R = tf.SO3(np.asarray(cam.wxyz)).as_matrix()
    pc = R.T @ (np.asarray(p, float) - np.asarray(cam.position))
    w, h = size
    f = (h / 2) / np.tan(cam.fov / 2)
    return w / 2 + f * pc[0] / pc[2], h / 2 + f * pc[1] / pc[2]


def _grab(cam, base) -> float:
    """Where along the gizmo's x arrow to grab it [m from its root]: 0.21 m on a gizmo of
    fixed world size (0.3 m), else 45% of an arrow drawn a fixed number of pixels long."""
    try:
        from pickstop_ui.selection import GIZMO_PX
    except ImportError:
        return 0.21
    dist = float(np.linalg.norm(np.asarray(base) - np.asarray(cam.position)))
    return 0.45 * GIZMO_PX * dist * 2 * np.tan(cam.fov / 2) / 800


def _drag(pg, a, b, steps: int, pause: float, hold: float = 0.0) -> None:
    """Press at ``a``, move to ``b`` in ``steps`` moves ``pause`` s apart, hold still for
    ``hold`` s, release."""
    pg.mouse.move(*a)
    pg.mouse.down()
    for k in range(1, steps + 1):
        pg.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        time.sleep(pause)
    time.sleep(hold)
    pg.mouse.up()


def main() -> None:
    from playwright.sync_api import sync_playwright

    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient
    from pickstop_ui.draft import DRAFT_SCALE

    port = _port()
    env = {**os.environ, "PICKSTOP_API_KEYS": f'["{hash_key("bench-key")}"]'}
    with (Path(tempfile.gettempdir()) / "pickstop-bench-live-ui.log").open("w") as log:
        proc = spawn_api(port, env, log)
    app = None
    try:
        client = PickStopClient(f"http://127.0.0.1:{port}", "bench-key")
        stored = client.create_scene(json.loads(SCENE.read_text()))
        flat = "--environment-lighting" not in sys.argv
        draft = float(sys.argv[sys.argv.index("--draft-scale") + 1]) if (
            "--draft-scale" in sys.argv) else DRAFT_SCALE  # fmt: skip
        app = PlannerApp(client, stored.id, port=_port(), flat_lighting=flat, draft_scale=draft)
        meter = _Meter(app)
        print(f"lighting: {'flat (hemisphere light)' if flat else 'environment map'}; draft "
              f"scale {draft}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
              "cores")  # fmt: skip
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            pg = browser.new_page(viewport={"width": 1280, "height": 800})
            pg.add_init_script(FRAMES)
            pg.goto(f"http://127.0.0.1:{app.port}/")
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=180_000)  # fmt: skip
            time.sleep(3)
            # (1) Poses every 50 ms for 4 s, as a drag delivers them.
            pg.evaluate(COUNT_PREVIEWS)
            pg.evaluate("window.__frames = []")
            meter.reset()
            canvas = "[window.__viserMutable.canvas.width, window.__viserMutable.canvas.height]"
            full = pg.evaluate(canvas)
            tray = next(t for t in app.state.doc["trays"] if t["id"] == "tray_4")
            for k in range(80):
                with app._lock:
                    tray["pose"]["x"] += 0.025 if (k // 10) % 2 else -0.025
                app.request("bench", preview=True)
                time.sleep(0.05)
                if k == 40:
                    during = pg.evaluate(canvas)
            time.sleep(1.0)
            f, frames = pg.evaluate("window.__f"), pg.evaluate("window.__frames")
            span = (f[-1][0] - f[0][0]) / 1e3 if len(f) > 1 else float("nan")
            inside = [fr for fr in frames if f[0][0] <= fr[0] <= f[-1][0]]
            shown = len(set(_shown(frames, f)))
            gaps = np.diff([fr[0] for fr in inside]) if len(inside) > 1 else np.array([np.nan])
            print(f"(1) previews drawn in the page while poses arrive every 50 ms: {shown} "
                  f"canvas frames with a new preview in {span:.1f} s = {shown / span:.1f} per "
                  f"second (panel text: {len(f)}, {(len(f) - 1) / span:.1f} per second); "
                  f"{len(inside)} frames, interval median {np.median(gaps):.0f} ms (p90 "
                  f"{np.percentile(gaps, 90):.0f}); canvas {during[0]}x{during[1]} during "
                  f"the drag, {full[0]}x{full[1]} at rest")  # fmt: skip
            print(f"    {meter.line()}")
            app.request("bench")
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=120_000)  # fmt: skip
            time.sleep(1.0)
            # (2) + (3) A real drag of tray_4's gizmo arrow, 0.2 m back and forth, on its
            # table (the tray selected first: only the selected item carries a gizmo).
            if hasattr(app, "select"):
                app.select(("trays", "tray_4"))
                time.sleep(0.5)
            cam = next(iter(app.server.get_clients().values())).camera
            base = np.array([tray["pose"]["x"], tray["pose"]["y"], tray["pose"]["z"]])
            grab = _grab(cam, base)
            a = _project(cam, base + np.array([grab, 0.0, 0.0]))
            b = _project(cam, base + np.array([grab - 0.2, 0.0, 0.0]))
            pg.evaluate(COUNT_PREVIEWS)
            pg.evaluate(TIMER)
            t0 = time.perf_counter()
            _drag(pg, a, b, 20, 0.05)
            wall = time.perf_counter() - t0
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=120_000)  # fmt: skip
            text_ms, ms = _since_gesture(pg, f"plan #{app.state.seq} in")
            t = pg.evaluate("window.__t")
            f = pg.evaluate("window.__f")
            previews = len(set(_shown(pg.evaluate("window.__frames"), f)))
            print(f"(2) mouse drag of the gizmo: 20 moves took {wall:.1f} s in Playwright "
                  f"({20 / wall:.1f} moves per second reach the page); {previews} previews "
                  f"drawn on the canvas ({previews / wall:.1f} per second; panel text "
                  f"{len(f)})")  # fmt: skip
            print(f"(3) drag release -> exact plan drawn: {ms:.0f} ms (panel text {text_ms:.0f} "
                  f"ms; {t['moves']} pointer moves)")  # fmt: skip
            time.sleep(1.0)
            # (3b) The same drag back, the tray held still for a second before the release.
            tray = next(t for t in app.state.doc["trays"] if t["id"] == "tray_4")
            base = np.array([tray["pose"]["x"], tray["pose"]["y"], tray["pose"]["z"]])
            grab = _grab(cam, base)
            a = _project(cam, base + np.array([grab, 0.0, 0.0]))
            b = _project(cam, base + np.array([grab + 0.2, 0.0, 0.0]))
            pg.evaluate(TIMER)
            _drag(pg, a, b, 20, 0.05, hold=HOLD_STILL)
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=120_000)  # fmt: skip
            text_ms, ms = _since_gesture(pg, f"plan #{app.state.seq} in", since="up")
            print(f"(3b) drag held still {HOLD_STILL:g} s, then released -> exact plan drawn: "
                  f"{ms:.0f} ms (panel text {text_ms:.0f} ms)")  # fmt: skip
            time.sleep(1.0)
            # (4) sigma slider gestures.
            times, texts = [], []
            meter.reset()
            for value in (0.15, 0.10, 0.15, 0.10, 0.125, 0.10):
                root = pg.locator(".mantine-Slider-root").nth(0)
                box = root.bounding_box()
                thumb = root.locator("[role=slider]").bounding_box()
                start = (thumb["x"] + thumb["width"] / 2, thumb["y"] + thumb["height"] / 2)
                end = (box["x"] + value / SIGMA_MAX * box["width"], start[1])
                pg.evaluate(TIMER)
                _drag(pg, start, end, 8, 0.03)
                time.sleep(0.5)
                sigma = round(float(app.sigma.value), 3)
                text_ms, ms = _since_gesture(pg, f"σ = {sigma:.3f} m")
                times.append(ms)
                texts.append(text_ms)
                pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                     timeout=120_000)  # fmt: skip
            print("(4) sigma slider gesture end -> redrawn: "
                  + ", ".join(f"{x:.0f}" for x in times) + " ms (panel text "
                  + ", ".join(f"{x:.0f}" for x in texts) + f" ms); median "
                  f"{np.median(times):.0f} ms; {app.replanner.cancelled} Monte Carlos "
                  "cancelled so far")  # fmt: skip
            print(f"    {meter.line()}")
            browser.close()
    finally:
        if app is not None:
            app.close()
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
