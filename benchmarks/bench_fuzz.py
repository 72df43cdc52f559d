"""schemathesis with every check against a running service, for a fixed time: cases, server
errors, contract failures, and how fast ``/health`` answers meanwhile.

    python benchmarks/bench_fuzz.py [--minutes 20] [--data-dir DIR] [--samples N]

Starts ``pickstop serve`` on 127.0.0.1 over a copy of a data folder (default: a fresh one with
a small TIAGo database built first), runs ``st run --checks all --max-time`` over its OpenAPI
document with the statuses the document's prose allows (the same as
``tests/api/test_live.py``: 422 for a schema-valid scene the planner refuses, 412 for a made-up
If-Match, 428 for a missing one, 413 for a batch over the limit), while a second client polls
``/health`` every 50 ms. Prints the cases sent, the responses by status class, every failed
check with its count, the health latency (p50, p99, max) and the service's processes after
it stops.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
import psutil

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

KEY = "bench-key"
AUTH = {"Authorization": f"Bearer {KEY}"}
ROOT = Path(__file__).resolve().parents[1]
CONFIG = """
[checks.positive_data_acceptance]
expected-statuses = ["2xx", "3xx", "401", "403", "404", "409", "429", "5xx", "412", "422",
                     "428"]

[checks.missing_required_header]
expected-statuses = ["400", "401", "403", "406", "415", "422", "428"]

[checks.negative_data_rejection]
expected-statuses = ["400", "401", "403", "404", "405", "406", "409", "413", "415", "422",
                     "428", "429", "5xx"]
"""


def data_folder(args: argparse.Namespace) -> Path:
    """A scratch copy of ``--data-dir`` (fuzzed builds and deletes must not touch it), or a
    fresh folder with a small TIAGo database."""
    folder = Path(tempfile.mkdtemp(prefix="pickstop-fuzz-"))
    if args.data_dir:
        shutil.copytree(args.data_dir, folder, dirs_exist_ok=True)
        return folder
    from pickstop.reach.build import BuildParams
    from pickstop.robot.model import load
    from pickstop.store.reach_build import build

    print(f"building a {args.samples:,}-sample TIAGo database in {folder} ...", flush=True)
    build(load("tiago"), BuildParams(samples=args.samples), folder, workers=2)
    return folder


def known_ids(url: str) -> str:
    """Parameters that name things that exist: a stored scene of the paper-like example, a
    plan of it, the default database, the robot and one of its files, so that the fuzzer also
    reaches the operations behind them (exports, reports, guidance) with ids that resolve."""
    scene = json.loads((ROOT / "examples" / "scenes" / "paper_experiment.json").read_text())
    with httpx.Client(base_url=f"{url}/api/v1", headers=AUTH, timeout=300) as c:
        sid = c.post("/scenes", json=scene).raise_for_status().json()["id"]
        body = {"scene_id": sid, "options": {"samples": 200}}
        pid = c.post("/plans", json=body).raise_for_status().json()["id"]
        db = c.get("/databases").raise_for_status().json()[0]["id"]
        model = c.get("/robots/tiago/model").raise_for_status().json()
    file_id = next(iter(model.get("files") or {"": None}), "")
    ids = {"path.scene_id": sid, "path.plan_id": pid, "path.db_id": db, "path.name": "tiago",
           "path.file_id": file_id, "query.scene_id": sid}  # fmt: skip
    return "\n[parameters]\n" + "".join(f'"{k}" = "{v}"\n' for k, v in ids.items() if v)


def poll_health(
    url: str, stop: threading.Event, lat: list[float], bad: list[str], slow: list[tuple]
) -> None:
    """Poll ``/health`` every 50 ms: latencies into ``lat``, non-200 answers into ``bad``,
    (start, seconds) of polls over 100 ms into ``slow``."""
    with httpx.Client(base_url=url, timeout=30) as h:
        while not stop.is_set():
            start = time.time()
            t0 = time.perf_counter()
            try:
                r = h.get("/api/v1/health")
                if r.status_code != 200:
                    bad.append(str(r.status_code))
            except httpx.HTTPError as e:
                bad.append(type(e).__name__)
            lat.append(time.perf_counter() - t0)
            if lat[-1] > 0.1:
                slow.append((start, lat[-1]))
            time.sleep(0.05)


def in_flight(path: Path, slow: list[tuple]) -> list[str]:
    """For each slow poll, the fuzzer's requests in flight while it waited (from the run's
    ndjson events): method, path and their own time."""
    spans = []
    for line in path.read_text().splitlines():
        scenario = json.loads(line).get("ScenarioFinished")
        for it in ((scenario or {}).get("recorder") or {}).get("interactions", {}).values():
            if it.get("timestamp") and it.get("response"):
                end = it["timestamp"] + (it["response"].get("elapsed") or 0.0)
                what = f"{it['request']['method']} {it['request']['uri'].split('/api/v1')[-1]}"
                spans.append((it["timestamp"], end, what[:100]))
    out = []
    for start, took in slow:
        hits = [f"{w} ({e - s:.2f} s)" for s, e, w in spans if s < start + took and e > start]
        when = time.strftime("%H:%M:%S", time.localtime(start)) + f"{start % 1:.3f}"[1:]
        out.append(f"  {when} {took * 1e3:.0f} ms: " + ("; ".join(hits[:3])
                                                        or "no fuzzed request"))  # fmt: skip
    return out


def read_events(path: Path) -> tuple[int, collections.Counter, collections.Counter]:
    """(cases, responses by status class, failures by code, title and operation) from the
    run's ndjson events."""
    cases, statuses, failures = 0, collections.Counter(), collections.Counter()
    for line in path.read_text().splitlines():
        event = json.loads(line)
        scenario = event.get("ScenarioFinished")
        if not scenario:
            continue
        recorder = scenario.get("recorder") or {}
        cases += len(recorder.get("cases", {}))
        for checks in recorder.get("checks", {}).values():
            for check in checks:
                if check.get("status") == "failure":
                    failure = check["failure_info"]["failure"]
                    failures[f"{failure['code']} {failure['title']} ({failure['operation']})"] += 1
        for interactions in recorder.get("interactions", {}).values():
            response = interactions.get("response") or {}
            code = response.get("status_code")
            if code:
                statuses[f"{code // 100}xx"] += 1
                if code >= 500:
                    statuses[str(code)] += 1
    return cases, statuses, failures


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--data-dir", help="data folder with a TIAGo database, copied first")
    ap.add_argument("--samples", type=int, default=200_000, help="samples of a fresh build")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--known-ids", action="store_true",
                    help="path ids of a stored scene, plan, database and robot file")  # fmt: skip
    ap.add_argument("--max-examples", type=int, default=100_000, help="per operation and phase")
    args = ap.parse_args()
    folder = data_folder(args)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(folder),
           "PICKSTOP_API_KEYS": json.dumps([hash_key(KEY)])}  # fmt: skip
    log = (folder / "fuzz-serve.log").open("w")
    proc = spawn_api(port, env, log)
    url = f"http://127.0.0.1:{port}"
    (folder / "schemathesis.toml").write_text(CONFIG + (known_ids(url) if args.known_ids else ""))
    service = psutil.Process(proc.pid)
    events = folder / "events.ndjson"
    stop, lat, bad, slow = threading.Event(), [], [], []
    poller = threading.Thread(target=poll_health, args=(url, stop, lat, bad, slow))
    poller.start()
    t0 = time.monotonic()
    try:
        run = subprocess.run(
            ["st", "--config-file", str(folder / "schemathesis.toml"), "run",
             f"{url}/api/v1/openapi.json", "--checks", "all", "--max-time",
             str(int(args.minutes * 60)), "--continue-on-failure", "--seed", str(args.seed),
             "--max-examples", str(args.max_examples),
             "-H", f"Authorization: Bearer {KEY}", "--request-timeout", "120",
             "--report", "ndjson", "--report-ndjson-path", str(events)],
            capture_output=True, text=True, cwd=folder,
        )  # fmt: skip
        elapsed = time.monotonic() - t0
    finally:
        stop.set()
        poller.join()
        kids = service.children(recursive=True)
        peak = len(kids)
        proc.terminate()
        proc.wait(timeout=60)
        log.close()
    time.sleep(1.0)
    left = [p.pid for p in kids if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    (folder / "st-output.txt").write_text(run.stdout + run.stderr)
    cases, statuses, failures = read_events(events)
    lat.sort()
    pct = {q: lat[min(len(lat) - 1, int(len(lat) * q))] * 1e3 for q in (0.5, 0.99)}
    print(f"schemathesis {elapsed / 60:.1f} min, exit {run.returncode}: {cases:,} cases")
    print("responses: " + ", ".join(f"{k} {v:,}" for k, v in sorted(statuses.items())))
    print("failed checks: " + (", ".join(f"{k} {v}" for k, v in failures.most_common())
                               or "none"))  # fmt: skip
    print(f"/health: {len(lat):,} polls, p50 {pct[0.5]:.1f} ms, p99 {pct[0.99]:.1f} ms, "
          f"max {lat[-1] * 1e3:.1f} ms, over 100 ms: {len(slow)}, not 200: {len(bad)}")  # fmt: skip
    print("\n".join(in_flight(events, slow)))
    print(f"service processes: {peak} children at the end, {len(left)} alive 1 s after stop")
    print(f"output and events: {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
