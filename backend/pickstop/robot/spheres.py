"""Sphere covers of collision links, and sphere trees over them.

:func:`cover` returns spheres such that every point of a link's collision set lies inside one of
them: each sphere's radius is the largest distance from its centre to the points of the elements
it holds, and every element's convex hull (grown by its pad) holds a piece of the set, so the
cover is exact by construction, not by sampling. Centres are picked greedily inside the solid,
where a sphere of radius ``depth + excess`` sticks out of the geometry by at most ``excess``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickstop.robot.link_geometry import LinkShape


def _lattice(lo: np.ndarray, hi: np.ndarray, h: float) -> np.ndarray:
    """Nodes ``(N, 3)`` of a grid of spacing ~``h`` [m] spanning ``[lo, hi]``."""
    n = np.maximum(1, np.ceil((hi - lo) / h)).astype(int)
    axes = [np.linspace(lo[k], hi[k], n[k] + 1) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _holds(
    centres: np.ndarray, radii: np.ndarray, ball_c: np.ndarray, ball_r: np.ndarray
) -> np.ndarray:
    """``(C, E)`` bool: sphere (centre, radius) holds the element ball (ball_c, ball_r)."""
    out = np.empty((len(centres), len(ball_c)), dtype=bool)
    bc = ball_c.astype(np.float32)
    for s in range(0, len(centres), 256):
        c = centres[s : s + 256].astype(np.float32)
        d2 = (c * c).sum(1)[:, None] + (bc * bc).sum(1)[None] - 2 * c @ bc.T
        d = np.sqrt(np.maximum(d2, 0)) + 1e-6  # float32 slack: only decides, never sizes
        out[s : s + 256] = d + ball_r[None] <= radii[s : s + 256, None]
    return out


def _clusters(
    pts: np.ndarray, pad: np.ndarray, centres: np.ndarray, idx: np.ndarray, radius: float
) -> list[list[float]]:
    """Bisect elements ``idx`` (at the median of the widest axis) until a ball of <= ``radius``
    [m] (or a single element's ball) holds each part."""
    out: list[list[float]] = []
    stack = [idx] if len(idx) else []
    while stack:
        part = stack.pop()
        p = pts[part].reshape(-1, 3)
        c = 0.5 * (p.min(axis=0) + p.max(axis=0))
        r = float((np.linalg.norm(pts[part] - c, axis=2).max(axis=1) + pad[part]).max())
        if r <= radius or len(part) == 1:
            out.append([*c, r])
            continue
        cen = centres[part]
        order = part[np.argsort(cen[:, int(np.argmax(np.ptp(cen, axis=0)))], kind="stable")]
        stack += [order[: len(order) // 2], order[len(order) // 2 :]]
    return out


def cover(link: LinkShape, excess: float, max_elements: int = 4000) -> np.ndarray:
    """Spheres ``(S, 4)`` (x, y, z, radius) [m] holding every point of ``link``.

    excess: how far a sphere may stick out of the link's solid [m]; a link too big for
    ``max_elements`` elements of that size gets coarser elements and bigger spheres.
    """
    # Coarser elements until few enough; a mesh's triangles never merge, so growth stops once
    # elements reach the link's size (dense meshes arrive as hull solids, see link_geometry).
    h, largest = excess, max(float(np.max(link.hi - link.lo)), excess)
    while True:
        pts, pad = link.elements(h)
        if len(pts) <= max_elements or h > largest:
            break
        h *= 1.25
    # Every element inside a small ball; spheres are sized on the exact points at the end.
    ball_c = 0.5 * (pts.min(axis=1) + pts.max(axis=1))
    ball_r = np.linalg.norm(pts - ball_c[:, None], axis=2).max(axis=1) + pad
    # Candidate centres: a lattice inside the solid, where a sphere of radius depth + excess
    # sticks out by <= excess. Elements no such sphere can hold (thin parts) are clustered
    # around their own centres instead; the rest are covered greedily, biggest gain first.
    extent = np.maximum(link.hi - link.lo, h)
    g = max(h, float(np.prod(extent) / 1500) ** (1 / 3))
    grid = _lattice(link.lo, link.hi, g)
    depth = link.depth(grid)
    grid, depth = grid[depth > 0], depth[depth > 0]
    slack = max(excess, h)
    can = _holds(grid, depth + slack, ball_c, ball_r)
    todo = can.any(axis=0)
    spheres = _clusters(pts, pad, ball_c, np.flatnonzero(~todo), slack)
    gain = can[:, todo].sum(axis=1)  # (C,) the open elements each candidate holds
    while todo.any():
        k = int(np.argmax(gain))
        take = can[k] & todo
        d = np.linalg.norm(pts[take] - grid[k], axis=2).max(axis=1) + pad[take]
        spheres.append([*grid[k], float(d.max())])
        todo &= ~take
        gain -= can[:, take].sum(axis=1)
    return np.array(spheres)


@dataclass(frozen=True)
class SphereNode:
    """A ball holding every sphere below it, in its joint frame."""

    centre: np.ndarray  # (3,) [m]
    radius: float  # [m]
    links: tuple[int, ...]  # links below this node
    children: tuple[SphereNode, ...] = ()
    partner: int = -1  # screened against this link only (-1: every partner of its links)
    pair: int = -1  # at a leaf screened against one partner: the link pair it reports


def ball_of_spheres(s: np.ndarray) -> tuple[np.ndarray, float]:
    """A ball ``(centre (3,), radius)`` [m] holding every sphere of ``s: (S, 4)``."""
    c = 0.5 * ((s[:, :3] - s[:, 3:]).min(axis=0) + (s[:, :3] + s[:, 3:]).max(axis=0))
    return c, float((np.linalg.norm(s[:, :3] - c, axis=1) + s[:, 3]).max())


def _widest_order(centres: np.ndarray) -> np.ndarray:
    return np.argsort(centres[:, int(np.argmax(np.ptp(centres, axis=0)))], kind="stable")


def sphere_tree(s: np.ndarray, link: int) -> SphereNode:
    """Binary tree over the spheres ``s: (S, 4)`` of one link, split at the widest axis."""
    c, r = ball_of_spheres(s)
    if len(s) == 1:
        return SphereNode(c, r, (link,))
    order = _widest_order(s[:, :3])
    half = len(s) // 2
    kids = (sphere_tree(s[order[:half]], link), sphere_tree(s[order[half:]], link))
    return SphereNode(c, r, (link,), kids)


def group_tree(
    links: list[int], covers: dict[int, np.ndarray], trees: dict[int, SphereNode]
) -> SphereNode:
    """Binary tree over several links of one joint, ending in each link's sphere tree."""
    if len(links) == 1:
        return trees[links[0]]
    c, r = ball_of_spheres(np.concatenate([covers[i] for i in links]))
    order = [links[i] for i in _widest_order(np.array([trees[i].centre for i in links]))]
    half = len(order) // 2
    kids = (group_tree(order[:half], covers, trees), group_tree(order[half:], covers, trees))
    return SphereNode(c, r, tuple(links), kids)


def split_by_partner(
    node: SphereNode, partners: dict[int, list[int]], pair_index: dict[tuple[int, int], int]
) -> SphereNode:
    """Give each link node one copy of its subtree per partner link, so that leaves report
    link pairs ``pair_index[(partner, link)]``."""
    if len(node.links) > 1:
        kids = tuple(split_by_partner(k, partners, pair_index) for k in node.children)
        return SphereNode(node.centre, node.radius, node.links, kids)
    (link,) = node.links

    def copy(n: SphereNode, partner: int) -> SphereNode:
        kids = tuple(copy(k, partner) for k in n.children)
        pair = -1 if kids else pair_index[(partner, link)]
        return SphereNode(n.centre, n.radius, n.links, kids, partner, pair)

    kids = tuple(copy(node, p) for p in partners[link])
    return SphereNode(node.centre, node.radius, node.links, kids)
