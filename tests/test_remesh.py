"""Uniform remeshing through the SEM map: disk sampling, triangulation, improvement, quality
measures, baselines, the stage's files, the CLI and the config; then every shared disk mesh
at 20k vertices (each parameterized once per session)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import require_data, run_cli
from pipeline.geometry import topology as topo
from pipeline.geometry.disk_sampling import (PATTERNS, _delaunay, sample_disk, snap_rim,
                                             triangulate_samples)
from pipeline.geometry.locate import PointLocator, _closest_on_segments, lift
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh_improve import (RemeshState, _edge_table, _independent_by_faces,
                                              collapse_short_edges, edge_sag,
                                              delaunay_flips, insert_vertices,
                                              split_edges, split_long_edges,
                                              tangential_relaxation)
from pipeline.geometry.remesh_quality import (bounding_box_diagonal, is_disk, mesh_facts,
                                              point_mesh_distance, remesh_quality,
                                              surface_distance, triangle_quality,
                                              valence_stats, closest_points_on_triangles)
from pipeline.geometry.repair import repair_mesh
from pipeline.geometry.sem import SEMOptions
from pipeline.io.meshio import read_mesh, write_obj
from pipeline.sample import make_face
from pipeline.stages.parameterize import parameterize_stage
from pipeline.stages.remesh import RemeshOptions, remesh_stage
from pipeline.report.remesh import remesh_warnings


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


# --------------------------------------------------------------------------- disk sampling


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


# --------------------------------------------------------------------------- quality measures


def lattice_mesh(k=20, h=1.0):
    """An equilateral triangle lattice (a parallelogram patch) in the plane z = 0."""
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    P = np.column_stack([(i + 0.5 * j).ravel() * h, (j * np.sqrt(3) / 2).ravel() * h,
                         np.zeros(i.size)])
    idx = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), \
        idx[1:, 1:].ravel()
    return P, np.vstack([np.column_stack([a, b, c]), np.column_stack([b, d, c])])


def test_quality_of_an_equilateral_lattice():
    V, F = lattice_mesh(12)
    q = triangle_quality(V, F)
    assert abs(q["min_angle_deg"] - 60) < 1e-9 and abs(q["mean_min_angle_deg"] - 60) < 1e-9
    assert q["area_cv"] < 1e-12 and q["edge_length_cv"] < 1e-12
    assert q["fraction_min_angle_below_30"] == 0.0
    v = valence_stats(F, len(V))
    assert v["interior_fraction_6"] == 1.0
    assert is_disk(mesh_facts(V, F))


def test_point_triangle_distance_is_exact():
    rng = np.random.default_rng(0)
    A, B, C = rng.normal(size=(3, 300, 3))
    P = rng.normal(size=(300, 3)) * 2
    Q = closest_points_on_triangles(P, A, B, C)
    t = np.linspace(0, 1, 301)
    u, v = np.meshgrid(t, t)
    ok = u + v <= 1
    u, v = u[ok], v[ok]
    for i in range(0, 300, 30):
        S = A[i] + u[:, None] * (B[i] - A[i]) + v[:, None] * (C[i] - A[i])
        dense = np.linalg.norm(S - P[i], axis=1).min()
        ours = np.linalg.norm(Q[i] - P[i])
        assert ours <= dense + 1e-12 and ours >= dense - 2e-2


def test_surface_distance_of_a_shifted_plane_is_the_shift():
    V, F = lattice_mesh(10)
    W = V + np.array([0.0, 0.0, 0.25])
    d = surface_distance(V, F, W, F, n_random=5000)
    assert abs(d["hausdorff"] - 0.25) < 1e-12 and abs(d["rms"] - 0.25) < 1e-12
    assert surface_distance(V, F, V, F, n_random=2000)["hausdorff"] < 1e-14
    dist, _ = point_mesh_distance(np.array([[3.0, 2.0, -1.5]]), V, F)
    assert abs(dist[0] - 1.5) < 1e-12


# ------------------------------------------------------------------------- stage (synthetic)


@pytest.fixture(scope="module")
def face_map():
    face = make_face(2500)
    mesh = repair_mesh(face.V, face.F)
    mesh.colors = (face.V - face.V.min(0)) / np.ptp(face.V, axis=0)        # a colour per vertex
    p = parameterize_stage(mesh, SEMOptions(mode="converged", max_iter=60))
    return face, mesh, p


def on_surface(X, mesh):
    d, _ = point_mesh_distance(X, mesh.V, mesh.F)
    return d.max() / bounding_box_diagonal(mesh.V)


@pytest.mark.parametrize("improve", [False, True])
def test_stage_gives_a_disk_with_lifted_attributes(face_map, improve):
    face, mesh, p = face_map
    lms = face.landmarks
    r = remesh_stage(mesh, p.uv, RemeshOptions(vertices=3000, improve=improve), lms)
    q = remesh_quality(mesh.V, mesh.F, r.V, r.F, n_random=20000)
    assert q["is_disk"] and q["facts"]["degenerate_faces"] == 0
    assert abs(len(r.V) - 3000) <= 60
    assert on_surface(r.V, mesh) <= 1e-9                          # every vertex on the surface
    assert np.all(signed_double_areas(r.uv, r.F) > 0)              # a valid map to the disk
    assert np.allclose(lift(mesh.V, mesh.F, r.face, r.bary), r.V, atol=0, rtol=0)
    assert np.allclose(r.colors, lift(mesh.colors, mesh.F, r.face, r.bary))
    assert set(r.landmarks) == set(lms)
    spacing = r.info["spacing_mesh_units"]
    for name, d in r.landmarks.items():
        assert np.linalg.norm(r.V[d["vertex"]] - mesh.V[lms[name]]) <= 1.5 * spacing
    if not improve:                                               # the paper's plain lift
        assert np.array_equal(r.V, r.lifted[0]) and np.array_equal(r.F, r.lifted[1])
    else:
        t0 = triangle_quality(*r.lifted)
        t1 = q["triangles"]
        assert t1["mean_min_angle_deg"] > t0["mean_min_angle_deg"]
        assert t1["min_angle_p05_deg"] > t0["min_angle_p05_deg"]


def test_stage_with_spacing(face_map):
    _, mesh, p = face_map
    L = 0.6
    r = remesh_stage(mesh, p.uv, RemeshOptions(spacing=L))
    E, _ = topo.edges_with_faces(r.F)
    med = np.median(np.linalg.norm(r.V[E[:, 0]] - r.V[E[:, 1]], axis=1))
    assert 0.8 * L < med < 1.2 * L


def test_bad_options_are_user_errors(face_map):
    from pipeline.errors import UserError

    _, mesh, p = face_map
    for opts in (RemeshOptions(), RemeshOptions(vertices=100, spacing=1.0),
                 RemeshOptions(vertices=10), RemeshOptions(vertices=1000, pattern="square")):
        with pytest.raises(UserError):
            remesh_stage(mesh, p.uv, opts)
    bad = p.uv.copy()
    bad[:, 0] *= -1                                               # every face flipped
    with pytest.raises(UserError):
        remesh_stage(mesh, bad, RemeshOptions(vertices=1000))


def test_improvement_steps_keep_the_disk(face_map):
    _, mesh, p = face_map
    s = sample_disk(2000, polygon=p.uv[mesh.boundary])
    F = triangulate_samples(s)
    L = PointLocator(p.uv, mesh.F, mesh.boundary)
    face, bary = L.locate(s.points)
    X = lift(mesh.V, mesh.F, face, bary)
    F2, flips, _ = delaunay_flips(X, F, s.points)
    assert flips > 0 and is_disk(mesh_facts(X, F2))
    assert np.all(signed_double_areas(s.points, F2) > 0)
    assert (np.degrees(corner_angles(X, F2)).min(1).mean()
            > np.degrees(corner_angles(X, F)).min(1).mean())
    movable = np.arange(len(X)) >= s.n_rim
    uv2, f2, b2, X2, moved = tangential_relaxation(mesh.V, mesh.F, p.uv, L, s.points, F2,
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


def test_flips_of_a_plane_reach_its_delaunay_triangulation():
    """On a plane the 3D and 2D criteria agree, so Lawson flips from any triangulation end at
    the unique Delaunay one (rim on a circle, interior points in general position; no Delaunay
    face then has three rim corners). Many rounds of many flips: the in-place half-edge
    twins must stay right throughout."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(7)
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    r, a = 0.9 * np.sqrt(rng.random(400)), 2 * np.pi * rng.random(400)
    uv = np.vstack([np.column_stack([np.cos(t), np.sin(t)]),
                    np.column_stack([r * np.cos(a), r * np.sin(a)])])
    F0 = Delaunay(uv * [8.0, 1.0]).simplices                      # the Delaunay of a squash
    F0 = np.where((signed_double_areas(uv, F0) > 0)[:, None], F0, F0[:, ::-1])
    X = np.column_stack([uv, np.zeros(len(uv))])
    F, flips, rounds = delaunay_flips(X, F0, uv, max_rounds=500)
    want = {tuple(sorted(f)) for f in Delaunay(uv).simplices.tolist()}
    assert flips > 500 and rounds > 5
    assert {tuple(sorted(f)) for f in F.tolist()} == want
    assert np.all(signed_double_areas(uv, F) > 0)


def test_local_flips_start_from_the_active_vertices_and_keep_the_twins():
    """``active`` all set gives the full result; none set flips nothing; one edge spoiled in
    a plane's Delaunay triangulation is flipped back from its four corners alone. The twins
    passed in end as those of the result."""
    from scipy.spatial import Delaunay

    from pipeline.geometry.topology import interior_edge_twins

    rng = np.random.default_rng(5)
    uv = rng.random((300, 2))
    F_D = Delaunay(uv).simplices
    F_D = np.where((signed_double_areas(uv, F_D) > 0)[:, None], F_D, F_D[:, ::-1])
    X = np.column_stack([uv, np.zeros(len(uv))])
    F0 = Delaunay(uv * [6.0, 1.0]).simplices
    F0 = np.where((signed_double_areas(uv, F0) > 0)[:, None], F0, F0[:, ::-1])
    full, k_full, _ = delaunay_flips(X, F0, uv, max_rounds=500)
    twin = interior_edge_twins(F0)
    F1, k1, _ = delaunay_flips(X, F0, uv, max_rounds=500, active=np.ones(len(uv), bool),
                               twin=twin)
    assert k1 == k_full > 100 and np.array_equal(F1, full)
    assert np.array_equal(twin, interior_edge_twins(F1))
    F2, k2, _ = delaunay_flips(X, F0, uv, active=np.zeros(len(uv), bool))
    assert k2 == 0 and np.array_equal(F2, F0)
    # spoil one interior edge whose quad is convex: flip it by hand
    tw = interior_edge_twins(F_D)
    for h in np.flatnonzero(tw > np.arange(len(tw))):
        f, c, g, d = h // 3, h % 3, tw[h] // 3, tw[h] % 3
        a, b, p_, q = F_D[f, c], F_D[f, (c + 1) % 3], F_D[f, (c + 2) % 3], F_D[g, (d + 2) % 3]
        Fs = F_D.copy()
        Fs[f], Fs[g] = [p_, a, q], [q, b, p_]
        if np.all(signed_double_areas(uv, Fs[[f, g]]) > 1e-3):
            break
    active = np.zeros(len(uv), bool)
    active[[a, b, p_, q]] = True
    F3, k3, _ = delaunay_flips(X, Fs, uv, active=active)
    assert k3 == 1
    assert {tuple(sorted(t)) for t in F3.tolist()} == {tuple(sorted(t)) for t in F_D.tolist()}


def test_pullback_takes_a_displacement_to_the_disk_exactly():
    """On a face whose 3D position is an affine image of its disk position, the pullback of
    ``J e`` is ``e``, and a displacement along the normal pulls back to 0."""
    from pipeline.geometry.remesh_improve import pullback_matrices

    uv_in = np.array([[0.1, 0.2], [0.9, 0.3], [0.4, 0.8]])
    J = np.array([[2.0, 0.5], [-0.3, 1.5], [1.0, -0.7]])              # 3×2, rank 2
    V_in = uv_in @ J.T + [1.0, 2.0, 3.0]
    P = pullback_matrices(V_in, np.array([[0, 1, 2]]), uv_in)
    e = np.array([0.3, -0.2])
    assert np.allclose(P[0] @ (J @ e), e, atol=1e-14)
    normal = np.cross(J[:, 0], J[:, 1])
    assert np.allclose(P[0] @ normal, 0.0, atol=1e-14)
    degenerate = pullback_matrices(V_in, np.array([[0, 0, 1]]), uv_in)
    assert np.array_equal(degenerate, np.zeros((1, 2, 3)))


def test_row_helpers_match_numpy():
    from pipeline.geometry.rows import cross, dots, norms

    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(1000, 3)), rng.normal(size=(1000, 3))
    assert np.array_equal(cross(a, b), np.cross(a, b))            # the same arithmetic
    assert np.allclose(norms(a), np.linalg.norm(a, axis=1), rtol=1e-15, atol=0)
    assert np.allclose(dots(a, b), (a * b).sum(1), rtol=1e-13, atol=1e-15)


def _disk_points(rings, per):
    pts = [np.zeros((1, 2))]
    for i in range(1, rings + 1):
        t = np.linspace(0, 2 * np.pi, per * i, endpoint=False) + 0.3 * i
        pts.append(i / rings * np.column_stack([np.cos(t), np.sin(t)]))
    return np.vstack(pts)


def _ccw_delaunay(uv):
    from scipy.spatial import Delaunay

    F = Delaunay(uv).simplices
    return np.where((signed_double_areas(uv, F) > 0)[:, None], F, F[:, ::-1])


@pytest.mark.parametrize("max_gap", [None, 0.02])
def test_collapse_gap_guard_keeps_removed_vertices_near_the_result(max_gap):
    """A unit disk with a tent (height 0.3, radius 0.25) at its centre, parameterized by xy;
    a coarse remesh of it collapsed as far as the rules allow. With the guard every original
    vertex stays within the gap of the result; without it the tent's flanks are cut."""
    uv_in = _disk_points(40, 6)
    F_in = _ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, 0.3 * np.maximum(0, 1 - np.linalg.norm(uv_in, axis=1) / 0.25)])
    loop = topo.boundary_loops(F_in)[0]
    locator = PointLocator(uv_in, F_in, loop)
    uv = np.vstack([_disk_points(8, 6), [[0.004, 0.003]]])
    F = _ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    X0 = lift(V_in, F_in, face, bary)
    S = RemeshState(X0.copy(), F, uv, topo.boundary_vertices_mask(F, len(uv)), face, bary,
                    V_in, F_in, uv_in, locator, uv_in[loop])
    k = collapse_short_edges(S, np.inf, np.inf, max_gap=max_gap)
    assert k > 50 and is_disk(mesh_facts(S.X, S.F))
    d, _ = point_mesh_distance(X0, S.X, S.F)
    if max_gap is None:
        assert d.max() > 2 * 0.02
    else:
        assert d.max() <= max_gap


def test_insert_vertices_puts_locked_vertices_exactly_on_targets_inside_and_beyond_the_rim():
    """A flat unit disk (the image polygon: 240 points on the circle) remeshed coarsely with
    its rim on every 10th polygon point. Targets: inside a face, a second in the same face (it
    waits a round), and one between a rim chord and the polygon — beyond the remesh, where
    only a rim split (its vertex on the polygon) brings it inside. Each gets a locked vertex
    exactly there, and the result is still a counter-clockwise disk."""
    uv_in = _disk_points(40, 6)
    F_in = _ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, np.zeros(len(uv_in))])
    loop = topo.boundary_loops(F_in)[0]
    locator = PointLocator(uv_in, F_in, loop)
    ring = np.flatnonzero(np.isclose(np.linalg.norm(uv_in, axis=1), 1.0))[::10]
    uv = np.vstack([_disk_points(3, 6), uv_in[ring]])
    F = _ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, topo.boundary_vertices_mask(F, len(uv)),
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
    a = np.arctan2(*uv_in[ring[:2]][:, ::-1].T)                  # two neighbouring rim points
    mid = 0.5 * (a[0] + a[1]) if abs(a[1] - a[0]) < np.pi else 0.5 * (a[0] + a[1]) + np.pi
    beyond = 0.9985 * np.array([np.cos(mid), np.sin(mid)])       # chord at cos(π/24) ≈ 0.991
    T = np.array([[0.11, 0.07], [0.115, 0.072], beyond])
    assert not PointLocator(S.uv, S.F).locate_with_inside(beyond[None])[2][0]
    n0 = S.n
    v = insert_vertices(S, T)
    assert len(v) == 3 and S.n == n0 + 4                          # + the rim split
    assert np.array_equal(np.sort(S.uv[v], axis=0), np.sort(T, axis=0))
    assert S.locked[v].all() and not S.is_rim[v].any()
    assert np.allclose(S.X[v], np.column_stack([S.uv[v], np.zeros(3)]), atol=1e-15)
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))
    new_rim = np.setdiff1d(np.arange(n0, S.n), v)
    assert S.is_rim[new_rim].all()
    _, _, q = _closest_on_segments(S.uv[new_rim], uv_in[loop], np.roll(uv_in[loop], -1, 0))
    assert np.allclose(q, S.uv[new_rim], atol=1e-15)               # on the image polygon


def test_split_edges_keeps_the_cached_twins_right():
    """Rounds of independent splits — inner and rim edges, neighbouring ones whose outer
    half-edges are each other's twins — update the kept half-edge twins in place of
    recomputing them: after every round they equal a fresh computation."""
    uv_in = _disk_points(40, 6)
    F_in = _ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, np.zeros(len(uv_in))])
    loop = topo.boundary_loops(F_in)[0]
    locator = PointLocator(uv_in, F_in, loop)
    uv = uv_in.copy()
    face, bary = locator.locate(uv)
    S = RemeshState(V_in.copy(), F_in.copy(), uv, topo.boundary_vertices_mask(F_in, len(uv)),
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
    rng = np.random.default_rng(2)
    for _ in range(4):
        h, a, b, twin = _edge_table(S.F, twin=S.twins())
        pick = rng.permutation(len(h))
        f1 = h[pick] // 3
        f2 = np.where(twin[pick] >= 0, twin[pick] // 3, f1)
        sel = pick[_independent_by_faces(len(S.F), f1, f2, rng.random(len(pick)))]
        assert (twin[sel] < 0).any() and (twin[sel] >= 0).any()
        split_edges(S, h[sel], twin[sel], rng.uniform(0.2, 0.8, len(sel)))
        assert S._twin is not None and S._twin[0] is S.F               # kept, not dropped
        assert np.array_equal(S.twins(), topo.interior_edge_twins(S.F))
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


def test_collapse_sag_guard_creates_no_edge_off_the_surface():
    """The tent again: with ``max_sag`` every edge farther than it from the surface after the
    collapses was there before (a collapse never creates one); without it some are new."""
    uv_in = _disk_points(40, 6)
    F_in = _ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, 0.3 * np.maximum(0, 1 - np.linalg.norm(uv_in, axis=1) / 0.25)])
    loop = topo.boundary_loops(F_in)[0]
    locator = PointLocator(uv_in, F_in, loop)
    tol = 0.01

    def far_edges(S):
        E = np.sort(np.vstack([S.F[:, [0, 1]], S.F[:, [1, 2]], S.F[:, [2, 0]]]), axis=1)
        E = np.unique(E, axis=0)
        far = edge_sag(S, E[:, 0], E[:, 1]) > tol
        return {tuple(S.uv[i].round(12)) + tuple(S.uv[j].round(12)) for i, j in E[far]}

    new_far = {}
    for max_sag in (None, tol):
        uv = _disk_points(8, 6)
        F = _ccw_delaunay(uv)
        face, bary = locator.locate(uv)
        S = RemeshState(lift(V_in, F_in, face, bary), F, uv,
                        topo.boundary_vertices_mask(F, len(uv)), face, bary, V_in, F_in, uv_in,
                        locator, uv_in[loop])
        before = far_edges(S)
        k = collapse_short_edges(S, np.inf, np.inf, max_sag=max_sag)
        assert k > 20 and is_disk(mesh_facts(S.X, S.F))
        new_far[max_sag] = far_edges(S) - before
    assert len(new_far[None]) > 0 and len(new_far[tol]) == 0


def _has_edge(F, i, j) -> bool:
    return any({i, j} <= set(f) for f in F.tolist())


def test_folded_quad_flips_only_when_the_new_edge_is_closer_to_the_surface():
    """A cap (angle > 150° at p opposite edge a–b) folded 60° along a–b, inside a square:
    Delaunay wants the flip to p–q, the dihedral limit (20°) forbids it; with a sag measure it
    is made exactly when the new edge is no farther from the surface than the old one."""
    a, b, p, q, T1, T2, B1, B2 = range(8)
    uv = np.array([[-1.0, 0], [1, 0], [0, 0.18], [0, -1], [-2, 2], [2, 2], [-2, -2], [2, -2]])
    F = np.array([[a, b, p], [b, a, q], [a, p, T1], [p, T2, T1], [p, b, T2], [a, T1, B1],
                  [a, B1, q], [q, B1, B2], [q, B2, b], [b, B2, T2]])
    assert np.all(signed_double_areas(uv, F) > 0)
    fold = np.radians(60)                  # the half y < 0 turned 60° about the a–b axis
    y = uv[:, 1]
    X = np.column_stack([uv[:, 0], np.where(y < 0, y * np.cos(fold), y),
                         np.where(y < 0, -y * np.sin(fold), 0.0)])
    assert np.degrees(corner_angles(X, F))[0, 2] > 150            # the cap's angle at p
    F0, _, _ = delaunay_flips(X, F, uv)
    assert _has_edge(F0, a, b) and not _has_edge(F0, p, q)       # held by the dihedral limit

    def sag(new_closer):
        def measure(i, j):
            pq = np.isin(i, [p, q]) & np.isin(j, [p, q])
            return np.where(pq, 0.01 if new_closer else 0.09, 0.05)
        return measure

    F1, _, _ = delaunay_flips(X, F, uv, sag=sag(True))
    assert _has_edge(F1, p, q) and not _has_edge(F1, a, b)
    assert np.all(signed_double_areas(uv, F1) > 0) and is_disk(mesh_facts(X, F1))
    F2, _, _ = delaunay_flips(X, F, uv, sag=sag(False))
    assert _has_edge(F2, a, b) and not _has_edge(F2, p, q)


# --------------------------------------------------------------------------- baselines


def test_baselines_hit_the_vertex_count(face_map):
    from pipeline.stages import baselines

    _, mesh, _ = face_map
    d = baselines.decimate(mesh.V, mesh.F, 1000)
    assert abs(len(d.V) - 1000) <= 0.05 * 1000
    assert baselines.decimate(mesh.V, mesh.F, len(mesh.V)) is None
    if not baselines.pymeshlab_available():
        pytest.skip("pymeshlab not installed")
    b = baselines.isotropic_remesh(mesh.V, mesh.F, 1500)
    assert abs(len(b.V) - 1500) <= 0.05 * 1500 and len(b.runs) >= 1


def test_hausdorff_agrees_with_meshlab():
    pymeshlab = pytest.importorskip("pymeshlab")
    path = require_data("faces", "ict", "ict_A_neutral_disk.obj")
    raw = read_mesh(path)
    mesh = repair_mesh(raw.V, raw.faces)
    p = parameterize_stage(mesh, SEMOptions(mode="paper"))
    r = remesh_stage(mesh, p.uv, RemeshOptions(vertices=3000))
    ours = surface_distance(mesh.V, mesh.F, r.V, r.F, n_random=100_000)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(mesh.V, mesh.F.astype(np.int32)))
    ms.add_mesh(pymeshlab.Mesh(r.V, r.F.astype(np.int32)))
    for (s, t), key in (((1, 0), "output_to_input"), ((0, 1), "input_to_output")):
        ml = ms.get_hausdorff_distance(sampledmesh=s, targetmesh=t, samplevert=True,
                                       sampleedge=True, sampleface=True, samplenum=300_000,
                                       maxdist=pymeshlab.PercentageValue(50))["max"]
        # both are sampled lower bounds of the same maximum
        assert 0.85 * ml <= ours[key]["max"] <= 1.15 * ml


# ------------------------------------------------------------------- files, CLI and config



@pytest.fixture(scope="module")
def small_face_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("remesh_face")
    face = make_face(1500)
    path = write_obj(d / "face.obj", face.V, face.F)
    (d / "landmarks.json").write_text(json.dumps({"landmarks": face.landmarks}))
    return path, d / "landmarks.json", face


def test_cli_remesh_writes_the_contract_files(small_face_file, tmp_path):
    import trimesh

    mesh_path, lms, face = small_face_file
    out = tmp_path / "out"
    code, stdout, err = run_cli("remesh", mesh_path, "-o", out, "--vertices", 1200,
                                "--landmarks", lms, "--max-iter", 40)
    assert code == 0, err
    for name in ("remeshed.obj", "remesh_metrics.json", "report.html", "remesh_renders.png",
                 "remesh_min_angle.png", "remesh_valence.png", "remesh_disk.png",
                 "remeshed_landmarks.json"):
        assert (out / name).is_file(), name
    assert not list(out.glob(".partial-*"))
    m = json.loads((out / "remesh_metrics.json").read_text())
    sem = m["methods"]["sem"]
    assert sem["is_disk"] and sem["facts"]["vertices"] == 1200
    assert {"pymeshlab_isotropic", "fast_simplification", "sem_lifted", "input"} <= set(
        m["methods"])
    assert any(row["measure"].startswith("Hausdorff") for row in m["table"])
    assert m["warnings"] == remesh_warnings(m["parameterization"]["distortion"], m["methods"])
    for warning in m["warnings"]:
        assert f"remesh: warning: {warning}" in err
    html = (out / "report.html").read_text()
    assert "stretch anisotropy σ₁/σ₂" in html
    for png in ("remesh_renders.png", "remesh_min_angle.png", "remesh_valence.png",
                "remesh_disk.png"):
        assert f'src="{png}"' in html
    assert "<table>" in html and "% of bbox diagonal" in html
    tm = trimesh.load(out / "remeshed.obj", process=False)
    assert len(tm.vertices) == 1200 and len(tm.faces) == sem["facts"]["faces"]
    text = (out / "remeshed.obj").read_text()
    assert text.count("\nvt ") == 1200                              # one vt per vertex
    V = np.array(tm.vertices)
    F = np.array(tm.faces)
    assert topo.euler_characteristic(F, len(V)) == 1 and len(topo.boundary_loops(F)) == 1
    lm = json.loads((out / "remeshed_landmarks.json").read_text())["landmarks"]
    assert set(lm) == set(face.landmarks)


@pytest.mark.parametrize("args,words", [
    (["--vertices", "500", "--spacing", "0.1"], ["exactly one"]),
    ([], ["exactly one"]),
    (["--vertices", "5"], ["vertices"]),
    (["--vertices", "500", "--pattern", "square"], ["pattern"]),
])
def test_cli_remesh_bad_arguments_are_one_line(small_face_file, tmp_path, args, words):
    mesh_path, _, _ = small_face_file
    code, _, err = run_cli("remesh", mesh_path, "-o", tmp_path / "o", *args)
    lines = [x for x in err.strip().splitlines() if x.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0]


def test_cli_remesh_missing_mesh(tmp_path):
    code, _, err = run_cli("remesh", tmp_path / "nope.obj", "-o", tmp_path / "o",
                           "--vertices", "500")
    assert code == 2 and "does not exist" in err


def test_config_runs_remesh_after_parameterize(tmp_path):
    from pipeline.config import load_config
    from pipeline.runner import run_config

    cfg = tmp_path / "remesh.yaml"
    cfg.write_text("run: {name: r}\ninput: {sample: {vertices: 1200}}\n"
                   "parameterize: {max_iter: 40}\n"
                   "remesh: {vertices: 1000, compare: false, distance_samples: 5000}\n"
                   "report: {figures: false}\n")
    config, base = load_config(cfg)
    run_dir = run_config(config, base, tmp_path / "out")
    rem = run_dir / "remesh"
    assert (rem / "remeshed.obj").is_file() and (rem / "report.html").is_file()
    lm = json.loads((rem / "remeshed_landmarks.json").read_text())["landmarks"]
    assert len(lm) == 16                                          # the sample's landmarks
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert "remesh" in manifest["stages"]


def test_config_remesh_keys_are_checked(tmp_path):
    from pipeline.config import load_config
    from pipeline.errors import UserError

    cfg = tmp_path / "bad.yaml"
    cfg.write_text("input: {sample: {vertices: 1200}}\nremesh: {vertices: 1000, patern: x}\n")
    with pytest.raises(UserError, match="did you mean 'pattern'"):
        load_config(cfg)
    cfg.write_text("input: {sample: {vertices: 1200}}\nremesh: {pattern: hexagonal}\n")
    with pytest.raises(UserError, match="exactly one"):
        load_config(cfg)
    cfg.write_text("input: {sample: {vertices: 1200}}\n"
                   "remesh: {vertices: 1000, improve: {flip: true}}\n")
    with pytest.raises(UserError, match="did you mean 'flips'"):
        load_config(cfg)


# --------------------------------------------------------------------- every shared disk mesh

MESHES = [
    "meshes/c3d_alligator.obj", "meshes/choi_chinese_lion.obj", "meshes/choi_hand.obj",
    "meshes/choi_human_brain.obj", "meshes/choi_human_face.obj", "meshes/gpp_bunny.obj",
    "meshes/gpp_face.obj", "meshes/igl_camel_b.obj", "meshes/igl_camelhead.obj",
    "meshes/igl_lion.obj", "faces/ict/ict_A_neutral_disk.obj", "faces/ict/ict_A_smile_disk.obj",
    "faces/ict/ict_B_neutral_disk.obj", "faces/ict/ict_B_smile_jawopen_disk.obj",
]


@pytest.fixture(scope="module")
def remeshed_20k():
    from pipeline.stages.load import load_stage

    cache = {}

    def get(rel):
        if rel not in cache:
            intake = load_stage(require_data(*rel.split("/")))
            p = parameterize_stage(intake.mesh, SEMOptions(mode="converged", max_iter=60))
            assert p.ok
            r = remesh_stage(intake.mesh, p.uv, RemeshOptions(vertices=20000))
            q = remesh_quality(intake.mesh.V, intake.mesh.F, r.V, r.F, n_random=50_000)
            cache[rel] = (intake.mesh, r, q, p.metrics["distortion"])
        return cache[rel]

    return get


@pytest.mark.parametrize("rel", MESHES)
def test_real_mesh_remesh_is_one_disk_at_20k(remeshed_20k, rel):
    mesh, r, q, _ = remeshed_20k(rel)
    f = q["facts"]
    assert q["is_disk"], f
    assert f["euler_characteristic"] == 1 and f["boundary_loops"] == 1
    assert f["degenerate_faces"] == 0
    assert abs(len(r.V) - 20000) <= 0.02 * 20000
    assert np.all(signed_double_areas(r.uv, r.F) > 0)          # consistently oriented, bijective
    assert on_surface(r.V, mesh) <= 1e-9


@pytest.mark.parametrize("rel", MESHES)
def test_real_mesh_hausdorff_at_20k(remeshed_20k, rel):
    _, _, q, _ = remeshed_20k(rel)
    assert q["distance"]["hausdorff_rel"] <= 0.005


def test_real_mesh_anisotropy_warning_at_20k(remeshed_20k):
    """The hand's map stretches about a third of its surface more than 10:1 (the fingers);
    the human face's almost none: the warning tells them apart."""
    *_, hand = remeshed_20k("meshes/choi_hand.obj")
    *_, face = remeshed_20k("meshes/choi_human_face.obj")
    assert hand["anisotropy_area_above_10"] > 0.25 and hand["anisotropy_median"] > 5
    assert face["anisotropy_area_above_10"] < 0.02 and face["anisotropy_median"] < 2.5
    assert len(remesh_warnings(hand, {})) == 1 and remesh_warnings(face, {}) == []
