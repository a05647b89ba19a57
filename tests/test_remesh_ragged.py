"""A ragged rim (spurs and notches finer than the remesh, as on a scanned face's border)
remeshed end to end."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from pipeline.geometry import topology as topo
from pipeline.geometry.remesh_quality import is_disk, mesh_facts, surface_distance
from pipeline.geometry.repair import repair_mesh


def ragged_paraboloid(n: int = 80, seed: int = 2, passes: int = 4, drop: float = 0.4):
    """A paraboloid cap z = 0.4 (x² + y²) over the unit disk, Delaunay on an n×n grid jittered
    by 0.15 / n (seeded), with ``passes`` rounds each dropping the fraction ``drop`` of the
    faces with a corner on the boundary: spurs, single-face teeth and notches along the rim;
    then the faces at pinched (bowtie) vertices dropped until there are none, the largest
    piece kept."""
    rng = np.random.default_rng(seed)
    g = np.linspace(-1.0, 1.0, n)
    P = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    P = P[np.hypot(P[:, 0], P[:, 1]) <= 1.0]
    P = P + rng.normal(0.0, 0.15 / n, P.shape)
    F = Delaunay(P).simplices
    for _ in range(passes):
        E = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        u, c = np.unique(E, axis=0, return_counts=True)
        rim = np.isin(F, u[c == 1]).any(axis=1)
        F = F[~(rim & (rng.random(len(F)) < drop))]
    while len(pinched := topo.nonmanifold_vertices(F, len(P))):
        F = F[~np.isin(F, pinched).any(axis=1)]
    _, label = topo.connected_components(F, len(P))
    F = F[label == np.bincount(label).argmax()]
    used, F = np.unique(F, return_inverse=True)
    P = P[used]
    return np.column_stack([P, 0.4 * (P ** 2).sum(axis=1)]), F.reshape(-1, 3)


@pytest.mark.timeout(120)
def test_a_ragged_rim_remesh_keeps_the_angle_guarantee_and_does_not_fold():
    """The ragged paraboloid (4,280 vertices, 339 on the boundary, 102 of them the tips of
    spurs or the bottoms of notches: an input angle sum below 90° or above 270°) through its
    2-step paper map, remeshed at 1,500 vertices with no input corner kept: one disk, no face
    below 20° and none turned over against the input. With rim splits at the spurs' tips and
    the notches' bottoms, 5 faces below 20° and 2 folds are left. (Seeds 1 and 3 of the same
    construction still leave 15 and 11 faces below 20°, 1 and 0 folds: the guarantee is not
    yet general on a ragged rim.)"""
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.parameterize import parameterize_stage
    from pipeline.stages.remesh import ImproveConfig, RemeshConfig, remesh_stage

    V, F = ragged_paraboloid()
    mesh = repair_mesh(V, F)
    p = parameterize_stage(mesh, SEMOptions(mode="paper", max_iter=2))
    r = remesh_stage(mesh, p.image,
                     RemeshConfig(vertices=1500, improve=ImproveConfig(corner_angle_deg=0.0)))
    assert is_disk(mesh_facts(r.V, r.F))
    assert surface_distance(mesh.V, mesh.F, r.V, r.F)["turned_over_faces"] == 0
    assert r.info["improve"]["below_min_angle"]["faces"] == 0
