"""The floor as an obstacle: the sphere screens hold the exact coal check, for links and hand."""

from __future__ import annotations

import numpy as np
import pytest

from pickstop.regions.arm import ArmSpheres, ExactArm, screen_arm
from pickstop.robot.floor import ExactFloor, FloorSpheres, below_floor
from pickstop.robot.kinematics import Chain, fk_soa
from pickstop.scene.world import BoxArrays
from tests.utils import random_thetas

CLEARANCE = 0.01


@pytest.fixture(scope="module")
def floor_spheres(tiago):
    return FloorSpheres.of(tiago)


@pytest.fixture(scope="module")
def arm_spheres(tiago):
    return ArmSpheres.of(tiago)


@pytest.fixture(scope="module")
def low_thetas(tiago):
    """Random configurations, half of them with the torso down and the shoulder pitched
    forward-down, so that many reach the floor."""
    th = random_thetas(tiago, 1600, seed=5)
    names = [j.name for j in tiago.joints]
    half = th[::2]
    half[:, names.index("torso_lift_joint")] = tiago.lower[0]
    half[:, names.index("arm_2_joint")] = np.random.default_rng(6).uniform(-1.5, -0.5, len(half))
    th[::2] = half
    return th


def _frames(robot, thetas):
    return fk_soa(Chain.from_robot(robot), np.ascontiguousarray(thetas.T), frames=True)[2]


@pytest.mark.parametrize("clearance", [0.0, CLEARANCE, 0.2])
def test_screens_reject_every_configuration_the_exact_check_finds_below(
    tiago, floor_spheres, arm_spheres, low_thetas, clearance
):
    exact = ExactFloor(tiago).colliding(low_thetas, clearance)
    assert exact.sum() > 50, "too few configurations reach the floor to test anything"
    frames = _frames(tiago, low_thetas)
    build_screen = below_floor(floor_spheres, frames, clearance)
    xy = np.zeros((len(low_thetas), 2))
    region_screen = screen_arm(arm_spheres, BoxArrays.of([]), frames, xy, 0.0, floor=clearance)
    for flagged in (build_screen, region_screen):
        assert not (exact & ~flagged).any(), "a configuration below the floor passed the screen"
        # Conservative but tight: covers stick out by at most 1 cm.
        assert (flagged & ~exact).sum() <= 0.25 * exact.sum()


def _hand_geometry(robot, name: str) -> bool:
    """Is the geometry ``name`` part of the hand (a stand-in box ``hand:<k>`` or a hand link's)?"""
    from pickstop.robot.link_geometry import is_hand_link

    if name.startswith("hand:"):
        return True
    geom = robot.geom_model.geometryObjects[robot.geom_model.getGeometryId(name)]
    return is_hand_link(robot, robot.model.frames[geom.parentFrame].name)


def _lowest(tiago, thetas, only_hand: bool) -> np.ndarray:
    exact = ExactFloor(tiago)
    for th in thetas:
        names = exact.below(th, CLEARANCE)
        if names and all(_hand_geometry(tiago, n) for n in names) == only_hand:
            return th
    raise AssertionError("no such configuration among the samples")


@pytest.mark.parametrize("only_hand", [False, True])
def test_a_configuration_below_the_floor_is_rejected_by_screen_and_exact_check(
    tiago, arm_spheres, low_thetas, only_hand
):
    """A configuration with an arm link below the floor, and one where only the hand (TIAGo's
    own Hey5 links, or boxes where a preset stands them in) reaches below: both rejected, by
    both checks."""
    theta = _lowest(tiago, low_thetas, only_hand)
    exact = ExactArm(tiago)
    assert exact.colliding(theta, 1.0, 2.0, 0.3, [], floor=CLEARANCE)
    assert not exact.colliding(theta, 1.0, 2.0, 0.3, [])  # nothing else is in the way
    frames = _frames(tiago, theta[None])
    xy = np.array([[1.0, 2.0]])
    assert screen_arm(arm_spheres, BoxArrays.of([]), frames, xy, 0.3, floor=CLEARANCE)[0]
    assert below_floor(FloorSpheres.of(tiago), frames, CLEARANCE)[0]
    names = exact.below_floor(CLEARANCE)
    assert names and all(_hand_geometry(tiago, n) for n in names) == only_hand


def test_lifting_the_floor_check_away_frees_the_configuration(tiago, arm_spheres, low_thetas):
    """The floor is at z = 0 of the base: a clearance below the lowest point frees it."""
    theta = _lowest(tiago, low_thetas, False)
    frames = _frames(tiago, theta[None])
    xy = np.zeros((1, 2))
    assert screen_arm(arm_spheres, BoxArrays.of([]), frames, xy, 0.0, floor=CLEARANCE)[0]
    assert not screen_arm(arm_spheres, BoxArrays.of([]), frames, xy, 0.0, floor=-2.0)[0]
    assert not ExactArm(tiago).colliding(theta, 0.0, 0.0, 0.0, [], floor=-2.0)


def test_a_hand_of_links_is_screened_by_its_own_links(pr2):
    """PR2 checks its own gripper links: they are among the covered links, and the screens
    hold the exact check on random configurations."""
    from pickstop.robot.link_geometry import arm_links, is_hand_link

    assert any(is_hand_link(pr2, lk.name) for lk in arm_links(pr2))
    th = random_thetas(pr2, 1200, seed=9)
    frames = _frames(pr2, th)
    exact = ExactFloor(pr2)
    for clearance in (CLEARANCE, 0.3):
        below = exact.colliding(th, clearance)
        flagged = below_floor(FloorSpheres.of(pr2), frames, clearance)
        assert not (below & ~flagged).any()
    assert below.sum() > 20  # at 0.3 m many configurations reach down that far
    hands = [n for t in th[below][:50] for n in exact.below(t, 0.3)]
    assert any(n.startswith("r_gripper") for n in hands)


@pytest.mark.parametrize("name", ["tiago", "pr2"])
def test_geometry_placements_are_pinocchios(name, request):
    """Placements of the checked geometries, computed for all at once from the joints, are
    where ``pin.updateGeometryPlacements`` puts them."""
    import pinocchio as pin

    from pickstop.robot.floor import Placements

    robot = request.getfixturevalue(name)
    floor = ExactFloor(robot)
    placements = Placements(robot, floor.ids)
    data = robot.model.createData()
    gdata = pin.GeometryData(robot.geom_model)
    for theta in random_thetas(robot, 20, seed=3):
        q = robot.angles_to_q(theta)
        pin.forwardKinematics(robot.model, data, q)
        pin.updateGeometryPlacements(robot.model, data, robot.geom_model, gdata)
        R, p = placements.of(data)
        for k, i in enumerate(floor.ids):
            assert np.allclose(R[k], gdata.oMg[i].rotation, atol=1e-12)
            assert np.allclose(p[k], gdata.oMg[i].translation, atol=1e-12)


@pytest.mark.parametrize("name", ["tiago", "pr2"])
def test_exact_arm_places_its_geometries_where_pinocchio_does(name, request):
    """The exact check's placements, from the chain's compiled FK, are pinocchio's."""
    import pinocchio as pin

    robot = request.getfixturevalue(name)
    exact = ExactArm(robot)
    data = robot.model.createData()
    gdata = pin.GeometryData(robot.geom_model)
    for theta in random_thetas(robot, 20, seed=8):
        exact.place(theta)
        pin.forwardKinematics(robot.model, data, robot.angles_to_q(theta))
        pin.updateGeometryPlacements(robot.model, data, robot.geom_model, gdata)
        for k, i in enumerate(exact.ids):
            assert np.allclose(exact.R[k], gdata.oMg[i].rotation, atol=1e-12)
            assert np.allclose(exact.p[k], gdata.oMg[i].translation, atol=1e-12)
        assert np.allclose(exact.M[robot.dof], data.oMi[robot.dof].homogeneous, atol=1e-12)
