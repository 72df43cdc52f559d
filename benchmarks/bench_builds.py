"""Build and cancel, over and over: what the service holds after, and after it stops.

    python benchmarks/bench_builds.py [--cycles 200] [--samples 20000]

Starts ``pickstop serve`` on 127.0.0.1 over a fresh data folder; each cycle starts a build
(``--samples`` samples in chunks of 1,000, a new seed each time) and cancels it after a random
0-2 s (every other one once its pool computes chunks); every ``--every`` cycles prints the
service's process count and memory (its own and every descendant's), the databases it lists
and the bytes of the data folder's ``reach/``. Then stops the service with SIGTERM and counts
the processes it started that are still alive 1 and 10 s later.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import signal
import socket
import sys
import tempfile
import time
from pathlib import Path

import httpx
import psutil

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

KEY = "bench-key"
AUTH = {"Authorization": f"Bearer {KEY}"}


def tree(pid: int) -> tuple[list[psutil.Process], float]:
    """The service's descendants (alive, not zombies) and its and their memory [MB]."""
    root = psutil.Process(pid)
    kids = [p for p in root.children(recursive=True) if _running(p)]
    rss = 0.0
    for p in [root, *kids]:
        with contextlib.suppress(psutil.NoSuchProcess):
            rss += p.memory_info().rss / 1e6
    return kids, rss


def _running(p: psutil.Process) -> bool:
    try:
        return p.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def folder_bytes(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cycles", type=int, default=200)
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--every", type=int, default=25, help="print every N cycles")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="pickstop-builds-"))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(folder),
           "PICKSTOP_API_KEYS": json.dumps([hash_key(KEY)])}  # fmt: skip
    log = (folder / "serve.log").open("w")
    proc = spawn_api(port, env, log)
    rng = random.Random(args.seed)
    states: dict[str, int] = {}
    seen: dict[int, psutil.Process] = {}
    kids, rss = tree(proc.pid)
    print(f"started: {len(kids)} processes besides the service, {rss:.0f} MB")
    t0 = time.perf_counter()
    with httpx.Client(base_url=f"http://127.0.0.1:{port}/api/v1", timeout=120) as c:
        for k in range(1, args.cycles + 1):
            r = c.post("/databases", json={"samples": args.samples, "chunk_size": 1000,
                       "seed": 1000 + k}, headers=AUTH)  # fmt: skip
            job_id = r.json()["id"]
            while k % 2 == 0:  # every other build is cancelled while its pool computes chunks
                job = c.get(f"/jobs/{job_id}").json()
                if job["state"] not in ("queued", "running") or job["progress"] > 0:
                    break
                time.sleep(0.1)
            time.sleep(rng.uniform(0.0, 2.0))
            for p in psutil.Process(proc.pid).children(recursive=True):
                seen.setdefault(p.pid, p)
            job = c.post(f"/jobs/{job_id}/cancel", headers=AUTH).json()
            while job["state"] in ("queued", "running"):
                time.sleep(0.1)
                job = c.get(f"/jobs/{job_id}").json()
            states[job["state"]] = states.get(job["state"], 0) + 1
            if k % args.every == 0 or k == args.cycles:
                time.sleep(1.0)
                kids, rss = tree(proc.pid)
                dbs = c.get("/databases").json()
                unfinished = sum(d["state"] != "complete" for d in dbs)
                reach = folder_bytes(folder / "reach") if (folder / "reach").exists() else 0
                print(f"after {k} cycles ({time.perf_counter() - t0:.0f} s): {len(kids)} "
                      f"processes besides the service, {rss:.0f} MB; {len(dbs)} databases "
                      f"({unfinished} unfinished), reach/ {reach / 1e6:.1f} MB; jobs {states}",
                      flush=True)  # fmt: skip
    for p in psutil.Process(proc.pid).children(recursive=True):
        seen.setdefault(p.pid, p)
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=60)
    log.close()
    for wait in (1.0, 9.0):
        time.sleep(wait)
        left = [p for p in seen.values() if _running(p)]
        print(f"{wait if wait == 1.0 else 10.0:.0f} s after the service stopped: {len(left)} of "
              f"the {len(seen)} processes it started still alive "
              f"{[' '.join(p.cmdline())[-50:] for p in left]}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
