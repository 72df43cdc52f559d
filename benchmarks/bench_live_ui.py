"""Live layout editing in the browser: previews per second, release and slider to redrawn.

    PICKSTOP_DATA_DIR=<data with a TIAGo database> \
        python benchmarks/bench_live_ui.py [--flat-lighting]

Starts ``pickstop serve`` on 127.0.0.1 over the data folder, the 3D planner on the paper-like
scene in this process and Debian's headless Chromium (Playwright, software WebGL). Measured in
the page (``performance.now()``): (1) previews drawn per second while tray_4 moves 2.5 cm every
50 ms, as a gizmo drag delivers poses (set from the server side, so the browser's own pointer
handling is left out); (2) a real mouse drag of the gizmo: pointer moves the page handles per
second and previews drawn; (3) release of a drag to the exact plan drawn; (4) the end of a
sigma slider gesture to the redrawn plan. ``--flat-lighting`` runs the planner with its
hemisphere light instead of the environment map (``pickstop ui --flat-lighting``).
"""

from __future__ import annotations

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
COUNT_PREVIEWS = """() => {
    window.__f = [];
    new MutationObserver(() => {
        const m = document.body.innerText.match(/preview \\(not verified\\) · plan #(\\d+)/);
        if (m && (!window.__f.length || window.__f[window.__f.length - 1][1] !== +m[1])) {
            window.__f.push([performance.now(), +m[1]]);
        }
    }).observe(document.body, {subtree: true, childList: true, characterData: true});
}"""
TIMER = """() => {
    window.__t = {up: null, move: null, moves: 0, changes: []};
    addEventListener('pointerup', () => { window.__t.up = performance.now(); },
                     {capture: true, once: true});
    addEventListener('pointermove', () => {
        if (window.__t.up === null) { window.__t.move = performance.now(); window.__t.moves++; }
    }, {capture: true});
    new MutationObserver(() => {
        window.__t.changes.push([performance.now(), document.body.innerText]);
    }).observe(document.body, {subtree: true, childList: true, characterData: true});
}"""


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _since_gesture(pg, marker: str) -> float:
    pg.wait_for_function(
        "m => window.__t.up !== null && window.__t.changes.some(c => c[1].includes(m))",
        arg=marker,
        timeout=120_000,
    )
    t = pg.evaluate("window.__t")
    start = t["move"] if t["move"] is not None else t["up"]
    return float(next(c[0] for c in t["changes"] if marker in c[1] and c[0] >= start) - start)


def _project(cam, p) -> tuple[float, float]:
    from viser import transforms as tf

    R = tf.SO3(np.asarray(cam.wxyz)).as_matrix()
    pc = R.T @ (np.asarray(p, float) - np.asarray(cam.position))
    f = (cam.image_height / 2) / np.tan(cam.fov / 2)
    return cam.image_width / 2 + f * pc[0] / pc[2], cam.image_height / 2 + f * pc[1] / pc[2]


def _drag(pg, a, b, steps: int, pause: float) -> None:
    pg.mouse.move(*a)
    pg.mouse.down()
    for k in range(1, steps + 1):
        pg.mouse.move(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
        time.sleep(pause)
    pg.mouse.up()


def main() -> None:
    from playwright.sync_api import sync_playwright

    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient

    port = _port()
    env = {**os.environ, "PICKSTOP_API_KEYS": f'["{hash_key("bench-key")}"]'}
    with (Path(tempfile.gettempdir()) / "pickstop-bench-live-ui.log").open("w") as log:
        proc = spawn_api(port, env, log)
    app = None
    try:
        client = PickStopClient(f"http://127.0.0.1:{port}", "bench-key")
        stored = client.create_scene(json.loads(SCENE.read_text()))
        flat = "--flat-lighting" in sys.argv
        app = PlannerApp(client, stored.id, port=_port(), flat_lighting=flat)
        print(f"lighting: {'flat (hemisphere light)' if flat else 'environment map'}; "
              f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")  # fmt: skip
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            pg = browser.new_page(viewport={"width": 1280, "height": 800})
            pg.goto(f"http://127.0.0.1:{app.port}/")
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=180_000)  # fmt: skip
            time.sleep(3)
            # (1) Poses every 50 ms for 4 s, as a drag delivers them.
            pg.evaluate(COUNT_PREVIEWS)
            tray = next(t for t in app.state.doc["trays"] if t["id"] == "tray_4")
            for k in range(80):
                with app._lock:
                    tray["pose"]["x"] += 0.025 if (k // 10) % 2 else -0.025
                app.request("bench", preview=True)
                time.sleep(0.05)
            time.sleep(1.0)
            f = pg.evaluate("window.__f")
            span = (f[-1][0] - f[0][0]) / 1e3 if len(f) > 1 else float("nan")
            print(f"(1) previews drawn in the page while poses arrive every 50 ms: {len(f)} in "
                  f"{span:.1f} s = {(len(f) - 1) / span:.1f} per second")  # fmt: skip
            app.request("bench")
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=120_000)  # fmt: skip
            time.sleep(1.0)
            # (2) + (3) A real drag of tray_4's gizmo arrow, 0.3 m back and forth.
            cam = next(iter(app.server.get_clients().values())).camera
            base = np.array([tray["pose"]["x"], tray["pose"]["y"], tray["pose"]["z"]])
            a = _project(cam, base + np.array([0.21, 0.0, 0.0]))
            b = _project(cam, base + np.array([-0.09, 0.0, 0.0]))
            pg.evaluate(COUNT_PREVIEWS)
            pg.evaluate(TIMER)
            t0 = time.perf_counter()
            _drag(pg, a, b, 20, 0.05)
            wall = time.perf_counter() - t0
            pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                 timeout=120_000)  # fmt: skip
            ms = _since_gesture(pg, f"plan #{app.state.seq} in")
            t = pg.evaluate("window.__t")
            f = pg.evaluate("window.__f")
            print(f"(2) mouse drag of the gizmo: 20 moves took {wall:.1f} s in Playwright "
                  f"({20 / wall:.1f} moves per second reach the page); {len(f)} previews drawn "
                  f"({len(f) / wall:.1f} per second)")  # fmt: skip
            print(f"(3) drag release -> exact plan drawn: {ms:.0f} ms ({t['moves']} pointer moves)")
            time.sleep(1.0)
            # (4) sigma slider gestures.
            times = []
            for value in (0.15, 0.10, 0.15, 0.10):
                root = pg.locator(".mantine-Slider-root").nth(0)
                box = root.bounding_box()
                thumb = root.locator("[role=slider]").bounding_box()
                start = (thumb["x"] + thumb["width"] / 2, thumb["y"] + thumb["height"] / 2)
                end = (box["x"] + value / SIGMA_MAX * box["width"], start[1])
                pg.evaluate(TIMER)
                _drag(pg, start, end, 8, 0.03)
                time.sleep(0.5)
                sigma = round(float(app.sigma.value), 3)
                times.append(_since_gesture(pg, f"σ = {sigma:.3f} m"))
                pg.wait_for_function("document.body.innerText.includes('Status: ready')",
                                     timeout=120_000)  # fmt: skip
            print("(4) sigma slider gesture end -> redrawn: "
                  + ", ".join(f"{x:.0f}" for x in times) + " ms")  # fmt: skip
            browser.close()
    finally:
        if app is not None:
            app.close()
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
