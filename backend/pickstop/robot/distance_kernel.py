"""Point to triangle-set distance, compiled (numba): :func:`nearest_distances` is
:meth:`pickstop.robot.link_geometry._Triangles.exact` followed by a minimum over the
triangles, without its ``(N, K)`` temporaries.

It evaluates the same floating-point expressions in the same order: each ``P @ W`` entry as
BLAS's dgemm sums it on FMA hardware (``fma(z, w2, fma(y, w1, x * w0))``), every other step as
numpy does, so the two agree bit for bit there (and to rounding elsewhere); the tests hold them
to each other. It skips a triangle for a point when the triangle's padded bounding ball proves
its computed distance larger than the point's least distance so far: the minimum is unchanged.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

#: Columns of a triangle's row in :attr:`~pickstop.robot.link_geometry._Triangles.rows`:
#: 10 vectors (unit normal, 3 inward edge normals, 3 edge vectors, 3 edge origins) as x, y, z
#: each; 4 plane offsets (normal, edge normals); 3 ``u.e``, 3 ``e.e`` and 3 ``u.u``; the flat
#: flag (1.0: degenerate, only its edges count); the bounding ball's centre and its pad (the
#: ball's radius plus how far the vertices stray from the triangle's computed plane).
OFF, UE, EE, UU, FLAT, CENTRE, PAD = 30, 34, 37, 40, 43, 44, 47
ROW = 48

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
