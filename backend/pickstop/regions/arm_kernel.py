"""The arm's covering spheres against the scene, compiled (numba): where a screen of a few
hundred configurations was mostly numpy calls.

- :func:`screen_links`, :func:`pickstop.regions.arm.screen_arm` in one pass per
  configuration: each joint group's bounds, then each link's bounding sphere placed in the
  world from its joint's frame and tested against the solids it may meet (bounds first, then
  the exact sphere-box or sphere-cylinder distance); where it meets one, each of the link's
  covering spheres (leaves) the same way, every solid a leaf meets recorded. The tests of
  :func:`pickstop.scene.world.spheres_hit` on the spheres of
  :func:`pickstop.regions.arm.points_to_world`, without their temporaries.
- :func:`link_contacts`: the (link, solid) pairs of one configuration whose spheres meet,
  all that :class:`pickstop.regions.arm.ExactArm` hands coal.
- :func:`group_boxes`: per joint group the world box around its spheres, over many
  configurations at once, gathered per owner (:class:`pickstop.speedups.checked.CheckedLinks`).
- :func:`boxes_hit`: which remembered things' boxes a change may reach, and
  :func:`configs_touched`: whether their configurations may see it
  (:meth:`pickstop.speedups.region_memo.RefineMemo.held`), coarse to fine.

Frames, points and boxes go through :mod:`pickstop.robot.frame_kernel`'s helpers. The loops
over solids, links and leaves stay in each kernel: an inlined helper that branches or loops
keeps its array arguments' reference counts, which doubled the time of the kernels here.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pickstop.robot.fk_kernel import joint_frames
from pickstop.robot.frame_kernel import Base, Frame, compose, frame, put, to_world, world_box

BOUNDS_PAD = 1e-9  # [m] a bounding sphere's bounds grown by this against rounding

#: The solids as the kernels take them (:class:`~pickstop.scene.world.BoxArrays`): centres
#: ``(K, 3)``, rotations ``(K, 3, 3)``, half extents ``(K, 3)``, cylinder flags ``(K,)``, radii
#: ``(K,)`` and world bounds ``lo, hi: (K, 3)`` [m].
Solids = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@njit(cache=True, nogil=True, inline="always")
def _in_bounds(
    x: float,
    y: float,
    z: float,
    hx: float,
    hy: float,
    hz: float,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    k: int,
) -> bool:
    """Does the box ``(x, y, z) +- (hx, hy, hz)`` [m] overlap solid ``k``'s bounds? Written
    without a branch (``&``, not ``and``): so inlined, its array arguments cost nothing."""
    return (
        (x + hx > box_lo[k, 0])
        & (x - hx < box_hi[k, 0])
        & (y + hy > box_lo[k, 1])
        & (y - hy < box_hi[k, 1])
        & (z + hz > box_lo[k, 2])
        & (z - hz < box_hi[k, 2])
    )


@njit(cache=True, nogil=True, inline="always")
def _sphere_meets(
    x: float, y: float, z: float, r: float, k: int, solids: Solids, touch: float
) -> bool:
    """Does the sphere ``(x, y, z), r`` meet solid ``k`` (its bounds, then exactly)?"""
    box_c, box_R, box_half, box_cyl, box_rad, box_lo, box_hi = solids
    if not _in_bounds(x, y, z, r, r, r, box_lo, box_hi, k):
        return False
    ex, ey, ez = x - box_c[k, 0], y - box_c[k, 1], z - box_c[k, 2]
    # the centre in the solid's frame: (p - c) @ R
    d0 = ex * box_R[k, 0, 0] + ey * box_R[k, 1, 0] + ez * box_R[k, 2, 0]
    d1 = ex * box_R[k, 0, 1] + ey * box_R[k, 1, 1] + ez * box_R[k, 2, 1]
    d2 = ex * box_R[k, 0, 2] + ey * box_R[k, 1, 2] + ez * box_R[k, 2, 2]
    if box_cyl[k]:
        radial = max(np.hypot(d0, d1) - box_rad[k], 0.0)
        axial = max(abs(d2) - box_half[k, 2], 0.0)
        dist2 = radial * radial + axial * axial
    else:
        q0 = max(abs(d0) - box_half[k, 0], 0.0)
        q1 = max(abs(d1) - box_half[k, 1], 0.0)
        q2 = max(abs(d2) - box_half[k, 2], 0.0)
        dist2 = q0 * q0 + q1 * q1 + q2 * q2
    return dist2 < (r - touch) ** 2


@njit(cache=True, nogil=True)
def screen_links(
    R: np.ndarray,
    p: np.ndarray,
    link_joint: np.ndarray,
    bound_c: np.ndarray,
    bound_r: np.ndarray,
    is_hand: np.ndarray,
    leaf_start: np.ndarray,
    leaf_count: np.ndarray,
    leaf_c: np.ndarray,
    leaf_r: np.ndarray,
    base_xy: np.ndarray,
    cos_yaw: float,
    sin_yaw: float,
    box_c: np.ndarray,
    box_R: np.ndarray,
    box_half: np.ndarray,
    box_cyl: np.ndarray,
    box_rad: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    box_code: np.ndarray,
    code: np.ndarray,
    touch: float,
    group_joint: np.ndarray,
    group_lo: np.ndarray,
    group_hi: np.ndarray,
    link_group: np.ndarray,
    flagged: np.ndarray,
    box_hit: np.ndarray,
) -> None:
    """In place: ``flagged[b]`` set where a covering sphere of configuration b meets a solid,
    ``box_hit[k]`` where one meets solid k (each solid once found is not tested again for a
    configuration already flagged).

    R: ``(J, 3, 3, B)``, p: ``(J, 3, B)`` joint frames in the base frame (:func:`fk_soa`);
    link_joint: ``(L,)`` 0-based joint of each link; leaves of link l are
    ``leaf_start[l] : leaf_start[l] + leaf_count[l]``; base_xy ``(B, 2)``; the solids as
    :class:`~pickstop.scene.world.BoxArrays`, with ``box_code[k]`` their owner's code and
    ``code[b]`` the owner configuration b's hand may touch (-1: none). Groups: a box
    ``group_lo, group_hi`` around the leaves of the links ``link_group == g`` in the frame of
    joint ``group_joint[g]`` (0-based): a solid clear of the box's world bounds meets none of
    them, and their links are tested against the others alone."""
    solids = (box_c, box_R, box_half, box_cyl, box_rad, box_lo, box_hi)
    K = box_lo.shape[0]
    near = np.empty(K, np.int64)  # the solids a link's bounding sphere meets, in order
    g_near = np.empty((group_joint.shape[0], K), np.int64)  # the solids near each group
    g_count = np.zeros(group_joint.shape[0], np.int64)
    for b in range(base_xy.shape[0]):
        base = (base_xy[b, 0], base_xy[b, 1], cos_yaw, sin_yaw)
        Rb, pb = R[:, :, :, b], p[:, :, b]
        for g in range(group_joint.shape[0]):
            j = group_joint[g]
            cx, cy, cz, hx, hy, hz = world_box(
                frame(Rb[j], pb[j]), base, group_lo[g], group_hi[g], BOUNDS_PAD
            )
            n = 0
            for k in range(K):
                if _in_bounds(cx, cy, cz, hx, hy, hz, box_lo, box_hi, k):
                    g_near[g, n] = k
                    n += 1
            g_count[g] = n
        for lk in range(bound_r.shape[0]):
            g = link_group[lk]
            if g < 0 or g_count[g] == 0:  # no leaves, or none near a solid
                continue
            F = frame(Rb[link_joint[lk]], pb[link_joint[lk]])
            skip = code[b] if is_hand[lk] else -1
            wx, wy, wz = to_world(F, base, bound_c[lk, 0], bound_c[lk, 1], bound_c[lk, 2])
            # Every leaf lies inside the bounding sphere: a solid the leaves may meet is one
            # whose bounds meet the bounding sphere's (padded against rounding).
            r = bound_r[lk] + BOUNDS_PAD
            n = 0
            meets = False
            for i in range(g_count[g]):
                k = g_near[g, i]
                if box_code[k] != skip and _in_bounds(wx, wy, wz, r, r, r, box_lo, box_hi, k):
                    near[n] = k
                    n += 1
                    if not meets:
                        meets = _sphere_meets(wx, wy, wz, bound_r[lk], k, solids, touch)
            if not meets:
                continue
            for f in range(leaf_start[lk], leaf_start[lk] + leaf_count[lk]):
                if flagged[b]:
                    # Flagged already: only what no leaf has been seen to touch is news.
                    todo = 0
                    for i in range(n):
                        if not box_hit[near[i]]:
                            near[todo] = near[i]
                            todo += 1
                    n = todo
                    if n == 0:
                        break
                wx, wy, wz = to_world(F, base, leaf_c[f, 0], leaf_c[f, 1], leaf_c[f, 2])
                r = leaf_r[f]
                for i in range(n):
                    k = near[i]
                    # the bounds here first: a call with the solids' arrays costs more
                    if _in_bounds(wx, wy, wz, r, r, r, box_lo, box_hi, k) and _sphere_meets(
                        wx, wy, wz, r, k, solids, touch
                    ):
                        flagged[b] = True
                        box_hit[k] = True


#: One :class:`pickstop.speedups.region_memo.Change` as the kernels pass it, by value (an array
#: argument costs its reference count on every call): the box it was in (lo 0-2, hi 3-5), the
#: box it moved to (6-11, NaN if it did not move) and 1.0 if it moved (12).
ChangeRow = tuple[
    float, float, float, float, float, float, float, float, float, float, float, float, float
]


@njit(cache=True, nogil=True, inline="always")
def _change_row(
    c_lo: np.ndarray,
    c_hi: np.ndarray,
    n_lo: np.ndarray,
    n_hi: np.ndarray,
    moved: np.ndarray,
    h: int,
) -> ChangeRow:
    """Change ``h`` of the arrays as a :data:`ChangeRow`."""
    return (
        c_lo[h, 0], c_lo[h, 1], c_lo[h, 2], c_hi[h, 0], c_hi[h, 1], c_hi[h, 2],
        n_lo[h, 0], n_lo[h, 1], n_lo[h, 2], n_hi[h, 0], n_hi[h, 1], n_hi[h, 2],
        1.0 if moved[h] else 0.0,
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _box_meets(
    lo0: float,
    lo1: float,
    lo2: float,
    hi0: float,
    hi1: float,
    hi2: float,
    b_lo0: float,
    b_lo1: float,
    b_lo2: float,
    b_hi0: float,
    b_hi1: float,
    b_hi2: float,
    same: float,
) -> bool:
    """Do the boxes ``lo, hi`` and ``b_lo, b_hi`` touch or overlap (within ``same``)?"""
    return (
        lo0 <= b_hi0 + same
        and b_lo0 <= hi0 + same
        and lo1 <= b_hi1 + same
        and b_lo1 <= hi1 + same
        and lo2 <= b_hi2 + same
        and b_lo2 <= hi2 + same
    )


@njit(cache=True, nogil=True, inline="always")
def _clip_axis(
    lo: float, hi: float, a_lo: float, a_hi: float, b_lo: float, b_hi: float, same: float
) -> tuple[bool, bool, bool]:
    """On one axis, the interval ``lo, hi`` clipped to ``a`` and to ``b``: whether each clip
    is empty, and whether the two are the same."""
    alo, ahi = max(lo, a_lo), min(hi, a_hi)
    blo, bhi = max(lo, b_lo), min(hi, b_hi)
    return alo > ahi + same, blo > bhi + same, abs(alo - blo) <= same and abs(ahi - bhi) <= same


@njit(cache=True, nogil=True, inline="always")
def _change_hits(
    ch: ChangeRow,
    lo0: float,
    lo1: float,
    lo2: float,
    hi0: float,
    hi1: float,
    hi2: float,
    same: float,
) -> bool:
    """:meth:`pickstop.speedups.region_memo.Change.hits` of the change ``ch`` for the box
    ``lo, hi``."""
    m_old = _box_meets(lo0, lo1, lo2, hi0, hi1, hi2, ch[0], ch[1], ch[2], ch[3], ch[4], ch[5], same)
    if ch[12] == 0.0:
        return m_old
    if not (
        m_old
        or _box_meets(
            lo0, lo1, lo2, hi0, hi1, hi2, ch[6], ch[7], ch[8], ch[9], ch[10], ch[11], same
        )
    ):
        return False
    # Both clip the box to the same bounds, or both miss it: the same inside it.
    e0, f0, s0 = _clip_axis(lo0, hi0, ch[0], ch[3], ch[6], ch[9], same)
    e1, f1, s1 = _clip_axis(lo1, hi1, ch[1], ch[4], ch[7], ch[10], same)
    e2, f2, s2 = _clip_axis(lo2, hi2, ch[2], ch[5], ch[8], ch[11], same)
    a_empty = e0 or e1 or e2
    b_empty = f0 or f1 or f2
    alike = s0 and s1 and s2
    return not ((a_empty and b_empty) or (not a_empty and not b_empty and alike))


@njit(cache=True, nogil=True)
def boxes_hit(
    lo: np.ndarray,
    hi: np.ndarray,
    g_lo: np.ndarray,
    g_hi: np.ndarray,
    c_lo: np.ndarray,
    c_hi: np.ndarray,
    n_lo: np.ndarray,
    n_hi: np.ndarray,
    moved: np.ndarray,
    same: float,
    out: np.ndarray,
) -> None:
    """In place: ``out[h, i]`` set where change ``h`` (as in :func:`configs_touched`) hits
    the box ``lo[i], hi[i]`` (``(n, 3)``) and, where there are finer boxes ``g_*: (n, J, 3)``
    (J > 0), one of box ``i``'s too: the coarse stage of
    :meth:`pickstop.speedups.region_memo.RefineMemo.held`, every change against every box at
    once."""
    n = lo.shape[0]
    J = g_lo.shape[1]
    for h in range(c_lo.shape[0]):
        ch = _change_row(c_lo, c_hi, n_lo, n_hi, moved, h)
        for i in range(n):
            if not _change_hits(
                ch, lo[i, 0], lo[i, 1], lo[i, 2], hi[i, 0], hi[i, 1], hi[i, 2], same
            ):
                continue
            if J == 0:
                out[h, i] = True
                continue
            for j in range(J):
                if _change_hits(
                    ch, g_lo[i, j, 0], g_lo[i, j, 1], g_lo[i, j, 2], g_hi[i, j, 0],
                    g_hi[i, j, 1], g_hi[i, j, 2], same,
                ):  # fmt: skip
                    out[h, i] = True
                    break


@njit(cache=True, nogil=True, inline="always")
def _placed_box_hits(
    ch: ChangeRow, F: Frame, base: Base, lo: np.ndarray, hi: np.ndarray, margin: float,
    same: float,
) -> bool:  # fmt: skip
    """Does the change ``ch`` hit the box ``lo, hi`` (3,) of the joint frame ``F``, the base at
    ``base``, bounded in the world and padded by ``margin``?"""
    cx, cy, cz, hx, hy, hz = world_box(F, base, lo, hi, margin)
    return _change_hits(ch, cx - hx, cy - hy, cz - hz, cx + hx, cy + hy, cz + hz, same)


@njit(cache=True, nogil=True)
def group_boxes(
    thetas: np.ndarray,
    xy: np.ndarray,
    owner: np.ndarray,
    cos_yaw: float,
    sin_yaw: float,
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    group_joint: np.ndarray,
    group_lo: np.ndarray,
    group_hi: np.ndarray,
    margin: float,
    out_lo: np.ndarray,
    out_hi: np.ndarray,
) -> None:
    """In place: ``out_lo[a, g], out_hi[a, g]`` grown to hold, for every configuration
    ``thetas[c]`` on its base ``xy[c]`` with ``owner[c] == a``, the world box of joint group
    ``g``: its box ``group_lo[g], group_hi[g]`` in the frame of joint ``group_joint[g]``
    (0-based) turned into the world (the base at yaw ``cos_yaw, sin_yaw``), padded by
    ``margin``. The chain's arrays as for :func:`~pickstop.robot.fk_kernel.joint_frames`."""
    C, n = thetas.shape
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    for c in range(C):
        a = owner[c]
        joint_frames(R_parent, p_parent, axis_index, axes, prismatic, thetas[c], R, p)
        base = (xy[c, 0], xy[c, 1], cos_yaw, sin_yaw)
        for g in range(group_joint.shape[0]):
            j = group_joint[g]
            cx, cy, cz, hx, hy, hz = world_box(
                frame(R[j], p[j]), base, group_lo[g], group_hi[g], margin
            )
            lo, hi = out_lo[a, g], out_hi[a, g]
            lo[0], lo[1], lo[2] = min(lo[0], cx - hx), min(lo[1], cy - hy), min(lo[2], cz - hz)
            hi[0], hi[1], hi[2] = max(hi[0], cx + hx), max(hi[1], cy + hy), max(hi[2], cz + hz)


@njit(cache=True, nogil=True)
def configs_touched(
    thetas: np.ndarray,
    xy: np.ndarray,
    owner: np.ndarray,
    cos_yaw: float,
    sin_yaw: float,
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    group_joint: np.ndarray,
    group_lo: np.ndarray,
    group_hi: np.ndarray,
    group_start: np.ndarray,
    group_links: np.ndarray,
    link_lo: np.ndarray,
    link_hi: np.ndarray,
    leaf_start: np.ndarray,
    leaf_count: np.ndarray,
    leaf_c: np.ndarray,
    leaf_r: np.ndarray,
    margin: float,
    c_lo: np.ndarray,
    c_hi: np.ndarray,
    n_lo: np.ndarray,
    n_hi: np.ndarray,
    moved: np.ndarray,
    reach: np.ndarray,
    same: float,
    touched: np.ndarray,
) -> None:
    """In place: ``touched[a]`` set where a covering sphere of a configuration owned by ``a``
    (``owner: (C,)``, 0..A-1) may meet a change that reaches ``a`` (``reach: (A, H)``).

    Coarse to fine, as :class:`pickstop.speedups.checked.CheckedLinks` tests: per joint group a
    box around its spheres (``group_*``, joint frames, 0-based ``group_joint``), then the box of
    each of its links (``group_links[group_start[g]:group_start[g + 1]]``), then each sphere,
    every box padded by ``margin``; the changes as :class:`pickstop.speedups.region_memo.Change`
    (``moved[h]``: an axis-aligned box that moved from ``c_*`` to ``n_*``). A configuration's
    frames are computed only while its owner is not yet known to be touched."""
    C, n = thetas.shape
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    for c in range(C):
        a = owner[c]
        if touched[a]:
            continue
        joint_frames(R_parent, p_parent, axis_index, axes, prismatic, thetas[c], R, p)
        base = (xy[c, 0], xy[c, 1], cos_yaw, sin_yaw)
        for h in range(c_lo.shape[0]):
            if not reach[a, h] or touched[a]:
                continue
            ch = _change_row(c_lo, c_hi, n_lo, n_hi, moved, h)
            for g in range(group_joint.shape[0]):
                F = frame(R[group_joint[g]], p[group_joint[g]])
                if not _placed_box_hits(ch, F, base, group_lo[g], group_hi[g], margin, same):
                    continue
                for i in range(group_start[g], group_start[g + 1]):
                    lk = group_links[i]
                    if not _placed_box_hits(ch, F, base, link_lo[lk], link_hi[lk], margin, same):
                        continue
                    for f in range(leaf_start[lk], leaf_start[lk] + leaf_count[lk]):
                        wx, wy, wz = to_world(F, base, leaf_c[f, 0], leaf_c[f, 1], leaf_c[f, 2])
                        r = leaf_r[f] + margin
                        if _change_hits(ch, wx - r, wy - r, wz - r, wx + r, wy + r, wz + r, same):
                            touched[a] = True
                            break
                    if touched[a]:
                        break
                if touched[a]:
                    break


@njit(cache=True, nogil=True)
def link_contacts(
    M: np.ndarray,
    link_joint: np.ndarray,
    bound_c: np.ndarray,
    bound_r: np.ndarray,
    is_hand: np.ndarray,
    leaf_start: np.ndarray,
    leaf_count: np.ndarray,
    leaf_c: np.ndarray,
    leaf_r: np.ndarray,
    bx: float,
    by: float,
    cos_yaw: float,
    sin_yaw: float,
    box_c: np.ndarray,
    box_R: np.ndarray,
    box_half: np.ndarray,
    box_cyl: np.ndarray,
    box_rad: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    box_code: np.ndarray,
    code: int,
    touch: float,
    out_link: np.ndarray,
    out_box: np.ndarray,
) -> int:
    """Every (link, solid) pair of one configuration where a covering sphere of the link
    meets the solid, as :func:`screen_links` tests them; returns how many, written to
    ``out_link``, ``out_box`` (each at least ``L * K`` long).

    M: ``(n + 1, 4, 4)`` the joints' placements in the base frame (index = joint id, as
    ``link_joint``); the base at ``(bx, by)``; ``code``: the owner the hand may touch."""
    solids = (box_c, box_R, box_half, box_cyl, box_rad, box_lo, box_hi)
    base = (bx, by, cos_yaw, sin_yaw)
    K = box_lo.shape[0]
    near = np.empty(K, np.int64)
    found = np.zeros(K, np.bool_)
    count = 0
    for lk in range(bound_r.shape[0]):
        F = frame(M[link_joint[lk]], M[link_joint[lk], :, 3])
        skip = code if is_hand[lk] else -1
        wx, wy, wz = to_world(F, base, bound_c[lk, 0], bound_c[lk, 1], bound_c[lk, 2])
        r = bound_r[lk] + BOUNDS_PAD
        n = 0
        meets = False
        for k in range(K):
            if box_code[k] != skip and _in_bounds(wx, wy, wz, r, r, r, box_lo, box_hi, k):
                near[n] = k
                n += 1
                if not meets:
                    meets = _sphere_meets(wx, wy, wz, bound_r[lk], k, solids, touch)
        if not meets:
            continue
        left = n
        for f in range(leaf_start[lk], leaf_start[lk] + leaf_count[lk]):
            wx, wy, wz = to_world(F, base, leaf_c[f, 0], leaf_c[f, 1], leaf_c[f, 2])
            r = leaf_r[f]
            for i in range(n):
                k = near[i]
                if (
                    not found[k]
                    and _in_bounds(wx, wy, wz, r, r, r, box_lo, box_hi, k)
                    and _sphere_meets(wx, wy, wz, r, k, solids, touch)
                ):
                    found[k] = True
                    out_link[count] = lk
                    out_box[count] = k
                    count += 1
                    left -= 1
            if left == 0:
                break
        for i in range(n):
            found[near[i]] = False
    return count


@njit(cache=True, nogil=True, inline="always")
def _place_row(
    theta: np.ndarray,
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    geom_parent: np.ndarray,
    geom_R: np.ndarray,
    geom_p: np.ndarray,
    geom_c: np.ndarray,
    geom_h: np.ndarray,
    R: np.ndarray,
    p: np.ndarray,
    M: np.ndarray,
    R_geom: np.ndarray,
    p_geom: np.ndarray,
) -> float:
    """One row of :func:`contacts_many`: the joints' placements of ``theta`` into ``M`` (by
    way of ``R, p``), the geometries' into ``R_geom, p_geom``; returns their lowest z [m]."""
    joint_frames(R_parent, p_parent, axis_index, axes, prismatic, theta, R, p)
    for r in range(4):
        for c in range(4):
            M[0, r, c] = 1.0 if r == c else 0.0
    M[1:, :3, :3] = R
    M[1:, :3, 3] = p
    M[1:, 3, :3] = 0.0
    M[1:, 3, 3] = 1.0
    low = np.inf
    for g in range(geom_parent.shape[0]):
        j = geom_parent[g]
        put(compose(frame(M[j], M[j, :, 3]), frame(geom_R[g], geom_p[g])), R_geom[g], p_geom[g])
        z = p_geom[g, 2]
        for c in range(3):
            z += R_geom[g, 2, c] * geom_c[g, c] - abs(R_geom[g, 2, c]) * geom_h[g, c]
        low = min(low, z)
    return low


@njit(cache=True, nogil=True)
def contacts_many(
    thetas: np.ndarray,
    xy: np.ndarray,
    codes: np.ndarray,
    cos_yaw: float,
    sin_yaw: float,
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    link_joint: np.ndarray,
    bound_c: np.ndarray,
    bound_r: np.ndarray,
    is_hand: np.ndarray,
    leaf_start: np.ndarray,
    leaf_count: np.ndarray,
    leaf_c: np.ndarray,
    leaf_r: np.ndarray,
    box_c: np.ndarray,
    box_R: np.ndarray,
    box_half: np.ndarray,
    box_cyl: np.ndarray,
    box_rad: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    box_code: np.ndarray,
    touch: float,
    geom_parent: np.ndarray,
    geom_R: np.ndarray,
    geom_p: np.ndarray,
    geom_c: np.ndarray,
    geom_h: np.ndarray,
    M: np.ndarray,
    R_geom: np.ndarray,
    p_geom: np.ndarray,
    z_low: np.ndarray,
    start: np.ndarray,
    out_link: np.ndarray,
    out_box: np.ndarray,
) -> None:
    """:func:`link_contacts` of B configurations ``thetas: (B, n)`` on bases ``xy: (B, 2)``,
    the hand of each free to touch owner ``codes[b]``: the joints' placements into
    ``M: (B, n + 1, 4, 4)`` (:func:`~pickstop.robot.fk_kernel.joint_frames`, the base at index
    0) and configuration ``b``'s pairs into ``out_link, out_box[start[b]:start[b + 1]]``
    (``start: (B + 1,)``; the outputs at least ``B * L * K`` long). The G geometries on joints
    ``geom_parent`` at ``geom_R, geom_p`` there are placed in the base frame into
    ``R_geom: (B, G, 3, 3)``, ``p_geom: (B, G, 3)`` (as
    :class:`~pickstop.robot.floor.Placements` places them), and ``z_low: (B,)`` is the lowest
    z of their local bounding boxes (centres ``geom_c``, half extents ``geom_h``) so placed."""
    B, n = thetas.shape
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    start[0] = 0
    for b in range(B):
        z_low[b] = _place_row(thetas[b], R_parent, p_parent, axis_index, axes, prismatic,
                              geom_parent, geom_R, geom_p, geom_c, geom_h, R, p, M[b],
                              R_geom[b], p_geom[b])  # fmt: skip
        # written in place: the outputs hold at least L * K slots past any row's start
        k = link_contacts(
            M[b], link_joint, bound_c, bound_r, is_hand, leaf_start, leaf_count, leaf_c,
            leaf_r, xy[b, 0], xy[b, 1], cos_yaw, sin_yaw, box_c, box_R, box_half, box_cyl,
            box_rad, box_lo, box_hi, box_code, codes[b], touch, out_link[start[b]:],
            out_box[start[b]:],
        )  # fmt: skip
        start[b + 1] = start[b] + k
