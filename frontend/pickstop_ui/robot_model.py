"""The scene's robot, fetched from the API: its URDF and meshes, the joint values to draw it
and its travel posture.

The API serves a robot's URDF with mesh references ``files/<id>`` and each file by its id; they
are kept in a cache folder (per API and robot), so a planner draws any registered robot, not
only the bundled one, and imports no backend robot code.
"""

from __future__ import annotations

import hashlib
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pickstop_ui.client import PickStopClient
from pickstop_ui.mesh_lod import fit_budget

#: Triangles the planner draws of the robot (visual meshes) and of each ghost (collision
#: meshes): a software-rendered frame costs about 2 ms per thousand (see :mod:`mesh_lod`).
VISUAL_FACES = 15_000
GHOST_FACES = 8_000

_REF = re.compile(r'filename="files/([A-Za-z0-9._-]+)"')


@dataclass(frozen=True)
class RobotDrawing:
    name: str
    urdf: Any  # yourdfpy.URDF
    arm_joints: list[str]
    joint_values: dict[str, float]  # every joint that is not sampled: locked or pre-grasp
    travel: dict[str, float]  # the arm's travel posture, every arm joint [rad or m]
    travel_collisions: list[tuple[str, str]]  # link pairs in contact there (empty: free)

    def travel_theta(self, joints: list[str]) -> list[float]:
        """The travel posture in the order of ``joints`` (a plan's arm joints)."""
        return [float(self.travel[j]) for j in joints]


def scene_robot_name(doc: dict[str, Any]) -> str:
    """The robot a scene document names (a preset or a registered robot)."""
    ref = doc.get("robot") or {}
    return str(ref.get("preset") or "tiago")


def fetch_robot(client: PickStopClient, name: str, cache: Path | None = None) -> RobotDrawing:
    """Download robot ``name``'s model (URDF and meshes, each file once) and load it, its
    meshes thinned to the planner's triangle budgets."""
    import yourdfpy

    model = client.robot_model(name)
    key = hashlib.sha256(f"{client.base_url}|{name}".encode()).hexdigest()[:16]
    folder = (cache or Path(tempfile.gettempdir()) / "pickstop-ui-robots") / key
    (folder / "files").mkdir(parents=True, exist_ok=True)
    for fid in sorted(set(_REF.findall(model["urdf"]))):
        target = folder / "files" / fid
        if not target.is_file():
            data = client.robot_file(name, fid)
            tmp = target.with_suffix(target.suffix + ".part")
            tmp.write_bytes(data)
            tmp.replace(target)
    urdf_path = folder / f"{name}.urdf"
    urdf_path.write_text(_REF.sub(lambda m: f'filename="files/{m.group(1)}"', model["urdf"]))
    urdf = yourdfpy.URDF.load(
        str(urdf_path),
        filename_handler=lambda fname: str(folder / fname),
        load_meshes=True,
        build_scene_graph=True,
        load_collision_meshes=True,
        build_collision_scene_graph=True,
    )
    # Drawn only: the backend checks the robot's real geometry.
    fit_budget(urdf.scene, VISUAL_FACES)
    fit_budget(urdf.collision_scene, GHOST_FACES)
    return RobotDrawing(
        name=name,
        urdf=urdf,
        arm_joints=list(model["arm_joints"]),
        joint_values={k: float(v) for k, v in model["joint_values"].items()},
        travel={k: float(v) for k, v in model["travel"].items()},
        travel_collisions=[(str(a), str(b)) for a, b in model["travel_collisions"]],
    )
