"""What a client needs to draw a robot: its URDF with portable mesh references, and the files.

:func:`robot_assets` rewrites every mesh reference of the URDF (visual and collision, given as
``package://``, relative or absolute paths) to ``files/<id>`` (ids derived from the file's
path), so the URDF can be served and its meshes fetched one by one from the same place; only
the files listed in the result are ever served. Joint values to draw it with come along: every
joint that is not sampled at its locked value (the hand at its pre-grasp posture), and the
arm's travel posture with the link pairs the exact check finds in contact there.
"""

from __future__ import annotations

import hashlib
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from pickstop.robot.model import RobotModel, resolve_path
from pickstop.robot.travel import Travel


@dataclass(frozen=True)
class RobotAssets:
    name: str
    urdf: str  # the URDF with mesh references ``files/<id>``
    files: dict[str, Path]  # id -> file on the server
    arm_joints: list[str]
    joint_values: dict[str, float]  # joints not sampled: locked or pre-grasp values [rad or m]
    hand_joints: list[str]
    travel: dict[str, float]  # the arm's travel posture [rad or m]
    travel_collisions: list[tuple[str, str]]  # link pairs in contact there (empty: free)


def file_id(path: Path) -> str:
    """A stable id for a served file: a hash of its resolved path, and its suffix."""
    digest = hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:20]
    return digest + path.suffix.lower()


def robot_assets(robot: RobotModel, travel: Travel) -> RobotAssets:
    """The URDF of ``robot`` with every resolvable mesh served as ``files/<id>``; a visual
    mesh that does not resolve is left out (collision meshes were checked at load).
    ``travel``: its travel posture (:func:`pickstop.robot.travel.travel_of`)."""
    from pickstop.robot.hand import hand_joints

    root = ET.parse(robot.urdf_path).getroot()
    files: dict[str, Path] = {}
    for link in root.iter("link"):
        for kind in ("visual", "collision"):
            for element in list(link.iter(kind)):
                for mesh in element.iter("mesh"):
                    ref = mesh.get("filename", "").removeprefix("file://")
                    try:
                        path = resolve_path(ref, robot.urdf_path.parent, robot.package_dirs, "mesh")
                    except Exception:
                        link.remove(element) if element in list(link) else None
                        break
                    fid = file_id(path)
                    files[fid] = path.resolve()
                    mesh.set("filename", f"files/{fid}")
    full = robot.full_model
    arm = {j.name for j in robot.joints}
    values: dict[str, float] = {}
    for jid in range(1, full.njoints):
        name, iq, nq = str(full.names[jid]), full.idx_qs[jid], full.nqs[jid]
        if name in arm:
            continue
        q = robot.q_full[iq : iq + nq]
        if nq == 1:
            values[name] = float(q[0])
        elif nq == 2:
            values[name] = float(math.atan2(q[1], q[0]))
    return RobotAssets(
        name=robot.name,
        urdf=ET.tostring(root, encoding="unicode"),
        files=files,
        arm_joints=[j.name for j in robot.joints],
        joint_values=values,
        hand_joints=list(hand_joints(robot)),
        travel=travel.by_joint(robot),
        travel_collisions=list(travel.collisions),
    )
