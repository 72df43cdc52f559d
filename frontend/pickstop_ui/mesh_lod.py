"""Fewer triangles for drawing a robot: vertex clustering of its meshes to a face budget.

A browser without a GPU (software WebGL) spends its frame time on triangles: TIAGo's visual
meshes are about 114 000 of them, over a third of a second a frame in headless Chromium here,
and every pointer move and every redraw waits for that frame. The planner draws the robot
for orientation only (the backend checks the real geometry), so it draws it with vertices
merged on a grid in each mesh's own frame: the silhouette stays within one grid cell of
the original, the triangle count drops ten-fold.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

#: Grid cells across a mesh's largest extent, tried from fine to coarse until the budget holds.
DIVISIONS = (96, 64, 48, 32, 24, 16, 12, 8)
MIN_FACES = 12  # a mesh keeps at least this many triangles


def cluster(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge the vertices ``(V, 3)`` that share a grid cell of edge ``cell`` into their mean and
    drop the faces ``(F, 3)`` that collapse (two corners in one cell) or repeat another.

    Returns the new vertices ``(V', 3)`` and faces ``(F', 3)`` (F' <= F); each new vertex lies
    in the cell of the vertices it replaces, so no surface moves by more than the cell's
    diagonal."""
    assert vertices.ndim == 2 and vertices.shape[1] == 3, vertices.shape
    assert faces.ndim == 2 and faces.shape[1] == 3, faces.shape
    assert cell > 0, cell
    keys = np.floor((vertices - vertices.min(axis=0)) / cell).astype(np.int64)
    _, label, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    label = label.reshape(-1)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, label, vertices)
    merged = sums / counts[:, None]
    f = label[faces]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[ok]
    if len(f):
        _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
        f = f[np.sort(first)]
    used = np.unique(f)
    remap = np.full(len(merged), -1, np.int64)
    remap[used] = np.arange(len(used))
    return merged[used], remap[f]


def simplified(mesh: trimesh.Trimesh, divisions: int) -> trimesh.Trimesh:
    """``mesh`` clustered on a grid of ``divisions`` cells across its largest extent (finer
    where that leaves fewer than ``MIN_FACES``: a thin part must not vanish), in one colour
    (its main colour: textures and per-face colours do not survive the merge)."""
    extent = float(np.max(mesh.extents)) if len(mesh.vertices) else 0.0
    if extent <= 0 or len(mesh.faces) <= MIN_FACES:
        return mesh
    n = divisions
    while True:
        v, f = cluster(np.asarray(mesh.vertices), np.asarray(mesh.faces), extent / n)
        if len(f) >= MIN_FACES or n >= DIVISIONS[0]:
            break
        n *= 2
    if len(f) >= len(mesh.faces) or len(f) < MIN_FACES:  # nothing gained, or nothing left
        return mesh
    colours = np.tile(main_colour(mesh), (len(v), 1))
    return trimesh.Trimesh(v, f, vertex_colors=colours, process=False)


def main_colour(mesh: trimesh.Trimesh) -> np.ndarray:
    """RGBA ``(4,)`` uint8 a mesh mostly shows: its colour visuals' or its material's."""
    visual = mesh.visual
    for source in (visual, getattr(visual, "material", None)):
        main = getattr(source, "main_color", None)
        if main is not None:
            return np.asarray(main, np.uint8).reshape(-1)[:4]
    return np.array([180, 180, 180, 255], np.uint8)


def faces_of(scene: Any) -> int:
    return int(sum(len(g.faces) for g in scene.geometry.values() if hasattr(g, "faces")))


def fit_budget(scene: Any, max_faces: int) -> int:
    """Replace the meshes of the trimesh ``scene`` (a URDF's visual or collision scene) by
    clustered copies, each on the finest grid of :data:`DIVISIONS` at which the whole scene
    has at most ``max_faces`` triangles (the coarsest when none does). Names, frames and
    mesh count stay. Returns the scene's triangle count after."""
    meshes = {k: g for k, g in scene.geometry.items() if isinstance(g, trimesh.Trimesh)}
    if faces_of(scene) <= max_faces:
        return faces_of(scene)
    others = faces_of(scene) - sum(len(g.faces) for g in meshes.values())
    for n in DIVISIONS:
        trial = {k: simplified(g, n) for k, g in meshes.items()}
        if others + sum(len(g.faces) for g in trial.values()) <= max_faces or n == DIVISIONS[-1]:
            break
    scene.geometry.update(trial)
    return faces_of(scene)
