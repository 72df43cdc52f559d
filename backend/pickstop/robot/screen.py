"""Fast, conservative self-collision screen over many configurations (numpy, float32).

For every pair of bodies (arm joints ``a < b``, 0 = the fixed base) with enabled link pairs,
body b's links are sphere trees (:mod:`pickstop.robot.spheres`) and body a's links are exact
distance grids in a's frame (:func:`pickstop.robot.link_geometry.distance_grid`), one grid per
set of a-links a tree node must keep away from. A node (centre, radius ``r``) at ``x`` in a's
frame is possibly colliding when a lower bound of the distance at ``x`` is ``<= r``: from the
nearest grid node ``n``, ``D(n) - |x - n|`` (distance is 1-Lipschitz); outside the grid, the gap
to the grid box plus the grid margin. All (configuration, node) entries still possibly
colliding are expanded level by level, vectorised; a configuration is flagged at its first
leaf hit. A pair is not screened when one link lies inside a convex solid link on the same
joint that is screened against the same partner (coal would report that pair too).

Guarantee: a configuration reported free is free for coal on the enabled pairs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pickstop.robot.link_geometry import CollisionLink, LinkShape, distance_grid
from pickstop.robot.screen_kernel import screen_rows
from pickstop.robot.spheres import (
    SphereNode,
    cover,
    group_tree,
    sphere_tree,
    split_by_partner,
)

if TYPE_CHECKING:
    from pickstop.robot.model import RobotModel
    from pickstop.robot.pairs import DisabledPairs

Frames = Sequence[tuple[np.ndarray, np.ndarray]]

#: Added to every radius [m]: covers coal's GJK tolerance and float32 rounding.
MARGIN = 1e-4


@dataclass(frozen=True)
class SphereModel:
    """Sphere covers, distance grids and the flat traversal plan of the enabled link pairs.

    spheres: ``(S, 6)`` rows (joint, link, x, y, z, radius) [m], every involved link's cover
    in its joint frame. pairs: enabled link pairs ``(P, 2)`` into ``link_names``.
    Nodes, fields and body pairs are flat arrays so the model pickles cheaply to workers.
    """

    link_names: tuple[str, ...]
    link_joints: np.ndarray  # (L,)
    spheres: np.ndarray  # (S, 6)
    pairs: np.ndarray  # (P, 2)
    excess: float  # [m] how far a sphere may stick out of its link
    step: float  # [m] distance grid spacing
    body_pairs: np.ndarray  # (BP, 2) joints (a, b), a < b
    roots: np.ndarray  # (BP,) root node of each body pair
    node_centre: np.ndarray  # (N, 3) float32 [m] in body b's frame
    node_radius: np.ndarray  # (N,) float32 [m], margin included
    node_field: np.ndarray  # (N,) int
    node_body_pair: np.ndarray  # (N,)
    node_pair: np.ndarray  # (N,) link pair a leaf reports, -1 if not a leaf
    child_start: np.ndarray  # (N,)
    child_count: np.ndarray  # (N,)
    children: np.ndarray  # (M,)
    field_origin: np.ndarray  # (F, 3) float32 [m] first grid node in body a's frame
    field_top: np.ndarray  # (F, 3) float32 [m] last grid node
    field_dims: np.ndarray  # (F, 3)
    field_offset: np.ndarray  # (F,) start in field_values
    field_margin: np.ndarray  # (F,) float32 [m] distance from the grid box to its links
    field_values: np.ndarray  # (sum of grid sizes,) float32 [m] lower bounds of distance
    node_rec: np.ndarray  # (N, 13) float32: centre, radius, grid origin, grid top, ny, nz, margin
    node_offset: np.ndarray  # (N,) start of the node's grid in field_values

    @classmethod
    def from_robot(
        cls,
        robot: RobotModel,
        disabled: DisabledPairs,
        excess: float = 0.01,
        step: float = 0.01,
        margin: float = 0.1,
        per_pair: bool = False,
        link_excess: dict[str, float] | None = None,
    ) -> SphereModel:
        """Cover the links of the pairs ``disabled`` enables and plan their screen.

        excess: how far a sphere may stick out of its link [m]; step: distance grid spacing
        [m]; margin: how far grids reach beyond their links [m]; per_pair: plan for
        :func:`screen_pairs` (slower) instead of :func:`screen`; link_excess: a finer
        ``excess`` [m] for some links, by name.
        """
        links = disabled.links
        ids = {lk.name: i for i, lk in enumerate(links)}
        pairs = sorted(
            (min(ids[a], ids[b]), max(ids[a], ids[b])) for a, b in disabled.enabled_pairs()
        )
        joints = np.array([lk.joint for lk in links], dtype=np.int64)
        involved = sorted({i for p in pairs for i in p})
        shapes = {i: LinkShape.of(robot, links[i].geometry_ids) for i in involved}
        covers = _covers(shapes, links, excess, link_excess or {})
        trees = {i: sphere_tree(covers[i], i) for i in involved}
        # (a-link, b-link) with a on the lower joint, for every enabled pair.
        oriented = [(i, j) if joints[i] < joints[j] else (j, i) for i, j in pairs]
        screened = oriented if per_pair else _without_implied(oriented, shapes, joints)
        fields = _Fields(shapes, step, margin)
        pair_index = {p: k for k, p in enumerate(oriented)} if per_pair else None
        plan, body_pairs = _plan_body_pairs(fields, screened, joints, covers, trees, pair_index)

        rows = [[joints[i], i, *s] for i in involved for s in covers[i]]
        nodes, grids = plan.arrays(), fields.arrays()
        f = nodes["node_field"]
        return cls(
            link_names=tuple(lk.name for lk in links),
            link_joints=joints,
            spheres=np.array(rows, dtype=float).reshape(-1, 6),
            pairs=np.array(oriented, dtype=np.int64).reshape(-1, 2),
            excess=excess,
            step=step,
            body_pairs=np.array(body_pairs, dtype=np.int64).reshape(-1, 2),
            node_rec=_node_records(nodes, grids),
            node_offset=grids["field_offset"][f],
            **nodes,
            **grids,
        )


def _covers(
    shapes: dict[int, LinkShape],
    links: tuple[CollisionLink, ...],
    excess: float,
    finer: dict[str, float],
) -> dict[int, np.ndarray]:
    """Sphere cover ``(S, 4)`` [m] of each link ``i`` of ``shapes`` (``links[i]``), to
    ``excess`` [m] or the link's ``finer`` excess [m], by link name."""
    covers = {}
    for i in shapes:
        e = finer.get(links[i].name, excess)
        # Finer spheres need proportionally more (surface) elements to be finer.
        covers[i] = cover(shapes[i], e, max_elements=min(16000, int(4000 * (excess / e) ** 2)))
    return covers


def _plan_body_pairs(
    fields: _Fields,
    screened: list[tuple[int, int]],
    joints: np.ndarray,
    covers: dict[int, np.ndarray],
    trees: dict[int, SphereNode],
    pair_index: dict[tuple[int, int], int] | None,
) -> tuple[_Plan, list[tuple[int, int]]]:
    """The plan of one tree per body pair (joints ``a < b``) of the ``screened`` link pairs,
    and those body pairs in plan order: body b's links grouped, each node screened against the
    grid of its a-partners; with ``pair_index`` (per-pair screening), split so each leaf
    reports its link pair's index."""
    plan = _Plan()
    body_pairs = sorted({(int(joints[a]), int(joints[b])) for a, b in screened})
    for bp, (ja, jb) in enumerate(body_pairs):
        partners: dict[int, list[int]] = {}
        for a, b in screened:
            if joints[a] == ja and joints[b] == jb:
                partners.setdefault(b, []).append(a)
        root = group_tree(sorted(partners), covers, trees)
        if pair_index is not None:
            root = split_by_partner(root, partners, pair_index)
        plan.add_root(root, bp, partners, fields, ja)
    return plan, body_pairs


def _node_records(nodes: dict[str, np.ndarray], grids: dict[str, np.ndarray]) -> np.ndarray:
    """``(N, 13)`` float32 per node: centre, radius, its grid's origin and top [m], the grid's
    ny and nz, and its margin [m] (what the kernel reads of a node, in one row)."""
    f = nodes["node_field"]
    return np.concatenate(
        [
            nodes["node_centre"],
            nodes["node_radius"][:, None],
            grids["field_origin"][f],
            grids["field_top"][f],
            grids["field_dims"][f][:, 1:].astype(np.float32),
            grids["field_margin"][f][:, None],
        ],
        axis=1,
    ).astype(np.float32)


def _without_implied(
    pairs: list[tuple[int, int]], shapes: dict[int, LinkShape], joints: np.ndarray
) -> list[tuple[int, int]]:
    """Drop pair (l, m) when l lies strictly inside a convex solid link l' on the same joint
    and (l', m) is screened: any coal contact of l with m is then a contact of l' with m."""
    solid = {i: s for i, s in shapes.items() if len(s.shapes) == 1 and s.shapes[0].convex}
    volume = {i: float(np.prod(s.hi - s.lo)) for i, s in shapes.items()}
    inside: dict[int, list[int]] = {}
    for i, s in shapes.items():
        pts, pad = s.elements(max(0.01, float(np.max(s.hi - s.lo)) / 40))  # <= ~64,000 cells
        for j, box in solid.items():
            if j == i or joints[j] != joints[i] or (volume[j], -j) <= (volume[i], -i):
                continue
            sdf = box.shapes[0].sdf
            assert sdf is not None
            if (sdf(pts.reshape(-1, 3)).reshape(pts.shape[:2]) + pad[:, None]).max() < -MARGIN:
                inside.setdefault(i, []).append(j)
    keep = set(pairs)
    out = []
    for a, b in pairs:
        implied = any((c, b) in keep for c in inside.get(a, [])) or any(
            (a, c) in keep for c in inside.get(b, [])
        )
        if not implied:
            out.append((a, b))
    return out


class _Fields:
    """Distance grids per (body, set of links), on one lattice per body (spacing ``step``)."""

    def __init__(self, shapes: dict[int, LinkShape], step: float, margin: float) -> None:
        self.shapes, self.step, self.margin = shapes, step, margin
        self.link_grid: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # origin index, values
        self.ids: dict[frozenset[int], int] = {}
        self.grids: list[tuple[np.ndarray, np.ndarray]] = []  # (origin index (3,), values)

    def _box(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        s = self.shapes[link]
        lo = np.floor((s.lo - self.margin) / self.step).astype(np.int64)
        hi = np.ceil((s.hi + self.margin) / self.step).astype(np.int64)
        return lo, hi

    def _link(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        if link not in self.link_grid:
            lo, hi = self._box(link)
            dims = (int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1), int(hi[2] - lo[2] + 1))
            vals = distance_grid(self.shapes[link], lo * self.step, dims, self.step)
            self.link_grid[link] = (lo, vals)
        return self.link_grid[link]

    def field(self, members: frozenset[int]) -> int:
        """Id of the grid of the union of ``members`` (links of one body)."""
        if members not in self.ids:
            boxes = [self._box(i) for i in members]
            lo = np.min([b[0] for b in boxes], axis=0)
            hi = np.max([b[1] for b in boxes], axis=0)
            vals = np.full(tuple(int(v) for v in hi - lo + 1), np.inf)
            axes = [np.arange(lo[k], hi[k] + 1) * self.step for k in range(3)]
            for i in members:
                mlo, mvals = self._link(i)
                # Outside a member's own grid: the distance to its AABB bounds it from below.
                s = self.shapes[i]
                g = [
                    np.maximum(np.maximum(s.lo[k] - axes[k], axes[k] - s.hi[k]), 0)
                    for k in range(3)
                ]
                aabb = np.sqrt(g[0][:, None, None] ** 2 + g[1][None, :, None] ** 2 + g[2] ** 2)
                o = mlo - lo
                region = tuple(slice(int(o[k]), int(o[k]) + mvals.shape[k]) for k in range(3))
                aabb[region] = np.maximum(mvals, aabb[region])
                vals = np.minimum(vals, aabb)
            self.ids[members] = len(self.grids)
            self.grids.append((lo, vals))
        return self.ids[members]

    def arrays(self) -> dict[str, np.ndarray]:
        dims = np.array([v.shape for _, v in self.grids], dtype=np.int64).reshape(-1, 3)
        origin = np.array([lo for lo, _ in self.grids], dtype=float).reshape(-1, 3) * self.step
        sizes = np.array([v.size for _, v in self.grids], dtype=np.int64)
        assert (sizes < 2**24).all(), "a distance grid too big for float32 indexing"
        values = np.concatenate([v.ravel() for _, v in self.grids]) if self.grids else np.zeros(0)
        # float32 rounding must not raise a lower bound.
        v32 = values.astype(np.float32)
        v32 = np.where(v32 > values, np.nextafter(v32, np.float32(-np.inf)), v32)
        return {
            "field_origin": origin.astype(np.float32),
            "field_top": (origin + (dims - 1) * self.step).astype(np.float32),
            "field_dims": dims,
            "field_offset": np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64),
            "field_margin": np.full(len(self.grids), self.margin * (1 - 1e-6), dtype=np.float32),
            "field_values": v32,
        }


class _Plan:
    """Flattens node trees into arrays (children contiguous per node)."""

    def __init__(self) -> None:
        self.centre: list[np.ndarray] = []
        self.radius: list[float] = []
        self.field: list[int] = []
        self.body_pair: list[int] = []
        self.pair: list[int] = []
        self.kids: list[list[int]] = []
        self.roots: list[int] = []

    def add_root(
        self, root: SphereNode, bp: int, partners: dict[int, list[int]], fields: _Fields, ja: int
    ) -> None:
        def field_of(n: SphereNode) -> int:
            if n.partner >= 0:
                return fields.field(frozenset([n.partner]))
            return fields.field(frozenset(a for b in n.links for a in partners[b]))

        def visit(n: SphereNode) -> int:
            k = len(self.centre)
            self.centre.append(n.centre)
            self.radius.append(n.radius + MARGIN)
            self.field.append(field_of(n))
            self.body_pair.append(bp)
            self.pair.append(n.pair)
            self.kids.append([])
            self.kids[k] = [visit(c) for c in n.children]
            return k

        self.roots.append(visit(root))

    def arrays(self) -> dict[str, np.ndarray]:
        counts = np.array([len(k) for k in self.kids], dtype=np.int64)
        flat = [c for k in self.kids for c in k]
        return {
            "roots": np.array(self.roots, dtype=np.int64),
            "node_centre": np.array(self.centre, dtype=np.float32).reshape(-1, 3),
            "node_radius": np.array(self.radius, dtype=np.float32),
            "node_field": np.array(self.field, dtype=np.int64),
            "node_body_pair": np.array(self.body_pair, dtype=np.int64),
            "node_pair": np.array(self.pair, dtype=np.int64),
            "child_start": np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64),
            "child_count": counts,
            "children": np.array(flat, dtype=np.int64),
        }


def _poses(model: SphereModel, frames: Frames) -> np.ndarray:
    """``(BP * B, 12)`` float32: pose of body b in body a per body pair and configuration,
    as (R column 0, column 1, column 2, p)."""
    B = frames[0][1].shape[1]
    out = np.empty((len(model.body_pairs), 12, B), dtype=np.float32)
    for k, (ja, jb) in enumerate(model.body_pairs):
        Rb, pb = frames[jb - 1]
        if ja == 0:
            R, p = Rb, pb
        else:
            Ra, pa = frames[ja - 1]
            R = np.einsum("kin,kjn->ijn", Ra, Rb)
            p = np.einsum("kin,kn->in", Ra, pb - pa)
        out[k, :9] = R.transpose(1, 0, 2).reshape(9, B)
        out[k, 9:] = p
    return np.ascontiguousarray(out.transpose(0, 2, 1)).reshape(-1, 12)


def _run(model: SphereModel, frames: Frames, per_pair: bool) -> np.ndarray:
    B = frames[0][1].shape[1] if len(frames) else 0
    colliding = np.zeros(B, dtype=bool)
    hits = np.zeros((len(model.pairs), B), dtype=bool) if per_pair else np.zeros((0, B), bool)
    if not B or not len(model.roots):
        return hits if per_pair else colliding
    poses = _poses(model, frames)
    h = np.float32(model.step)
    inv_h = np.float32(1 / model.step)
    # Level 0: every body pair's root for every configuration (the rows of poses, in order).
    node = np.repeat(model.roots, B)
    cfg = np.tile(np.arange(B), len(model.roots))
    pose = poses
    while len(node):
        rec = model.node_rec[node]
        x = (
            pose[:, 0:3] * rec[:, 0:1]
            + pose[:, 3:6] * rec[:, 1:2]
            + pose[:, 6:9] * rec[:, 2:3]
            + pose[:, 9:12]
        )
        o = rec[:, 4:7]
        xc = np.minimum(np.maximum(x, o), rec[:, 7:10])  # into the grid box
        i = np.rint((xc - o) * inv_h)
        flat = (i[:, 0] * rec[:, 10] + i[:, 1]) * rec[:, 11] + i[:, 2]
        val = model.field_values[flat.astype(np.int64) + model.node_offset[node]]
        # Distance is 1-Lipschitz: D(x) >= D(n) - |x - n|; outside the grid, >= gap + margin.
        lb = val - np.sqrt(((x - o - i * h) ** 2).sum(axis=1))
        gap2 = ((x - xc) ** 2).sum(axis=1)
        out = gap2 > 0
        if out.any():
            lb[out] = np.maximum(lb[out], np.sqrt(gap2[out]) + rec[out, 12])
        hit = lb <= rec[:, 3]
        count = model.child_count[node]
        leaf = hit & (count == 0)
        if per_pair:
            hits[model.node_pair[node[leaf]], cfg[leaf]] = True
            go = hit & ~leaf
        else:
            colliding[cfg[leaf]] = True
            go = hit & ~leaf & ~colliding[cfg]
        node, cfg, count = node[go], cfg[go], count[go]
        # Expand each surviving entry into its children.
        start = np.repeat(model.child_start[node] - np.cumsum(count) + count, count)
        node = model.children[start + np.arange(int(count.sum()))]
        cfg = np.repeat(cfg, count)
        pose = poses[model.node_body_pair[node] * B + cfg]
    return hits if per_pair else colliding


def screen(model: SphereModel, frames: Frames) -> np.ndarray:
    """``(B,)`` bool, possibly colliding; False means free for the exact check.

    frames: :func:`pickstop.robot.kinematics.fk_soa` joint frames, n tuples
    ``(R: (3, 3, B), p: (3, B))`` [m] in the base frame. Compiled
    (:func:`~pickstop.robot.screen_kernel.screen_rows`), the same answers as the numpy passes.
    """
    B = frames[0][1].shape[1] if len(frames) else 0
    out = np.zeros(B, dtype=bool)
    if not B or not len(model.roots):
        return out
    screen_rows(
        _poses(model, frames),
        B,
        model.roots,
        model.node_rec,
        model.node_offset,
        model.field_values,
        model.node_body_pair,
        model.child_start,
        model.child_count,
        model.children,
        float(model.step),
        out,
    )
    return out


def screen_pairs(model: SphereModel, frames: Frames) -> np.ndarray:
    """``(P, B)`` bool: link pair ``model.pairs[k]`` possibly colliding in configuration b.

    Needs a model built with ``per_pair=True``.
    """
    assert (model.node_pair >= 0).any() or not len(model.pairs), "build with per_pair=True"
    return _run(model, frames, per_pair=True)


def config_count(model: SphereModel) -> dict[str, int]:
    """Sizes of the model, for reports."""
    return {
        "spheres": len(model.spheres),
        "nodes": len(model.node_radius),
        "fields": len(model.field_dims),
        "field_MB": math.ceil(model.field_values.nbytes / 2**20),
    }
