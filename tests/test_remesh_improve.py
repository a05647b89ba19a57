"""The improvement operations together on a real map (pipeline.geometry.remesh)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry.locate import PointLocator, lift
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.collapse import collapse_short_edges
from pipeline.geometry.remesh.flips import flip_edges
from pipeline.geometry.remesh.refine import split_long_edges
from pipeline.geometry.remesh.relax import tangential_smoothing
from pipeline.geometry.remesh.sampling import sample_disk, triangulate_samples
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import face_map, on_surface  # noqa: F401  (face_map: a fixture)


def test_improvement_steps_keep_the_disk(face_map):
    _, mesh, p = face_map
    s = sample_disk(2000, polygon=p.uv[mesh.boundary])
    F = triangulate_samples(s)
    L = PointLocator(p.uv, mesh.F, mesh.boundary)
    face, bary = L.locate(s.points)
    X = lift(mesh.V, mesh.F, face, bary)
    F2, flips, _ = flip_edges(X, F, s.points)
    assert flips > 0 and is_disk(mesh_facts(X, F2))
    assert np.all(signed_double_areas(s.points, F2) > 0)
    assert (np.degrees(corner_angles(X, F2)).min(1).mean()
            > np.degrees(corner_angles(X, F)).min(1).mean())
    movable = np.arange(len(X)) >= s.n_rim
    uv2, f2, b2, X2, moved = tangential_smoothing(mesh.V, mesh.F, p.uv, L, s.points, F2,
                                                   face, bary, movable, 2)
    assert sum(moved) > 0 and np.array_equal(uv2[:s.n_rim], s.points[:s.n_rim])
    assert np.all(signed_double_areas(uv2, F2) > 0) and on_surface(X2, mesh) <= 1e-9
    S = RemeshState(X2, F2, uv2, ~movable, f2, b2, mesh.V, mesh.F, p.uv, L,
                    p.uv[mesh.boundary])
    k = split_long_edges(S, 0.0, budget=100)
    assert k == 100 and S.n == len(X) + 100
    c = collapse_short_edges(S, np.inf, np.inf, budget=100)
    assert c == 100 and S.n == len(X)
    assert is_disk(mesh_facts(S.X, S.F)) and np.all(signed_double_areas(S.uv, S.F) > 0)
    assert on_surface(S.X, mesh) <= 1e-9
