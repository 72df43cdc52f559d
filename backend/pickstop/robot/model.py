"""Load a mobile manipulator: pinocchio kinematics reduced to the arm, coal collision geometry.

The base frame is the URDF root link (for TIAGo ``base_footprint``). The model is a fixed-base
model of the robot standing at the base frame origin; the mobile base pose enters later as
``T_world_base``.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from pickstop.errors import RobotConfigError
from pickstop.robot.config import RobotConfig, example_robot_data_share, resolve_robot

JointKind = Literal["revolute", "prismatic", "continuous"]

_KIND_BY_SHORTNAME: dict[str, JointKind] = {
    "JointModelRX": "revolute",
    "JointModelRY": "revolute",
    "JointModelRZ": "revolute",
    "JointModelRevoluteUnaligned": "revolute",
    "JointModelPX": "prismatic",
    "JointModelPY": "prismatic",
    "JointModelPZ": "prismatic",
    "JointModelPrismaticUnaligned": "prismatic",
    "JointModelRUBX": "continuous",
    "JointModelRUBY": "continuous",
    "JointModelRUBZ": "continuous",
    "JointModelRevoluteUnboundedUnaligned": "continuous",
}


@dataclass(frozen=True)
class ArmJoint:
    """One sampled joint of the arm (torso included)."""

    name: str
    kind: JointKind
    axis: tuple[float, float, float]  # unit axis in the joint frame
    lower: float  # [rad or m]
    upper: float  # [rad or m]
    idx_q: int  # first coordinate in the reduced pinocchio q
    nq: int  # 1, or 2 for continuous joints (cos, sin)


@dataclass
class Derived:
    """What is derived from one loaded robot alone, each field made once by the function named
    beside it (a loaded robot never changes, so nothing invalidates them). Typed ``Any`` where
    the type lives in a module that imports this one."""

    hand_shape: Any = None  # robot/hand.py hand_shape(): HandShape
    screen: Any = None  # robot/artifacts.py self_collision(): (DisabledPairs, SphereModel, figures)
    travel: Any = None  # robot/travel.py travel_of(): Travel
    upper_body: Any = None  # regions/footprint.py upper_body(): UpperBody
    # regions/footprint.py: where the base may not stand, per (solids, yaw, body parts) and
    # per solid piece; a Keep the speed-ups hang here (speedups/region_planner.py), else none
    blocked_regions: Any = None
    blocked_pieces: Any = None


@dataclass(eq=False)
class RobotModel:
    """A loaded robot. ``model`` is immutable; make a ``model.createData()`` per thread."""

    config: RobotConfig
    urdf_path: Path
    srdf_path: Path | None
    package_dirs: list[str]
    full_model: Any  # pin.Model, every joint
    q_full: np.ndarray  # (full_model.nq,) locked values, arm at zero
    model: Any  # pin.Model reduced to the arm joints
    geom_model: Any  # pin.GeometryModel (collision) of the reduced model
    tool_frame_id: int
    joints: tuple[ArmJoint, ...]
    robot_hash: str
    footprint: Any = None  # config.Footprint with a radius or polygon (derived if not given)
    source: str = ""  # what to pass as ``--robot`` to load it again: a preset or a config path
    # What is derived from this robot alone, made once per loaded robot (see Derived).
    derived: Derived = field(default_factory=lambda: Derived(), repr=False)

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def dof(self) -> int:
        """Number of sampled joints (one angle or length each)."""
        return len(self.joints)

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])

    @property
    def base_frame(self) -> str:
        return str(self.full_model.frames[1].name)

    def angles_to_q(self, thetas: np.ndarray) -> np.ndarray:
        """``thetas: (..., dof)`` joint values [rad or m] -> pinocchio ``q: (..., nq)``."""
        thetas = np.asarray(thetas, dtype=float)
        assert thetas.shape[-1] == self.dof, thetas.shape
        q = np.empty((*thetas.shape[:-1], self.model.nq))
        for i, j in enumerate(self.joints):
            if j.nq == 2:
                q[..., j.idx_q] = np.cos(thetas[..., i])
                q[..., j.idx_q + 1] = np.sin(thetas[..., i])
            else:
                q[..., j.idx_q] = thetas[..., i]
        return q

    def q_to_angles(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio ``q: (..., nq)`` -> ``thetas: (..., dof)``."""
        q = np.asarray(q, dtype=float)
        out = np.empty((*q.shape[:-1], self.dof))
        for i, j in enumerate(self.joints):
            if j.nq == 2:
                out[..., i] = np.arctan2(q[..., j.idx_q + 1], q[..., j.idx_q])
            else:
                out[..., i] = q[..., j.idx_q]
        return out

    def full_q(self, theta: np.ndarray) -> np.ndarray:
        """Full-model configuration (for display) with the arm at ``theta: (dof,)``."""
        q = self.q_full.copy()
        for value, j in zip(theta, self.joints, strict=True):
            jid = self.full_model.getJointId(j.name)
            iq = self.full_model.idx_qs[jid]
            if j.nq == 2:
                q[iq : iq + 2] = (math.cos(value), math.sin(value))
            else:
                q[iq] = value
        return q


def resolve_path(ref: str, root: Path, package_dirs: list[str], what: str) -> Path:
    """A config path: ``package://pkg/rel``, absolute, or relative to ``root``."""
    if ref.startswith("package://"):
        rel = ref[len("package://") :]
        for d in package_dirs:
            cand = Path(d) / rel
            if cand.is_file():
                return cand
        raise RobotConfigError(
            f"{what} {ref!r} not found in package dirs {package_dirs}", field=what.replace(" ", "_")
        )
    p = Path(ref)
    if not p.is_absolute():
        p = root / p
    if not p.is_file():
        raise RobotConfigError(f"{what} file not found: {p}", field=what.replace(" ", "_"))
    return p


def _mesh_refs(urdf_path: Path, package_dirs: list[str]) -> tuple[ET.Element, list[Path]]:
    """Parse the URDF as XML and resolve every collision mesh (pinocchio's errors name neither).

    The returned tree has every collision mesh's ``filename`` replaced by its resolved absolute
    path, so meshes given relative to the URDF load too.
    """
    try:
        root = ET.parse(urdf_path).getroot()
    except ET.ParseError as e:
        raise RobotConfigError(f"{urdf_path}: broken URDF (not well-formed XML: {e})") from None
    if root.tag != "robot":
        raise RobotConfigError(
            f"{urdf_path}: broken URDF (root element is <{root.tag}>, not <robot>)"
        )
    meshes: list[Path] = []
    for link in root.iter("link"):
        for coll in link.iter("collision"):
            for mesh in coll.iter("mesh"):
                ref = mesh.get("filename", "")
                try:
                    path = resolve_path(
                        ref.removeprefix("file://"), urdf_path.parent, package_dirs, "mesh"
                    )
                except RobotConfigError:
                    raise RobotConfigError(
                        f"{urdf_path.name}: collision mesh of link {link.get('name')!r} not "
                        f"found: {ref}",
                        field="urdf",
                    ) from None
                meshes.append(path)
                mesh.set("filename", str(path.resolve()))
    return root, meshes


def _hash(config: RobotConfig, files: list[Path]) -> str:
    """Hash of everything a reachability database depends on: config and file contents.

    The footprint, the travel posture and the hand's grasp description (links, tool offset,
    axes, opening) do not change what the arm reaches nor its self-collision; the hand's
    pre-grasp joints and the ignored links do (and enter the hash only when given, so older
    databases stay valid).
    """
    doc = config.model_dump(
        mode="json", exclude={"footprint", "hand", "hand_links", "approach_axis", "travel"}
    )
    if config.hand.pregrasp:
        doc["pregrasp"] = config.hand.pregrasp
    if config.hand.ignore_links:
        doc["ignore_links"] = config.hand.ignore_links
    h = hashlib.sha256()
    h.update(json.dumps(doc, sort_keys=True).encode())
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def _joint_axis(jm: Any, shortname: str) -> tuple[float, float, float]:
    if shortname[-1] in "XYZ" and not shortname.endswith("Unaligned"):
        axis = [0.0, 0.0, 0.0]
        axis["XYZ".index(shortname[-1])] = 1.0
        return (axis[0], axis[1], axis[2])
    a = np.asarray(jm.extract().axis, dtype=float)
    a /= np.linalg.norm(a)
    return (float(a[0]), float(a[1]), float(a[2]))


def load_robot(config: RobotConfig, root: Path) -> RobotModel:
    """Build the reduced kinematic and collision model of ``config`` (paths from ``root``)."""
    package_dirs = [str((root / d).resolve()) for d in config.package_dirs]
    package_dirs.append(str(example_robot_data_share()))
    urdf_path = resolve_path(config.urdf, root, package_dirs, "urdf")
    srdf_path = (
        resolve_path(config.srdf, root, package_dirs, "srdf") if config.srdf is not None else None
    )
    tree, meshes = _mesh_refs(urdf_path, package_dirs)
    urdf_xml = ET.tostring(tree, encoding="unicode")

    try:
        full = pin.buildModelFromXML(urdf_xml)
    except (ValueError, RuntimeError) as e:
        raise RobotConfigError(f"{urdf_path.name}: broken URDF: {e}", field="urdf") from None
    _check_names(config, full, urdf_path)
    q_full = _locked_configuration(config, full)
    geom_full = _collision_geometry(config, full, urdf_xml, package_dirs, urdf_path)
    arm_ids = [full.getJointId(j) for j in config.arm_joints]
    lock_ids = [j for j in range(1, full.njoints) if j not in arm_ids]
    model, geom_model = pin.buildReducedModel(full, geom_full, lock_ids, q_full)
    joints = _arm_chain(config, model, urdf_path)
    _check_travel(config, joints)
    tool_id = model.getFrameId(config.tool_frame)
    if model.frames[tool_id].parentJoint != len(joints):
        raise RobotConfigError(
            f"{urdf_path}: tool frame {config.tool_frame!r} is not carried by the last arm joint "
            f"{config.arm_joints[-1]!r}",
            field="tool_frame",
        )

    files = [urdf_path, *([srdf_path] if srdf_path else []), *sorted(set(meshes))]
    robot = RobotModel(
        config=config,
        urdf_path=urdf_path,
        srdf_path=srdf_path,
        package_dirs=package_dirs,
        full_model=full,
        q_full=q_full,
        model=model,
        geom_model=geom_model,
        tool_frame_id=tool_id,
        joints=tuple(joints),
        robot_hash=_hash(config, files),
    )
    robot.footprint = _footprint(robot, config.footprint)
    return robot


def _check_names(config: RobotConfig, full: Any, urdf_path: Path) -> None:
    """Every joint and frame the config names exists in the URDF's model ``full``."""
    names = list(full.names)
    for i, jn in enumerate(config.arm_joints):
        if jn not in names:
            raise RobotConfigError(
                f"{urdf_path}: unknown arm joint {jn!r} (movable joints: {', '.join(names[1:])})",
                field=f"arm_joints[{i}]",
            )
    for jn in config.locked_joints:
        if jn not in names:
            raise RobotConfigError(
                f"{urdf_path.name}: unknown locked joint {jn!r} (movable joints: "
                f"{', '.join(names[1:])})",
                field=f"locked_joints.{jn}",
            )
    if not full.existFrame(config.tool_frame):
        frames = sorted({str(f.name) for f in full.frames} - {"universe"})
        raise RobotConfigError(
            f"{urdf_path.name}: unknown tool frame {config.tool_frame!r}; its frames are "
            f"{', '.join(frames)}",
            field="tool_frame",
        )
    for jn in config.hand.pregrasp:
        if jn not in names:
            raise RobotConfigError(
                f"{urdf_path.name}: unknown hand joint {jn!r} (movable joints: "
                f"{', '.join(names[1:])})",
                field=f"hand.pregrasp.{jn}",
            )


def _locked_configuration(config: RobotConfig, full: Any) -> np.ndarray:
    """``(full.nq,)``: the hand's pre-grasp values, the given locked values, else 0 clipped
    into the joint limits (the arm's entries are replaced when it moves)."""
    locked = {**config.locked_joints, **config.hand.pregrasp}
    q_full = pin.neutral(full)
    for jid in range(1, full.njoints):
        jn, iq, nq = full.names[jid], full.idx_qs[jid], full.nqs[jid]
        value = locked.get(jn)
        where = "hand.pregrasp" if jn in config.hand.pregrasp else "locked_joints"
        if nq == 2:
            angle = float(value) if isinstance(value, int | float) else 0.0
            q_full[iq : iq + 2] = (math.cos(angle), math.sin(angle))
        elif nq == 1:
            v = float(value) if isinstance(value, int | float) else 0.0
            lo, hi = full.lowerPositionLimit[iq], full.upperPositionLimit[iq]
            if value is not None and not (lo - 1e-9 <= v <= hi + 1e-9):
                raise RobotConfigError(
                    f"joint {jn!r} value {v} is outside its limits [{lo}, {hi}]",
                    field=f"{where}.{jn}",
                )
            q_full[iq] = min(max(v, lo), hi)
        elif value is not None:
            raise RobotConfigError(
                f"joint {jn!r} has {nq} coordinates; give its value as a list",
                field=f"{where}.{jn}",
            )
    return q_full  # type: ignore[no-any-return]


def _collision_geometry(
    config: RobotConfig, full: Any, urdf_xml: str, package_dirs: list[str], urdf_path: Path
) -> Any:
    """The URDF's collision geometry (pin.GeometryModel), the hand's ignored links left out."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            geom_full = pin.buildGeomFromUrdfString(
                full, urdf_xml, pin.GeometryType.COLLISION, package_dirs=package_dirs
            )
        except (ValueError, RuntimeError) as e:
            raise RobotConfigError(f"{urdf_path}: cannot load collision geometry: {e}") from None
    return _without_ignored(geom_full, config.hand.ignore_links, urdf_path)


def _arm_chain(config: RobotConfig, model: Any, urdf_path: Path) -> list[ArmJoint]:
    """The arm joints of the reduced ``model``: a serial chain root -> tip, each revolute,
    prismatic or continuous with usable limits."""
    joints: list[ArmJoint] = []
    for i, jn in enumerate(config.arm_joints):
        jid = model.getJointId(jn)
        if jid != i + 1 or model.parents[jid] != i:
            raise RobotConfigError(
                f"{urdf_path}: arm joint {jn!r} does not follow "
                f"{config.arm_joints[i - 1] if i else 'the root'!r} on one serial chain; list the "
                "arm joints root to tip along the chain that carries the tool frame",
                field=f"arm_joints[{i}]",
            )
        jm = model.joints[jid]
        short = jm.shortname()
        kind = _KIND_BY_SHORTNAME.get(short)
        if kind is None:
            raise RobotConfigError(
                f"{urdf_path}: arm joint {jn!r} is of type {short}; only revolute, prismatic and "
                "continuous joints can be sampled",
                field=f"arm_joints[{i}]",
            )
        iq = model.idx_qs[jid]
        if kind == "continuous":
            lo, hi = config.continuous_limits
        else:
            lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise RobotConfigError(
                    f"{urdf_path}: arm joint {jn!r} has no usable limits ({lo}, {hi})",
                    field=f"arm_joints[{i}]",
                )
        joints.append(ArmJoint(jn, kind, _joint_axis(jm, short), lo, hi, iq, model.nqs[jid]))
    return joints


def _check_travel(config: RobotConfig, joints: list[ArmJoint]) -> None:
    """Every value of the config's travel posture lies within its joint's limits."""
    by_name = {j.name: j for j in joints}
    for jn, v in (config.travel or {}).items():
        j = by_name[jn]
        if not (j.lower - 1e-9 <= v <= j.upper + 1e-9):
            unit = "m" if j.kind == "prismatic" else "rad"
            raise RobotConfigError(
                f"travel posture: joint {jn!r} value {v} is outside its limits "
                f"[{j.lower:.6g}, {j.upper:.6g}] {unit}",
                field=f"travel.{jn}",
            )


def _footprint(robot: RobotModel, footprint: Any) -> Any:
    """The config's footprint, or the base's outline derived from its collision geometry
    (kept in the cache per robot hash and footprint settings)."""
    from pickstop.robot.base_outline import derived_footprint

    if footprint.radius is not None or footprint.polygon is not None:
        return footprint
    from pickstop.robot.cache import derived
    from pickstop.settings import cache_dir

    key = hashlib.sha256(footprint.model_dump_json().encode()).hexdigest()[:12]
    return derived(
        robot, cache_dir(), f"outline-{key}", lambda: derived_footprint(robot, footprint)
    )


def _without_ignored(geom: Any, patterns: list[str], urdf_path: Path) -> Any:
    """The collision model without the links ``patterns`` names (padding volumes)."""
    import fnmatch
    import re

    if not patterns:
        return geom
    link = [re.sub(r"_\d+$", "", o.name) for o in geom.geometryObjects]
    for k, p in enumerate(patterns):
        if not any(fnmatch.fnmatch(n, p) for n in link):
            raise RobotConfigError(
                f"{urdf_path.name}: hand.ignore_links pattern {p!r} matches no collision link",
                field=f"hand.ignore_links[{k}]",
            )
    out = pin.GeometryModel()
    for obj, name in zip(geom.geometryObjects, link, strict=True):
        if not any(fnmatch.fnmatch(name, p) for p in patterns):
            out.addGeometryObject(obj)
    return out


def load(robot: str) -> RobotModel:
    """Load a preset by name or a robot config file by path."""
    config, root = resolve_robot(robot)
    return replace(load_robot(config, root), source=robot)
