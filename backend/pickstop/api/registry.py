"""The robots a service knows: the presets and the configs registered with it, each file of
which is confined to the allowed folders at every open.

Registered configs live in the service's records; their files (URDF, SRDF, meshes) must lie in
the data folder's ``robots/`` or in the example-robot-data share, symlinks resolved.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pickstop.api.body import type_errors
from pickstop.errors import ExistsError, InputError, RobotConfigError
from pickstop.pool import PlannerPool
from pickstop.robot.config import (
    RobotConfig,
    example_robot_data_share,
    parse_config,
    preset_names,
)
from pickstop.robot.model import RobotModel
from pickstop.store.records import ServiceStore


class RobotRegistry:
    """Presets and registered robots by name; their models come from the planner pool.

    ``assets`` and ``checks`` keep, per (name, config JSON), a robot's drawing assets and its
    check report; a config is never changed once registered and the key holds all of it, so
    an entry stays valid while the service runs.
    """

    def __init__(self, store: ServiceStore, data_dir: Path, planners: PlannerPool) -> None:
        self.store = store
        self.data_dir = Path(data_dir)
        self.planners = planners
        self.robot_dir = self.data_dir / "robots"
        self.robot_dir.mkdir(parents=True, exist_ok=True)
        self.assets: dict[tuple[str, str], Any] = {}
        self.checks: dict[tuple[str, str], dict[str, Any]] = {}

    def allowed_roots(self) -> list[Path]:
        return [self.robot_dir.resolve(), example_robot_data_share().resolve()]

    def config(self, name: str) -> tuple[RobotConfig, Path]:
        """A preset or a registered robot's config, by name, and the folder its paths start
        from."""
        if name in preset_names():
            return self.planners.configs.resolve(name)
        row = self.store.robot(name)
        if row is None:
            known = preset_names() + [r["name"] for r in self.store.robots()]
            raise InputError(
                f"unknown robot {name!r}; known: {', '.join(known)}", field="robot.preset"
            )
        config = parse_config(json.loads(row["config"]), f"robot {name}")
        self.confine(config)  # at every open: a file swapped for a symlink since is refused
        return config, self.robot_dir

    def exists(self, name: str) -> bool:
        """Whether ``name`` is a preset or a registered robot."""
        return name in preset_names() or self.store.robot(name) is not None

    def model(self, name: str) -> RobotModel:
        """The loaded robot ``name`` (from the planner pool: loaded once per config)."""
        return self.planners.robot(*self.config(name))

    def register(self, data: dict[str, Any]) -> RobotModel:
        """Validate a robot config whose files lie in the allowed folders, and keep it."""
        strict = type_errors(RobotConfig, data) if isinstance(data, dict) else []
        if strict:
            err = RobotConfigError("; ".join(f"{f}: {m}" for f, m in strict[:5]),
                                   field=strict[0][0])  # fmt: skip
            err.problems = strict  # type: ignore[attr-defined]
            raise err
        config = parse_config(data, "robot")
        if config.name in preset_names() or self.store.robot(config.name) is not None:
            raise ExistsError(f"robot {config.name!r} already exists", field="name")
        self.confine(config)
        robot = self.planners.robot(config, self.robot_dir)
        self.store.add_robot(config.name, config.model_dump(mode="json"))
        return robot

    def confine(self, config: RobotConfig) -> None:
        """Refuse any file of the config (URDF, SRDF, package dirs, and every mesh its URDF
        names, visual or collision) outside the allowed folders: relative paths start at the
        data folder's robots/ (a mesh's at its URDF's folder), package:// resolves only to
        allowed roots. Real paths are compared (symlinks resolved), and a file that is missing
        gets the same answer as one outside, so the answer tells nothing about the server."""
        pkg = []
        for i, d in enumerate(config.package_dirs):
            p = self._inside(self.robot_dir / d)
            if p is None:
                raise _refuse(f"package_dirs[{i}]", d, f"package_dirs.{i}")
            pkg.append(p)
        pkg.append(example_robot_data_share().resolve())
        for what, ref in (("urdf", config.urdf), ("srdf", config.srdf)):
            if ref is None:
                continue
            path = self._file(ref, self.robot_dir, pkg)
            if path is None:
                raise _refuse(what, ref, what)
            if what == "urdf":
                for link, mesh in _urdf_meshes(path, ref):
                    if self._file(mesh.removeprefix("file://"), path.parent, pkg) is None:
                        raise _refuse(f"mesh of link {link!r} in the URDF", mesh, "urdf")

    def _inside(self, p: Path) -> Path | None:
        """``p``'s real path if it lies in an allowed folder (whether or not it exists)."""
        try:
            real = p.resolve()
        except (OSError, ValueError):  # a name too long, a NUL, a symlink loop
            return None
        return real if any(real.is_relative_to(r) for r in self.allowed_roots()) else None

    def _file(self, ref: str, root: Path, pkg: list[Path]) -> Path | None:
        """The real path of the file ``ref`` names (package://, absolute, or relative to
        ``root``) as the robot loader finds it, if it is a file in an allowed folder."""
        if ref.startswith("package://"):
            rel = ref[len("package://") :]
            found = [d / rel for d in pkg if _is_file(d / rel)]
            candidate = found[0] if found else None
        else:
            candidate = root / ref
        real = None if candidate is None else self._inside(candidate)
        return real if real is not None and _is_file(real) else None

    def listing(self) -> list[dict[str, Any]]:
        """Every robot by name: the presets, then the registered ones."""
        out = [{"name": n, "kind": "preset"} for n in preset_names()]
        out += [
            {"name": r["name"], "kind": "registered", "created": r["created"]}
            for r in self.store.robots()
        ]
        return out


def _refuse(what: str, ref: str, field: str) -> RobotConfigError:
    return RobotConfigError(
        f"{what} {ref!r} lies outside the allowed folders or is not a file there", field=field
    )


def _is_file(p: Path) -> bool:
    try:
        return p.is_file()
    except (OSError, ValueError):
        return False


def _urdf_meshes(urdf: Path, ref: str) -> list[tuple[str, str]]:
    """(link, mesh filename) of every mesh a URDF names, visual and collision."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as e:
        raise RobotConfigError(f"urdf {ref!r}: not well-formed XML ({e})", field="urdf") from None
    return [
        (str(link.get("name")), mesh.get("filename", ""))
        for link in root.iter("link")
        for mesh in link.iter("mesh")
    ]
