"""The arm's sphere screen against the scene's solids, compiled (numba).

:func:`pickstop.regions.arm.screen_arm` in one pass per configuration: each link's bounding
sphere placed in the world from its joint's frame and tested against every solid it may meet
(its bounds first, then the exact sphere-box or sphere-cylinder distance); where it meets one,
each of the link's covering spheres (leaves) the same way, every solid a leaf meets recorded.
The tests of :func:`pickstop.scene.world.spheres_hit` on the spheres of
:func:`pickstop.regions.arm.points_to_world`, without their temporaries: a screen of a few
hundred configurations was mostly numpy calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

BOUNDS_PAD = 1e-9  # [m] a bounding sphere's bounds grown by this against rounding


@njit(cache=True, nogil=True, inline="always")
def _sphere_meets(
    x: float,
    y: float,
    z: float,
    r: float,
    k: int,
    box_c: np.ndarray,
    box_R: np.ndarray,
    box_half: np.ndarray,
    box_cyl: np.ndarray,
    box_rad: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    touch: float,
) -> bool:
    """Does the sphere ``(x, y, z), r`` meet solid ``k`` (its bounds, then exactly)?"""
    if not (
        x + r > box_lo[k, 0]
        and x - r < box_hi[k, 0]
        and y + r > box_lo[k, 1]
        and y - r < box_hi[k, 1]
        and z + r > box_lo[k, 2]
        and z - r < box_hi[k, 2]
    ):
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
    ``code[b]`` the owner configuration b's hand may touch (-1: none)."""
    B = base_xy.shape[0]
    L = bound_r.shape[0]
    K = box_lo.shape[0]
    near = np.empty(K, np.int64)  # the solids a link's bounding sphere meets, in order
    for b in range(B):
        bx, by = base_xy[b, 0], base_xy[b, 1]
        for lk in range(L):
            j = link_joint[lk]
            skip = code[b] if is_hand[lk] else -1
            # the bounding sphere in the world
            lx, ly, lz = bound_c[lk, 0], bound_c[lk, 1], bound_c[lk, 2]
            px = R[j, 0, 0, b] * lx + R[j, 0, 1, b] * ly + R[j, 0, 2, b] * lz + p[j, 0, b]
            py = R[j, 1, 0, b] * lx + R[j, 1, 1, b] * ly + R[j, 1, 2, b] * lz + p[j, 1, b]
            pz = R[j, 2, 0, b] * lx + R[j, 2, 1, b] * ly + R[j, 2, 2, b] * lz + p[j, 2, b]
            wx = cos_yaw * px - sin_yaw * py + bx
            wy = sin_yaw * px + cos_yaw * py + by
            # Every leaf lies inside the bounding sphere: a solid the leaves may meet is one
            # whose bounds meet the bounding sphere's (padded against rounding).
            r = bound_r[lk] + BOUNDS_PAD
            n = 0
            meets = False
            for k in range(K):
                if (
                    box_code[k] != skip
                    and wx + r > box_lo[k, 0]
                    and wx - r < box_hi[k, 0]
                    and wy + r > box_lo[k, 1]
                    and wy - r < box_hi[k, 1]
                    and pz + r > box_lo[k, 2]
                    and pz - r < box_hi[k, 2]
                ):
                    near[n] = k
                    n += 1
                    if not meets:
                        meets = _sphere_meets(
                            wx, wy, pz, bound_r[lk], k, box_c, box_R, box_half, box_cyl,
                            box_rad, box_lo, box_hi, touch,
                        )  # fmt: skip
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
                lx, ly, lz = leaf_c[f, 0], leaf_c[f, 1], leaf_c[f, 2]
                px = R[j, 0, 0, b] * lx + R[j, 0, 1, b] * ly + R[j, 0, 2, b] * lz + p[j, 0, b]
                py = R[j, 1, 0, b] * lx + R[j, 1, 1, b] * ly + R[j, 1, 2, b] * lz + p[j, 1, b]
                pz = R[j, 2, 0, b] * lx + R[j, 2, 1, b] * ly + R[j, 2, 2, b] * lz + p[j, 2, b]
                wx = cos_yaw * px - sin_yaw * py + bx
                wy = sin_yaw * px + cos_yaw * py + by
                for i in range(n):
                    k = near[i]
                    if _sphere_meets(
                        wx, wy, pz, leaf_r[f], k, box_c, box_R, box_half, box_cyl, box_rad,
                        box_lo, box_hi, touch,
                    ):  # fmt: skip
                        flagged[b] = True
                        box_hit[k] = True
