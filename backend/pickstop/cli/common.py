"""What several command groups share: JSON on stdout, atomic JSON files, the reach build's
progress bar, the plan options and the planner pool a command plans with."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.errors import InputError


def emit(obj: Any) -> None:
    """``obj`` as indented JSON on stdout (numpy arrays and scalars, paths as plain JSON)."""
    json.dump(obj, sys.stdout, indent=2, default=json_default)
    sys.stdout.write("\n")


def json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.integer | np.floating):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)


def write_json(path: Path, doc: Any) -> None:
    """Write atomically: a reader never sees half a file, a failure leaves the old one."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=1, default=json_default) + "\n")
    tmp.replace(path)


class Progress:
    """tqdm bar over samples, with rate and ETA, on stderr."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.bar: Any = None
        self.closed = False

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or self.closed:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total,
                initial=done,
                unit="sample",
                unit_scale=True,
                file=sys.stderr,
                desc="reach build",
                smoothing=0.1,
            )
        else:
            self.bar.update(done - self.bar.n)
        if done >= total:  # what follows (indexing) draws its own line
            self.close()

    def close(self) -> None:
        if self.bar is not None and not self.closed:
            self.bar.close()
            self.closed = True


def plan_options(args: argparse.Namespace) -> Any:
    """The ``PlanOptions`` the flags give; a bad value raises ``InputError`` naming its flag."""
    from pydantic import ValidationError

    from pickstop.sequence.plan_model import PlanOptions

    fields = {
        "sigma": args.sigma,
        "rule": args.rule,
        "target": args.target,
        "objective": args.objective,
        "placement": getattr(args, "placement", None),
        "samples": args.samples,
        "seed": args.seed,
        "time_limit": args.time_limit,
    }
    try:
        return PlanOptions(**{k: v for k, v in fields.items() if v is not None})
    except ValidationError as e:
        err = e.errors()[0]
        name = str(err["loc"][0]).replace("_", "-")
        raise InputError(f"--{name}: {err['msg']}", field=name) from None


def planner_pool(args: argparse.Namespace) -> Any:
    """The planner pool of this command (scenes of one robot share its planners)."""
    from pickstop.pool import PlannerPool
    from pickstop.settings import data_dir

    return PlannerPool(data_dir(args.data_dir))
