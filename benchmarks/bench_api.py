"""The REST service under load: 50 concurrent clients on loopback for 60 s.

    python benchmarks/bench_api.py [--seconds 60] [--clients 50] [--planners 2] [--build-samples N]
                                   [--workers N]

Starts ``pickstop serve`` on 127.0.0.1 (default data folder, warm database), stores the
paper-like scene and one plan, then for the duration runs ``clients`` concurrent clients:
``planners`` of them compute interactive plans of the scene (sigma varies per request, 200
Monte Carlo samples per stop) and the rest read the stored plan, while a database build job
runs. Prints throughput, p50/p99 latency per kind, errors, and lost writes (plans the clients
were told were stored but that the service cannot list). Readers are driven by ``wrk`` when
it is installed (``apt-get install wrk``), else (or with BENCH_PYTHON_READERS=1) by Python
clients, which on 2 cores measure themselves as much as the service.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import shutil
import socket
import statistics
import tempfile
import time
from pathlib import Path

import httpx

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

WRK = shutil.which("wrk")  # Debian's wrk; without it, Python clients read
PYTHON_READERS = os.environ.get("BENCH_PYTHON_READERS") == "1"
SCENE = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"
KEY = "bench-key"
AUTH = {"Authorization": f"Bearer {KEY}"}


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] * 1e3 if xs else float("nan")


async def run(url: str, seconds: float, clients: int, planners: int, build: int) -> None:
    doc = json.loads(SCENE.read_text())
    limits = httpx.Limits(max_connections=clients + 5, max_keepalive_connections=clients + 5)
    async with httpx.AsyncClient(base_url=url, timeout=300, limits=limits) as c:
        sid = (await c.post("/api/v1/scenes", json=doc, headers=AUTH)).json()["id"]
        r = await c.post("/api/v1/plans", json={"scene_id": sid}, headers=AUTH)
        plan_id = r.json()["id"]
        job = (
            await c.post("/api/v1/databases", json={"samples": build, "seed": 977}, headers=AUTH)
        ).json()
        reads: list[float] = []
        plans: list[float] = []
        errors: list[str] = []
        stored: list[str] = []
        stop = time.perf_counter() + seconds

        async def reader() -> None:
            while time.perf_counter() < stop:
                t0 = time.perf_counter()
                resp = await c.get(f"/api/v1/plans/{plan_id}")
                if resp.status_code != 200:
                    errors.append(f"read {resp.status_code}")
                else:
                    reads.append(time.perf_counter() - t0)

        async def planner(k: int) -> None:
            n = 0
            while time.perf_counter() < stop:
                sigma = 0.02 + 0.01 * ((k * 7 + n) % 12)
                n += 1
                t0 = time.perf_counter()
                resp = await c.post(
                    "/api/v1/plans",
                    json={"scene_id": sid, "options": {"sigma": sigma, "samples": 200}},
                    headers=AUTH,
                )
                if resp.status_code == 201:
                    plans.append(time.perf_counter() - t0)
                    stored.append(resp.json()["id"])
                elif resp.status_code == 422 and "Infeasible" in resp.text:
                    plans.append(time.perf_counter() - t0)
                else:
                    errors.append(f"plan {resp.status_code}: {resp.text[:200]}")

        t_start = time.perf_counter()
        wrk_out = None
        if WRK and not PYTHON_READERS:
            # wrk (C, event-driven) holds the readers' connections: the figure is the
            # service's, not a Python client's.
            proc = await asyncio.create_subprocess_exec(
                WRK, "-t2", f"-c{clients - planners}", f"-d{int(seconds)}s", "--latency",
                f"{url}/api/v1/plans/{plan_id}", stdout=asyncio.subprocess.PIPE,
            )  # fmt: skip
            results = await asyncio.gather(
                proc.communicate(), *(planner(k) for k in range(planners))
            )
            wrk_out = results[0][0].decode()
        else:
            await asyncio.gather(
                *(planner(k) for k in range(planners)),
                *(reader() for _ in range(clients - planners)),
            )
        elapsed = time.perf_counter() - t_start
        listed: set[str] = set()
        while True:  # every page of the scene's plans
            page = (await c.get(f"/api/v1/scenes/{sid}/plans",
                                params={"limit": 500, "offset": len(listed)})).json()  # fmt: skip
            listed |= {p["id"] for p in page}
            if len(page) < 500:
                break
        lost = [p for p in stored if p not in listed]
        state = (await c.get(f"/api/v1/jobs/{job['id']}")).json()
        await c.post(f"/api/v1/jobs/{job['id']}/cancel", headers=AUTH)
        for _ in range(120):  # then remove the partial database the load test made
            j = (await c.get(f"/api/v1/jobs/{job['id']}")).json()
            if j["state"] not in ("queued", "running"):
                break
            await asyncio.sleep(0.5)
        for d in (await c.get("/api/v1/databases")).json():
            if d["seed"] == 977 and d["samples"] == build:
                await c.delete(f"/api/v1/databases/{d['id']}", headers=AUTH)
    print(f"{clients} clients for {elapsed:.0f} s; database build job: {state['state']} at "
          f"{state['progress']:.0%} when the load ended")  # fmt: skip
    if wrk_out is not None:
        rps = re.search(r"Requests/sec:\s+([\d.]+)", wrk_out)
        p50 = re.search(r"^\s*50%\s+(\S+)", wrk_out, re.MULTILINE)  # the latency table
        p99 = re.search(r"^\s*99%\s+(\S+)", wrk_out, re.MULTILINE)
        bad = re.search(r"Non-2xx or 3xx responses:\s+(\d+)", wrk_out)
        errs = re.search(r"Socket errors:.*", wrk_out)
        print(
            f"read stored plan (wrk, {clients - planners} connections): "
            f"{rps.group(1) if rps else '?'} req/s, p50 {p50.group(1) if p50 else '?'}, "
            f"p99 {p99.group(1) if p99 else '?'} (target p99 < 20 ms); non-2xx "
            f"{bad.group(1) if bad else 0}; {errs.group(0) if errs else 'no socket errors'}"
        )
    else:
        print(
            f"read stored plan: {len(reads) / elapsed:.0f} req/s, p50 {_pct(reads, 0.5):.1f} "
            f"ms, p99 {_pct(reads, 0.99):.1f} ms (target p99 < 20 ms)"
        )
    print(
        f"interactive plan ({planners} clients): {len(plans) / elapsed:.1f} req/s, p50 "
        f"{_pct(plans, 0.5):.0f} ms, p99 {_pct(plans, 0.99):.0f} ms, mean "
        f"{statistics.mean(plans) * 1e3 if plans else float('nan'):.0f} ms (target p99 < 1.5 s)"
    )
    print(f"errors: {len(errors)} {errors[:3]}; writes acknowledged {len(stored)}, lost "
          f"{len(lost)}")  # fmt: skip


def memory(pid: int) -> str:
    """Memory of the service's processes: resident, proportional (shared pages split among
    their users) and own (pages no other process maps), and the peak resident."""
    try:
        import psutil
    except ImportError:
        return "memory: psutil not installed"
    main = psutil.Process(pid)
    parts = []
    for p in [main, *main.children(recursive=True)]:
        full = p.memory_full_info()
        rss, pss, uss = full.rss / 2**20, full.pss / 2**20, full.uss / 2**20
        peak = _peak_kib(p.pid) / 1024
        parts.append(f"pid {p.pid}: {rss:.0f} MiB resident ({pss:.0f} proportional, {uss:.0f} "
                     f"own), peak {peak:.0f} MiB")  # fmt: skip
    return "memory per process: " + "; ".join(parts)


def _peak_kib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return float(line.split()[1])
    return float("nan")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--planners", type=int, default=2)
    ap.add_argument("--build-samples", type=int, default=20_000_000)
    ap.add_argument("--workers", type=int, default=1, help="API processes (serve --workers)")
    args = ap.parse_args()
    port = _port()
    env = {**os.environ, "PICKSTOP_API_KEYS": f'["{hash_key(KEY)}"]',
           "PICKSTOP_WORKERS": str(args.workers)}  # fmt: skip
    log_path = Path(tempfile.gettempdir()) / "pickstop-bench-serve.log"
    url = f"http://127.0.0.1:{port}"
    t0 = time.time()
    with log_path.open("w") as log:
        proc = spawn_api(port, env, log)
    try:
        print(f"service up in {time.time() - t0:.1f} s (database loaded at start-up)")
        asyncio.run(run(url, args.seconds, args.clients, args.planners, args.build_samples))
        print(memory(proc.pid))
    finally:
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
