"""Robot config files: which URDF, which joints form the arm, where the tool is.

A config is YAML or JSON. Relative paths are relative to the config file; ``package://NAME/...``
resolves against ``package_dirs`` (the example-robot-data share folder is always one of them).
See ``docs/conventions.md`` for frames and units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from pickstop.errors import RobotConfigError

PRESET_DIR = Path(__file__).parent / "presets"


def example_robot_data_share() -> Path:
    """Folder that holds ``example-robot-data/robots/...`` (the package installs data only)."""
    import pinocchio

    for root in map(Path, __import__("site").getsitepackages()):
        share = root / "cmeel.prefix" / "share"
        if (share / "example-robot-data").is_dir():
            return share
    here = Path(pinocchio.__file__).resolve()
    for parent in here.parents:
        share = parent / "cmeel.prefix" / "share"
        if (share / "example-robot-data").is_dir():
            return share
    raise RobotConfigError(
        "example-robot-data is not installed: run `pip install example-robot-data`"
    )


class Footprint(BaseModel):
    """Base outline in the base frame: a circle (``radius``) or a polygon (``polygon``) [m];
    with neither, the outline of the base's own collision geometry below ``height``, grown by
    ``clearance`` (:mod:`pickstop.robot.base_outline`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius: Annotated[float, Field(gt=0, lt=5)] | None = None
    polygon: list[tuple[float, float]] | None = None
    height: Annotated[float, Field(gt=0, lt=3)] = 0.35  # base body: what reaches below it blocks
    clearance: Annotated[float, Field(ge=0, le=0.5)] = 0.02  # around a derived outline [m]
    derived: bool = Field(default=False, description="set on an outline derived from the URDF")

    @model_validator(mode="after")
    def _one_shape(self) -> Footprint:
        if self.radius is not None and self.polygon is not None:
            raise ValueError("give at most one of 'radius' or 'polygon'")
        if self.polygon is not None:
            if len(self.polygon) < 3:
                raise ValueError("polygon needs at least 3 vertices")
            if not all(math.isfinite(v) for xy in self.polygon for v in xy):
                raise ValueError("polygon vertices must be finite numbers")
        return self

    @property
    def bounding_radius(self) -> float:
        """Radius of the smallest base-centred circle holding the footprint [m]."""
        if self.radius is not None:
            return self.radius
        assert self.polygon is not None, "a derived footprint: use RobotModel.footprint"
        return max(math.hypot(x, y) for x, y in self.polygon)


class RobotConfig(BaseModel):
    """What PickStop needs to know about a mobile manipulator."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")]
    urdf: str = Field(description="URDF path or package:// URI")
    package_dirs: list[str] = Field(default_factory=list)
    srdf: str | None = Field(
        default=None, description="optional SRDF giving disabled collision pairs"
    )
    arm_joints: list[str] = Field(
        min_length=1, description="joints sampled for reachability, root to tip (torso included)"
    )
    tool_frame: str
    locked_joints: dict[str, float | list[float]] = Field(
        default_factory=dict,
        description="values for joints not in the arm [rad or m]; unlisted joints take 0 clipped "
        "into their limits (continuous joints: an angle)",
    )
    continuous_limits: tuple[float, float] = Field(
        default=(-math.pi, math.pi), description="sampling range of continuous arm joints [rad]"
    )
    footprint: Footprint = Field(default_factory=Footprint)
    approach_axis: tuple[float, float, float] = Field(
        default=(1.0, 0.0, 0.0), description="gripper approach direction in the tool frame"
    )
    hand_links: list[str] = Field(
        default_factory=list,
        description="links of the hand (fnmatch patterns): their pose follows from the grasp, "
        "so the grasp's open-hand model is checked against the scene in their place",
    )

    @field_validator("arm_joints")
    @classmethod
    def _unique_joints(cls, v: list[str]) -> list[str]:
        dup = sorted({j for j in v if v.count(j) > 1})
        if dup:
            raise ValueError(f"joints listed twice: {', '.join(dup)}")
        return v

    @model_validator(mode="after")
    def _check(self) -> RobotConfig:
        clash = sorted(set(self.arm_joints) & set(self.locked_joints))
        if clash:
            raise ValueError(f"joints both in arm_joints and locked_joints: {', '.join(clash)}")
        lo, hi = self.continuous_limits
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError("continuous_limits must be finite with lower < upper")
        if math.hypot(*self.approach_axis) < 1e-9:
            raise ValueError("approach_axis must be non-zero")
        return self


def _format_validation(err: ValidationError, source: str) -> str:
    parts = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(root)"
        parts.append(f"{loc}: {e['msg']}")
    return f"{source}: invalid robot config: " + "; ".join(parts)


def parse_config(data: Any, source: str = "robot config") -> RobotConfig:
    """Validate a decoded config mapping; errors name the source and each bad field."""
    try:
        return RobotConfig.model_validate(data)
    except ValidationError as e:
        first = e.errors()[0]["loc"] if e.errors() else ()
        raise RobotConfigError(
            _format_validation(e, source), field=".".join(map(str, first)) or None
        ) from None


def load_config(path: str | Path) -> tuple[RobotConfig, Path]:
    """Read a YAML or JSON robot config; returns it and the folder its relative paths start from."""
    path = Path(path)
    if not path.is_file():
        raise RobotConfigError(f"{path}: robot config file not found")
    text = path.read_text(encoding="utf-8")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise RobotConfigError(
            f"{path}: not valid {path.suffix.lstrip('.') or 'YAML'}: {e}"
        ) from None
    if not isinstance(data, dict):
        raise RobotConfigError(
            f"{path}: a robot config must be a mapping, got {type(data).__name__}"
        )
    return parse_config(data, str(path)), path.parent.resolve()


def preset_names() -> list[str]:
    """Names of the built-in robot presets."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def resolve_robot(robot: str) -> tuple[RobotConfig, Path]:
    """A preset name (``tiago``) or a path to a config file."""
    preset = PRESET_DIR / f"{robot}.yaml"
    if preset.is_file():
        return load_config(preset)
    candidate = Path(robot)
    if candidate.suffix.lower() in {".yaml", ".yml", ".json"} or candidate.exists():
        return load_config(candidate)
    raise RobotConfigError(
        f"unknown robot {robot!r}: not a preset ({', '.join(preset_names())}) nor a config file",
        field="robot",
    )
