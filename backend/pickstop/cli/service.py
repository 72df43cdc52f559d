"""``pickstop serve``, ``pickstop ui`` and ``pickstop api-key``: the REST API, the 3D planner
as its client, and the keys that let a client write."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from pickstop.argtypes import positive_int, unit_fraction
from pickstop.cli.common import emit
from pickstop.errors import InputError, PickStopError


def cmd_serve(args: argparse.Namespace) -> int:
    """The REST API under uvicorn and, unless --no-ui, the 3D planner beside it."""
    from pickstop import stack
    from pickstop.settings import Settings

    overrides: dict[str, Any] = {}
    if args.data_dir:
        overrides["data_dir"] = Path(args.data_dir)
    for name in ("host", "port", "ui_port", "workers"):
        if getattr(args, name) is not None:
            overrides[name] = getattr(args, name)
    settings = Settings(**overrides)
    if not settings.api_keys:
        print("pickstop: no API keys configured (PICKSTOP_API_KEYS): the API refuses writes; "
              "make one with `pickstop api-key`", file=sys.stderr)  # fmt: skip
    if args.scene_file:
        from pickstop.scene.load import load_scene

        load_scene(args.scene_file)  # a bad file fails here, naming its field
    run = stack.start(
        settings,
        ui=not args.no_ui,
        scene_id=args.scene,
        scene_file=Path(args.scene_file) if args.scene_file else None,
        log_level=args.log_level,
    )
    print(f"PickStop API on {run.api_url}/api/v1 (docs: {run.api_url}/api/v1/docs)",
          file=sys.stderr, flush=True)  # fmt: skip
    if run.ui_url:
        print(f"PickStop 3D planner on {run.ui_url} (scene {run.scene_id})", file=sys.stderr,
              flush=True)  # fmt: skip
    run.wait()
    return 0


def cmd_ui(args: argparse.Namespace) -> int:
    """The 3D planner, a client of a running API."""
    from pickstop_ui.app import run
    from pickstop_ui.client import ApiProblem, PickStopClient

    key = args.key or os.environ.get("PICKSTOP_UI_KEY")
    scene_id = args.scene
    if args.scene_file:
        from pickstop.scene.load import load_scene

        load_scene(args.scene_file)  # a bad file fails here, with its field
        doc = json.loads(Path(args.scene_file).read_text(encoding="utf-8"))
        try:
            client = PickStopClient(args.api, key)
            if args.robot is not None:
                doc["robot"] = {"preset": _api_robot(client, args.robot)}
            scene_id = client.create_scene(doc).id
        except ApiProblem as e:
            raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    elif scene_id and args.robot is not None:  # a copy of the stored scene with that robot
        try:
            client = PickStopClient(args.api, key)
            doc = {
                **client.scene(scene_id).doc,
                "robot": {"preset": _api_robot(client, args.robot)},
            }
            scene_id = client.create_scene(doc).id
        except ApiProblem as e:
            raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    if not scene_id:
        raise InputError("give --scene SCENE_ID or --scene-file FILE", field="scene")
    try:
        app = run(args.api, scene_id, key, args.host, args.port, args.lighting == "flat",
                  args.draft_scale)  # fmt: skip
    except ApiProblem as e:
        raise PickStopError(f"{args.api}: {e.title}: {e.detail}") from None
    print(f"PickStop 3D planner on http://{args.host}:{app.port}/ (scene {scene_id})",
          file=sys.stderr, flush=True)  # fmt: skip
    try:
        while True:
            time.sleep(3600)
    finally:
        app.close()


def _api_robot(client: Any, robot: str) -> str:
    """The name the API knows the robot ``--robot`` names by: a preset or a registered
    robot's name as it is; a config file is registered first under its ``name`` (the API
    accepts it when its files lie in the API's ``<data>/robots/`` folder)."""
    from pickstop.robot.config import load_config, preset_names
    from pickstop_ui.client import API, ApiProblem

    path = Path(robot)
    if robot in preset_names() or not path.is_file():
        return robot  # a name: the API refuses one it does not know, listing those it does
    config, _ = load_config(path)  # a bad config fails here, naming its field
    r = client.http.get(f"{API}/robots")
    if r.status_code < 400 and config.name in {x.get("name") for x in r.json()}:
        return config.name
    yaml = path.suffix.lower() in {".yaml", ".yml"}
    r = client.http.post(
        f"{API}/robots",
        content=path.read_bytes(),
        headers={"Content-Type": "application/yaml" if yaml else "application/json"},
    )
    if r.status_code >= 400:
        body = r.json() if r.headers.get("content-type", "").endswith("json") else {}
        raise ApiProblem(r.status_code, body.get("title", "Error"), body.get("detail", r.text))
    return config.name


def cmd_api_key(args: argparse.Namespace) -> int:
    """A new random API key and the hash to configure (the service stores only hashes)."""
    import secrets

    from pickstop.settings import hash_key

    key = secrets.token_urlsafe(32)
    emit({"key": key, "hash": hash_key(key),
          "configure": f"PICKSTOP_API_KEYS='[\"{hash_key(key)}\"]'"})  # fmt: skip
    return 0


def add_parser(sub: Any) -> None:
    """Add the serve, ui and api-key commands to ``sub``."""
    sv = sub.add_parser("serve", help="run the REST API (uvicorn)")
    sv.add_argument("--host", help="listen address (default: $PICKSTOP_HOST or 127.0.0.1)")
    sv.add_argument("--port", type=positive_int, help="port (default: $PICKSTOP_PORT or 8000)")
    sv.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    sv.add_argument("--ui-port", type=positive_int, help="3D planner port (default 8080)")
    sv.add_argument("--no-ui", action="store_true", help="the API alone")
    sv.add_argument("--workers", type=positive_int,
                    help="API processes on the port (default: $PICKSTOP_WORKERS or 1)")  # fmt: skip
    sv.add_argument("--scene", help="scene the planner opens (default: the first stored one)")
    sv.add_argument("--scene-file", help="or a scene file, stored first")
    sv.set_defaults(func=cmd_serve)

    _add_ui(sub)

    ak = sub.add_parser("api-key", help="make a new API key and print its hash for the settings")
    ak.set_defaults(func=cmd_api_key)


def _add_ui(sub: Any) -> None:
    ui = sub.add_parser("ui", help="run the 3D planner against a running API")
    ui.add_argument("--api", default="http://127.0.0.1:8000", help="the API's base URL")
    ui.add_argument("--scene", help="id of a stored scene")
    ui.add_argument("--scene-file", help="or a scene file: stored through the API first")
    ui.add_argument("--key", help="API key for saving (default: $PICKSTOP_UI_KEY)")
    ui.add_argument("--host", default="127.0.0.1")
    ui.add_argument("--port", type=positive_int, default=8080)
    ui.add_argument(
        "--lighting",
        choices=("flat", "environment"),
        default="flat",
        help="flat: one hemisphere light (default; about twice the frame rate of the other in "
        "a browser without a GPU); environment: an environment map, shinier colours",
    )
    ui.add_argument(  # the default since --lighting; kept for scripts that still pass it
        "--flat-lighting", dest="lighting", action="store_const", const="flat",
        help=argparse.SUPPRESS,
    )  # fmt: skip
    ui.add_argument(
        "--draft-scale",
        type=unit_fraction,
        help="pixel ratio, as a fraction of the device's, at which a browser without a GPU "
        "draws the previews that follow a drag (default 0.35, about an eighth of the pixels; "
        "1: full resolution throughout)",
    )
    ui.add_argument(
        "--robot",
        help="plan with this robot instead of the scene's: a preset, a robot the API has "
        "registered, or a config file (registered with the API first; its files must lie in "
        "the API's <data>/robots/ folder); with --scene, a copy of the scene is stored",
    )
    ui.set_defaults(func=cmd_ui)
