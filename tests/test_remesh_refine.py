"""Edge splits (pipeline.geometry.remesh.refine)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import lift
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh.halfedge import (DISK_SHAPE_MIN, disk_shape, edge_table,
                                               independent_by_faces)
from pipeline.geometry.remesh.improve import degenerate_faces
from pipeline.geometry.remesh.refine import split_edges, split_faces, split_long_edges
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import disk_map


def _map_state() -> RemeshState:
    """The disk map of :func:`disk_map` as a remesh state of itself (its own vertices and
    faces, located and lifted)."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    uv = uv_in.copy()
    face, bary = locator.locate(uv)
    return RemeshState(V_in.copy(), F_in.copy(), uv, topo.boundary_vertices_mask(F_in, len(uv)),
                       face, bary, V_in, F_in, uv_in, locator, uv_in[loop])


def test_split_edges_keeps_the_cached_twins_right():
    """Rounds of independent splits — inner and rim edges, neighbouring ones whose outer
    half-edges are each other's twins — update the kept half-edge twins in place of
    recomputing them: after every round they equal a fresh computation."""
    S = _map_state()
    rng = np.random.default_rng(2)
    for _ in range(4):
        h, a, b, twin = edge_table(S.F, twin=S.twins())
        pick = rng.permutation(len(h))
        f1 = h[pick] // 3
        f2 = np.where(twin[pick] >= 0, twin[pick] // 3, f1)
        sel = pick[independent_by_faces(len(S.F), f1, f2, rng.random(len(pick)))]
        assert (twin[sel] < 0).any() and (twin[sel] >= 0).any()
        split_edges(S, h[sel], twin[sel], rng.uniform(0.2, 0.8, len(sel)))
        assert S.cached_twins() is not None                            # kept, not dropped
        assert np.array_equal(S.twins(), topo.interior_edge_twins(S.F))
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


def test_split_faces_keeps_the_cached_twins_right():
    """Rounds of 1 → 3 splits of many faces at once — neighbouring ones, rim faces — update
    the kept half-edge twins in place of recomputing them: after every round they equal a
    fresh computation; without cached twins none are made up."""
    S = _map_state()
    rng = np.random.default_rng(5)
    for _ in range(4):
        S.twins()
        faces = np.sort(rng.choice(len(S.F), len(S.F) // 3, replace=False))
        tw = S.twins()
        nb = tw[3 * faces] // 3
        assert np.isin(nb[nb >= 0], faces).any() and (tw[3 * faces] < 0).any()
        M = S.uv[S.F[faces]].mean(axis=1)
        split_faces(S, faces, M)
        assert S.cached_twins() is not None
        assert np.array_equal(S.twins(), topo.interior_edge_twins(S.F))
    S.set_faces(S.F)
    split_faces(S, np.array([0]), S.uv[S.F[[0]]].mean(axis=1))
    assert S.cached_twins() is None
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


def thin_face_state():
    """Four faces on a disk map with a tent: face ``[A, B, P]`` is thin on the disk (``P`` is
    1e-14 above the midpoint of ``A–B``) but not on the surface (the tent lifts ``P``), the
    state a chain of splits and flips in a squeezed region of a real map reached."""
    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.1)
    uv = np.array([[-0.2, 0.0], [0.2, 0.0], [0.0, 1e-14], [0.0, -0.2], [0.0, 0.2]])
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 2, 4], [2, 1, 4]])
    face, bary = locator.locate(uv)
    X = lift(V_in, F_in, face, bary)
    rim = np.array([True, True, False, True, True])
    return RemeshState(X, F, uv, rim, face, bary, V_in, F_in, uv_in, locator, uv_in[loop])


def test_split_never_lands_on_the_corner_of_a_face_thin_on_the_disk():
    """Splitting ``A–B`` of the thin face at its disk midpoint would put the new vertex on
    ``P``: two vertices at one point, a zero-length edge (the NaN angles of c3d_alligator at
    20k). The split is refused: no face thinner than DISK_SHAPE_MIN on the disk is made."""
    S = thin_face_state()
    assert len(degenerate_faces(S)) == 0 and (signed_double_areas(S.uv, S.F) > 0).all()
    split_long_edges(S, 0.35)                       # only A–B (0.4) is longer
    assert len(degenerate_faces(S)) == 0
    assert (signed_double_areas(S.uv, S.F) > 0).all()
    fresh = disk_shape(S.uv, S.F[4:])               # the faces the splits made, if any
    assert (fresh >= DISK_SHAPE_MIN).all()


def test_compiled_edge_lengths_are_the_row_norms():
    """:func:`.halfedge.edge_lengths` gives the values of ``norms(X[a] − X[b])`` bit for bit,
    on coordinates of mixed magnitudes."""
    from pipeline.geometry.remesh.halfedge import edge_lengths
    from pipeline.geometry.rows import norms

    rng = np.random.default_rng(7)
    X = rng.normal(size=(500, 3)) * 10.0 ** rng.integers(-6, 6, size=(500, 1))
    a, b = rng.integers(0, 500, 3000), rng.integers(0, 500, 3000)
    assert np.array_equal(edge_lengths(X, a, b), norms(X[a] - X[b]))
