"""Distance grids to a triangle soup, compiled (numba).

:func:`nearest_distances` is :meth:`pickstop.robot.link_geometry._Triangles.exact` followed by
a minimum over the triangles, without its ``(N, K)`` temporaries; :func:`mesh_distances` is
:func:`pickstop.robot.link_geometry.mesh_distance_reference`'s block loop around it. Both
evaluate numpy's floating-point expressions in numpy's order, each dot product as BLAS's dgemm
sums it on FMA hardware (``fma(z, w2, fma(y, w1, x * w0))``). BLAS sums some columns of a
matrix (and a single point's products) in another order, so a value may differ from numpy's in
its last bits; the tests hold the two within 1e-12 m.

A triangle is skipped for a point when its padded bounding ball proves the triangle's computed
distance no less than the point's least distance so far, so skipping changes no value.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

#: Columns of a triangle's row in :attr:`~pickstop.robot.link_geometry._Triangles.rows`:
#: 10 vectors (unit normal, 3 inward edge normals, 3 edge vectors, 3 edge origins) as x, y, z
#: each; 4 plane offsets (normal, edge normals); 3 ``u.e``, 3 ``e.e`` and 3 ``u.u``; the flat
#: flag (1.0: degenerate, only its edges count); the bounding ball's centre, its radius and its
#: pad (the radius plus how far the vertices stray from the triangle's computed plane).
OFF, UE, EE, UU, FLAT, CENTRE, RADIUS, PAD = 30, 34, 37, 40, 43, 44, 47, 48
ROW = 49

#: A computed distance is within ``ROUNDING * S`` of the exact distance to the triangle (``S``:
#: the sum of the point's norm, a vertex's and an edge's; about ``sqrt(20 eps) S`` at worst,
#: from the expanded ``|p - a - u e|^2``), so a triangle is skipped only when its ball is this
#: much farther than the point's least distance.
ROUNDING = 1e-6


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's fma)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dot(x: float, y: float, z: float, row: np.ndarray, j: int) -> float:
    """Vector ``j`` of ``row`` dotted with ``(x, y, z)``, summed as dgemm does."""
    return _fma(z, row[3 * j + 2], _fma(y, row[3 * j + 1], x * row[3 * j]))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _triangle_distance(x: float, y: float, z: float, pp: float, row: np.ndarray) -> float:
    """Exact distance [m] from ``(x, y, z)`` (``pp = |p|^2``) to one triangle's ``row``: to
    its plane if the point projects inside it, else to its nearest edge."""
    inside = row[FLAT] == 0.0
    for m in range(1, 4):
        if not _dot(x, y, z, row, m) - row[OFF + m] >= 0.0:
            inside = False
    face = abs(_dot(x, y, z, row, 0) - row[OFF]) if inside else np.inf
    d2 = np.inf
    for e in range(3):
        pe = _dot(x, y, z, row, 4 + e) - row[UE + e]
        ee = row[EE + e]
        u = 0.0 if pe <= 0.0 else min(pe / ee, 1.0)  # numpy's clip(pe / ee, 0, 1)
        pu = pp + row[UU + e] - 2 * _dot(x, y, z, row, 7 + e)
        d2 = min(d2, pu - 2 * u * pe + u * u * ee)
    return min(face, np.sqrt(max(d2, 0.0)))


@njit(cache=True, nogil=True, error_model="numpy")
def nearest_distances(P: np.ndarray, rows: np.ndarray, cand: np.ndarray, out: np.ndarray) -> None:
    """``out[n]`` = least exact distance [m] from ``P[n]: (N, 3)`` to triangles ``cand: (K,)``
    of ``rows: (T, ROW)`` (``inf`` when ``K == 0``). Any order of ``cand`` gives the same
    values; nearest first, more triangles are skipped."""
    n_points = P.shape[0]
    pp = np.empty(n_points)
    scale = 0.0
    for n in range(n_points):
        pp[n] = P[n, 0] * P[n, 0] + P[n, 1] * P[n, 1] + P[n, 2] * P[n, 2]
        scale = max(scale, np.sqrt(pp[n]))
        out[n] = np.inf
    reach = 0.0
    for c in cand:
        row = rows[c]
        centre = np.sqrt(row[CENTRE] ** 2 + row[CENTRE + 1] ** 2 + row[CENTRE + 2] ** 2)
        reach = max(reach, centre + 3 * row[PAD])
    slack = ROUNDING * (1.0 + scale + reach)
    for c in cand:
        row = rows[c]
        pad = row[PAD] + slack
        for n in range(n_points):
            dx, dy, dz = P[n, 0] - row[CENTRE], P[n, 1] - row[CENTRE + 1], P[n, 2] - row[CENTRE + 2]
            t = out[n] + pad
            if dx * dx + dy * dy + dz * dz <= t * t:
                d = _triangle_distance(P[n, 0], P[n, 1], P[n, 2], pp[n], row)
                out[n] = min(out[n], d)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bound(x: float, y: float, z: float, row: np.ndarray) -> float:
    """:meth:`~pickstop.robot.link_geometry._Triangles.bound` of one point and triangle [m]:
    from its plane and edge half-planes, and its bounding ball."""
    beyond = 0.0
    for m in range(1, 4):
        beyond = max(beyond, -(_dot(x, y, z, row, m) - row[OFF + m]))
    g0 = _dot(x, y, z, row, 0) - row[OFF]
    slab = np.sqrt(g0 * g0 + beyond * beyond)
    dx, dy, dz = x - row[CENTRE], y - row[CENTRE + 1], z - row[CENTRE + 2]
    d = np.sqrt(dx * dx + dy * dy + dz * dz) - row[RADIUS]
    return max(slab, d - 1e-9)


@njit(cache=True, nogil=True, error_model="numpy")
def _block(nodes: np.ndarray, i: int, j: int, k: int, bs: int, P: np.ndarray) -> int:
    """Copy the nodes of the block at ``(i, j, k)`` into ``P`` (C order); their count."""
    n = 0
    for a in range(i, min(i + bs, nodes.shape[0])):
        for b in range(j, min(j + bs, nodes.shape[1])):
            for c in range(k, min(k + bs, nodes.shape[2])):
                for x in range(3):
                    P[n, x] = nodes[a, b, c, x]
                n += 1
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def _centre(P: np.ndarray, n: int, cb: np.ndarray) -> float:
    """``cb`` = the centre of the bounding box of ``P[:n]``; the farthest point's distance
    from it [m]."""
    for a in range(3):
        lo = hi = P[0, a]
        for m in range(1, n):
            lo, hi = min(lo, P[m, a]), max(hi, P[m, a])
        cb[a] = 0.5 * (lo + hi)
    rb = 0.0
    for m in range(n):
        dx, dy, dz = P[m, 0] - cb[0], P[m, 1] - cb[1], P[m, 2] - cb[2]
        rb = max(rb, np.sqrt(dx * dx + dy * dy + dz * dz))
    return rb


@njit(cache=True, nogil=True, error_model="numpy")
def _candidates(
    rows: np.ndarray, cb: np.ndarray, rb: float, cap: float, lb: np.ndarray, cand: np.ndarray
) -> tuple[int, float]:
    """The triangles that may be nearest to a block (centre ``cb``, radius ``rb`` [m]):
    their count ``K`` in ``cand[:K]`` (the nearest by the bound first), and the least bound
    [m] of the others (``inf``: none)."""
    T = rows.shape[0]
    near = 0
    for t in range(T):  # holds for every node of the block
        lb[t] = _bound(cb[0], cb[1], cb[2], rows[t]) - rb
        if lb[t] < lb[near]:
            near = t
    pp = cb[0] * cb[0] + cb[1] * cb[1] + cb[2] * cb[2]
    ub = _triangle_distance(cb[0], cb[1], cb[2], pp, rows[near]) + rb
    limit = min(ub, cap + 2 * rb)
    K, floor = 0, np.inf
    for t in range(T):
        if lb[t] <= limit:
            cand[K] = t
            K += 1
        else:
            floor = min(floor, lb[t])
    for m in range(K):  # near first: its distances skip more triangles
        if cand[m] == near:
            cand[0], cand[m] = cand[m], cand[0]
            break
    return K, floor


@njit(cache=True, nogil=True, error_model="numpy")
def mesh_distances(
    nodes: np.ndarray, rows: np.ndarray, cap: float, bs: int, out: np.ndarray
) -> None:
    """:func:`pickstop.robot.link_geometry.mesh_distance_reference`, compiled: ``out`` =
    the distance [m] from ``nodes: (nx, ny, nz, 3)`` to the triangles ``rows: (T, ROW)``,
    exact up to ``cap`` [m] and a lower bound beyond, by blocks of ``bs^3`` nodes."""
    nx, ny, nz = nodes.shape[0], nodes.shape[1], nodes.shape[2]
    lb = np.empty(rows.shape[0])
    cand = np.empty(rows.shape[0], np.int64)
    P = np.empty((bs**3, 3))
    val = np.empty(bs**3)
    cb = np.empty(3)
    for i in range(0, nx, bs):
        for j in range(0, ny, bs):
            for k in range(0, nz, bs):
                n = _block(nodes, i, j, k, bs, P)
                rb = _centre(P, n, cb)
                K, floor = _candidates(rows, cb, rb, cap, lb, cand)
                nearest_distances(P[:n], rows, cand[:K], val[:n])
                m = 0
                for a in range(i, min(i + bs, nx)):
                    for b in range(j, min(j + bs, ny)):
                        for c in range(k, min(k + bs, nz)):
                            out[a, b, c] = min(floor, val[m])
                            m += 1


@njit(cache=True, nogil=True, error_model="numpy")
def winding_numbers(P: np.ndarray, tris: np.ndarray, out: np.ndarray) -> None:
    """``out[n]`` = :func:`pickstop.robot.link_geometry.winding_number` of ``P[n]: (N, 3)``
    with respect to the triangle soup ``tris: (T, 3, 3)`` (about 1 inside a closed mesh, 0
    outside): the same solid angles (Van Oosterom and Strackee), summed per point."""
    for n in range(P.shape[0]):
        x, y, z = P[n, 0], P[n, 1], P[n, 2]
        total = 0.0
        for t in range(tris.shape[0]):
            ax, ay, az = tris[t, 0, 0] - x, tris[t, 0, 1] - y, tris[t, 0, 2] - z
            bx, by, bz = tris[t, 1, 0] - x, tris[t, 1, 1] - y, tris[t, 1, 2] - z
            cx, cy, cz = tris[t, 2, 0] - x, tris[t, 2, 1] - y, tris[t, 2, 2] - z
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            ab = ax * bx + ay * by + az * bz
            bc = bx * cx + by * cy + bz * cz
            ca = cx * ax + cy * ay + cz * az
            total += np.arctan2(det, la * lb * lc + ab * lc + bc * la + ca * lb)
        out[n] = abs(total / (2 * np.pi))
