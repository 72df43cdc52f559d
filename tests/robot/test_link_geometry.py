"""The compiled point-to-triangles distance (distance_kernel) against its numpy reference
(``_Triangles.exact``), and the distance grids built on it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.robot.distance_kernel import nearest_distances, winding_numbers
from pickstop.robot.link_geometry import (
    LinkShape,
    _mesh_distance,
    _Triangles,
    collision_links,
    distance_grid,
    mesh_distance_reference,
    point_triangle_distance,
    winding_number,
)

#: The kernel and numpy evaluate the same expressions; BLAS may sum a dot product in another
#: order for some columns of its matrix, a last-bit difference.
EQUAL = 1e-12


def _kernel(ts: _Triangles, P: np.ndarray, cand: np.ndarray) -> np.ndarray:
    out = np.empty(len(P))
    nearest_distances(np.ascontiguousarray(P), ts.rows, np.asarray(cand, dtype=np.int64), out)
    return out


def _soup(rng: np.random.Generator, n: int) -> np.ndarray:
    """``(n, 3, 3)`` random triangles [m], the first 16 degenerate or nearly so."""
    tris = rng.normal(size=(n, 3, 3)) * 0.1
    tris[0:4, 2] = tris[0:4, 0] + 0.4 * (tris[0:4, 1] - tris[0:4, 0])  # collinear: flat
    tris[4:7, 1] = tris[4:7, 0]  # two vertices coincide: a segment
    tris[7:9] = tris[7:9, :1]  # all three coincide: a point
    side = np.cross(tris[9:16, 1] - tris[9:16, 0], rng.normal(size=(7, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    mid = 0.5 * (tris[9:16, 0] + tris[9:16, 1])
    tris[9:16, 2] = mid + side * np.array([1e-13, 1e-11, 1e-9, 1e-7, 1e-5, 1e-3, 0])[:, None]
    return tris


def _on(rng: np.random.Generator, tris: np.ndarray) -> np.ndarray:
    """Points on the triangles: on their faces, on their edges and at their vertices."""
    face = np.einsum("tv,tvk->tk", rng.dirichlet(np.ones(3), len(tris)), tris)
    k = rng.integers(0, 3, len(tris))
    a, b = tris[np.arange(len(tris)), k], tris[np.arange(len(tris)), (k + 1) % 3]
    edge = a + rng.uniform(size=(len(tris), 1)) * (b - a)
    return np.concatenate([face, edge, tris[:, 0], tris[:, 2]])


def _probes(rng: np.random.Generator, tris: np.ndarray) -> np.ndarray:
    on = _on(rng, tris)
    near = on + rng.normal(size=on.shape) * rng.choice([1e-6, 1e-3, 0.03], size=(len(on), 1))
    return np.concatenate([on, near, rng.normal(size=(40, 3)) * 0.4])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_kernel_equals_numpy_exact(seed):
    rng = np.random.default_rng(seed)
    tris = _soup(rng, 60)
    ts = _Triangles(tris)
    P = _probes(rng, tris)
    for cand in (
        np.arange(len(ts)),
        np.sort(rng.choice(len(ts), 17, replace=False)),
        rng.permutation(len(ts))[:30],  # any order
        np.array([int(rng.integers(0, len(ts)))]),
    ):
        ref = ts.exact(P, cand).min(axis=1)
        got = _kernel(ts, P, cand)
        assert np.abs(got - ref).max() <= EQUAL
    # on them, up to the rounding of the expanded |p - a - u e|^2 (sqrt(eps) |p|)
    assert (_kernel(ts, P, np.arange(len(ts)))[: 4 * len(tris)] <= 1e-7).all()
    assert np.isposinf(_kernel(ts, P, np.zeros(0, dtype=np.int64))).all()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_skipped_triangles_change_nothing(seed):
    """Triangles skipped by their balls leave every value as it is, bit for bit: any order of
    the candidates equals the least of the triangles measured one by one (none skipped)."""
    rng = np.random.default_rng(seed)
    tris = _soup(rng, 80)
    ts = _Triangles(tris)
    P = _probes(rng, tris[rng.choice(len(tris), 10)])
    each = np.min([_kernel(ts, P, np.array([c])) for c in range(len(ts))], axis=0)
    order = np.argsort(ts.bound(P.mean(axis=0)[None], np.arange(len(ts)))[0])
    for cand in (order, order[::-1], rng.permutation(len(ts))):
        assert np.array_equal(_kernel(ts, P, cand), each)


def _lattice(lo: np.ndarray, dims: tuple[int, int, int], h: float) -> np.ndarray:
    axes = [lo[k] + h * np.arange(dims[k]) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_compiled_grid_equals_numpy_reference(seed):
    """The compiled block loop (bounds, culling, the floor beyond ``cap``) against the numpy
    one, on lattices with partial blocks."""
    rng = np.random.default_rng(seed)
    tris = _soup(rng, 40)
    dims = tuple(int(v) for v in rng.integers(1, 16, 3))
    nodes = _lattice(tris.min(axis=(0, 1)) - 0.05, dims, float(rng.uniform(0.01, 0.05)))
    cap = float(rng.choice([0.02, 0.1]))
    ref = mesh_distance_reference(nodes, tris, cap)
    assert np.abs(_mesh_distance(nodes, tris, cap) - ref).max() <= EQUAL


@pytest.fixture(scope="module")
def palm(tiago):
    links = {lk.name: lk for lk in collision_links(tiago)}
    shape = LinkShape.of(tiago, links["hand_palm_link"].geometry_ids)  # 618 triangles
    assert len(shape.shapes) == 1 and shape.shapes[0].tris is not None
    return shape


def test_kernel_equals_numpy_exact_on_a_mesh_link(palm):
    tris = palm.shapes[0].tris
    ts = _Triangles(tris)
    rng = np.random.default_rng(3)
    P = _probes(rng, tris[rng.choice(len(tris), 150, replace=False)])
    ref = ts.exact(P, np.arange(len(ts))).min(axis=1)
    got = _kernel(ts, P, np.arange(len(ts)))
    assert np.abs(got - ref).max() <= EQUAL


def test_distance_grid_equals_numpy_reference_on_a_mesh_link(palm):
    h, cap = 0.01, 0.1
    origin = np.floor((palm.lo - 0.05) / h) * h
    dims = tuple(int(v) for v in np.ceil((palm.hi + 0.05 - origin) / h) + 1)
    grid = distance_grid(palm, origin, dims, h, cap)
    idx = np.random.default_rng(1).integers(0, dims, (3000, 3))
    ref = point_triangle_distance(origin + idx * h, palm.shapes[0].tris).min(axis=1)
    got = grid[idx[:, 0], idx[:, 1], idx[:, 2]]
    assert (ref < cap).sum() > 500
    assert np.abs(got - ref)[ref < cap].max() <= EQUAL  # exact up to cap
    assert (got <= ref + EQUAL).all()  # a lower bound beyond


def test_compiled_grid_equals_numpy_reference_on_a_mesh_link(palm):
    h = 0.01
    lo = np.floor((palm.lo - 0.1) / h) * h
    dims = tuple(int(v) for v in np.ceil((palm.hi + 0.1 - lo) / h) + 1)
    nodes = _lattice(lo, dims, h)
    tris = palm.shapes[0].tris
    ref = mesh_distance_reference(nodes, tris, 0.1)
    assert (ref > 0.1).any()  # beyond cap too
    assert np.abs(_mesh_distance(nodes, tris, 0.1) - ref).max() <= EQUAL


def _winding(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    out = np.empty(len(P))
    winding_numbers(np.ascontiguousarray(P), np.ascontiguousarray(tris), out)
    return out


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_compiled_winding_numbers_equal_numpy(seed):
    rng = np.random.default_rng(seed)
    tris = _soup(rng, int(rng.integers(16, 60)))
    # Off the surface: on it, the solid angle of the triangle under the point is +-2 pi by
    # the sign of a rounding error.
    on = _on(rng, tris)
    P = np.concatenate([on + rng.normal(size=on.shape) * 1e-3, rng.normal(size=(40, 3)) * 0.4])
    assert np.abs(_winding(P, tris) - winding_number(P, tris)).max() <= 1e-9


def test_depth_of_a_mesh_link_is_the_distance_to_its_surface_inside_and_0_outside(palm):
    tris = palm.shapes[0].tris
    h = float(np.max(palm.hi - palm.lo + 0.02)) / 23
    P = _lattice(palm.lo - 0.01 + 1e-4, (24, 24, 24), h).reshape(-1, 3)
    wn = winding_number(P, tris)
    assert np.abs(_winding(P, tris) - wn).max() <= 1e-9
    inside = wn > 0.5
    assert 100 < inside.sum() < len(P) - 100  # a closed mesh: points on both sides
    ref = np.where(inside, point_triangle_distance(P, tris).min(axis=1), 0.0)
    assert np.abs(palm.depth(P) - ref).max() <= EQUAL
