"""Executed against expected time: each example's plans run by the simulated vehicle.

    python benchmarks/bench_execution.py [--runs N] [--db ID] [--scenes a,b]

For each example scene and each way of planning it (the paper's rule; the expected-time
objective; the expected-time objective with stops placed for success), plans with
``pickstop plan`` and runs the plan ``--runs`` times (200) with ``pickstop execute-sim``: the
simulated vehicle lands by the scene's error model, re-docks and calls an operator as the
scene's failure model says, and its clock is the plan's time model. Prints the executed mean
time per run (with its 95% interval, 1.96 sd / sqrt(runs)) beside the plan's predicted and
expected time, the executed plan success beside the predicted one, and the re-docks and
operator calls per run beside the failure model's expectation. An operator's call is rare and
dear (0.4% of the rack cell's runs, minutes each): a few hundred runs may see none, and their
mean time then falls short of the expected by that call's share. The commands run as a
user runs them (the same data folder, ``PICKSTOP_DATA_DIR``); run it alone.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENES = Path(__file__).parents[1] / "examples" / "scenes"
NAMES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]
WAYS = (
    ("paper's rule", []),
    ("expected time", ["--objective", "expected-time"]),
    ("expected, placed", ["--objective", "expected-time", "--placement", "success"]),
)


def _run(cmd: list[str]) -> None:
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr[-2000:]}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--db")
    ap.add_argument("--scenes", default=",".join(NAMES))
    args = ap.parse_args()
    db = ["--db", args.db] if args.db else []
    print(f"{'scene':17s} {'plan':17s} stops  predicted  expected  executed (95% interval)"
          f"   success predicted / executed   re-docks and operator calls per run, "
          f"expected / executed   [s to run]")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes.split(","):
            scene = str(SCENES / f"{name}.json")
            for label, extra in WAYS:
                plan, rep = Path(tmp, "plan.json"), Path(tmp, "rep.json")
                _run(["pickstop", "plan", scene, "--out", str(plan), *db, *extra])
                t0 = time.perf_counter()
                _run(["pickstop", "execute-sim", str(plan), "--scene", scene, "--runs",
                      str(args.runs), "--out", str(rep), *db])  # fmt: skip
                took = time.perf_counter() - t0
                r = json.loads(rep.read_text())
                p = json.loads(plan.read_text())
                t = r["time"]
                half = 1.96 * t["executed_sd"] / math.sqrt(r["runs"])
                ok, rec = r["plan"], r["recovery"] or {}
                print(f"{name:17s} {label:17s} {len(p['stops']):5d}  {t['predicted']:8.1f}  "
                      f"{t['expected']:8.1f}  {t['executed_mean']:8.1f} "
                      f"({t['executed_mean'] - half:6.1f} to {t['executed_mean'] + half:6.1f})"
                      f"   {ok['predicted']:7.1%} / {ok['executed']:6.1%}   re-docks "
                      f"{rec.get('retries_expected') or 0:.3f} / {rec.get('retries_mean', 0):.3f}"
                      f"  operator {rec.get('operator_calls_expected') or 0:.4f} / "
                      f"{rec.get('operator_calls_mean', 0):.4f}   [{took:5.1f}]")  # fmt: skip


if __name__ == "__main__":
    main()
