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


def ellipsoid_triangles(semi: tuple[float, float, float], triangles: int) -> np.ndarray:
    """A closed ellipsoid of semi-axes ``semi`` [m] and about ``triangles`` triangles."""
    return sphere_triangles(1.0, triangles) * np.asarray(semi)


# The generated manipulator's arm, root to tip: joint, parent link, origin in the parent [m],
# axis, limits [rad or m], and the link's ellipsoid mesh (centre, semi-axes) [m].
_ARM = [
    ("torso_lift_joint", "column_link", (0, 0, 0.75), "0 0 1", (0.0, 0.35),
     ((0.0, 0, 0.06), (0.1, 0.13, 0.1))),
    ("arm_1_joint", "torso_lift_link", (0.15, 0, 0.08), "0 0 1", (-2.7, 2.7),
     ((0.03, 0, 0), (0.045, 0.045, 0.05))),
    ("arm_2_joint", "arm_1_link", (0.09, 0, 0), "0 1 0", (-1.5, 1.5),
     ((0.0, 0, 0), (0.04, 0.045, 0.04))),
    ("arm_3_joint", "arm_2_link", (0.06, 0, 0), "1 0 0", (-2.9, 2.9),
     ((0.14, 0, 0), (0.11, 0.04, 0.04))),
    ("arm_4_joint", "arm_3_link", (0.28, 0, 0), "0 1 0", (-2.2, 2.2),
     ((0.0, 0, 0), (0.04, 0.045, 0.04))),
    ("arm_5_joint", "arm_4_link", (0.05, 0, 0), "1 0 0", (-2.9, 2.9),
     ((0.12, 0, 0), (0.09, 0.035, 0.035))),
    ("arm_6_joint", "arm_5_link", (0.24, 0, 0), "0 1 0", (-1.8, 1.8),
     ((0.0, 0, 0), (0.035, 0.04, 0.035))),
    ("arm_7_joint", "arm_6_link", (0.045, 0, 0), "1 0 0", (-2.9, 2.9),
     ((0.015, 0, 0), (0.02, 0.035, 0.035))),
]  # fmt: skip
#: The parallel gripper (in the palm frame, x approach, y closing): fingers 62 mm long from
#: x = 0.07, pads 32 mm long standing 3 mm proud of the fingers' inner faces, ending 15 mm
#: short of the fingertips; the tool frame lies between the pads, at their middle.
PAD_TIP = 0.07 + 0.047  # [m] the pads' fingertip-side edge along the approach, palm frame
FINGER_TIP = 0.07 + 0.062  # [m]
TOOL_X = 0.07 + 0.031  # [m] the tool frame between the pads


def _mesh_link(name: str, mesh: str, centre: tuple[float, ...]) -> str:
    xyz = " ".join(map(str, centre))
    return (
        f'  <link name="{name}"><collision><origin xyz="{xyz}"/><geometry>\n'
        f'    <mesh filename="meshes/{mesh}"/></geometry></collision></link>\n'
    )


def _joint(name: str, kind: str, parent: str, child: str, xyz, axis="", limits=None) -> str:
    out = f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
    out += f'<origin xyz="{" ".join(map(str, xyz))}"/>'
    if axis:
        out += f'<axis xyz="{axis}"/>'
    if limits is not None:
        out += f'<limit lower="{limits[0]}" upper="{limits[1]}" effort="10" velocity="1"/>'
    return out + "</joint>\n"


def _box_link(name: str, size, xyz) -> str:
    return (
        f'  <link name="{name}"><collision><origin xyz="{" ".join(map(str, xyz))}"/><geometry>'
        f'<box size="{" ".join(map(str, size))}"/></geometry></collision></link>\n'
    )


def _gripper() -> str:
    """Palm, two fingers on prismatic joints (0: closed, 0.04: open each), their pads and
    the tool frame between the pads."""
    out = _mesh_link("gripper_palm_link", "palm.stl", (0.035, 0, 0))
    out += _joint("gripper_palm_joint", "fixed", "arm_7_link", "gripper_palm_link", (0.035, 0, 0))
    for side, s in (("left", 1), ("right", -1)):
        finger, pad = f"gripper_{side}_finger_link", f"gripper_{side}_pad_link"
        out += _box_link(finger, (0.062, 0.012, 0.022), (0.031, s * 0.009, 0))
        out += _joint(f"gripper_{side}_finger_joint", "prismatic", "gripper_palm_link", finger,
                      (0.07, 0, 0), f"0 {s} 0", (0.0, 0.045))  # fmt: skip
        out += _box_link(pad, (0.032, 0.003, 0.02), (0.031, s * 0.0015, 0))
        out += _joint(f"gripper_{side}_pad_joint", "fixed", finger, pad, (0, 0, 0))
    out += '  <link name="gripper_grasping_frame"/>\n'
    out += _joint("gripper_grasping_joint", "fixed", "gripper_palm_link",
                  "gripper_grasping_frame", (TOOL_X, 0, 0))  # fmt: skip
    return out


def _srdf(pairs: list[tuple[str, str, str]]) -> str:
    """An SRDF disabling ``pairs`` (link1, link2, reason) as MoveIt's setup assistant writes
    them."""
    rows = "".join(
        f'  <disable_collisions link1="{a}" link2="{b}" reason="{r.capitalize()}"/>\n'
        for a, b, r in pairs
    )
    return f'<?xml version="1.0"?>\n<robot name="gen_arm">\n{rows}</robot>\n'


def setup_assistant_pairs(config: Path) -> list[tuple[str, str, str]]:
    """The pairs MoveIt's setup assistant disables for the robot of ``config`` (adjacent,
    colliding at home, always or never over its default 10,000 random samples), as
    :func:`pickstop.robot.selfcollision.disabled_pairs` computes them."""
    from pickstop.robot.model import load
    from pickstop.robot.selfcollision import disabled_pairs

    dp = disabled_pairs(load(str(config)), samples=10_000)
    return [(p.link1, p.link2, p.reason) for p in dp.pairs]


def write_manipulator(folder: Path, triangles: int = 4000, tool_offset: float = 0.0) -> Path:
    """A mobile manipulator as vendors ship them: an SRDF, dense collision meshes (about
    ``triangles`` each on the torso, the seven arm links, the palm and the base's laser and
    cover), a torso lift and a 7-joint arm, and a parallel gripper whose tool frame lies
    between the pads; the config names the grasp point ``tool_offset`` [m] along the approach
    from the tool frame. Returns its config file."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "meshes").mkdir(exist_ok=True)
    write_stl(folder / "meshes" / "laser.stl", sphere_triangles(0.04, triangles))
    write_stl(folder / "meshes" / "cover.stl", ellipsoid_triangles((0.28, 0.24, 0.04), triangles))
    write_stl(folder / "meshes" / "palm.stl", ellipsoid_triangles((0.035, 0.06, 0.03), triangles))
    urdf = '<?xml version="1.0"?>\n<robot name="gen_arm">\n  <link name="base_footprint"/>\n'
    urdf += _box_link("base_link", (0.6, 0.5, 0.3), (0, 0, 0.15))
    urdf += _joint("base_joint", "fixed", "base_footprint", "base_link", (0, 0, 0))
    urdf += _mesh_link("laser_link", "laser.stl", (0, 0, 0))
    urdf += _joint("laser_joint", "fixed", "base_link", "laser_link", (0.26, 0, 0.2))
    urdf += _mesh_link("cover_link", "cover.stl", (0, 0, 0))
    urdf += _joint("cover_joint", "fixed", "base_link", "cover_link", (0, 0, 0.32))
    urdf += _box_link("column_link", (0.14, 0.14, 0.6), (0, 0, 0.3))
    urdf += _joint("column_joint", "fixed", "base_link", "column_link", (-0.1, 0, 0.3))
    for joint, parent, xyz, axis, limits, (centre, semi) in _ARM:
        link = joint.replace("_joint", "_link")
        kind = "prismatic" if joint == "torso_lift_joint" else "revolute"
        write_stl(folder / "meshes" / f"{link}.stl", ellipsoid_triangles(semi, triangles))
        urdf += _mesh_link(link, f"{link}.stl", centre)
        urdf += _joint(joint, kind, parent, link, xyz, axis, limits)
    urdf += _gripper() + "</robot>\n"
    (folder / "gen_arm.urdf").write_text(urdf)
    offset = f"\n  tool_offset: {{position: [{tool_offset}, 0, 0]}}" if tool_offset else ""
    config = folder / "gen_arm.yaml"
    text = (
        "name: gen_arm\n"
        "urdf: gen_arm.urdf\n"
        f"arm_joints: [torso_lift_joint, {', '.join(f'arm_{k}_joint' for k in range(1, 8))}]\n"
        "tool_frame: gripper_grasping_frame\n"
        "footprint: {}\n"
        "hand:\n"
        '  links: ["gripper_*"]\n'
        "  pregrasp: {gripper_left_finger_joint: 0.04, gripper_right_finger_joint: 0.04}\n"
        f"  max_opening: 0.08{offset}\n"
    )
    config.write_text(text)  # the robot's pairs, as a vendor's setup assistant run wrote them
    (folder / "gen_arm.srdf").write_text(_srdf(setup_assistant_pairs(config)))
    config.write_text(
        text.replace("urdf: gen_arm.urdf\n", "urdf: gen_arm.urdf\nsrdf: gen_arm.srdf\n")
    )
    return config
