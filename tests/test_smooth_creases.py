"""Smooth creases below the fold-back threshold taken as feature lines
(pipeline.geometry.remesh.features.smooth_creases, smooth_chain_mask)."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO

from pipeline.geometry.remesh.features import (FOLD_BACK_DEG, SMOOTH_CREASE_DEG, edge_folds,
                                               feature_chains, feature_edges, smooth_chain_mask,
                                               smooth_creases)

sys.path.insert(0, str(REPO / "benchmarks"))
from bench_shapes import revolution  # noqa: E402  (the made shapes' surfaces of revolution)
from remesh_helpers import remesh_map


def cap_on_neck(n_cap: int = 24, n_neck: int = 16, n_around: int = 64) -> tuple:
    """A unit sphere's cap of 140° on a neck of radius sin 140° going straight down 2 radii:
    the profile turns by 50° where they meet, a closed crease on ring ``n_cap``."""
    th = np.linspace(0, np.radians(140), n_cap + 1)
    r = np.r_[np.sin(th), np.full(n_neck, np.sin(th[-1]))]
    z = np.r_[np.cos(th), np.cos(th[-1]) - np.linspace(0, 2.0, n_neck + 1)[1:]]
    return revolution(r, z, n_around)


def crease_ring(n_cap: int = 24, n_around: int = 64) -> set:
    """The edges of ring ``n_cap`` of :func:`cap_on_neck` as sorted vertex pairs."""
    ring = 1 + (n_cap - 1) * n_around + np.arange(n_around)
    return {tuple(sorted(p)) for p in zip(ring.tolist(), np.roll(ring, -1).tolist())}


def test_the_junction_of_a_cap_and_a_neck_is_a_smooth_crease():
    """The cap-on-neck's crease ring folds by 40–90° (below ``FOLD_BACK_DEG``): no feature
    edge at the default threshold, and :func:`smooth_creases` takes exactly its 64 edges,
    one closed chain, at any target length."""
    V, F = cap_on_neck()
    E, angle = feature_edges(V, F, SMOOTH_CREASE_DEG)
    assert {tuple(sorted(e)) for e in E.tolist()} == crease_ring()
    assert SMOOTH_CREASE_DEG < np.degrees(angle.min()) <= np.degrees(angle.max()) < FOLD_BACK_DEG
    assert len(feature_edges(V, F, FOLD_BACK_DEG)[0]) == 0
    for L in (0.01, 0.1, 10.0):
        E_smooth, angle_smooth = smooth_creases(V, F, L)
        assert {tuple(sorted(e)) for e in E_smooth.tolist()} == crease_ring()
        np.testing.assert_array_equal(np.sort(angle_smooth), np.sort(angle))
    assert len(smooth_creases(V, F, 0.1, max_deg=SMOOTH_CREASE_DEG)[0]) == 0


def interior_edges(V: np.ndarray, F: np.ndarray) -> tuple:
    """:func:`edge_folds`' edges and their dihedral angles (radians)."""
    _, _, A, cos = edge_folds(V, F)
    return A, np.arccos(cos)


def folded_grid(rows_folded: tuple, fold_deg: float = 60.0) -> tuple:
    """A 20 × 6 unit grid (two triangles a square) in the plane z = 0, bent by ``fold_deg``
    about each line y = k of ``rows_folded``: ``(V, F)``."""
    x, y = np.meshgrid(np.arange(21.0), np.arange(7.0))
    turn = np.radians(fold_deg) * np.array([sum(k < row for k in rows_folded)
                                            for row in range(6)])
    step = np.column_stack([np.zeros(6), np.cos(turn), np.sin(turn)])   # row k → k + 1
    lift = np.vstack([np.zeros(3), np.cumsum(step, axis=0)])            # (7, 3)
    V = lift[y.ravel().astype(int)] + np.column_stack([x.ravel(), np.zeros((x.size, 2))])
    q = (np.arange(20)[None, :] + 21 * np.arange(6)[:, None]).ravel()
    F = np.vstack([np.column_stack([q, q + 1, q + 22]), np.column_stack([q, q + 22, q + 21])])
    return V, F


def test_a_long_straight_crease_is_taken_only_where_long_enough():
    """A grid folded by 60° along one row line: one open chain of 18 edges (its ends off the
    boundary), 18 units long; taken at L = 1 (≥ 3 L), not at L = 7."""
    V, F = folded_grid((3,))
    E, angle = feature_edges(V, F, SMOOTH_CREASE_DEG)
    chains = feature_chains(V, E, 15.0)
    assert [len(c) for c in chains] == [19]
    np.testing.assert_allclose(np.degrees(angle), 60.0)
    A, fold = interior_edges(V, F)
    assert smooth_chain_mask(V, A, fold, chains, 1.0).tolist() == [True]
    assert smooth_chain_mask(V, A, fold, chains, 7.0).tolist() == [False]
    assert len(smooth_creases(V, F, 1.0)[0]) == 18


def test_a_crease_beside_another_is_not_taken():
    """The grid folded by 60° along two neighbouring row lines: two chains of 18 edges, each
    one edge from the other (the surface beside it is not smooth); neither is taken, while
    two lines three edges apart are both."""
    V, F = folded_grid((2, 3))
    E, angle = feature_edges(V, F, SMOOTH_CREASE_DEG)
    chains = feature_chains(V, E, 15.0)
    assert sorted(len(c) for c in chains) == [19, 19]
    A, fold = interior_edges(V, F)
    assert smooth_chain_mask(V, A, fold, chains, 1.0).tolist() == [False, False]
    assert len(smooth_creases(V, F, 1.0)[0]) == 0
    V, F = folded_grid((1, 4))
    assert len(smooth_creases(V, F, 1.0)[0]) == 36


def test_random_creases_of_a_rough_surface_are_not_taken():
    """A 30 × 30 grid with random heights (seeded): hundreds of edges fold by more than
    ``SMOOTH_CREASE_DEG``, in zig-zag runs with rough surface beside them; none is taken."""
    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(31.0), np.arange(31.0))
    V = np.column_stack([x.ravel(), y.ravel(), rng.normal(0.0, 0.6, x.size)])
    q = (np.arange(30)[None, :] + 31 * np.arange(30)[:, None]).ravel()
    F = np.vstack([np.column_stack([q, q + 1, q + 32]), np.column_stack([q, q + 32, q + 31])])
    E, angle = feature_edges(V, F, SMOOTH_CREASE_DEG)
    assert len(E) > 200
    chains = feature_chains(V, E, 15.0)
    A, fold = interior_edges(V, F)
    assert not smooth_chain_mask(V, A, fold, chains, 0.01).any()
    assert len(smooth_creases(V, F, 0.01)[0]) == 0


def test_remesh_command_follows_a_smooth_crease():
    """The cap on a neck through the remesh stage's defaults at 3000 vertices (its SEM map,
    as the command makes it): its 50° crease ring is below ``FOLD_BACK_DEG`` but a smooth
    crease, so vertices and edges are kept along it and no input point is farther than
    0.1 L from the remesh (0.045 L; without it, 0.18 L), with the smallest angle at least
    20°, no face turned over and one disk."""
    from pipeline.geometry.remesh_quality import remesh_quality
    from pipeline.geometry.repair import repair_mesh
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    V, F = cap_on_neck()
    mesh = repair_mesh(V, F, name="cap_on_neck")
    uv = remesh_map(mesh)
    r = remesh_stage(mesh, uv, RemeshConfig(vertices=3000))
    L = r.info["improve"]["target_edge_length"]
    q = remesh_quality(mesh.V, mesh.F, r.V, r.F)
    assert r.info["improve"]["features_joined"] > 0
    assert q["distance"]["input_to_output"]["max"] < 0.1 * L
    assert q["triangles"]["min_angle_deg"] >= 20.0
    assert q["distance"]["turned_over_faces"] == 0
    assert q["is_disk"]
