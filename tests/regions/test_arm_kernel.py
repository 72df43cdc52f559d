"""The compiled kernels against the numpy computations they stand for."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.frames import R_z
from pickstop.regions.arm import TOUCH, ArmSpheres, ExactArm, points_to_world
from pickstop.regions.arm_kernel import contacts_many, link_contacts
from pickstop.robot.fk_kernel import joint_frames
from pickstop.robot.kinematics import FEW, Chain, fk_soa
from pickstop.scene.load import load_scene
from pickstop.scene.world import AGREE_MARGIN, BoxArrays, scene_solids, spheres_hit
from pickstop.speedups.checked import CheckedConfigs, group_boxes_of
from pickstop.speedups.region_memo import Change, ChangeSet
from tests.regions.conftest import EXAMPLES
from tests.utils import random_thetas


@pytest.fixture(scope="module")
def tiago_kit(tiago):
    return SimpleNamespace(
        arm=ArmSpheres.of(tiago), solver=SimpleNamespace(chain=Chain.from_robot(tiago))
    )


@pytest.mark.parametrize("name", ["tiago", "pr2"])
def test_joint_frames_are_pinocchios(name, request):
    """The compiled FK of one configuration, and :func:`fk_soa` of a few (compiled) and of
    many (numpy), place every joint where pinocchio does."""
    robot = request.getfixturevalue(name)
    chain = Chain.from_robot(robot)
    assert robot.model.njoints - 1 == robot.dof  # joint i of the chain is pinocchio's i + 1
    thetas = random_thetas(robot, FEW + 50, seed=5)
    data = robot.model.createData()
    few = fk_soa(chain, np.ascontiguousarray(thetas[:50].T), frames=True)[2]
    many = fk_soa(chain, np.ascontiguousarray(thetas.T), frames=True)[2]
    R = np.empty((robot.dof, 3, 3))
    p = np.empty((robot.dof, 3))
    for b, theta in enumerate(thetas[:50]):
        pin.forwardKinematics(robot.model, data, robot.angles_to_q(theta))
        joint_frames(
            chain.R_parent_joint, chain.p_parent_joint, chain.axis_index, chain.axes,
            chain.prismatic, theta, R, p,
        )  # fmt: skip
        for j in range(robot.dof):
            M = data.oMi[j + 1]
            for Rj, pj in ((R[j], p[j]), (few[j][0][:, :, b], few[j][1][:, b]),
                           (many[j][0][:, :, b], many[j][1][:, b])):  # fmt: skip
                assert np.allclose(Rj, M.rotation, atol=1e-12)
                assert np.allclose(pj, M.translation, atol=1e-12)


def _world_box(Rz, Rj, pj, lo, hi, base):
    """The world box ``(1, 3)`` twice of the box ``lo, hi`` in a joint's frame ``Rj, pj``,
    the base at ``base`` turned by ``Rz``, padded by :data:`AGREE_MARGIN`."""
    c = Rz @ (Rj @ ((lo + hi) / 2) + pj) + np.array([base[0], base[1], 0.0])
    half = np.abs(Rz @ Rj) @ ((hi - lo) / 2) + AGREE_MARGIN
    return (c - half)[None], (c + half)[None]


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_group_boxes_gather_each_owners_numpy_boxes_and_hold_its_spheres(tiago, tiago_kit, seed):
    """Per owner and joint group, the compiled boxes are the numpy boxes of its
    configurations gathered (min and max), hold every covering sphere of the group's links
    (padded), and stay empty (inf) for an owner without configurations."""
    rng = np.random.default_rng(seed)
    C, A = 60, 9
    thetas = random_thetas(tiago, C, seed=seed % 1000)
    xy = rng.uniform(-0.5, 0.5, (C, 2))
    yaw = float(rng.uniform(-np.pi, np.pi))
    owner = rng.integers(0, A - 1, C)  # owner A - 1 has none
    lo, hi = group_boxes_of(tiago_kit, thetas, xy, yaw, owner, A)
    groups, arm = tiago_kit.arm.joint_groups, tiago_kit.arm
    _, _, frames = fk_soa(tiago_kit.solver.chain, np.ascontiguousarray(thetas.T), frames=True)
    want_lo = np.full_like(lo, np.inf)
    want_hi = np.full_like(hi, -np.inf)
    Rz = R_z(yaw)
    for c in range(C):
        for g, j in enumerate(groups.joints):
            Rj, pj = frames[j - 1][0][:, :, c], frames[j - 1][1][:, c]
            b_lo, b_hi = _world_box(Rz, Rj, pj, groups.lo[g], groups.hi[g], xy[c])
            want_lo[owner[c], g] = np.minimum(want_lo[owner[c], g], b_lo[0])
            want_hi[owner[c], g] = np.maximum(want_hi[owner[c], g], b_hi[0])
            for lk in groups.links[g]:
                s = slice(arm.leaf_start[lk], arm.leaf_start[lk] + arm.leaf_count[lk])
                centres = (Rz @ (Rj @ arm.leaf_c[s].T + pj[:, None])).T + np.array([*xy[c], 0.0])
                r = arm.leaf_r[s, None]
                assert np.all(centres - r >= lo[owner[c], g] - 1e-12)
                assert np.all(centres + r <= hi[owner[c], g] + 1e-12)
    assert np.allclose(lo, want_lo, atol=1e-12) and np.allclose(hi, want_hi, atol=1e-12)
    assert np.all(np.isinf(lo[A - 1])) and np.isfinite(lo[: A - 1]).any()


def _touched_reference(kit, thetas, xy, yaw, owner, changes, reached):
    """Owners some padded covering sphere of whose configurations a change reaching them
    hits, tested coarse to fine with numpy and :meth:`Change.hits`."""
    arm, chain = kit.arm, kit.solver.chain
    groups = arm.joint_groups
    link_lo, link_hi = arm.link_boxes
    _, _, frames = fk_soa(chain, np.ascontiguousarray(thetas.T), frames=True)
    Rz = R_z(yaw)

    def world_box(Rj, pj, lo, hi, base):
        return _world_box(Rz, Rj, pj, lo, hi, base)

    out = set()
    for b in range(len(thetas)):
        for change, ids in zip(changes, reached, strict=True):
            if owner[b] not in ids or owner[b] in out:
                continue
            for g, j in enumerate(groups.joints):
                Rj, pj = frames[j - 1][0][:, :, b], frames[j - 1][1][:, b]
                if not change.hits(*world_box(Rj, pj, groups.lo[g], groups.hi[g], xy[b]))[0]:
                    continue
                for lk in groups.links[g]:
                    box = world_box(Rj, pj, link_lo[lk], link_hi[lk], xy[b])
                    if not change.hits(*box)[0]:
                        continue
                    leaves = np.flatnonzero(arm.leaf_link == lk)
                    base = np.array([*xy[b], 0.0])
                    cl = (Rz @ (Rj @ arm.leaf_c[leaves].T + pj[:, None])).T + base
                    r = (arm.leaf_r[leaves] + AGREE_MARGIN)[:, None]
                    if change.hits(cl - r, cl + r).any():
                        out.add(int(owner[b]))
    return out


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_configurations_touched_by_changes_are_the_numpy_tests(tiago, tiago_kit, seed):
    """The compiled fine test finds exactly the owners the numpy boxes and spheres find, for
    boxes that fill (or left) a place and axis-aligned boxes that moved."""
    rng = np.random.default_rng(seed)
    C, owners = 80, 20
    thetas = random_thetas(tiago, C, seed=seed % 1000)
    xy = rng.uniform(-0.3, 0.3, (C, 2))
    yaw = float(rng.uniform(-np.pi, np.pi))
    owner = rng.integers(0, owners, C) * 3 + 7  # any ids
    changes = []
    for k in range(4):
        lo = np.array([*rng.uniform(-1.2, 0.8, 2), rng.uniform(0.0, 1.2)])
        hi = lo + rng.uniform(0.1, 0.6, 3)
        if k % 2:
            d = np.array([rng.uniform(0.02, 0.3), 0.0, 0.0])
            changes.append(Change(lo, hi, lo + d, hi + d))
        else:
            changes.append(Change(lo, hi))
    # the base's column: every configuration's torso stands in it
    changes.append(Change(np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 0.8])))
    ids = np.unique(owner)
    some = ids[: 3 * len(ids) // 4]  # the rest is reached by no change
    reached = [np.unique(rng.choice(some, owners // 2)) for _ in changes]
    got = CheckedConfigs(tiago_kit, thetas, xy, yaw, owner).touched_by(changes, reached)
    want = _touched_reference(tiago_kit, thetas, xy, yaw, owner, changes, reached)
    assert set(got.tolist()) == want
    assert want and not set(ids[len(some) :].tolist()) & want


def _hit_reference(changes, lo, hi, g_lo=None, g_hi=None):
    """:meth:`RefineMemo.held`'s coarse stage with numpy: each change against each box, then
    against the finer boxes of the boxes it hit."""
    out = np.zeros((len(changes), len(lo)), bool)
    for h, c in enumerate(changes):
        hit = np.flatnonzero(c.hits(lo, hi))
        if len(hit) and g_lo is not None:
            J = g_lo.shape[1]
            sub_lo, sub_hi = g_lo[hit].reshape(-1, 3), g_hi[hit].reshape(-1, 3)
            hit = hit[c.hits(sub_lo, sub_hi).reshape(-1, J).any(1)]
        out[h, hit] = True
    return out


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_boxes_hit_by_changes_are_the_numpy_tests(seed):
    """The compiled coarse stage marks exactly the boxes :meth:`Change.hits` marks, with and
    without finer boxes, for boxes that fill a place and boxes that moved, including moves
    along a box (clipped alike: no change inside it) and boxes that just touch."""
    rng = np.random.default_rng(seed)
    n, J = 300, 4
    g_lo = rng.uniform(-1.0, 1.0, (n, J, 3)).round(2)  # on a 1 cm lattice: touching happens
    g_hi = g_lo + rng.uniform(0.0, 0.4, (n, J, 3)).round(2)
    lo, hi = g_lo.min(1), g_hi.max(1)
    changes = []
    for k in range(6):
        c_lo = rng.uniform(-1.0, 1.0, 3).round(2)
        c_hi = c_lo + rng.uniform(0.05, 0.8, 3).round(2)
        if k % 3 == 0:
            changes.append(Change(c_lo, c_hi))
        else:
            d = np.zeros(3)
            d[k % 3] = rng.choice([-1, 1]) * rng.uniform(0.01, 0.5)
            if k == 5:  # a long slab slid along its length: alike inside most boxes
                c_lo[0], c_hi[0] = -5.0, 5.0
                d = np.array([0.3, 0.0, 0.0])
            changes.append(Change(c_lo, c_hi, c_lo + d, c_hi + d))
    cs = ChangeSet.of(changes)
    want = _hit_reference(changes, lo, hi, g_lo, g_hi)
    assert np.array_equal(cs.hit(lo, hi, (g_lo, g_hi)), want)
    assert np.array_equal(cs.hit(lo, hi), _hit_reference(changes, lo, hi))
    assert want.any() and not want.all()
    fixed = ChangeSet.boxes(np.array([c.lo for c in changes]), np.array([c.hi for c in changes]))
    assert np.array_equal(
        fixed.hit(lo, hi), _hit_reference([Change(c.lo, c.hi) for c in changes], lo, hi)
    )
    assert ChangeSet.of([]).hit(lo, hi).shape == (0, n)


@pytest.fixture(scope="module")
def paper_solids():
    solids = scene_solids(load_scene(EXAMPLES / "paper_experiment.json"))
    return solids, BoxArrays.of(solids), [BoxArrays.of([s]) for s in solids]


def _pairs_reference(arm, frames, b, xy, yaw, solids, code):
    """The (link, solid) pairs of configuration ``b`` of :func:`fk_soa`'s ``frames`` where a
    covering sphere of the link meets the solid (:func:`spheres_hit`, one solid at a time),
    solids of owner ``code`` no obstacle for the hand."""
    _, boxes, each = solids
    leaves = points_to_world(frames, arm.link_joint[arm.leaf_link], arm.leaf_c, xy, yaw)[b]
    out = set()
    for k, one in enumerate(each):
        hit = spheres_hit(one, leaves, arm.leaf_r)
        if boxes.owner_codes[k] == code:
            hit &= ~arm.is_hand[arm.leaf_link]
        out |= {(int(lk), k) for lk in np.unique(arm.leaf_link[hit])}
    return out


def _bases(rng, tiago, n):
    th = rng.uniform(tiago.lower, tiago.upper, (n, tiago.dof))
    xy = np.stack([rng.uniform(0.5, 2.2, n), rng.uniform(0.6, 1.1, n)], 1)
    return th, xy, float(rng.uniform(0, 2 * np.pi))


def _contacts_of_one(arm, M, x, y, yaw, boxes, code):
    L, K = len(arm.bound_r), len(boxes.owners)
    out_link, out_box = np.empty(L * K, np.int64), np.empty(L * K, np.int64)
    n = link_contacts(
        M, arm.link_joint, arm.bound_c, arm.bound_r, arm.is_hand, arm.leaf_start,
        arm.leaf_count, arm.leaf_c, arm.leaf_r, x, y, np.cos(yaw), np.sin(yaw), boxes.centres,
        boxes.R, boxes.half, boxes.is_cylinder, boxes.radius, boxes.lo, boxes.hi,
        boxes.owner_codes, code, TOUCH, out_link, out_box,
    )  # fmt: skip
    return list(zip(out_link[:n].tolist(), out_box[:n].tolist(), strict=True))


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_link_contacts_are_the_pairs_whose_numpy_spheres_meet(tiago, tiago_kit, paper_solids, seed):
    """Per configuration, the compiled contacts are each (link, solid) pair where a covering
    sphere of the link meets the solid, once, the hand's target owner no obstacle for it."""
    rng = np.random.default_rng(seed)
    _, boxes, _ = paper_solids
    arm, exact = tiago_kit.arm, ExactArm(tiago)
    n = 60
    th, xy, yaw = _bases(rng, tiago, n)
    codes = rng.integers(-1, len(boxes.owner_index), n)
    _, _, frames = fk_soa(tiago_kit.solver.chain, np.ascontiguousarray(th.T), frames=True)
    found = 0
    for b in range(n):
        exact.place(th[b])
        got = _contacts_of_one(arm, exact.M, xy[b, 0], xy[b, 1], yaw, boxes, codes[b])
        assert len(set(got)) == len(got)
        assert set(got) == _pairs_reference(arm, frames, b, xy, yaw, paper_solids, codes[b])
        found += bool(got)
    assert 0 < found < n


@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_contacts_many_are_link_contacts_row_by_row(tiago, tiago_kit, paper_solids, seed):
    """The batched kernel places each row's joints as the one-configuration FK does, its
    geometries and their lowest points as numpy does, and finds the pairs
    :func:`link_contacts` finds, in its order."""
    rng = np.random.default_rng(seed)
    _, boxes, _ = paper_solids
    arm, chain, exact = tiago_kit.arm, tiago_kit.solver.chain, ExactArm(tiago)
    fl, pl = exact.floor, exact.floor.placements
    B, n = 40, tiago.dof
    th, xy, yaw = _bases(rng, tiago, B)
    codes = rng.integers(-1, len(boxes.owner_index), B)
    G, L, K = len(pl.parent), len(arm.bound_r), len(boxes.owners)
    M, R, p = np.empty((B, n + 1, 4, 4)), np.empty((B, G, 3, 3)), np.empty((B, G, 3))
    z, start = np.empty(B), np.zeros(B + 1, np.int64)
    out_link, out_box = np.empty(B * L * K, np.int64), np.empty(B * L * K, np.int64)
    contacts_many(
        th, xy, codes, np.cos(yaw), np.sin(yaw), chain.R_parent_joint, chain.p_parent_joint,
        chain.axis_index.astype(np.int64), chain.axes, chain.prismatic, arm.link_joint,
        arm.bound_c, arm.bound_r, arm.is_hand, arm.leaf_start, arm.leaf_count, arm.leaf_c,
        arm.leaf_r, boxes.centres, boxes.R, boxes.half, boxes.is_cylinder, boxes.radius,
        boxes.lo, boxes.hi, boxes.owner_codes, TOUCH, pl.parent,
        np.ascontiguousarray(pl.R_local), np.ascontiguousarray(pl.p_local), fl.box_c, fl.box_h,
        M, R, p, z, start, out_link, out_box,
    )  # fmt: skip
    for b in range(B):
        exact.place(th[b])
        assert np.array_equal(M[b], exact.M)
        assert np.allclose(R[b], exact.R, atol=1e-12) and np.allclose(p[b], exact.p, atol=1e-12)
        low = np.einsum("gj,gj->g", R[b, :, 2], fl.box_c) + p[b, :, 2]
        low -= np.einsum("gj,gj->g", np.abs(R[b, :, 2]), fl.box_h)
        assert np.isclose(z[b], low.min(), atol=1e-12)
        rows = slice(start[b], start[b + 1])
        got = list(zip(out_link[rows].tolist(), out_box[rows].tolist(), strict=True))
        assert got == _contacts_of_one(arm, M[b], xy[b, 0], xy[b, 1], yaw, boxes, codes[b])
    assert 0 < start[B] < B * L * K
