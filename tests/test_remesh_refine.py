"""Edge splits (pipeline.geometry.remesh.refine)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh.halfedge import edge_table, independent_by_faces
from pipeline.geometry.remesh.refine import split_edges
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import disk_map


def test_split_edges_keeps_the_cached_twins_right():
    """Rounds of independent splits — inner and rim edges, neighbouring ones whose outer
    half-edges are each other's twins — update the kept half-edge twins in place of
    recomputing them: after every round they equal a fresh computation."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    uv = uv_in.copy()
    face, bary = locator.locate(uv)
    S = RemeshState(V_in.copy(), F_in.copy(), uv, topo.boundary_vertices_mask(F_in, len(uv)),
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
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
