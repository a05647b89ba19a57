"""The remesh follows the input's sharp creases (pipeline.geometry.remesh.fidelity)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import PointLocator
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh import uniform_remesh
from pipeline.geometry.remesh.fidelity import far_input_vertices, follow_input
from pipeline.geometry.remesh_quality import (MeshDistance, is_disk, mesh_facts,
                                              triangle_quality)
from remesh_helpers import ccw_delaunay, coarse_state, disk_points


def creased_disk(slope: float, x0: float = 0.1):
    """The unit disk folded along the line ``u = x0``: ``z = slope·|u − x0|``, its map the
    ``uv`` coordinates. The ring points of :func:`remesh_helpers.disk_points` (40 rings) off
    the line and 158 points on it, so that input edges run along the crease. Returns
    ``(uv_in, F_in, V_in, loop, locator)``."""
    uv = disk_points(40, 6)
    uv = uv[np.abs(uv[:, 0] - x0) > 0.01]
    y = np.linspace(-1, 1, 161)[1:-1]
    y = y[np.abs(y) < np.sqrt(1 - x0 ** 2) - 0.02]
    uv = np.vstack([uv, np.column_stack([np.full(len(y), x0), y])])
    F = ccw_delaunay(uv)
    V = np.column_stack([uv, slope * np.abs(uv[:, 0] - x0)])
    loop = topo.boundary_loops(F)[0]
    return uv, F, V, loop, PointLocator(uv, F, loop)


def interior_distances(V_in, F_in, X, F):
    """The distance of every interior input vertex from the mesh ``(X, F)``."""
    inner = ~topo.boundary_vertices_mask(F_in, len(V_in))
    return MeshDistance(X, F)(V_in[inner])[0]


@pytest.mark.timeout(60)
def test_follow_input_puts_a_locked_vertex_on_far_input_vertices_of_a_crease():
    """A coarse remesh (85 vertices, 4 rings) of the disk creased at slope 1: it cuts across
    the crease, 365 interior input vertices farther than 0.05 from it, the farthest 0.137.
    After :func:`follow_input` (tolerance 0.05, gap 0.1) each vertex it returns is locked and
    lies exactly on a far input vertex, none of the input vertices is farther than 0.05 any
    more, and the remesh is still a counter-clockwise disk."""
    S, _ = coarse_state(*creased_disk(1.0), 4)
    F_in, V_in = S.F_in, S.V_in
    far = far_input_vertices(S, 0.05)
    assert len(far) == 365
    assert np.isclose(interior_distances(V_in, F_in, S.X, S.F).max(), 0.1366, atol=1e-4)
    v = follow_input(S, 0.05, min_gap=0.1)
    assert len(v) and S.locked[v].all()
    on = np.linalg.norm(S.X[v][:, None] - V_in[far][None], axis=2).min(axis=1)
    assert np.all(on < 1e-12)
    assert len(far_input_vertices(S, 0.05)) == 0
    assert interior_distances(V_in, F_in, S.X, S.F).max() <= 0.05
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


@pytest.mark.timeout(120)
def test_uniform_remesh_follows_a_sharp_crease():
    """The disk creased at slope 2 (a 127° fold) remeshed at 1000 vertices: without
    ``follow_input`` its faces cut across the crease, an input vertex on it 0.35 L from the
    remesh; with it (0.25, the default) every interior input vertex is within 0.25 L, with the
    same count, one disk, and no smaller smallest angle."""
    uv_in, F_in, V_in, loop, _ = creased_disk(2.0)
    far, smallest = {}, {}
    for follow in (0.0, 0.25):
        r = uniform_remesh(V_in, F_in, uv_in, loop, vertices=1000, follow_input=follow)
        L = r.info["spacing_mesh_units"]
        far[follow] = interior_distances(V_in, F_in, r.V, r.F).max() / L
        smallest[follow] = triangle_quality(r.V, r.F)["min_angle_deg"]
        assert len(r.V) == 1000 and is_disk(mesh_facts(r.V, r.F))
    assert far[0.0] > 0.3 and far[0.25] <= 0.25
    assert smallest[0.25] >= smallest[0.0]
