"""Opening the reachability database: whole-process `pickstop regions`, open time, memory.

    python benchmarks/bench_open.py --data-dir /path/to/data [--scene SCENE] [--procs 4]

Runs the code on ``PYTHONPATH`` (so the same script measures any tree). Prints one figure a
line:

- ``regions_process_s``: wall time of a whole ``pickstop regions SCENE`` process (median of
  ``--repeat``), with a warm page cache, and once cold: the database files are evicted from the
  page cache first (``posix_fadvise(DONTNEED)``; dropping every cache needs a privilege this
  machine may not grant, so Python and its libraries stay warm);
- the in-process breakdown of one warm run: import, robot, ``open_database``, region planner
  construction, the regions themselves;
- resident memory of one planner process and of ``--procs`` concurrent ones: the peak RSS and
  PSS (``/proc/PID/smaps_rollup``) of each process tree, polled every 20 ms. PSS counts a page
  mapped by k processes as 1/k in each, so the sum of PSS is what the processes cost together.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

BREAKDOWN = r"""
import json, os, sys, time
t0 = time.perf_counter()
from pathlib import Path
from pickstop.store.reach_catalog import open_database
from pickstop.speedups.region_planner import RegionPlanner
from pickstop.robot.model import load_robot
from pickstop.robot.config import resolve_robot
from pickstop.scene.load import load_scene
from pickstop.settings import cache_dir
t1 = time.perf_counter()
scene = load_scene(sys.argv[1])
config, root = resolve_robot(scene.robot.ref)
robot = load_robot(config, root)
t2 = time.perf_counter()
data = Path(sys.argv[2])
db = open_database(data, robot)
t3 = time.perf_counter()
planner = RegionPlanner(robot, db, cache_dir=cache_dir(data))
t4 = time.perf_counter()
planner.regions(scene, workers=1)
t5 = time.perf_counter()
mapped = resident = 0  # the database's mapped files: their size, and what of them is resident
inside = False
with open("/proc/self/smaps") as f:
    for line in f:
        parts = line.split()
        if "-" in parts[0] and len(parts) >= 5:
            inside = line.rstrip().endswith(".npy")
        elif inside and parts[0] == "Size:":
            mapped += int(parts[1])
        elif inside and parts[0] == "Rss:":
            resident += int(parts[1])
print(json.dumps({"import_s": t1 - t0, "robot_s": t2 - t1, "open_s": t3 - t2,
                  "planner_s": t4 - t3, "regions_s": t5 - t4, "rows": len(db),
                  "mapped_mb": mapped / 1024, "mapped_resident_mb": resident / 1024}))
"""


def _db_files(data_dir: Path) -> list[Path]:
    return [p for p in (data_dir / "reach").rglob("*") if p.is_file()]


def evict(data_dir: Path) -> None:
    """Drop the database files' pages from the page cache (clean pages only: no privilege)."""
    for p in _db_files(data_dir):
        fd = os.open(p, os.O_RDONLY)
        try:
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)


def _tree(pid: int) -> list[int]:
    out = [pid]
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                for c in f.read().split():
                    out += _tree(int(c))
    except OSError:
        pass
    return out


def _rollup(pid: int) -> tuple[int, int]:
    """(Rss, Pss) of one process [kB]; (0, 0) once it is gone."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            text = f.read()
    except OSError:
        return 0, 0
    vals = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] in ("Rss:", "Pss:"):
            vals[parts[0]] = int(parts[1])
    return vals.get("Rss:", 0), vals.get("Pss:", 0)


def run_processes(cmds: list[list[str]], env: dict[str, str]) -> list[dict[str, float]]:
    """Run ``cmds`` at once; per process: wall time, CPU time (user + system, its reaped
    children included) [s] and the peak RSS / PSS of its tree [MB]."""
    t0 = time.perf_counter()
    procs = [
        subprocess.Popen(c, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        for c in cmds
    ]
    peak = [{"rss": 0, "pss": 0, "main_rss": 0, "main_pss": 0} for _ in procs]
    ends: list[float | None] = [None] * len(procs)
    cpu = [0.0] * len(procs)
    codes = [0] * len(procs)
    while any(e is None for e in ends):
        for i, p in enumerate(procs):
            if ends[i] is not None:
                continue
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                ends[i] = time.perf_counter() - t0
                cpu[i] = usage.ru_utime + usage.ru_stime
                codes[i] = os.waitstatus_to_exitcode(status)
                continue
            tree = _tree(p.pid)
            figs = [_rollup(q) for q in tree]
            peak[i]["rss"] = max(peak[i]["rss"], sum(f[0] for f in figs))
            peak[i]["pss"] = max(peak[i]["pss"], sum(f[1] for f in figs))
            peak[i]["main_rss"] = max(peak[i]["main_rss"], figs[0][0])
            peak[i]["main_pss"] = max(peak[i]["main_pss"], figs[0][1])
        time.sleep(0.02)
    out = []
    for i, p in enumerate(procs):
        err = p.stderr.read().decode() if p.stderr else ""
        p.returncode = codes[i]
        if codes[i] != 0:
            raise SystemExit(f"{cmds[i]} failed ({codes[i]}):\n{err[-2000:]}")
        out.append({"wall_s": ends[i] or 0.0, "cpu_s": cpu[i],
                    **{k: v / 1024 for k, v in peak[i].items()}})  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data-dir", type=Path, required=True)
    ap.add_argument("--scene", type=Path, default=ROOT / "examples/scenes/paper_experiment.json")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--procs", type=int, default=4)
    args = ap.parse_args()

    env = dict(os.environ, PICKSTOP_DATA_DIR=str(args.data_dir), OPENBLAS_NUM_THREADS="1")
    regions = [sys.executable, "-m", "pickstop.cli", "regions", str(args.scene)]
    print(f"pythonpath: {env.get('PYTHONPATH', '(installed package)')}")
    disk = sum(p.stat().st_size for p in _db_files(args.data_dir))
    print(f"database_files_mb: {disk / 1e6:.1f}")

    run_processes([regions], env)  # warm the page cache
    warm = [run_processes([regions], env)[0] for _ in range(args.repeat)]
    walls = [round(w["wall_s"], 2) for w in warm]
    cpus = [round(w["cpu_s"], 2) for w in warm]
    print(f"load_average: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"regions_process_warm_s: {statistics.median(walls):.2f} wall (runs {walls}), "
          f"{statistics.median(cpus):.2f} CPU user+sys with its workers (runs {cpus})")  # fmt: skip
    one = warm[-1]
    print(
        f"one_process_peak_mb: main RSS {one['main_rss']:.0f} PSS {one['main_pss']:.0f}; "
        f"with its region workers RSS {one['rss']:.0f} PSS {one['pss']:.0f}"
    )
    evict(args.data_dir)
    cold = run_processes([regions], env)[0]
    print(f"regions_process_cold_db_s: {cold['wall_s']:.2f} wall, {cold['cpu_s']:.2f} CPU "
          "(database files evicted)")  # fmt: skip

    many = run_processes([regions] * args.procs, env)
    print(
        f"{args.procs}_concurrent_wall_s: {max(m['wall_s'] for m in many):.2f} "
        f"(CPU {sum(m['cpu_s'] for m in many):.1f} s in all); per process "
        f"main RSS {[round(m['main_rss']) for m in many]} MB, "
        f"main PSS {[round(m['main_pss']) for m in many]} MB; "
        f"sum of tree PSS {sum(m['pss'] for m in many):.0f} MB"
    )

    breakdown = [sys.executable, "-c", BREAKDOWN, str(args.scene), str(args.data_dir)]
    figs = []
    for _ in range(args.repeat):
        res = subprocess.run(breakdown, env=env, capture_output=True, text=True, check=True)
        figs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    for k in ("import_s", "robot_s", "open_s", "planner_s", "regions_s"):
        vals = [f[k] for f in figs]
        print(f"warm_{k}: {statistics.median(vals):.3f} (runs {[round(v, 3) for v in vals]})")
    evict(args.data_dir)
    res = subprocess.run(breakdown, env=env, capture_output=True, text=True, check=True)
    f = json.loads(res.stdout.strip().splitlines()[-1])
    print(f"cold_db_open_s: {f['open_s']:.3f}; cold_db_planner_s: {f['planner_s']:.3f}; "
          f"cold_db_regions_s: {f['regions_s']:.3f}")  # fmt: skip
    print(f"rows: {f['rows']}")
    if f.get("mapped_mb"):
        print(f"index_mapped_mb: {f['mapped_mb']:.0f}, of which resident after the regions "
              f"(cold): {f['mapped_resident_mb']:.0f}")  # fmt: skip


if __name__ == "__main__":
    main()
