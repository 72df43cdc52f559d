"""Robot config files: which URDF, which joints form the arm, where the tool is.

A config is YAML or JSON. Relative paths are relative to the config file; ``package://NAME/...``
resolves against ``package_dirs`` (the example-robot-data share folder is always one of them).
See ``docs/conventions.md`` for frames and units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from pickstop.errors import RobotConfigError

PRESET_DIR = Path(__file__).parent / "presets"
#: A file path or package:// URI in a config: printable, at most 1,024 characters.
ConfigPath = Annotated[str, Field(min_length=1, max_length=1024, pattern=r"^[^\x00-\x1f\x7f]+$")]


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
    drive: Literal["differential", "omnidirectional"] = Field(
        default="differential",
        description="how the base moves: differential (straight only along its heading, "
        "turning in place) or omnidirectional (any direction at any heading); routes dock at "
        "stops only with moves the base can make",
    )
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


Vec3 = tuple[float, float, float]


class ToolOffset(BaseModel):
    """The grasp point (TCP) in the tool frame: ``T_tool_tcp`` as a position [m] and roll,
    pitch, yaw [rad] (about fixed x, y, z, as URDF origins)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    position: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _finite(self) -> ToolOffset:
        if not all(math.isfinite(v) for v in (*self.position, *self.rpy)):
            raise ValueError("position and rpy must be finite numbers")
        if max(map(abs, self.position)) > 1.0:
            raise ValueError("the grasp point lies more than 1 m from the tool frame")
        return self


class BoxHand(BaseModel):
    """A hand described by boxes (two fingers and a palm, in the TCP frame: x approach, y
    closing), for a robot whose URDF carries no hand geometry [m]."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    finger_length: Annotated[float, Field(gt=0, le=0.5)] = 0.06
    finger_width: Annotated[float, Field(gt=0, le=0.5)] = 0.02  # along z
    finger_thickness: Annotated[float, Field(gt=0, le=0.2)] = 0.01  # along y, each side
    tip_offset: Annotated[float, Field(ge=0, le=0.5)] = 0.015  # grasp point to fingertips
    palm_depth: Annotated[float, Field(gt=0, le=0.5)] = 0.03  # along x, behind the fingers


class Hand(BaseModel):
    """The end effector as the robot carries it: its links, how it looks open on approach, and
    where and how it grasps. Axes are in the grasp point's (TCP) frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    links: list[str] = Field(
        default_factory=list,
        description="links of the hand (fnmatch patterns), all carried by the last arm joint",
    )
    pregrasp: dict[str, float] = Field(
        default_factory=dict,
        description="joint values of the open hand on approach [rad or m] (fingers, gripper "
        "joints); unlisted hand joints keep their locked value",
    )
    tool_offset: ToolOffset = ToolOffset()
    approach_axis: Vec3 = (1.0, 0.0, 0.0)
    closing_axis: Vec3 = (0.0, 1.0, 0.0)
    max_opening: Annotated[float, Field(gt=0, le=1.0)] = 0.08  # free gap when open [m]
    ignore_links: list[str] = Field(
        default_factory=list,
        description="collision links that are no body (padding volumes around the hand, fnmatch "
        "patterns): left out of every check",
    )
    geometry: Literal["links", "boxes"] = Field(
        default="links",
        description="what the hand is checked as: its links' own collision geometry, or the "
        "boxes of `boxes` standing in for the links (a URDF without hand geometry)",
    )
    boxes: BoxHand = BoxHand()

    @model_validator(mode="after")
    def _axes(self) -> Hand:
        a, c = self.approach_axis, self.closing_axis
        na, nc = math.hypot(*a), math.hypot(*c)
        if na < 1e-9 or nc < 1e-9:
            raise ValueError("approach_axis and closing_axis must be non-zero")
        if abs(sum(x * y for x, y in zip(a, c, strict=True))) > 1e-3 * na * nc:
            raise ValueError("closing_axis must be perpendicular to approach_axis (to 0.06 deg)")
        return self


class RobotConfig(BaseModel):
    """What PickStop needs to know about a mobile manipulator."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")]
    urdf: ConfigPath = Field(description="URDF path or package:// URI")
    package_dirs: list[ConfigPath] = Field(default_factory=list)
    srdf: ConfigPath | None = Field(
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
    hand: Hand = Hand()
    travel: dict[str, float] | None = Field(
        default=None,
        description="the arm's posture while the base drives, by arm joint [rad or m]; unlisted "
        "arm joints take 0 clipped into their limits; none: a folded posture computed from the "
        "robot (pickstop.robot.travel)",
    )

    hand_links: list[str] | None = Field(
        default=None, description="older configs: the hand's links (now hand.links)"
    )
    approach_axis: Vec3 | None = Field(
        default=None, description="older configs: the approach axis (now hand.approach_axis)"
    )

    @field_validator("arm_joints")
    @classmethod
    def _unique_joints(cls, v: list[str]) -> list[str]:
        dup = sorted({j for j in v if v.count(j) > 1})
        if dup:
            raise ValueError(f"joints listed twice: {', '.join(dup)}")
        return v

    @field_validator("travel")
    @classmethod
    def _travel_joints(
        cls, v: dict[str, float] | None, info: ValidationInfo
    ) -> dict[str, float] | None:
        arm = info.data.get("arm_joints")
        if v is None or arm is None:
            return v
        other = [j for j in v if j not in arm]
        if other:
            raise ValueError(
                f"not arm joints: {', '.join(other)} (the arm joints: {', '.join(arm)})"
            )
        bad = [j for j, x in v.items() if not math.isfinite(x)]
        if bad:
            raise ValueError(f"values must be finite numbers: {', '.join(bad)}")
        return v

    @model_validator(mode="after")
    def _check(self) -> RobotConfig:
        clash = sorted(set(self.arm_joints) & set(self.locked_joints))
        if clash:
            raise ValueError(f"joints both in arm_joints and locked_joints: {', '.join(clash)}")
        lo, hi = self.continuous_limits
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError("continuous_limits must be finite with lower < upper")
        if self.hand_links is not None or self.approach_axis is not None:
            # Configs written before the hand block: their fields move into it.
            update: dict[str, Any] = {}
            if self.hand_links is not None and not self.hand.links:
                update["links"] = self.hand_links
            if self.approach_axis is not None:
                update["approach_axis"] = self.approach_axis
            hand = Hand.model_validate({**self.hand.model_dump(), **update})
            object.__setattr__(self, "hand", hand)
        clash = sorted(set(self.arm_joints) & set(self.hand.pregrasp))
        if clash:
            raise ValueError(f"joints both in arm_joints and hand.pregrasp: {', '.join(clash)}")
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
    return config_from_text(path, path.read_text(encoding="utf-8"))


def config_from_text(path: Path, text: str) -> tuple[RobotConfig, Path]:
    """The config in ``text``, read from ``path`` (YAML, or JSON by its suffix)."""
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


def robot_config_file(robot: str) -> Path:
    """The config file of a preset name (``tiago``) or a path to one."""
    preset = PRESET_DIR / f"{robot}.yaml"
    if preset.is_file():
        return preset
    candidate = Path(robot)
    if candidate.suffix.lower() in {".yaml", ".yml", ".json"} or candidate.exists():
        return candidate
    raise RobotConfigError(
        f"unknown robot {robot!r}: not a preset ({', '.join(preset_names())}) nor a config file",
        field="robot",
    )


def resolve_robot(robot: str) -> tuple[RobotConfig, Path]:
    """A preset name (``tiago``) or a path to a config file."""
    return load_config(robot_config_file(robot))
