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


def lift_rim(P, X, points):
    """The surface points (k, 3) of ``points`` on the polygon ``P`` (p, 2): linear along the
    edge each lies on, between the surface points ``X`` (p, 3) of its ends."""
    from pipeline.geometry.remesh.sampling import arc_polygon

    seg, t, _ = arc_polygon(P).segments.closest(points)
    Xc = np.vstack([X, X[:1]])
    return Xc[seg] + t[:, None] * (Xc[seg + 1] - Xc[seg])


def stretched_rim(k=300, stretch=3.0):
    """A circle polygon (k, 2) and a surface rim over it (k, 3): the half ``y > 0`` lifted to
    a wave up to ``stretch`` times as long as the polygon (where it is steepest), the half
    ``y < 0`` squashed to ``1/stretch`` of its height (a rim the map stretches on one side and
    shrinks on the other)."""
    t = 2 * np.pi * np.arange(k) / k
    P = np.column_stack([np.cos(t), np.sin(t)])
    up = np.sin(t) > 0
    # on the upper half a z wave whose steepest slope makes the rim `stretch` × longer
    w = np.sqrt(stretch ** 2 - 1.0)
    z = np.where(up, w / 6 * np.sin(6 * t), 0.0)
    X = np.column_stack([P, z])
    X[~up, :2] = P[~up] * np.array([1.0, 1.0 / stretch])
    return P, X


def test_rim_samples_are_spaced_by_the_surface_rim_where_it_is_longer():
    """Where the surface rim is 3 × longer than the polygon, the rim samples are spaced evenly
    along it (their surface spacing within 10 % of its mean, that within 15 % of the samples'
    ``h``); where it is shorter, they keep the polygon's even spacing on the disk (never sparser
    than the lattice)."""
    P, X = stretched_rim()
    s = sample_disk(4000, polygon=P, rim_points=X)
    rim = s.rim
    Y = lift_rim(P, X, rim)
    gap3 = np.linalg.norm(np.roll(Y, -1, axis=0) - Y, axis=1)
    gap2 = np.linalg.norm(np.roll(rim, -1, axis=0) - rim, axis=1)
    mid = 0.5 * (rim + np.roll(rim, -1, axis=0))
    up, down = mid[:, 1] > 0.1, mid[:, 1] < -0.1
    for gap in (gap3[up], gap2[down]):
        assert np.abs(gap / gap.mean() - 1).max() < 0.10
        assert abs(gap.mean() / s.spacing - 1) < 0.15     # the rim count absorbs ≤ 15 %
    edge3 = np.linalg.norm(np.roll(X, -1, axis=0) - X, axis=1)
    edge2 = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    rim_length = np.maximum(edge3, edge2).sum()
    assert rim_length > 1.5 * edge2.sum()
    assert abs(s.n_rim * s.spacing / rim_length - 1) < 0.15
    F = triangulate_samples(s)
    facts = mesh_facts(np.column_stack([s.points, np.zeros(len(s.points))]), F)
    assert is_disk(facts) and facts["degenerate_faces"] == 0 and facts["leaf_faces"] == 0
    assert np.all(signed_double_areas(s.points, F) > 0)


def test_a_rim_shorter_on_the_surface_leaves_the_samples_unchanged():
    """A surface rim nowhere longer than the polygon, longer by less than
    ``RIM_STRETCH_MIN``, or folding back on itself at the spacing, gives exactly the
    polygon's samples."""
    from pipeline.geometry.remesh.sampling import rim_lengths_on_surface

    P = uneven_polygon(60, 5)
    X = np.column_stack([0.5 * P, np.zeros(len(P))])
    assert rim_lengths_on_surface(P, X, 0.05) is None
    # a rim longer on the surface, but by less than RIM_STRETCH_MIN: the same
    X = np.column_stack([P, 0.05 * np.sin(9 * np.arctan2(P[:, 1], P[:, 0]))])
    assert rim_lengths_on_surface(P, X, 0.05) is None
    # a rim 3 × longer that folds back on itself somewhere (a slit): the same
    P, X = stretched_rim()
    assert rim_lengths_on_surface(P, X, 0.01) is not None
    X[150, 2] += 0.3                            # out 0.3 and back across two edges
    assert rim_lengths_on_surface(P, X, 0.01) is None
    a, b = sample_disk(3000, polygon=P, rim_points=X), sample_disk(3000, polygon=P)
    assert np.array_equal(a.points, b.points) and a.rim_lengths is None


def test_a_clockwise_polygon_takes_its_rim_points_in_the_same_order():
    P, X = stretched_rim()
    a = sample_disk(3000, polygon=P, rim_points=X)
    b = sample_disk(3000, polygon=P[::-1], rim_points=X[::-1])
    assert np.array_equal(a.points, b.points)


def test_teeth_shorter_than_the_spacing_do_not_count():
    """A surface rim with 1,200 teeth (each about 0.26 h wide and as tall as wide) along a circle
    twice the polygon's size: the rim length the samples follow is that circle's (within 1 %),
    not the toothed polyline's (over 2 × longer)."""
    from pipeline.geometry.remesh.sampling import rim_lengths_on_surface

    k = 2400
    t = 2 * np.pi * np.arange(k) / k
    P = np.column_stack([np.cos(t), np.sin(t)])
    tooth = np.where(np.arange(k) % 2 == 1, 1.0 + 2 * np.pi / k * 1.9, 1.0)
    X = np.column_stack([2 * P * tooth[:, None], np.zeros(k)])
    assert np.linalg.norm(np.roll(X, -1, axis=0) - X, axis=1).sum() > 4 * 2 * np.pi
    lengths = rim_lengths_on_surface(P, X, 0.04)
    assert abs(lengths.sum() / (2 * 2 * np.pi) - 1) < 0.01


def test_snap_rim_by_the_surface_measure_keeps_the_rim_order():
    P, X = stretched_rim()
    s = sample_disk(3000, polygon=P, rim_points=X)
    targets = P[[20, 80, 200]]
    moved = snap_rim(s, targets)
    assert len(moved) == 3 and np.array_equal(s.points[moved], targets)
    F = triangulate_samples(s)
    assert np.all(signed_double_areas(s.points, F) > 0)
