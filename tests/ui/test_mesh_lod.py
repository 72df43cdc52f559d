"""Fewer triangles for drawing the robot: vertex clustering stays within its grid cell."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from pickstop_ui.mesh_lod import MIN_FACES, cluster, fit_budget, main_colour, simplified


def _sphere(subdivisions: int = 5, radius: float = 0.1, at=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    m.apply_translation(at)
    m.visual.vertex_colors = np.tile([255, 129, 11, 255], (len(m.vertices), 1))
    return m


@pytest.mark.parametrize("cell", [0.005, 0.02, 0.05])
def test_clustered_vertices_stay_in_their_cell_and_faces_stay_proper(cell):
    m = _sphere()
    v, f = cluster(np.asarray(m.vertices), np.asarray(m.faces), cell)
    assert len(f) < len(m.faces) and f.min() >= 0 and f.max() < len(v)
    assert np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2]))
    assert len(np.unique(np.sort(f, axis=1), axis=0)) == len(f)  # no face twice
    # Every new vertex is the mean of originals in one cell: within a cell diagonal of the
    # sphere's surface, and the outline keeps its size.
    r = np.linalg.norm(v, axis=1)
    assert np.all(np.abs(r - 0.1) <= np.sqrt(3) * cell + 1e-12)
    assert np.allclose(v.min(axis=0), m.vertices.min(axis=0), atol=np.sqrt(3) * cell)
    assert np.allclose(v.max(axis=0), m.vertices.max(axis=0), atol=np.sqrt(3) * cell)


def test_a_fine_cell_changes_nothing():
    m = _sphere(2)
    v, f = cluster(np.asarray(m.vertices), np.asarray(m.faces), 1e-6)
    assert len(f) == len(m.faces) and len(v) == len(m.vertices)


def test_simplified_keeps_the_colour_and_a_thin_part_does_not_vanish():
    m = _sphere()
    s = simplified(m, 8)
    assert MIN_FACES <= len(s.faces) < len(m.faces) / 10
    assert tuple(main_colour(s)) == (255, 129, 11, 255)
    thin = trimesh.creation.box((0.2, 0.2, 0.001)).subdivide().subdivide().subdivide()
    assert len(simplified(thin, 8).faces) >= MIN_FACES


def test_a_scene_is_fitted_to_its_budget_keeping_every_mesh():
    scene = trimesh.Scene()
    for k in range(4):
        scene.add_geometry(_sphere(5, 0.05 + 0.02 * k, (0.3 * k, 0, 0)), geom_name=f"link{k}")
    before = sum(len(g.faces) for g in scene.geometry.values())
    assert fit_budget(scene, before) == before  # within budget: untouched
    after = fit_budget(scene, 4000)
    assert after <= 4000 and set(scene.geometry) == {f"link{k}" for k in range(4)}
    assert all(len(g.faces) >= MIN_FACES for g in scene.geometry.values())
    assert sum(len(g.faces) for g in scene.geometry.values()) == after
