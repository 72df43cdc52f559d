"""``pickstop errors fit``: error models learned from an arrival log, written as a model file
or into a scene, and what a re-plan with them changes. A thin edge over
:mod:`pickstop.fleet.fit`; bad input raises :class:`InputError` (exit 2)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import yaml

from pickstop.errors import InputError
from pickstop.fleet import fit as ft
from pickstop.fleet.arrivals import read_log


def _mm(x: float) -> str:
    return f"{1000 * x:6.1f}"


def table(fits: list[ft.StationFit], notes: list[str]) -> str:
    """The fits as text: offsets and spreads in mm, angles in degrees, 95% half-widths."""
    lines = [
        f"{'station':24} {'n':>5} {'mean x':>7} {'±':>5} {'mean y':>7} {'±':>5} "
        f"{'sd major':>8} {'minor':>6} {'axis':>6} {'yaw mean':>8} {'yaw sd':>7} {'picks':>6}",
        f"{'':24} {'':>5} {'[mm]':>7} {'':>5} {'[mm]':>7} {'':>5} {'[mm]':>8} {'[mm]':>6} "
        f"{'[deg]':>6} {'[deg]':>8} {'[deg]':>7} {'ok':>6}",
    ]
    for f in fits:
        (x0, x1), (y0, y1) = f.mean_interval
        lines.append(
            f"{f.name[:24]:24} {f.arrivals:5d} {_mm(f.mean[0]):>7} {_mm((x1 - x0) / 2):>5} "
            f"{_mm(f.mean[1]):>7} {_mm((y1 - y0) / 2):>5} {_mm(f.axes[0]):>8} "
            f"{_mm(f.axes[1]):>6} {math.degrees(f.axes[2]):6.1f} "
            f"{math.degrees(f.yaw_mean):8.2f} {math.degrees(f.yaw_sigma):7.2f} "
            f"{f.picks.rate:6.1%}"
        )
    lines += [f"  {n}" for n in notes]
    return "\n".join(lines)


def _dump(path: str, doc: dict[str, Any]) -> None:
    p = Path(path)
    text = (
        yaml.safe_dump(doc, sort_keys=False, width=100)
        if p.suffix in (".yaml", ".yml")
        else json.dumps(doc, indent=1) + "\n"
    )
    tmp = p.with_name(f".{p.name}.tmp")
    tmp.write_text(text)
    tmp.replace(p)


def cmd_fit(args: argparse.Namespace) -> int:
    from pickstop.scene.load import load_scene, parse_scene
    from pickstop.scene.model import resolve_mesh_paths
    from pickstop.scene.positioning import of_scene

    if args.min_arrivals < 3:
        raise InputError("--min-arrivals: must be >= 3", field="min-arrivals")
    if args.write_scene and not args.scene:
        raise InputError("--write-scene needs --scene (the scene to write the fits into)",
                         field="scene")  # fmt: skip
    if args.replan and not args.write_scene:
        raise InputError("--replan needs --write-scene (the scene it plans with)", field="replan")
    arrivals = read_log(args.log)
    if not arrivals:
        raise InputError(f"log {args.log}: no arrivals", field="log")
    scene = load_scene(args.scene) if args.scene else None
    scene_doc = json.loads(Path(args.scene).read_text()) if args.scene else None
    fits, notes = ft.fit(arrivals, None if scene is None else of_scene(scene), args.frame)
    doc = ft.document(fits, notes, scene_doc, args.min_arrivals)
    print(table(fits, doc["fit"]["not_written"]))
    if args.out:
        _dump(args.out, doc)
    if args.write_scene:
        root = Path(args.scene).resolve().parent
        new = {**(scene_doc or {}), "error_model": doc["error_model"]}
        fitted = parse_scene(resolve_mesh_paths(new, root), f"--write-scene {args.write_scene}")
        _dump(args.write_scene, new)  # mesh paths as the scene gave them
        print(f"wrote {', '.join(doc['fit']['written']) or 'no station'} into "
              f"{args.write_scene}")  # fmt: skip
        if args.replan:
            print(replan(args, root, fitted))
    return 0


def replan(args: argparse.Namespace, root: Path, scene: Any) -> str:
    """The plan ``args.replan`` made again with the fitted ``scene``: what changed, per stop."""
    from pickstop.fleet.route import read_plan
    from pickstop.pool import PlannerPool
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.settings import data_dir

    old = read_plan(args.replan)
    p = old.parameters
    options = PlanOptions(sigma=p.sigma, rule=p.rule, target=p.target, objective=p.objective,
                          samples=p.samples, seed=p.seed)  # fmt: skip
    pool = PlannerPool(data_dir(args.data_dir))
    try:
        slot = pool.scene_slot(scene, root, args.db or old.database)
        new = slot.planner.plan(scene, options)
    finally:
        pool.close()
    return compare(old, new)


def compare(old: Any, new: Any) -> str:
    """Two plans of one layout, stop by stop (matched by the trays they serve)."""

    def pct(s: Any) -> str:
        return "     -" if s is None else f"{s.rate:6.1%}"

    lines = [f"re-plan: {len(old.stops)} -> {len(new.stops)} stops, predicted time "
             f"{old.totals.time.total:.1f} -> {new.totals.time.total:.1f} s, plan success "
             f"{_p(old.totals.success)} -> {_p(new.totals.success)}"]  # fmt: skip
    before = {tuple(s.trays): s for s in old.stops}
    for s in new.stops:
        o = before.pop(tuple(s.trays), None)
        moved = "" if o is None else f", moved {math.dist((o.x, o.y), (s.x, s.y)):.3f} m"
        was = "new stop" if o is None else f"{pct(o.success)} ->"
        lines.append(f"  trays {'+'.join(s.trays)}: {was} {pct(s.success)}"
                     f" (model {s.error_model or 'global'}){moved}")  # fmt: skip
    lines += [f"  trays {'+'.join(t)}: no longer a stop" for t in before]
    return "\n".join(lines)


def _p(x: float | None) -> str:
    return "-" if x is None else f"{x:.1%}"


def add_parser(sub: Any) -> None:
    """Add the errors command (``errors fit``) to ``sub``."""
    er = sub.add_parser("errors", help="positioning error models learned from arrival logs")
    esub = er.add_subparsers(dest="errors_command", required=True)
    f = esub.add_parser("fit", help="fit per-station error models to an arrival log")
    f.add_argument("log", help="arrival log (JSON lines, from dispatch or execute-sim --record)")
    f.add_argument("--scene", help="group arrivals by this scene's stations (default: by the "
                   "trays picked at each stop)")  # fmt: skip
    f.add_argument("--out", help="write the fitted model file here (.json or .yaml)")
    f.add_argument(
        "--frame",
        choices=["base", "map"],
        default="base",
        help="offsets along the planned heading (base, default) or the map axes",
    )
    f.add_argument(
        "--min-arrivals",
        type=int,
        default=ft.MIN_ARRIVALS,
        help="a station's fit is written only if it rests on this many arrivals",
    )
    f.add_argument("--write-scene", help="write --scene with the fitted models in it here")
    f.add_argument("--replan", help="a plan of --scene: plan again with the fitted scene and "
                   "show what changed")  # fmt: skip
    f.add_argument("--db", help="database for --replan (default: the plan's)")
    f.set_defaults(func=cmd_fit)
