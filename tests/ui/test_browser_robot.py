"""The robot as it is, in the browser: drawn at the start with its own meshes (the collision
meshes the ghosts use, opaque) in its travel posture; ghosts off until asked for; *Play route*
folds the arm to travel, reaches each witness at its stop and folds it back."""

from __future__ import annotations

import numpy as np
import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium

#: Every node under a prefix as the browser's scene tree holds it: its kind, its colour and
#: opacity (meshes), and its pose.
NODES = """p => { const s = window.__viserSceneTree.getState(), m = window.__viserMutable;
  return Object.keys(s).filter(n => n.startsWith(p)).map(n => {
    const msg = s[n] && s[n].message, pose = m.nodePoseData[n];
    return {name: n, type: msg ? msg.type : null,
            color: msg && msg.props.color ? [...msg.props.color] : null,
            opacity: msg && msg.props.opacity !== undefined ? msg.props.opacity : null,
            wxyz: pose ? [...pose.wxyz] : null, position: pose ? [...pose.position] : null};
  }); }"""


def _nodes(pg, prefix: str) -> dict[str, dict]:
    return {n["name"]: n for n in pg.evaluate(NODES, prefix)}


def test_the_start_robot_is_drawn_with_its_meshes_in_its_travel_posture(pg, app):
    b.settled(app)
    nodes = _nodes(pg, "/robot/")
    meshes = [n for n in nodes.values() if n["type"] == "MeshMessage"]
    assert meshes and all(n["name"].startswith("/robot/collision/") for n in meshes)
    assert not any("/visual" in n for n in nodes)
    # The ghosts' meshes, link for link, opaque.
    ghost = {n.removeprefix("/ghosts/0") for n in _nodes(pg, "/ghosts/0/")}
    assert {n.removeprefix("/robot") for n in nodes} == ghost
    assert all(n["opacity"] in (None, 1.0) for n in meshes)
    # The arm in the travel posture the API gives, every other joint at its drawn value.
    travel = app.robot.travel
    assert travel and list(travel) == app.robot.arm_joints
    assert travel["arm_4_joint"] == pytest.approx(1.94) and not app.robot.travel_collisions
    cfg = dict(zip(app._robot.get_actuated_joint_names(), app._robot_cfg, strict=True))
    for j, v in {**app.robot.joint_values, **travel}.items():
        assert cfg[j] == pytest.approx(v)
    # The browser holds that posture: each joint frame as the server set it.
    for h in app._robot._joint_frames:
        node = nodes[h.name]
        assert node["position"] == pytest.approx(list(h.position), abs=1e-6), h.name
        assert np.abs(np.dot(node["wxyz"], h.wxyz)) == pytest.approx(1.0, abs=1e-6), h.name
    torso = next(h for h in app._robot._joint_frames if h.name.endswith("/torso_lift_link"))
    assert nodes[torso.name]["position"][2] > 0.15  # the torso lifted 0.15 m


def test_ghosts_are_off_until_asked_for(pg, app):
    b.settled(app)
    assert not app.show_robots.value and app.layer.ghosts
    assert not any(frame.visible for frame, _ in app.layer.ghosts)
    visible = "n => window.__viserMutable.nodeRefFromName[n].visible"
    assert not pg.evaluate(visible, "/ghosts/0")
    tick = pg.get_by_label("ghost robots at stops")
    tick.click()
    b.wait_for(lambda: app.show_robots.value, 10, "the tick")
    n = len(app.state.plan.stops)
    b.wait_for(lambda: sum(f.visible for f, _ in app.layer.ghosts) == n, 30, "the ghosts")
    b.wait_for(lambda: pg.evaluate(visible, "/ghosts/0"), 10, "the ghost in the browser")
    tick.click()
    b.wait_for(lambda: not any(f.visible for f, _ in app.layer.ghosts), 10, "ghosts hidden")
    b.wait_for(lambda: not pg.evaluate(visible, "/ghosts/0"), 10, "hidden in the browser")


def test_play_route_travels_folded_reaches_each_witness_and_folds_back(pg, app, monkeypatch):
    import pickstop_ui.app as app_module

    b.settled(app)
    monkeypatch.setattr(app_module.time, "sleep", lambda s: None)  # no waiting between frames
    seen = []
    update = app._robot.update_cfg
    monkeypatch.setattr(app._robot, "update_cfg", lambda cfg: (seen.append(np.array(cfg)),
                                                                update(cfg)))  # fmt: skip
    plan = app.state.plan
    app._playback()
    names = list(app._robot.get_actuated_joint_names())
    arm = [names.index(j) for j in plan.joints]
    travel = np.array([app.robot.travel[j] for j in plan.joints])
    assert np.allclose(seen[0][arm], travel) and np.allclose(seen[-1][arm], travel)
    at = [k for k, c in enumerate(seen) if np.allclose(c[arm], travel)]
    for stop in plan.stops:
        for w in stop.witnesses:
            hits = [k for k, c in enumerate(seen) if np.allclose(c[arm], w.theta)]
            assert hits, "a witness never reached"
            # Reached from the travel posture and folded back to it, a few steps each way.
            before = max(k for k in at if k < hits[0])
            after = min(k for k in at if k > hits[0])
            assert hits[0] - before > 2 and after - hits[0] > 2
    # Back at the start when the route is played, the arm in travel.
    s = app.state.doc["start"]
    assert np.allclose(app._robot_frame.position[:2], [s["x"], s["y"]])
    assert np.allclose(app._robot_cfg[arm], travel)
