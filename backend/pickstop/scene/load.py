"""Reading a scene: a decoded document or a file -> a validated :class:`Scene`.

The shape is checked by pydantic (:mod:`pickstop.scene.model`), then the geometry by
:func:`pickstop.scene.checks.check_scene`; every problem is reported with its field path.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from pickstop.errors import InputError
from pickstop.scene.checks import check_scene
from pickstop.scene.model import FORMAT, VERSION, Scene, SceneError, resolve_mesh_paths


def parse_scene(
    data: Any,
    source: str = "scene",
    check: Callable[[Scene], list[tuple[str, str]]] = check_scene,
) -> Scene:
    """Validate a decoded scene document (shape by pydantic, then the geometry checks;
    ``check``: those checks, e.g. a :class:`~pickstop.scene.checks.CheckedScenes`)."""
    if isinstance(data, dict) and data.get("format", FORMAT) != FORMAT:
        raise SceneError([("format", f"expected {FORMAT!r}, got {data.get('format')!r}")], source)
    if isinstance(data, dict) and data.get("version", VERSION) != VERSION:
        raise SceneError(
            [("version", f"this PickStop reads version {VERSION}, got {data.get('version')!r}")],
            source,
        )
    try:
        scene = Scene.model_validate(data)
    except ValidationError as e:
        problems = [
            (".".join(str(p) for p in err["loc"]) or "(root)", err["msg"]) for err in e.errors()
        ]
        raise SceneError(problems, source) from None
    problems = check(scene)
    if problems:
        raise SceneError(problems, source)
    return scene


def load_scene(path: str | Path) -> Scene:
    """A scene file; its relative mesh paths start at the file's folder."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: scene file not found", field="scene")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not valid JSON: {e}", field="scene") from None
    data = resolve_mesh_paths(data, path.resolve().parent, source=str(path))
    return parse_scene(data, str(path))
