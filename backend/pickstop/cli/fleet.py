"""The fleet commands of ``pickstop``: export, dispatch, sim-vehicle, execute-sim.

Each is a thin edge over :mod:`pickstop.fleet`; bad input raises :class:`InputError` (exit 2).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pickstop.argtypes import finite_float
from pickstop.errors import InputError
from pickstop.fleet import mqtt
from pickstop.fleet import order as orders
from pickstop.fleet.route import read_plan
from pickstop.sequence import plan_model as pm

NO_RETRIES = (
    "a stop whose landing misses fails its picks at once (default: it re-docks and calls an "
    "operator as the scene's failure model says)"
)


def _scene(path: str | None, plan: pm.Plan | None = None) -> Any:
    if path is None:
        return None
    from pickstop.scene.load import load_scene
    from pickstop.sequence.request import scene_hash

    scene = load_scene(path)
    if plan is not None and scene_hash(scene) != plan.scene_hash:
        raise InputError(
            f"--scene {path}: not the scene this plan was made for (its hash differs from the "
            "plan's scene_hash)",
            field="scene",
        )
    return scene


def _yaw_tolerance(args: argparse.Namespace, plan: pm.Plan, scene: Any) -> Any:
    """``--yaw-tolerance``, or with ``--verify-yaw`` each stop's, checked exactly."""
    if not getattr(args, "verify_yaw", False):
        return args.yaw_tolerance
    if scene is None:
        raise InputError("--verify-yaw needs --scene (the plan's scene file)", field="scene")
    from pickstop.fleet.yaw import verified_yaw_tolerances

    return verified_yaw_tolerances(_plan_checker(args, plan, scene), plan)


def _plan_checker(args: argparse.Namespace, plan: pm.Plan, scene: Any) -> Any:
    """The plan scene's exact checker, made once per command."""
    if getattr(args, "_check", None) is None:
        args._check = _checker(args.scene, scene, args, args.db or plan.database)
    return args._check


def _shapes(args: argparse.Namespace, plan: pm.Plan, scene: Any) -> Any:
    """With ``--verify-xy``, each stop's circle and ellipse checked off the grid."""
    if not getattr(args, "verify_xy", False):
        return None
    if scene is None:
        raise InputError("--verify-xy needs --scene (the plan's scene file)", field="scene")
    return _plan_checker(args, plan, scene).shapes(plan)


def _vehicle_types(args: argparse.Namespace) -> Any:
    from pickstop.fleet.vehicle_types import VehicleTypes, load_vehicle_types

    path = getattr(args, "vehicle_types", None)
    return VehicleTypes() if path is None else load_vehicle_types(path)


def _order_options(
    args: argparse.Namespace, scene: Any, plan: pm.Plan | None = None
) -> orders.OrderOptions:
    return orders.OrderOptions(
        version=orders.version_of(args.vda_version),
        manufacturer=mqtt.check_level("manufacturer", args.manufacturer),
        serial_number=mqtt.check_level("serial", args.serial),
        map_id=args.map_id,
        order_id=args.order_id,
        release_stops=args.release_stops,
        start_yaw=None if scene is None else scene.start.yaw,
        goal_yaw=None if scene is None else scene.goal.yaw,
        yaw_tolerance=args.yaw_tolerance if plan is None else _yaw_tolerance(args, plan, scene),
        shapes=None if plan is None else _shapes(args, plan, scene),
    )


def _write(out: str | None, text: str) -> None:
    if out is None:
        sys.stdout.write(text)
        return
    path = Path(out)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)


def cmd_export(args: argparse.Namespace) -> int:
    from pickstop.fleet import nav2
    from pickstop.fleet import vda5050 as v

    plan = read_plan(args.plan)
    scene = _scene(args.scene, plan)
    if args.format == "lif":
        text = json.dumps(_lif(args, plan, scene), indent=1) + "\n"
    elif args.format == "vda5050":
        vt = _vehicle_types(args).select(args.manufacturer, args.serial, None, args.vehicle_type)
        opts = _order_options(args, scene, plan)
        if vt is not None:
            opts = replace(opts, pick=vt.pick)
        order = orders.build_order(plan, opts)
        text = json.dumps(v.dump(order), indent=1) + "\n"
    else:
        yaml_out = (args.out or "").endswith((".yaml", ".yml"))
        fmt: Literal["json", "yaml"] = "yaml" if (args.nav2_format or "") == "yaml" else "json"
        if args.nav2_format is None and yaml_out:
            fmt = "yaml"
        doc = nav2.build_nav2(
            plan,
            frame_id=args.map_id or "map",
            distro=args.distro,
            start_yaw=None if scene is None else scene.start.yaw,
            goal_yaw=None if scene is None else scene.goal.yaw,
            yaw_tolerance=_yaw_tolerance(args, plan, scene),
            shapes=_shapes(args, plan, scene),
        )
        text = nav2.dumps(doc, fmt)
    _write(args.out, text)
    if args.out:
        print(json.dumps({"format": args.format, "out": args.out, "stops": len(plan.stops)}))
    return 0


def _lif(args: argparse.Namespace, plan: pm.Plan, scene: Any) -> dict[str, Any]:
    """The plan as a LIF layout; its vehicle type ``manufacturer.seriesName`` (or the type's
    name) from ``--vehicle-types``, else the manufacturer alone."""
    from pickstop.fleet.lif import LifOptions, build_lif

    man = mqtt.check_level("manufacturer", args.manufacturer)
    vt = _vehicle_types(args).select(man, args.serial, None, args.vehicle_type)
    type_id = man if vt is None else f"{vt.manufacturer or man}.{vt.series_name or vt.name}"
    opts = LifOptions(
        vehicle_type_id=type_id,
        layout_id=args.order_id,
        map_id=args.map_id or "map",
        start_yaw=None if scene is None else scene.start.yaw,
        goal_yaw=None if scene is None else scene.goal.yaw,
        shapes=_shapes(args, plan, scene),
        pick=None if vt is None else vt.pick,
    )
    return build_lif(plan, opts)


def cmd_dispatch(args: argparse.Namespace) -> int:
    from pickstop.fleet.arrivals import Recorder
    from pickstop.fleet.dispatch import Dispatcher, checked_order

    plan = read_plan(args.plan)
    scene = _scene(args.scene, plan)
    broker = mqtt.parse_broker(args.broker)
    opts = _order_options(args, scene, plan)
    types = _vehicle_types(args)
    mqtt.check_level("interface", args.interface)
    d = Dispatcher(broker, args.manufacturer, args.serial, opts.version, args.interface)
    d.start()
    try:
        order, vt = checked_order(
            d, lambda pick: orders.build_order(plan, replace(opts, pick=pick)), types,
            args.vehicle_type, not args.no_factsheet, args.wait,
        )  # fmt: skip
        record = None if args.record is None else Recorder(args.record)

        def progress(s: dict[str, Any]) -> None:
            if not args.quiet:
                print(
                    f"nodes {s['nodes_reached']}/{s['nodes']}, picks finished "
                    f"{s['actions_finished']}, failed {s['actions_failed']}",
                    file=sys.stderr,
                )

        summary = d.run(
            order, timeout=args.timeout, wait_vehicle=args.wait, progress=progress,
            record=record, pick=None if vt is None else vt.pick,
        )  # fmt: skip
    finally:
        d.stop()
    print(json.dumps(summary, indent=1))
    return 0 if summary["actions_failed"] == 0 else 4


def _checker(scene_path: str, scene: Any, args: argparse.Namespace, db: str | None) -> Any:
    from pickstop.fleet.pickcheck import exact_checker
    from pickstop.pool import PlannerPool
    from pickstop.settings import data_dir

    pool = PlannerPool(data_dir(args.data_dir))
    return exact_checker(pool, scene, db, scene_root=Path(scene_path).resolve().parent)


def _positioning(args: argparse.Namespace, scene: Any, sigma: float) -> Any:
    """``--error-model FILE``, else the scene's models with ``sigma`` [m]."""
    from pickstop.scene.error_file import load_error_file
    from pickstop.scene.positioning import of_scene

    if getattr(args, "error_model", None) is None:
        return of_scene(scene, sigma)
    return load_error_file(args.error_model).positioning(scene, sigma)


def _sim_body(vt: Any) -> Any:
    """The simulated vehicle's factsheet body, with the series its type names."""
    from pickstop.fleet.factsheet import Body

    return Body(series_name=vt.series_name) if vt.series_name else Body()


def cmd_sim_vehicle(args: argparse.Namespace) -> int:
    from pickstop.fleet.sim_node import VehicleNode
    from pickstop.fleet.vehicle import Motion, SimVehicle, error_model
    from pickstop.sequence.failure import FailureCosts

    if args.rate <= 0:
        raise InputError(f"--rate: must be > 0, got {args.rate}", field="rate")
    if args.time_scale < 0:
        raise InputError(f"--time-scale: must be >= 0, got {args.time_scale}", field="time-scale")
    if args.sigma is not None and not 0 <= args.sigma <= 1:
        raise InputError(f"--sigma: must be in [0, 1] m, got {args.sigma}", field="sigma")
    scene = _scene(args.scene)
    broker = mqtt.parse_broker(args.broker)
    mqtt.check_level("interface", args.interface)
    vt = _vehicle_types(args).select(args.manufacturer, args.serial, None, args.vehicle_type)
    m = scene.motion
    sigma = scene.sigma if args.sigma is None else args.sigma
    veh = SimVehicle(
        manufacturer=mqtt.check_level("manufacturer", args.manufacturer),
        serial_number=mqtt.check_level("serial", args.serial),
        motion=Motion(m.max_speed, m.max_acceleration, m.stop_time, m.pick_time),
        error=error_model(_positioning(args, scene, sigma)),
        check=_checker(args.scene, scene, args, args.db),
        rng=np.random.default_rng(args.seed),
        version=orders.version_of(args.vda_version),
        **({} if vt is None else {"pick": vt.pick, "body": _sim_body(vt)}),
        x=scene.start.x,
        y=scene.start.y,
        theta=scene.start.yaw,
        map_id=args.map_id or "map",
        failure=None if args.no_retries else FailureCosts.of(scene.failure),
    )
    node = VehicleNode(veh, broker, args.interface, args.rate, args.time_scale).start()
    print(json.dumps({"vehicle": node.topics, "broker": broker.url, "sigma": sigma}), flush=True)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        node.stop()
    return 0


def cmd_execute_sim(args: argparse.Namespace) -> int:
    from pickstop.fleet import execution
    from pickstop.fleet.arrivals import Recorder

    plan = read_plan(args.plan)
    scene = _scene(args.scene, plan)
    check = _checker(args.scene, scene, args, args.db or plan.database)
    broker = None if args.broker is None else mqtt.parse_broker(args.broker)
    if args.no_retries:
        plan = plan.model_copy(
            update={"parameters": plan.parameters.model_copy(update={"failure": None})}
        )
    pos = _positioning(args, scene, plan.parameters.sigma)
    record = None if args.record is None else Recorder(args.record)
    outcomes = execution.execute(
        plan, check, args.runs, args.seed, args.vda_version, broker, positioning=pos,
        record=record,
    )  # fmt: skip
    rep = execution.report(plan, outcomes)
    print(execution.table(rep))
    if args.out:
        _write(args.out, json.dumps(rep, indent=1) + "\n")
    return 0


def _vehicle_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--manufacturer", default="pickstop", help="VDA 5050 manufacturer")
    p.add_argument("--serial", default="sim-1", help="VDA 5050 serialNumber")
    p.add_argument("--interface", default=mqtt.INTERFACE, help="topic interface name")
    p.add_argument("--vda-version", default="2.1", help="2.0, 2.1 (default) or 3.0")
    p.add_argument("--map-id", help="mapId / frame id (default: map)")
    p.add_argument(
        "--vehicle-types", help="vehicle types file: each type's pick action and parameter names"
    )
    p.add_argument(
        "--vehicle-type",
        help="the vehicle's type in --vehicle-types (default: the first matching the vehicle)",
    )


def _order_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", help="the plan's scene file: start and goal yaw, checked by hash")
    p.add_argument("--order-id", help="default: derived from the plan")
    p.add_argument("--release-stops", type=int, help="release this many stops (default: all)")
    p.add_argument("--yaw-tolerance", type=finite_float, help="allowedDeviationTheta [rad]")
    p.add_argument(
        "--verify-yaw",
        action="store_true",
        help="each stop's yaw tolerance from exact checks at its centre (needs --scene)",
    )
    p.add_argument(
        "--verify-xy",
        action="store_true",
        help="each stop's tolerance circle and (VDA 5050 3.0) ellipse checked off the grid by "
        "exact tests (needs --scene)",
    )
    p.add_argument("--db", help="database for --verify-yaw/--verify-xy (default: the plan's)")


def add_parser(sub: Any) -> None:
    """Add the export, dispatch, sim-vehicle and execute-sim commands to ``sub``."""
    _add_export(sub)
    _add_dispatch(sub)
    _add_sim_vehicle(sub)
    _add_execute_sim(sub)


def _add_export(sub: Any) -> None:
    ex = sub.add_parser(
        "export", help="a plan as a VDA 5050 order, a Nav2 goal or a LIF layout (stations)"
    )
    ex.add_argument("plan", help="plan JSON (from pickstop plan)")
    ex.add_argument("--format", choices=["vda5050", "nav2", "lif"], required=True)
    ex.add_argument("--out", help="write here (default: stdout)")
    ex.add_argument("--nav2-format", choices=["json", "yaml"], help="default: by --out suffix")
    ex.add_argument("--distro", default="jazzy", choices=["humble", "jazzy", "kilted"])
    _vehicle_args(ex)
    _order_args(ex)
    ex.set_defaults(func=cmd_export)


def _add_dispatch(sub: Any) -> None:
    dp = sub.add_parser("dispatch", help="send a plan's order to a vehicle over MQTT, follow it")
    dp.add_argument("plan")
    dp.add_argument("--broker", required=True, help="mqtt://HOST:PORT")
    dp.add_argument(
        "--timeout", type=finite_float, default=600.0, help="[s] until the order is done"
    )
    dp.add_argument("--wait", type=finite_float, default=10.0, help="[s] for the vehicle to appear")
    dp.add_argument("--quiet", action="store_true")
    dp.add_argument("--record", help="append every arrival at a stop to this JSON-lines log")
    dp.add_argument(
        "--no-factsheet",
        action="store_true",
        help="send without reading the vehicle's factsheet (a vehicle older than VDA 5050 2.0)",
    )
    _vehicle_args(dp)
    _order_args(dp)
    dp.set_defaults(func=cmd_dispatch)


def _add_sim_vehicle(sub: Any) -> None:
    sv = sub.add_parser("sim-vehicle", help="a simulated VDA 5050 vehicle for a scene")
    sv.add_argument("--broker", required=True, help="mqtt://HOST:PORT")
    sv.add_argument("--scene", required=True, help="scene JSON file")
    sv.add_argument(
        "--sigma", type=finite_float, help="positioning error [m] (default: the scene's)"
    )
    sv.add_argument("--error-model", help="where it lands: an error model file (default: the "
                    "scene's models)")  # fmt: skip
    sv.add_argument("--rate", type=finite_float, default=1.0, help="state messages per second")
    sv.add_argument("--time-scale", type=finite_float, default=1.0, help="sim s per s; 0: at once")
    sv.add_argument("--seed", type=int, default=0)
    sv.add_argument("--db", help="reachability database id")
    sv.add_argument("--no-retries", action="store_true", help=NO_RETRIES)
    _vehicle_args(sv)
    sv.set_defaults(func=cmd_sim_vehicle)


def _add_execute_sim(sub: Any) -> None:
    es = sub.add_parser("execute-sim", help="run a plan N times on a simulated vehicle")
    es.add_argument("plan")
    es.add_argument("--scene", required=True, help="the plan's scene file")
    es.add_argument("--runs", type=int, default=200)
    es.add_argument("--seed", type=int, default=0)
    es.add_argument("--broker", help="mqtt://HOST:PORT (default: a local Mosquitto)")
    es.add_argument("--vda-version", default="2.1", help="2.0, 2.1 (default) or 3.0")
    es.add_argument("--db", help="reachability database id (default: the plan's)")
    es.add_argument("--out", help="write the report JSON here")
    es.add_argument("--record", help="append every arrival at a stop to this JSON-lines log")
    es.add_argument(
        "--error-model",
        help="where the vehicle lands: an error model file (default: the scene's models, "
        "the ones the plan predicts with)",
    )
    es.add_argument("--no-retries", action="store_true", help=NO_RETRIES)
    es.set_defaults(func=cmd_execute_sim)
