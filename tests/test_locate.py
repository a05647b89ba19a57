"""Point location in a disk map's image and barycentric lifting (pipeline.geometry.locate):
exact facts on constructed triangulations, then a real SEM map."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require_data
from pipeline.geometry.locate import (PointLocator, barycentric_coordinates, lift,
                                      locate_points, project_to_boundary_polygon)


def grid_mesh(n=12, jitter=0.0, seed=0):
    """A triangulated square [0,1]² (n×n cells, each split in two), CCW, optional jitter of
    the interior vertices; returns ``(uv, F, boundary loop CCW)``."""
    t = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(t, t)
    uv = np.column_stack([X.ravel(), Y.ravel()])
    if jitter:
        rng = np.random.default_rng(seed)
        inner = (uv > 0).all(1) & (uv < 1).all(1)
        uv[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 2)) / n
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    loop = np.r_[idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]]
    return uv, F, loop


def disk_mesh(k=64, rings=6):
    """A polygon inscribed in the unit circle (k vertices), triangulated with rings inside
    (Delaunay); returns ``(uv, F, boundary loop CCW)``."""
    from scipy.spatial import Delaunay

    pts = [np.zeros((1, 2))]
    for r in range(1, rings + 1):
        m = max(6, int(round(k * r / rings)))
        t = 2 * np.pi * (np.arange(m) + 0.5 * (r % 2)) / m
        pts.append(r / rings * np.column_stack([np.cos(t), np.sin(t)]))
    uv = np.vstack(pts)
    F = Delaunay(uv).simplices
    x, y = uv[:, 0], uv[:, 1]
    a2 = (x[F[:, 1]] - x[F[:, 0]]) * (y[F[:, 2]] - y[F[:, 0]]) - \
        (y[F[:, 1]] - y[F[:, 0]]) * (x[F[:, 2]] - x[F[:, 0]])
    F[a2 < 0] = F[a2 < 0][:, [0, 2, 1]]
    loop = np.arange(len(uv) - k, len(uv))
    return uv, F, loop


def reconstruct(uv, F, face, bary):
    return lift(uv, F, face, bary)


def check_valid(face, bary, k):
    assert face.dtype == np.int64 and face.shape == (k,)
    assert bary.dtype == np.float64 and bary.shape == (k, 3)
    assert np.all(face >= 0)
    assert np.all(bary >= 0.0)
    assert np.allclose(bary.sum(axis=1), 1.0, atol=1e-15, rtol=0)


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_vertices_are_located_exactly(jitter):
    uv, F, loop = grid_mesh(10, jitter)
    face, bary = locate_points(uv, F, uv, loop)
    check_valid(face, bary, len(uv))
    # the located face has the vertex as a corner with weight exactly 1
    corner = F[face]
    hit = corner == np.arange(len(uv))[:, None]
    assert hit.any(axis=1).all()
    assert np.array_equal(bary[hit], np.ones(len(uv)))
    assert np.array_equal(reconstruct(uv, F, face, bary), uv)


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_points_on_edges(jitter):
    uv, F, loop = grid_mesh(10, jitter)
    E = np.unique(np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    rng = np.random.default_rng(1)
    t = np.r_[np.full(len(E), 0.5), rng.random(len(E))]
    E2 = np.vstack([E, E])
    P = uv[E2[:, 0]] + t[:, None] * (uv[E2[:, 1]] - uv[E2[:, 0]])
    face, bary = locate_points(uv, F, P, loop)
    check_valid(face, bary, len(P))
    assert np.abs(reconstruct(uv, F, face, bary) - P).max() <= 1e-12
    # the face found contains the edge, and the third corner has weight 0
    corners = F[face]
    has_both = ((corners == E2[:, :1]).any(1)) & ((corners == E2[:, 1:]).any(1))
    assert has_both.all()
    third = ~((corners == E2[:, :1]) | (corners == E2[:, 1:]))
    assert np.abs(bary[third]).max() <= 1e-12


def test_random_points_inside_match_brute_force():
    uv, F, loop = grid_mesh(16, 0.35)
    rng = np.random.default_rng(2)
    P = rng.random((20000, 2))
    face, bary = locate_points(uv, F, P, loop)
    check_valid(face, bary, len(P))
    assert np.abs(reconstruct(uv, F, face, bary) - P).max() <= 1e-12
    # brute force: the point's barycentrics in the found face are all >= 0 (to rounding)
    T = F[face]
    b = barycentric_coordinates(P, uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]])
    assert b.min() >= -1e-12


def test_points_outside_go_to_the_closest_boundary_point():
    uv, F, loop = grid_mesh(8)
    rng = np.random.default_rng(3)
    P = rng.uniform(-0.5, 1.5, (4000, 2))
    P = P[~((P >= 0) & (P <= 1)).all(1)]
    face, bary = locate_points(uv, F, P, loop)
    check_valid(face, bary, len(P))
    Q = reconstruct(uv, F, face, bary)
    expected = np.clip(P, 0.0, 1.0)                        # closest point of the square
    assert np.abs(Q - expected).max() <= 1e-12
    assert np.abs(project_to_boundary_polygon(uv, loop, P) - expected).max() <= 1e-12


def test_rim_polygon_points_and_circle_points():
    uv, F, loop = disk_mesh(48)
    # points on the polygon's edges (the sampler's rim samples) locate exactly on them
    rng = np.random.default_rng(4)
    i = rng.integers(0, len(loop), 500)
    t = rng.random(500)
    A, B = uv[loop[i]], uv[loop[(i + 1) % len(loop)]]
    P = A + t[:, None] * (B - A)
    face, bary = locate_points(uv, F, P, loop)
    check_valid(face, bary, len(P))
    assert np.abs(reconstruct(uv, F, face, bary) - P).max() <= 1e-12
    # points on the unit circle lie outside the inscribed polygon: they go to its closest point
    ang = 2 * np.pi * rng.random(2000)
    C = np.column_stack([np.cos(ang), np.sin(ang)])
    face, bary = locate_points(uv, F, C, loop)
    check_valid(face, bary, len(C))
    Q = reconstruct(uv, F, face, bary)
    proj = project_to_boundary_polygon(uv, loop, C)
    assert np.abs(Q - proj).max() <= 1e-12
    # brute force closest point on the polygon
    Ak, Bk = uv[loop], uv[np.roll(loop, -1)]
    D = Bk - Ak
    tt = np.clip(np.einsum("ksj,sj->ks", C[:, None] - Ak[None], D) / (D * D).sum(1), 0, 1)
    cand = Ak[None] + tt[..., None] * D[None]
    best = cand[np.arange(len(C)), np.argmin(((cand - C[:, None]) ** 2).sum(2), axis=1)]
    assert np.abs(proj - best).max() <= 1e-12
    # every projected point is on a boundary edge: one barycentric is 0
    assert (bary.min(axis=1) == 0).all()


def test_boundary_defaults_to_all_boundary_edges_and_holes():
    uv, F, _ = grid_mesh(9)
    # punch a hole: drop the faces of the middle cell block
    c = uv[F].mean(axis=1)
    keep = ~((np.abs(c - 0.5) < 0.17).all(axis=1))
    F = F[keep]
    P = np.array([[0.5, 0.5], [0.52, 0.47], [1.2, 0.4], [-0.1, -0.1]])
    face, bary = locate_points(uv, F, P)
    check_valid(face, bary, len(P))
    Q = reconstruct(uv, F, face, bary)
    # the hole is the square [1/3, 2/3]²: a point in it goes to the hole's nearest edge, not
    # to the outer square
    assert np.isclose(np.linalg.norm(Q[0] - 0.5), 1 / 6, atol=1e-12)
    assert np.allclose(Q[1], [0.52, 1 / 3], atol=1e-12)
    assert np.allclose(Q[2], [1.0, 0.4], atol=1e-12) and np.allclose(Q[3], [0.0, 0.0])


def test_empty_and_single_queries():
    uv, F, loop = grid_mesh(4)
    face, bary = locate_points(uv, F, np.zeros((0, 2)), loop)
    assert face.shape == (0,) and bary.shape == (0, 3)
    face, bary = locate_points(uv, F, np.array([0.3, 0.3]), loop)
    check_valid(face, bary, 1)


def test_lift_positions_and_attributes():
    uv, F, loop = grid_mesh(6, 0.2)
    V = np.column_stack([uv, np.sin(uv[:, 0]) * uv[:, 1]])          # a surface over the square
    C = np.column_stack([uv, 1 - uv[:, 0]])                          # colours
    rng = np.random.default_rng(5)
    P = rng.random((300, 2))
    face, bary = locate_points(uv, F, P, loop)
    X = lift(V, F, face, bary)
    manual = (bary[:, :, None] * V[F[face]]).sum(axis=1)
    assert np.array_equal(X, manual)
    assert np.allclose(X[:, :2], P, atol=1e-12)                     # linear in uv: exact
    assert lift(C, F, face, bary).shape == (300, 3)
    s = lift(np.arange(len(uv), dtype=float), F, face, bary)         # scalar attribute
    assert s.shape == (300,)


def test_matches_matplotlib_trifinder():
    from matplotlib.tri import Triangulation, TrapezoidMapTriFinder

    uv, F, loop = disk_mesh(80, 10)
    rng = np.random.default_rng(6)
    r = np.sqrt(rng.random(5000)) * 0.98
    a = 2 * np.pi * rng.random(5000)
    P = np.column_stack([r * np.cos(a), r * np.sin(a)])
    face, bary = locate_points(uv, F, P, loop)
    tf = TrapezoidMapTriFinder(Triangulation(uv[:, 0], uv[:, 1], F))(P[:, 0], P[:, 1])
    inside = tf >= 0
    same = face[inside] == tf[inside]
    # on a shared edge either face is right: the other must contain the point too
    T = F[tf[inside][~same]]
    b = barycentric_coordinates(P[inside][~same], uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]])
    assert same.mean() > 0.999 and (len(b) == 0 or b.min() >= -1e-12)


def test_relocate_agrees_with_locate():
    uv, F, loop = grid_mesh(12, 0.3)
    L = PointLocator(uv, F, loop)
    rng = np.random.default_rng(7)
    P = rng.random((3000, 2))
    f0, b0 = L.locate(P)
    Q = np.clip(P + rng.normal(scale=0.02, size=P.shape), 0, 1)
    f1, b1, inside = L.relocate(Q, f0)
    assert inside.all()
    assert np.abs(lift(uv, F, f1, b1) - Q).max() <= 1e-12


@pytest.mark.parametrize("walk", [0, 1, 2, 5])
def test_relocate_walks_to_the_same_answer(walk, monkeypatch):
    """Hints one to a few faces away: every walk length gives the grid's answer (exact
    positions), the walk finds most of them without the grid, and points outside the
    mesh are still reported outside."""
    uv, F, loop = grid_mesh(20, 0.3)
    L = PointLocator(uv, F, loop)
    rng = np.random.default_rng(11)
    P = 0.05 + 0.9 * rng.random((4000, 2))
    f0, _ = L.locate(P)
    Q = P + rng.normal(scale=0.015, size=P.shape)              # about one face
    Q[:50] = [1.3, 0.5]                                         # outside the unit square
    calls = []
    grid = L._grid_locate
    monkeypatch.setattr(L, "_grid_locate", lambda pts, tol=1e-12, project=True:
                        calls.append(len(pts)) or grid(pts, tol, project))
    f1, b1, inside = L.relocate(Q, f0, walk=walk)
    want_f, want_b, want_inside = grid(Q)
    assert np.array_equal(inside, want_inside) and not inside[:50].any()
    assert np.abs(lift(uv, F, f1, b1) - lift(uv, F, want_f, want_b)).max() <= 1e-12
    if walk >= 2:
        assert sum(calls) < 0.2 * len(Q)          # most points found by walking


def test_relocate_without_projection_marks_outside_points():
    """Without ``project``, the points outside the square (the walk stops at the rim, the
    grid finds no face) get face −1 and zero barycentrics; the inside ones get the projecting
    call's faces and barycentrics, bit for bit."""
    uv, F, loop = grid_mesh(20, 0.3)
    L = PointLocator(uv, F, loop)
    rng = np.random.default_rng(5)
    P = 0.05 + 0.9 * rng.random((2000, 2))
    f0, _ = L.locate(P)
    Q = P + rng.normal(scale=0.015, size=P.shape)
    Q[:40] = [1.3, 0.5]
    Q[40:80] = [-0.2, 0.7]
    f1, b1, in1 = L.relocate(Q, f0, walk=3)
    f2, b2, in2 = L.relocate(Q, f0, walk=3, project=False)
    assert np.array_equal(in1, in2) and not in2[:80].any() and in2[80:].all()
    assert (f2[:80] == -1).all() and (b2[:80] == 0.0).all()
    assert (f1[:80] >= 0).all()
    assert np.array_equal(f1[80:], f2[80:]) and np.array_equal(b1[80:], b2[80:])


def test_walk_rows_hold_each_faces_corners_and_neighbours():
    """The walk's table (one 64-byte row a face, the array on a 64-byte boundary): the
    corners' coordinates bit for bit, and the face across each edge ``F[f, c] → F[f, c+1]``
    (−1 on the boundary), read from the row's int32 tail."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry._kernels import walk_rows

    uv, F, _ = grid_mesh(7, 0.3)
    rows = walk_rows(uv, np.ascontiguousarray(F, dtype=np.int64),
                     topo.interior_edge_twins(F))
    assert rows.shape == (len(F), 8) and rows.ctypes.data % 64 == 0
    assert np.array_equal(rows[:, :6], uv[F].reshape(-1, 6))
    across = rows.view(np.int32)[:, 12:15]
    for f in range(len(F)):
        for c in range(3):
            a, b = F[f, c], F[f, (c + 1) % 3]
            other = [g for g in range(len(F)) if g != f and {a, b} <= set(F[g])]
            assert across[f, c] == (other[0] if other else -1)


def test_a_batch_walks_each_point_as_it_would_alone():
    """The walk takes several points at once (lanes): every point of a batch (walks of 0 to
    many steps, some ending at the rim or out of steps) gets the face, barycentrics and
    not-found answer it gets walked alone, and the points not found come back in order."""
    from pipeline.geometry._kernels import walk_to_faces

    uv, F, loop = grid_mesh(20, 0.3)
    L = PointLocator(uv, F, loop)
    rows = L.walk_table()
    rng = np.random.default_rng(5)
    P = np.ascontiguousarray(rng.uniform(-0.2, 1.2, (500, 2)))
    start = rng.integers(0, len(F), len(P))
    todo = np.arange(len(P))
    face, bary = np.full(len(P), -1), np.zeros((len(P), 3))
    left = walk_to_faces(rows, P, start, todo, 6, 1e-10, face, bary)
    alone_left = []
    for i in range(len(P)):
        f1, b1 = np.full(len(P), -1), np.zeros((len(P), 3))
        alone_left += list(walk_to_faces(rows, P, start, np.array([i]), 6, 1e-10, f1, b1))
        assert f1[i] == face[i] and np.array_equal(b1[i], bary[i])
    assert list(left) == alone_left and 0 < len(left) < len(P)


@pytest.mark.parametrize("method", ["locate_with_inside", "locate_from_cells"])
def test_large_batches_walk_to_the_grids_answer(method, monkeypatch):
    """A batch of at least half as many points as image vertices walks from the nearest
    vertex's face (``locate_with_inside``) or from a face of its grid cell
    (``locate_from_cells``): the same inside/outside answer and positions as the grid,
    vertices still located with weight exactly 1, and only a few points left for the grid."""
    uv, F, loop = grid_mesh(60, 0.3)
    L = PointLocator(uv, F, loop)
    rng = np.random.default_rng(3)
    E = np.unique(np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]]]), axis=1), axis=0)
    P = np.vstack([uv, 0.5 * (uv[E[:, 0]] + uv[E[:, 1]]), rng.random((5000, 2)),
                   rng.uniform(-0.5, 1.5, (500, 2))])
    assert len(P) >= max(4096, len(uv) / 2)
    calls = []
    grid = L._grid_locate
    monkeypatch.setattr(L, "_grid_locate", lambda pts, tol=1e-10, project=True:
                        calls.append(len(pts)) or grid(pts, tol, project))
    f, b, inside = getattr(L, method)(P)
    check_valid(f, b, len(P))
    want_f, want_b, want_inside = grid(P)
    assert np.array_equal(inside, want_inside) and not inside[-500:][
        ((P[-500:] < 0) | (P[-500:] > 1)).any(axis=1)].any()
    assert np.abs(lift(uv, F, f, b) - lift(uv, F, want_f, want_b)).max() <= 1e-15
    hit = F[f[:len(uv)]] == np.arange(len(uv))[:, None]
    assert np.array_equal(b[:len(uv)][hit], np.ones(len(uv)))
    assert 0 < sum(calls) < 0.05 * len(P)        # the outside points (and a few) use the grid


def test_real_sem_map_reconstructs_to_1e_12():
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.load import load_stage
    from pipeline.stages.parameterize import parameterize_stage

    path = require_data("meshes", "gpp_bunny.obj")
    intake = load_stage(path)
    p = parameterize_stage(intake.mesh, SEMOptions(mode="paper"))
    uv, F, loop = p.uv, intake.mesh.F, intake.mesh.boundary
    rng = np.random.default_rng(8)
    r = np.sqrt(rng.random(20000))
    a = 2 * np.pi * rng.random(20000)
    P = np.column_stack([r * np.cos(a), r * np.sin(a)])            # the whole unit disk
    face, bary = locate_points(uv, F, P, loop)
    check_valid(face, bary, len(P))
    Q = lift(uv, F, face, bary)
    from matplotlib.path import Path as MplPath

    inside = MplPath(uv[loop]).contains_points(P)
    assert np.abs(Q[inside] - P[inside]).max() <= 1e-12
    # the others (outside the inscribed polygon) go to its closest point
    proj = project_to_boundary_polygon(uv, loop, P[~inside])
    assert (~inside).sum() > 0
    assert np.abs(Q[~inside] - proj).max() <= 1e-12
    # every vertex of the map locates onto itself
    f, b = locate_points(uv, F, uv, loop)
    assert np.abs(lift(uv, F, f, b) - uv).max() == 0.0


def test_closest_on_segments_matches_the_brute_force_where_segment_lengths_vary():
    """A closed polygon of 400 segments, one of them 100 times longer than the others (so the
    first 8 nearest midpoints settle few points), and 2,000 random points plus every polygon
    vertex (where two segments tie): each point's segment is one of the nearest of the brute
    force over all segments, at exactly the smallest distance, with its ``t`` and closest
    point."""
    from pipeline.geometry.locate import _closest_on_segments

    rng = np.random.default_rng(3)
    x = np.concatenate([np.linspace(0.0, 1.0, 400, endpoint=False), [100.0]])
    C = np.column_stack([x, 0.01 * np.sin(7 * x)])
    C = np.vstack([C, [[100.0, 1.0], [0.0, 1.0]]])
    A, B = C, np.roll(C, -1, axis=0)
    P = np.vstack([rng.uniform([-1, -1], [101, 2], (2000, 2)), C])
    seg, t, Q = _closest_on_segments(P, A, B)
    D = B - A
    L2 = np.einsum("ij,ij->i", D, D)
    rel = P[:, None, :] - A[None]
    tt = np.clip(np.einsum("psj,sj->ps", rel, D) / L2, 0.0, 1.0)
    d2 = ((rel - tt[..., None] * D[None]) ** 2).sum(axis=2)
    r = np.arange(len(P))
    np.testing.assert_array_equal(d2[r, seg], d2.min(axis=1))
    np.testing.assert_array_equal(t, tt[r, seg])
    np.testing.assert_array_equal(Q, A[seg] + t[:, None] * D[seg])


def test_grid_candidates_are_the_first_best_face_of_the_cell_bit_for_bit():
    """The compiled cell search gives, per point, the first face of its cell (in the cell's
    order) with the largest smallest barycentric (a non-finite one counting as −inf), and
    that face's barycentrics as :func:`barycentric_coordinates` computes them, to the bit:
    at vertices, on edges (ties between the two faces), inside, outside the square and at a
    NaN point (the first cell)."""
    uv, F, loop = grid_mesh(9, 0.3)
    L = PointLocator(uv, F, loop)
    rng = np.random.default_rng(5)
    P = np.vstack([uv, (uv[F[:, 0]] + uv[F[:, 1]]) / 2, rng.uniform(-0.3, 1.3, (3000, 2)),
                   [[np.nan, 0.5], [0.5, np.inf]]])
    face, bary, score = L._candidates(P)
    with np.errstate(invalid="ignore"):
        ij = L._cell_xy(P)                       # numpy's cells (NaN, inf: the first)
    for i, p in enumerate(P):
        cx, cy = ij[i]
        cell = cy * L.shape[0] + cx
        cand = L.cell_faces[L.cell_start[cell]:L.cell_start[cell + 1]]
        if len(cand) == 0:
            assert face[i] == -1 and score[i] == -np.inf and np.isnan(bary[i]).all()
            continue
        T = F[cand]
        with np.errstate(invalid="ignore"):
            lam = barycentric_coordinates(np.repeat(p[None], len(cand), axis=0),
                                          uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]])
        sc = lam.min(axis=1)
        sc[~np.isfinite(sc)] = -np.inf
        j = int(np.flatnonzero(sc == sc.max())[0])
        assert face[i] == cand[j]
        assert bary[i].tobytes() == lam[j].tobytes()
        assert score[i] == sc[j]


def _grid_table_numpy(L: PointLocator) -> tuple[np.ndarray, np.ndarray]:
    """The locator's ``(cell_faces, cell_start)`` by the numpy formula: every face's bounding
    box cells (x fastest), a pair of a face of more than two cells dropped when the cell lies
    beyond one edge's line by more than 1e-9 cell sizes, a stable sort by cell."""
    uv, F, cell = L.uv, L.F, L.cell
    m, (ox, oy) = len(F), L.origin
    T = uv[F]
    lo = np.minimum(np.minimum(T[:, 0], T[:, 1]), T[:, 2])
    hi = np.maximum(np.maximum(T[:, 0], T[:, 1]), T[:, 2])
    i0, i1 = L._cell_xy(lo), L._cell_xy(hi)
    wx = i1[:, 0] - i0[:, 0] + 1
    count = wx * (i1[:, 1] - i0[:, 1] + 1)
    face = np.repeat(np.arange(m), count)
    k = np.arange(len(face)) - np.repeat(np.cumsum(count) - count, count)
    cx, cy = i0[face, 0] + k % wx[face], i0[face, 1] + k // wx[face]
    tx, ty = uv[F[face], 0], uv[F[face], 1]
    x0, y0 = ox + cx.astype(np.float64) * cell, oy + cy.astype(np.float64) * cell
    a2 = ((tx[:, 1] - tx[:, 0]) * (ty[:, 2] - ty[:, 0])
          - (ty[:, 1] - ty[:, 0]) * (tx[:, 2] - tx[:, 0]))
    s = np.where(a2 < 0, -1.0, 1.0)
    touch = np.ones(len(face), bool)
    for c in range(3):
        px, py, qx, qy = tx[:, c], ty[:, c], tx[:, (c + 1) % 3], ty[:, (c + 1) % 3]
        nx, ny = s * (qy - py), (-s) * (qx - px)
        mx, my = np.where(nx > 0, x0, x0 + cell), np.where(ny > 0, y0, y0 + cell)
        touch &= nx * (mx - px) + ny * (my - py) <= 1e-9 * cell * (np.abs(nx) + np.abs(ny))
    keep = (count[face] <= 2) | touch
    cells = (cy * L.shape[0] + cx)[keep]
    order = np.argsort(cells, kind="stable")
    start = np.r_[0, np.cumsum(np.bincount(cells, minlength=int(np.prod(L.shape))))]
    return face[keep][order], start


@pytest.mark.parametrize("mesh", ["grid", "disk", "thin", "sem"])
def test_grid_table_is_the_numpy_formula(mesh):
    """The compiled grid table (:func:`.._kernels.grid_cells`) is the numpy formula's, face
    for face: a jittered grid (vertices on cell borders), a Delaunay disk, long thin
    triangles across many cells, and a SEM map of a real mesh."""
    if mesh == "grid":
        uv, F, _ = grid_mesh(12, 0.3)
    elif mesh == "disk":
        uv, F, _ = disk_mesh(96, 8)
    elif mesh == "thin":
        rng = np.random.default_rng(2)
        uv = rng.uniform(-1, 1, (400, 2))
        F = rng.integers(0, 400, (600, 3))
        uv[F[:, 2]] = 0.5 * (uv[F[:, 0]] + uv[F[:, 1]]) + rng.normal(0, 1e-3, (600, 2))
    else:
        from pipeline.geometry.sem import SEMOptions
        from pipeline.stages.load import load_stage
        from pipeline.stages.parameterize import parameterize_stage

        intake = load_stage(require_data("meshes", "gpp_bunny.obj"))
        uv = parameterize_stage(intake.mesh, SEMOptions(mode="paper")).uv
        F = intake.mesh.F
    for factor in (0.5, 4.0):
        L = PointLocator(uv, F, cell_factor=factor)
        faces, start = _grid_table_numpy(L)
        assert L.cell_faces.dtype == L.cell_start.dtype == np.int64
        np.testing.assert_array_equal(L.cell_start, start)
        np.testing.assert_array_equal(L.cell_faces, faces)
        assert len(faces) > len(F)
