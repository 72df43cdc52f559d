"""The REST service against hostile and careless clients: what each request gets, how long it
takes, and how fast ``/health`` answers meanwhile.

    python benchmarks/bench_hostile.py [--data-dir DIR] [--samples N] [--cases TEXT]

Starts ``pickstop serve`` on 127.0.0.1 over a data folder (default: a fresh temporary one with
a small TIAGo database built first) with a 20 MB body limit (``--max-body-bytes``; the default
of 2 MB answers the 10,000-tray scene 413 at once), so that the scene limits, not the body
limit, answer the big scenes. First times the refusal of the 2,000- and 10,000-tray scenes by
one client alone. For each case, one client sends the request while another
polls ``/health`` every 10 ms; prints the status, the request's time (min-max over
``--repeat`` runs) and the health latency (worst p50, max) during it.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

SCENE = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"
KEY = "bench-key"
AUTH = {"Authorization": f"Bearer {KEY}"}
JSON = {"content-type": "application/json"}


def paper() -> dict[str, Any]:
    return json.loads(SCENE.read_text())


def trays(n: int) -> dict[str, Any]:
    doc = paper()
    first = doc["trays"][0]
    doc["trays"] = [{**copy.deepcopy(first), "id": f"t{i}", "name": f"t{i}",
                     "pose": {**first["pose"], "x": 0.4 * i}} for i in range(n)]  # fmt: skip
    doc.pop("task", None)
    return doc


def parts(n: int, which: tuple[int, ...] = (0,)) -> dict[str, Any]:
    doc = paper()
    for k in which:
        doc["trays"][k]["parts"] = [
            {"id": f"p{k}_{i}", "geometry": {"shape": "box", "size": [0.01, 0.01, 0.01]},
             "pose": {"x": -0.12 + 0.02 * (i % 13), "y": -0.08 + 0.02 * (i // 13 % 9), "z": 0}}
            for i in range(n)
        ]  # fmt: skip
    return doc


def obstacles(n: int) -> dict[str, Any]:
    doc = paper()
    doc["obstacles"] += [{"id": f"o{i}", "geometry": {"shape": "box", "size": [0.01] * 3},
                          "pose": {"x": 4.5, "y": -0.9 + i * 1e-4}} for i in range(n)]  # fmt: skip
    return doc


def huge_floor() -> dict[str, Any]:
    doc = paper()
    doc["floor"] = {"min": [-1e308, -1e308], "max": [1e308, 1e308]}
    return doc


def chunks(total: int) -> Any:
    yield b'{"name": "'
    block = b" " * 65536
    for _ in range(total // len(block)):
        yield block
    yield b'"}'


def yaml_config(size: int) -> bytes:
    """A robot config as YAML of about ``size`` bytes (a long list of locked joints)."""
    text = "name: big\nurdf: robot.urdf\narm_joints: [a]\ntool_frame: t\nlocked_joints:\n"
    lines = []
    while len(text) + sum(map(len, lines)) < size - 40:
        lines.append(f"  joint_{len(lines)}: {{x: [1, 2.5, true, null, 'q{len(lines)}']}}\n")
    return (text + "".join(lines)).encode()


def at_once(n: int, send: Callable[[httpx.Client], httpx.Response]) -> Callable[..., Any]:
    """``send`` by ``n`` clients at once; the last answer."""

    def run(c: httpx.Client) -> httpx.Response:
        out: list[httpx.Response] = []
        threads = [threading.Thread(target=lambda: out.append(send(c))) for _ in range(n)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        return out[-1]

    return run


def cases(sid: str, heavy_sid: str) -> list[tuple[str, Callable[[httpx.Client], httpx.Response]]]:
    """(name, send): every body is encoded before the clock starts."""
    seed = time.time_ns() % 2**31
    t2k, t10k = json.dumps(trays(2000)).encode(), json.dumps(trays(10_000)).encode()
    plan10k = json.dumps({"scene": trays(10_000)}).encode()
    batch = json.dumps({"scenes": [{"scene": trays(2000)}] * 3}).encode()
    print(f"bodies: 2,000 trays {len(t2k) / 1e6:.1f} MB, 10,000 trays {len(t10k) / 1e6:.1f} MB")
    yml = yaml_config(99_000)
    nested = b"a: " + b"[" * 49_000 + b"]" * 49_000 + b"\n"
    YAML = {**AUTH, "content-type": "application/yaml"}

    def post_yaml(body: bytes) -> Callable[[httpx.Client], httpx.Response]:
        return lambda c: c.post("/api/v1/robots", content=body, headers=YAML)

    return [
        ("POST /robots, YAML 99 kB (limit 100 kB)", post_yaml(yml)),
        ("POST /robots, 3 x YAML 99 kB at once", at_once(3, post_yaml(yml))),
        ("POST /robots, YAML nested 49,000 deep", post_yaml(nested)),
        ("POST /robots, 3 x YAML nested at once", at_once(3, post_yaml(nested))),
        ("POST /scenes, 2,000 trays ", lambda c: c.post("/api/v1/scenes",
         content=t2k, headers={**AUTH, **JSON})),
        ("POST /scenes, 10,000 trays", lambda c: c.post("/api/v1/scenes",
         content=t10k, headers={**AUTH, **JSON})),
        ("PUT /scenes/{id}, 2,000 trays", lambda c: c.put(f"/api/v1/scenes/{sid}",
         content=t2k, headers={**AUTH, **JSON, "If-Match": "*"})),
        ("POST /plans inline, 10,000 trays", lambda c: c.post("/api/v1/plans",
         content=plan10k, headers={**AUTH, **JSON})),
        ("POST /jobs/batch, 3 x 2,000 trays", lambda c: c.post("/api/v1/jobs/batch",
         content=batch, headers={**AUTH, **JSON})),
        ("POST /scenes, 1,000 parts in a tray", lambda c: c.post("/api/v1/scenes",
         json=parts(1000), headers=AUTH)),
        ("POST /scenes, 5,000 obstacles", lambda c: c.post("/api/v1/scenes",
         json=obstacles(5000), headers=AUTH)),
        ("POST /scenes, floor extent 1e308", lambda c: c.post("/api/v1/scenes",
         json=huge_floor(), headers=AUTH)),
        ("GET /scenes?offset=2^63", lambda c: c.get("/api/v1/scenes",
         params={"offset": 2**63})),
        ("POST /plans, seed -1", lambda c: c.post("/api/v1/plans",
         json={"scene_id": sid, "options": {"seed": -1}}, headers=AUTH)),
        ("POST /plans mode job, seed -1", lambda c: c.post("/api/v1/plans",
         json={"scene_id": sid, "options": {"seed": -1}, "mode": "job"}, headers=AUTH)),
        ("POST /scenes, robot preset ../../etc/passwd", lambda c: c.post("/api/v1/scenes",
         json={**paper(), "robot": {"preset": "../../etc/passwd"}}, headers=AUTH)),
        ("POST /databases, seed -1", lambda c: c.post("/api/v1/databases",
         json={"seed": -1}, headers=AUTH)),
        ("POST /scenes, nested 100,000 deep", lambda c: c.post("/api/v1/scenes",
         content=b"[" * 100_000 + b"]" * 100_000, headers={**AUTH, **JSON})),
        ("POST /scenes, 5,000-digit integer", lambda c: c.post("/api/v1/scenes",
         content=b'{"sigma": ' + b"9" * 5000 + b"}", headers={**AUTH, **JSON})),
        ("POST /scenes, invalid UTF-8", lambda c: c.post("/api/v1/scenes",
         content=b'{"name": "\xff\xfe"}', headers={**AUTH, **JSON})),
        ("POST /scenes, chunked 25 MB", lambda c: c.post("/api/v1/scenes",
         content=chunks(25_000_000), headers={**AUTH, **JSON})),
        ("POST /scenes, text/plain", lambda c: c.post("/api/v1/scenes",
         content=json.dumps(paper()), headers={**AUTH, "content-type": "text/plain"})),
        ("POST /scenes, bad JSON, no key", lambda c: c.post("/api/v1/scenes",
         content=b"{not json", headers=JSON)),
        ("GET /scenes/{id}/regions, 4 trays x 48 parts", lambda c: c.get(
         f"/api/v1/scenes/{heavy_sid}/regions")),
        ("POST /plans, 20,000 Monte Carlo samples per stop", lambda c: c.post("/api/v1/plans",
         json={"scene_id": sid, "options": {"samples": 20000, "seed": seed}, "store": False},
         headers=AUTH)),
        ("POST /plans, 100,000 Monte Carlo samples per stop", lambda c: c.post("/api/v1/plans",
         json={"scene_id": sid, "options": {"samples": 100_000}}, headers=AUTH)),
    ]  # fmt: skip


def measure(url: str, send: Callable[[httpx.Client], httpx.Response]) -> tuple[Any, ...]:
    done = threading.Event()
    out: dict[str, Any] = {}

    def request() -> None:
        with httpx.Client(base_url=url, timeout=300) as c:
            t0 = time.perf_counter()
            try:
                r = send(c)
                out["status"], out["field"] = r.status_code, _field(r)
            except httpx.HTTPError as e:
                out["status"], out["field"] = type(e).__name__, ""
            out["seconds"] = time.perf_counter() - t0
        done.set()

    lat: list[float] = []
    worker = threading.Thread(target=request)
    with httpx.Client(base_url=url, timeout=30) as h:
        worker.start()
        while not done.is_set():
            t0 = time.perf_counter()
            h.get("/api/v1/health")
            lat.append(time.perf_counter() - t0)
            time.sleep(0.01)
    worker.join()
    lat.sort()
    p50 = lat[len(lat) // 2] * 1e3 if lat else float("nan")
    top = lat[-1] * 1e3 if lat else float("nan")
    return out["status"], out["field"], out["seconds"], len(lat), p50, top


def _field(r: httpx.Response) -> str:
    try:
        return str(r.json().get("field") or "") if r.status_code >= 400 else ""
    except ValueError:
        return ""


def rejections(url: str, runs: int = 10) -> None:
    """Time to refuse the 2,000- and 10,000-tray scenes, one client alone (no health poller
    sharing its process)."""
    with httpx.Client(base_url=url, timeout=60) as c:
        for n in (2000, 10_000):
            body = json.dumps(trays(n)).encode()
            times = []
            for _ in range(runs):
                t0 = time.perf_counter()
                r = c.post("/api/v1/scenes", content=body, headers={**AUTH, **JSON})
                times.append((time.perf_counter() - t0) * 1e3)
            times.sort()
            print(f"refuse {n:,} trays ({len(body) / 1e6:.1f} MB) alone: {r.status_code} "
                  f"{_field(r)}, min {times[0]:.0f} ms, median {times[len(times) // 2]:.0f} "
                  f"ms, max {times[-1]:.0f} ms")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", help="data folder with a TIAGo database (default: build one)")
    ap.add_argument("--samples", type=int, default=1_000_000, help="samples of that build")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each quick case (min-max)")
    ap.add_argument("--max-body-bytes", default="20000000", help="the service's body limit")
    ap.add_argument("--cases", default="", help="only the cases whose name holds this text")
    args = ap.parse_args()
    folder = Path(args.data_dir or tempfile.mkdtemp(prefix="pickstop-hostile-"))
    if not args.data_dir:
        from pickstop.reach.build import BuildParams
        from pickstop.robot.model import load
        from pickstop.store.reach_build import build

        print(f"building a {args.samples:,}-sample TIAGo database in {folder} ...", flush=True)
        build(load("tiago"), BuildParams(samples=args.samples), folder, workers=2)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(folder),
           "PICKSTOP_API_KEYS": json.dumps([hash_key(KEY)]),
           "PICKSTOP_MAX_BODY_BYTES": args.max_body_bytes}  # fmt: skip
    log = (folder / "hostile-serve.log").open("w")
    proc = spawn_api(port, env, log)
    url = f"http://127.0.0.1:{port}"
    try:
        with httpx.Client(base_url=url, timeout=300) as c:
            sid = c.post("/api/v1/scenes", json=paper(), headers=AUTH).json()["id"]
            c.post(
                "/api/v1/plans", json={"scene_id": sid, "options": {"samples": 0}}, headers=AUTH
            )  # fmt: skip  (warm: regions of the paper scene cached)
            heavy = c.post("/api/v1/scenes", json=parts(48, (0, 1, 2, 3)), headers=AUTH)
            heavy_sid = heavy.json()["id"]
            limits = c.get("/api/v1/limits").json()
        print(f"limits: {json.dumps(limits)}")
        if not args.cases:
            rejections(url)
        print(f"{'case':52} {'status':>6} {'field':24} {'time':>11} {'polls':>5} "
              f"{'health p50':>10} {'max':>8}")  # fmt: skip
        for name, send in [c for c in cases(sid, heavy_sid) if args.cases in c[0]]:
            runs = [measure(url, send) for _ in range(1 if "regions" in name or "20,000" in name
                                                      else args.repeat)]  # fmt: skip
            status, field = runs[-1][0], runs[-1][1]
            times = sorted(r[2] * 1e3 for r in runs)
            n, p50, top = sum(r[3] for r in runs), max(r[4] for r in runs), max(r[5] for r in runs)
            took = f"{times[0]:.0f}-{times[-1]:.0f}ms" if len(times) > 1 else f"{times[0]:.0f}ms"
            print(f"{name:52} {status!s:>6} {field[:24]:24} {took:>11} {n:5d} "
                  f"{p50:8.1f}ms {top:6.1f}ms", flush=True)  # fmt: skip
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
