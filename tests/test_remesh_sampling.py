"""Disk samples and their triangulation (pipeline.geometry.remesh.sampling)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry import topology as topo
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh.sampling import (PATTERNS, _delaunay, sample_disk, snap_rim,
                                               triangulate_samples)
from pipeline.geometry.remesh_quality import is_disk, mesh_facts


def uneven_polygon(k=40, seed=0):
    """A polygon inscribed in the unit circle with very uneven edges (like a SEM boundary)."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.random(k)) * 2 * np.pi
    return np.column_stack([np.cos(t), np.sin(t)])


def polygon_distance(P, poly):
    A, B = poly, np.roll(poly, -1, axis=0)
    D = B - A
    t = np.clip(np.einsum("ksj,sj->ks", P[:, None] - A[None], D) / (D * D).sum(1), 0, 1)
    Q = A[None] + t[..., None] * D[None]
    return np.sqrt(((Q - P[:, None]) ** 2).sum(2)).min(axis=1)


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("n", [100, 300, 1000, 5000, 20000])
def test_sample_count_within_2_percent(pattern, n):
    s = sample_disk(n, pattern=pattern, polygon=uneven_polygon())
    assert abs(len(s.points) - n) <= 0.02 * n
    assert s.pattern == pattern and s.n_rim >= 8


@pytest.mark.parametrize("pattern", PATTERNS)
def test_rim_samples_on_the_polygon_and_interior_away_from_it(pattern):
    poly = uneven_polygon(30, 1)
    s = sample_disk(4000, pattern=pattern, polygon=poly)
    rim, inner = s.points[:s.n_rim], s.points[s.n_rim:]
    assert polygon_distance(rim, poly).max() <= 1e-15
    # CCW along the rim
    ang = np.unwrap(np.arctan2(rim[:, 1], rim[:, 0]))
    assert np.all(np.diff(ang) > 0)
    # no interior sample near the rim (the band relaxation keeps them ≳ 0.5 h away)
    assert polygon_distance(inner, poly).min() >= 0.4 * s.spacing


@pytest.mark.parametrize("pattern", PATTERNS)
def test_triangulation_is_a_ccw_disk_without_leaves(pattern):
    s = sample_disk(3000, pattern=pattern, polygon=uneven_polygon(25, 2))
    F = triangulate_samples(s)
    n = len(s.points)
    X = np.column_stack([s.points, np.zeros(n)])
    facts = mesh_facts(X, F)
    assert is_disk(facts) and facts["degenerate_faces"] == 0 and facts["leaf_faces"] == 0
    assert np.all(signed_double_areas(s.points, F) > 0)
    loop = topo.boundary_loops(F)[0]
    assert sorted(loop.tolist()) == list(range(s.n_rim))          # the boundary = the rim
    assert len(F) == 2 * n - s.n_rim - 2


@pytest.mark.parametrize("k, n", [(3, 100), (4, 100), (4, 2000), (5, 500), (6, 300)])
def test_triangulation_of_a_polygon_with_few_sharp_corners(k, n):
    """A mesh with only k boundary vertices maps onto a k-gon with corners of 60°–120°: the
    rim push dents the rim at such a corner and the hull folds three rim samples of one edge
    into a flat face over the rim. The triangulation is still the disk of the samples, every
    face counter-clockwise with positive area, the boundary exactly the rim."""
    t = 2 * np.pi * np.arange(k) / k
    s = sample_disk(n, polygon=np.column_stack([np.cos(t), np.sin(t)]))
    F = triangulate_samples(s)
    m = len(s.points)
    facts = mesh_facts(np.column_stack([s.points, np.zeros(m)]), F)
    assert is_disk(facts) and facts["degenerate_faces"] == 0 and facts["leaf_faces"] == 0
    assert np.all(signed_double_areas(s.points, F) > 0)
    assert sorted(topo.boundary_loops(F)[0].tolist()) == list(range(s.n_rim))
    assert len(F) == 2 * m - s.n_rim - 2


def test_hexagonal_construction_equals_delaunay():
    s = sample_disk(30000, polygon=uneven_polygon(60, 3))
    F = triangulate_samples(s)                                   # band Delaunay + lattice
    G = _delaunay(s.points, s.n_rim, s.spacing)                  # Delaunay of everything
    key = lambda T: set(map(tuple, np.sort(T, axis=1).tolist()))  # noqa: E731
    assert key(F) == key(G)


def test_spacing_gives_the_lattice_spacing():
    s = sample_disk(spacing=0.05)
    F = triangulate_samples(s)
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]]])
    inner = (E >= s.n_rim).all(1)
    L = np.linalg.norm(s.points[E[inner, 0]] - s.points[E[inner, 1]], axis=1)
    assert abs(np.median(L) - 0.05) < 1e-12


def test_snap_rim_moves_the_nearest_rim_sample_onto_a_corner():
    poly = uneven_polygon(20, 4)
    s = sample_disk(2000, polygon=poly)
    moved = snap_rim(s, poly[[3, 11]])
    assert len(moved) == 2
    assert np.array_equal(s.points[moved], poly[[3, 11]])
    F = triangulate_samples(s)
    assert np.all(signed_double_areas(s.points, F) > 0)


def test_jittered_points_are_the_lattice_moved_by_at_most_a_quarter_spacing():
    """Every jittered point is the hexagonal lattice point of the same spacing nearest to it,
    moved by at most ``JITTER/2 · h`` along each axis; none stays on the lattice; the same seed
    gives the same points."""
    from pipeline.geometry.remesh.sampling import JITTER, _Polygon, jittered_points

    poly = _Polygon(uneven_polygon())
    h = 0.05
    X = jittered_points(poly, h, seed=3)
    dy = h * np.sqrt(3.0) / 2.0
    r = np.rint(X[:, 1] / dy)
    c = np.rint(X[:, 0] / h - 0.5 * (r % 2))
    off = X - np.column_stack([(c + 0.5 * (r % 2)) * h, r * dy])
    assert np.abs(off).max() <= JITTER / 2 * h and (np.abs(off).max(axis=1) > 0).all()
    assert np.array_equal(X, jittered_points(poly, h, seed=3))
    assert not np.array_equal(X, jittered_points(poly, h, seed=4))
