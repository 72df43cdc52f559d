"""The headless way: plan every scene of a folder in Python, locally or on Dask.

python examples/batch_plan.py [FOLDER] [--dask local|tcp://host:8786] [--out plans/]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pickstop.settings import data_dir

HERE = Path(__file__).parent


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("folder", nargs="?", default=str(HERE / "scenes"))
    ap.add_argument("--dask", help="'local' or a scheduler address; default: this process")
    ap.add_argument("--out", default="plans")
    args = ap.parse_args()
    files = sorted(Path(args.folder).glob("*.json"))
    items = [(f.stem, json.loads(f.read_text()), f.parent) for f in files]
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    options = {"samples": 500}
    if args.dask:
        from pickstop.distributed import client_for, plan_batch

        client = client_for(args.dask)
        results = dict(plan_batch(client, items, options, data_dir(), None))
        client.close()
    else:
        from pickstop.distributed import plan_task

        results = {k: plan_task(doc, options, str(root), str(data_dir()), None)
                   for k, (_, doc, root) in enumerate(items)}  # fmt: skip
    for k, (name, _, _) in enumerate(items):
        res = results[k]
        if "error" in res:
            print(f"{name}: {res['error']}")
            continue
        (out / f"{name}.plan.json").write_text(json.dumps(res, indent=1))
        t = res["totals"]
        time_s, length = t["time"]["total"], t["route_length"]
        print(f"{name}: {t['stops']} stops, {time_s:.1f} s, route {length:.2f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
