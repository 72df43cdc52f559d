"""The MES way: store a scene over REST, plan it, fetch the stored plan later.

    PICKSTOP_KEY=... python examples/mes_client.py [--api http://127.0.0.1:8000] [SCENE.json]

Needs a running API (``pickstop serve``) whose PICKSTOP_API_KEYS holds the hash of the key.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import httpx

HERE = Path(__file__).parent


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default=str(HERE / "scenes" / "paper_experiment.json"))
    ap.add_argument("--api", default="http://127.0.0.1:8000")
    ap.add_argument("--sigma", type=float, default=0.10)
    args = ap.parse_args()
    key = os.environ.get("PICKSTOP_KEY")
    if not key:
        print("set PICKSTOP_KEY to an API key (pickstop api-key makes one)", file=sys.stderr)
        return 2
    auth = {"Authorization": f"Bearer {key}"}
    with httpx.Client(base_url=f"{args.api}/api/v1", headers=auth, timeout=300) as api:
        r = api.post("/scenes", json=json.loads(Path(args.scene).read_text()))
        if r.status_code != 201:
            print(f"scene refused: {r.json()['detail']}", file=sys.stderr)
            return 1
        scene_id = r.json()["id"]
        r = api.post("/plans", json={"scene_id": scene_id, "options": {"sigma": args.sigma}})
        if r.status_code != 201:
            print(f"no plan: {r.json()['detail']}", file=sys.stderr)
            return 1
        plan_id = r.json()["id"]
        plan = api.get(f"/plans/{plan_id}").json()["plan"]  # what the robot will run
    print(f"scene {scene_id}, plan {plan_id}: {plan['totals']['stops']} stops")
    for s in plan["stops"]:
        print(f"  stop {s['index'] + 1} at ({s['x']:.3f}, {s['y']:.3f}) yaw {s['yaw']:.3f}: "
              f"{', '.join(s['trays'])}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
