"""Live layout editing, API side: previews and exact re-plans of moved trays, sigma steps.

    PICKSTOP_DATA_DIR=<data with a TIAGo database> python benchmarks/bench_live.py
        [--scenes paper_experiment five_trays factory_cell] [--trays N]
        [--only moves|options] [--hold S] [--verbose]

Starts ``pickstop serve`` on 127.0.0.1 over the data folder, then per example scene: plans the
scene as it is (warm), and for each of its first ``--trays`` trays and each move (0.05, 0.1,
0.2, 0.3 and 0.5 m along x or y, and a 0.3 rad turn) asks for the preview (``mode: preview``)
and then the exact plan of the moved layout, before the layout goes back and a pause of a
second (what an engineer takes to look; the service checks candidates in the background
then); a move that makes
the scene invalid (a tray into its neighbour, off its table) is skipped. Then sigma steps
(0.05 to 0.15 m), rule, target and objective changes on the scene as it is. Prints the time
each request took at the client (HTTP and JSON included), median and p90, per kind and scene.
``--hold S`` waits S seconds between a move's preview and its exact plan (the engineer
holding the tray still before letting go: the service plans the previewed layout ahead
then). ``--verbose`` prints each exact plan's time and stages. ``--only options`` runs only
the sigma, rule, target and objective part (a minute instead of several per scene), ``--only
moves`` only the tray moves; ``--sweeps K`` repeats the sigma sweep K times (more samples, a
steadier median); ``--kinds turn`` moves the trays only by turns (``move``: only translations).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import socket
import statistics
import tempfile
import time
from pathlib import Path

import httpx

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
KEY = "bench-key"
AUTH = {"Authorization": f"Bearer {KEY}"}
PAUSE = 1.0  # [s] between a move and the next (background checks of the last plan run then)
MOVES = [(0.05, 0, 0), (0, 0.05, 0), (0.1, 0, 0), (0, -0.1, 0), (0.2, 0, 0), (-0.3, 0, 0),
         (0.5, 0, 0), (0, 0, 0.3)]  # fmt: skip


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _stats(xs: list[float]) -> str:
    if not xs:
        return "n/a"
    xs = sorted(xs)
    p90 = xs[min(len(xs) - 1, int(0.9 * len(xs)))]
    return f"median {statistics.median(xs) * 1e3:6.0f} ms, p90 {p90 * 1e3:6.0f} ms (n={len(xs)})"


SERVER: list[float] = []  # the plans' own total times [s] (timings.total), request by request
PARTS: list[dict[str, float]] = []  # the plans' timings [s] by stage, request by request
LAST_SIZE = [0]  # bytes of the last response body
VERBOSE = False  # --verbose: each exact plan's time and stages


def _plan(c: httpx.Client, doc: dict, options: dict, mode: str = "sync") -> tuple[float, int]:
    """Seconds the request took and its status (-1: the service has no such mode); the plan's
    own computing time is appended to SERVER."""
    body = {"scene": doc, "options": {"samples": 0, **options}, "store": False}
    if mode != "sync":
        body["mode"] = mode
    t0 = time.perf_counter()
    r = c.post("/api/v1/plans", json=body, headers=AUTH)
    dt = time.perf_counter() - t0
    LAST_SIZE[0] = len(r.content)
    if r.status_code == 422 and r.json().get("field") == "mode":
        return dt, -1
    timings = r.json()["plan"]["timings"] if r.status_code == 200 else {}
    SERVER.append(timings.get("total", float("nan")))
    PARTS.append(timings)
    return dt, r.status_code


def _moved(doc: dict, tray_id: str, dx: float, dy: float, dyaw: float) -> dict:
    out = copy.deepcopy(doc)
    for t in out["trays"]:
        if t["id"] == tray_id:
            p = t["pose"]
            p["x"], p["y"], p["yaw"] = p["x"] + dx, p["y"] + dy, p.get("yaw", 0.0) + dyaw
    return out


def bench_scene(
    c: httpx.Client,
    name: str,
    n_trays: int,
    only: str | None = None,
    sweeps: int = 1,
    hold: float = 0.0,
) -> None:
    doc = json.loads((SCENES / f"{name}.json").read_text())
    t, code = _plan(c, doc, {})
    print(f"\n{name}: first plan {t * 1e3:.0f} ms ({code})")
    if only != "options":
        bench_moves(c, doc, n_trays, hold)
    if only != "moves":
        bench_options(c, doc, sweeps)


def bench_moves(c: httpx.Client, doc: dict, n_trays: int, hold: float = 0.0) -> None:
    preview: dict[str, list[float]] = {"move": [], "turn": []}
    exact: dict[str, list[float]] = {"move": [], "turn": []}
    own: dict[str, list[float]] = {"preview": [], "exact": []}
    stages: list[dict[str, float]] = []  # the exact translations' timings
    skipped = 0
    no_preview = False
    for tray in doc["trays"][:n_trays]:
        for dx, dy, dyaw in MOVES:
            kind = "turn" if dyaw else "move"
            moved = _moved(doc, tray["id"], dx, dy, dyaw)
            tp, pcode = _plan(c, moved, {}, "preview")
            no_preview |= pcode == -1
            tp_own = SERVER[-1] if pcode not in (-1,) and SERVER else float("nan")
            time.sleep(hold)  # the tray held still before it is let go
            te, code = _plan(c, moved, {})
            if code != 200:
                skipped += 1  # the move made the scene invalid or infeasible
                continue
            exact[kind].append(te)
            if VERBOSE:
                parts = ", ".join(
                    f"{k} {v * 1e3:.0f}" for k, v in PARTS[-1].items() if isinstance(v, float)
                )
                print(f"    {tray['id']} {(dx, dy, dyaw)}: exact {te * 1e3:.0f} ms ({parts})")
            if kind == "move":
                own["exact"].append(SERVER[-1])
                stages.append(PARTS[-1])
            if pcode == 200:
                preview[kind].append(tp)
                if kind == "move":
                    own["preview"].append(tp_own)
            _plan(c, doc, {})  # back to the layout as it was
            time.sleep(PAUSE)  # the engineer looks at the plan before the next move
    for kind in ("move", "turn"):
        if not any(("turn" if m[2] else "move") == kind for m in MOVES):
            continue
        label = "translations 0.05-0.5 m" if kind == "move" else "turns by 0.3 rad"
        pv = "not offered" if no_preview else _stats(preview[kind])
        print(f"  preview, {label:24s} {pv}")
        after = f"exact {hold:g} s after" if hold else "exact,  "
        print(f"  {after} {label:24s} {_stats(exact[kind])}")
    for what, xs in own.items():
        if not xs:
            continue  # no translations asked for (--kinds turn)
        print(f"  {what} of translations, the plan's own time (timings.total): {_stats(xs)}")
    if stages:
        keys = [k for k in stages[0] if k != "total" and isinstance(stages[0][k], float)]
        mids = {k: statistics.median(s.get(k, 0.0) for s in stages) * 1e3 for k in keys}
        shown = ", ".join(f"{k} {v:.0f} ms" for k, v in mids.items() if v >= 0.5)
        print(f"  exact of translations by stage, medians: {shown or 'each under 0.5 ms'}")
    print(f"  ({skipped} moves skipped: the moved layout is invalid or has no plan)")


def bench_options(c: httpx.Client, doc: dict, sweeps: int = 1) -> None:
    sig: list[float] = []
    other: list[float] = []
    sizes: list[int] = []
    own: list[float] = []
    time.sleep(PAUSE)
    for _ in range(sweeps):
        for k in range(11):
            t, code = _plan(c, doc, {"sigma": 0.05 + 0.01 * k})
            if code == 200:
                sig.append(t)
                own.append(SERVER[-1])
                sizes.append(LAST_SIZE[0])
        for opts in ({"rule": "success", "target": 0.9}, {"rule": "success", "target": 0.95},
                     {"objective": "time"}, {"objective": "stops"}, {"rule": "sigma"}):  # fmt: skip
            t, code = _plan(c, doc, opts)
            if code == 200:
                other.append(t)
    print(f"  sigma steps 0.05-0.15 m          {_stats(sig)}")
    print(f"  rule, target, objective changes  {_stats(other)}")
    print(f"  sigma steps, the plan's own time {_stats(own)}")
    if sizes:
        print(f"  response body of a sigma step    {statistics.median(sizes) / 1e3:.0f} kB")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "--scenes", nargs="+", default=["paper_experiment", "five_trays", "factory_cell"]
    )
    ap.add_argument("--trays", type=int, default=3, help="trays moved per scene")
    ap.add_argument(
        "--only",
        choices=["moves", "options"],
        help="only the tray moves, or only the sigma/rule/target/objective changes",
    )
    ap.add_argument("--sweeps", type=int, default=1, help="sigma sweeps per scene")
    ap.add_argument(
        "--hold", type=float, default=0.0, help="seconds between a preview and its exact plan"
    )
    ap.add_argument("--verbose", action="store_true", help="each exact plan's stages")
    ap.add_argument(
        "--kinds", nargs="+", choices=["move", "turn"], default=["move", "turn"],
        help="which tray moves: translations, turns or both",
    )  # fmt: skip
    args = ap.parse_args()
    global VERBOSE
    VERBOSE = args.verbose
    MOVES[:] = [m for m in MOVES if ("turn" if m[2] else "move") in args.kinds]
    port = _port()
    env = {**os.environ, "PICKSTOP_API_KEYS": f'["{hash_key(KEY)}"]'}
    log_path = Path(tempfile.gettempdir()) / "pickstop-bench-live.log"
    with log_path.open("w") as log:
        proc = spawn_api(port, env, log)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=300) as c:
            db = c.get("/api/v1/databases").json()
            print("database:", ", ".join(f"{d['id']} ({d['samples']:,} samples)" for d in db))
            for name in args.scenes:
                bench_scene(c, name, args.trays, args.only, args.sweeps, args.hold)
    finally:
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
