"""A generated mobile manipulator for tests: a box base with dense sensor meshes, a 4-DOF arm.

The meshes are written next to the URDF and referenced by relative paths, as many vendors'
URDFs do.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def sphere_triangles(radius: float, triangles: int) -> np.ndarray:
    """A closed UV sphere of about ``triangles`` triangles: ``(T, 3, 3)`` [m]."""
    n = max(4, int(math.sqrt(triangles / 2)))
    th = np.linspace(0, math.pi, n + 1)
    ph = np.linspace(0, 2 * math.pi, n + 1)
    P = (
        np.stack(
            [
                np.outer(np.sin(th), np.cos(ph)),
                np.outer(np.sin(th), np.sin(ph)),
                np.outer(np.cos(th), np.ones_like(ph)),
            ],
            -1,
        )
        * radius
    )
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    tris = np.concatenate([np.stack([a, b, c], 2), np.stack([a, c, d], 2)]).reshape(-1, 3, 3)
    return tris


def write_stl(path: Path, tris: np.ndarray) -> None:
    """Binary STL of ``tris: (T, 3, 3)``."""
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["v"] = tris
    with open(path, "wb") as f:
        f.write(b"pickstop synthetic".ljust(80, b" "))
        f.write(np.uint32(len(tris)).tobytes())
        f.write(rec.tobytes())


def write_dense_robot(folder: Path, triangles: int = 50_000, arm_mesh: bool = True) -> Path:
    """A robot whose base carries a laser and an e-stop of ``triangles`` triangles each (and,
    with ``arm_mesh``, a wrist camera as dense); returns its config file."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "meshes").mkdir(exist_ok=True)
    write_stl(folder / "meshes" / "laser.stl", sphere_triangles(0.04, triangles))
    write_stl(folder / "meshes" / "estop.stl", sphere_triangles(0.03, triangles))
    write_stl(folder / "meshes" / "camera.stl", sphere_triangles(0.025, triangles))
    cam = (
        """
  <link name="camera_link"><collision><geometry>
    <mesh filename="meshes/camera.stl"/></geometry></collision></link>
  <joint name="camera_joint" type="fixed"><parent link="link3"/><child link="camera_link"/>
    <origin xyz="0.12 0 0.05"/></joint>"""
        if arm_mesh
        else ""
    )
    urdf = f"""<?xml version="1.0"?>
<robot name="dense_amr">
  <link name="base_footprint"/>
  <link name="base_link"><collision><origin xyz="0 0 0.15"/><geometry>
    <box size="0.5 0.4 0.3"/></geometry></collision></link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
  </joint>
  <link name="laser_link"><collision><geometry>
    <mesh filename="meshes/laser.stl"/></geometry></collision></link>
  <joint name="laser_joint" type="fixed"><parent link="base_link"/><child link="laser_link"/>
    <origin xyz="0.22 0 0.2"/></joint>
  <link name="estop_link"><collision><geometry>
    <mesh filename="./meshes/estop.stl"/></geometry></collision></link>
  <joint name="estop_joint" type="fixed"><parent link="base_link"/><child link="estop_link"/>
    <origin xyz="-0.2 0.15 0.31"/></joint>
  <link name="column_link"><collision><origin xyz="0 0 0.25"/><geometry>
    <cylinder radius="0.06" length="0.5"/></geometry></collision></link>
  <joint name="column_joint" type="fixed"><parent link="base_link"/><child link="column_link"/>
    <origin xyz="0 0 0.3"/></joint>
  <link name="link1"><collision><origin xyz="0 0 0.05"/><geometry>
    <cylinder radius="0.045" length="0.1"/></geometry></collision></link>
  <joint name="joint1" type="revolute"><parent link="column_link"/><child link="link1"/>
    <origin xyz="0 0 0.52"/><axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" effort="10" velocity="1"/></joint>
  <link name="link2"><collision><origin xyz="0.15 0 0"/><geometry>
    <box size="0.3 0.06 0.06"/></geometry></collision></link>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="1"/></joint>
  <link name="link3"><collision><origin xyz="0.13 0 0"/><geometry>
    <box size="0.26 0.05 0.05"/></geometry></collision></link>
  <joint name="joint3" type="revolute"><parent link="link2"/><child link="link3"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" effort="10" velocity="1"/></joint>
  <link name="link4"><collision><origin xyz="0.04 0 0"/><geometry>
    <box size="0.08 0.04 0.04"/></geometry></collision></link>
  <joint name="joint4" type="revolute"><parent link="link3"/><child link="link4"/>
    <origin xyz="0.26 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-3.0" upper="3.0" effort="10" velocity="1"/></joint>
  <link name="tool_link"/>
  <joint name="tool_joint" type="fixed"><parent link="link4"/><child link="tool_link"/>
    <origin xyz="0.1 0 0"/></joint>{cam}
</robot>
"""
    (folder / "dense_amr.urdf").write_text(urdf)
    config = folder / "dense_amr.yaml"
    config.write_text(
        "name: dense_amr\n"
        "urdf: dense_amr.urdf\n"
        "arm_joints: [joint1, joint2, joint3, joint4]\n"
        "tool_frame: tool_link\n"
        "footprint: {radius: 0.34}\n"
    )
    return config
