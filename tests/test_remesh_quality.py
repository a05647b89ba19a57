"""Quality measures of a remesh (pipeline.geometry.remesh_quality)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require_data
from pipeline.geometry.remesh_quality import (DISTANCE_SAMPLES, MeshDistance, SampledSurface,
                                              closest_points_on_triangles, face_centroids,
                                              is_disk, longest_edge_squared, remesh_quality,
                                              mesh_facts, point_mesh_distance, surface_distance,
                                              surface_samples, triangle_quality,
                                              turned_over_faces, valence_stats, z_order)
from pipeline.geometry.repair import repair_mesh
from pipeline.geometry.sem import SEMOptions
from pipeline.io.meshio import read_mesh
from pipeline.stages.parameterize import parameterize_stage
from pipeline.stages.remesh import RemeshConfig, remesh_stage
from remesh_helpers import count_measured


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


def test_triangle_quality_is_its_definitions_bit_for_bit():
    """The angle extremes and edge lengths behind triangle_quality are numpy's reductions of
    their definitions, bit for bit, on a noisy height field at scales from 1e-6 to 1e6: the
    smallest and largest corner angle of each face, and the edges' Euclidean lengths; and a
    bounding-box diagonal is the norm of the extents."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.metrics import corner_angles
    from pipeline.geometry.remesh_quality import _unique_edge_lengths, bounding_box_diagonal

    _, V0, F = height_field(25)
    rng = np.random.default_rng(7)
    for scale in (1e-6, 1.0, 1e6):
        V = (V0 + rng.normal(scale=0.01, size=V0.shape)) * scale
        ang = np.degrees(corner_angles(V, F))
        q = triangle_quality(V, F)
        assert q["min_angle_deg"] == ang.min(axis=1).min()
        assert q["max_angle_deg"] == ang.max(axis=1).max()
        assert np.array_equal(q["_per_face_min_angle"], ang.min(axis=1))
        E, _ = topo.edges_with_faces(F)
        assert np.array_equal(_unique_edge_lengths(V, F),
                              np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1))
        assert bounding_box_diagonal(V) == float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


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


def test_compiled_face_distances_are_those_of_the_closest_points():
    """face_distances: per point, the least distance to its listed faces (−1 skipped, none:
    inf), each the distance to closest_points_on_triangles' point, degenerate faces (a
    repeated corner, coincident corners) included."""
    from pipeline.geometry._kernels import face_distances

    rng = np.random.default_rng(0)
    V = rng.normal(size=(300, 3))
    F = rng.integers(0, 300, size=(400, 3))
    F[:5, 1] = F[:5, 0]
    V[F[5:8, 2]] = V[F[5:8, 0]]
    P = rng.normal(size=(2000, 3)) * 2
    faces = rng.integers(-1, 400, size=(2000, 3))
    faces[0] = -1
    faces[1:40, 0] = np.arange(39) % 8                   # the degenerate ones
    expected = np.full(len(P), np.inf)
    for j in range(3):
        ok = faces[:, j] >= 0
        T = V[F[faces[ok, j]]]
        Q = closest_points_on_triangles(P[ok], T[:, 0], T[:, 1], T[:, 2])
        expected[ok] = np.minimum(expected[ok], np.linalg.norm(Q - P[ok], axis=1))
    np.testing.assert_allclose(face_distances(P, V, F, faces), expected, rtol=1e-14, atol=0)


def test_face_bounds_bound_the_distance_and_are_exact_on_the_corners_faces():
    """face_bounds: never below the distance; equal to it where the point's closest face is
    one of its corners' closest faces; above it elsewhere (but for ties, a foot on an edge
    or corner shared with a corner's face)."""
    from pipeline.geometry.remesh_quality import face_bounds

    V, F = lattice_mesh(10)
    V[:, 2] = 0.3 * np.sin(V[:, 0]) * np.cos(V[:, 1])
    distance = MeshDistance(V, F)
    W = V + np.array([0.1, 0.2, 0.3])                     # a shifted copy
    _, corner_face = distance(W)
    pairs = np.random.default_rng(1).integers(0, len(W), size=(2000, 2))
    P = (W[pairs[:, 0]] + W[pairs[:, 1]]) / 2
    bound = face_bounds(P, pairs, corner_face, distance)
    exact, closest = distance(P)
    assert np.all(bound >= exact * (1 - 1e-12))
    same = np.any(corner_face[pairs] == closest[:, None], axis=1)
    assert same.sum() > 50 and np.mean(bound[~same] > exact[~same]) > 0.9
    np.testing.assert_allclose(bound[same], exact[same], rtol=1e-12)


def test_face_centroids_are_the_mean_of_the_corners_bit_for_bit():
    """face_centroids, summed corner by corner: the values of ``V[F].mean(axis=1)`` exactly,
    on the surface (3 columns) and on a disk (2)."""
    rng = np.random.default_rng(5)
    F = rng.integers(0, 500, size=(3000, 3))
    for d in (3, 2):
        V = rng.normal(size=(500, d)) * 10.0 ** rng.integers(-3, 4, size=(500, 1))
        np.testing.assert_array_equal(face_centroids(V, F), V[F].mean(axis=1))


def test_middle_bounds_from_stored_offsets_are_those_computed_anew():
    """middle_offsets: the face centroids, their distances to the corners and half the edge
    lengths; middle_bounds with them given: the same numbers, bit for bit, as computed from
    the mesh, for another distance field each time; each bound at least the distance (the
    distance is 1-Lipschitz)."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh_quality import middle_bounds, middle_offsets
    from pipeline.geometry.rows import norms

    V, F = lattice_mesh(10)
    V[:, 2] = 0.3 * np.sin(V[:, 0]) * np.cos(V[:, 1])
    E, _ = topo.edges_with_faces(F)
    offsets = middle_offsets(V, F, E)
    np.testing.assert_array_equal(offsets.centroids, face_centroids(V, F))
    to_corners = (face_centroids(V, F)[:, None] - V[F]).reshape(-1, 3)
    np.testing.assert_array_equal(offsets.to_corners, norms(to_corners).reshape(F.shape))
    np.testing.assert_array_equal(offsets.half_lengths, norms(V[E[:, 1]] - V[E[:, 0]]) / 2)
    for shift in (0.1, 0.4):
        distance = MeshDistance(V + np.array([0.0, shift, 0.2]), F)
        d_vertex, _ = distance(V)
        fresh, stored = middle_bounds(V, F, E, d_vertex), middle_bounds(V, F, E, d_vertex,
                                                                         offsets)
        for a, b in zip(fresh, stored):
            np.testing.assert_array_equal(a, b)
        exact, _ = distance(np.vstack([(V[E[:, 0]] + V[E[:, 1]]) / 2, face_centroids(V, F)]))
        assert np.all(np.concatenate([stored[0], stored[2]]) >= exact * (1 - 1e-12))


def test_largest_distance_is_the_maximum_over_every_point_measuring_few(monkeypatch):
    """largest_distance of the edge midpoints of a shifted copy of a wavy lattice with a bump,
    bounded by their distances to the faces closest to their ends and to a point 0.1 beside
    them (candidate_face_distances): exactly the largest of all the points' distances, having
    measured the 64 of the largest bounds and at most a tenth of the others."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh_quality import (bound_slack, candidate_face_distances,
                                                  largest_distance)

    V, F = lattice_mesh(20)
    V[:, 2] = 0.3 * np.sin(V[:, 0]) * np.cos(V[:, 1])
    distance = MeshDistance(V, F)
    W = V + np.array([0.01, 0.02, 0.03])
    W[:, 2] += 0.5 * np.exp(-((V[:, 0] - 15) ** 2 + (V[:, 1] - 8) ** 2))     # a bump
    E, _ = topo.edges_with_faces(F)
    P = (W[E[:, 0]] + W[E[:, 1]]) / 2
    _, corner_face = distance(W)
    _, beside = distance(P + np.array([0.1, 0.0, 0.0]))
    expected = distance(P)[0].max()
    bound = candidate_face_distances(P, np.column_stack([corner_face[E], beside]), distance)
    measured = count_measured(monkeypatch)
    assert largest_distance(P, bound, distance, bound_slack(V)) == expected
    assert measured[0] == 64 and measured[1] <= 0.1 * (len(P) - 64)


def test_surface_distance_of_a_shifted_plane_is_the_shift():
    V, F = lattice_mesh(10)
    W = V + np.array([0.0, 0.0, 0.25])
    d = surface_distance(V, F, W, F, n_random=5000)
    assert abs(d["hausdorff"] - 0.25) < 1e-12 and abs(d["rms"] - 0.25) < 1e-12
    assert surface_distance(V, F, V, F, n_random=2000)["hausdorff"] < 1e-14
    dist, _ = point_mesh_distance(np.array([[3.0, 2.0, -1.5]]), V, F)
    assert abs(dist[0] - 1.5) < 1e-12


def height_field(k=30):
    """A square grid of right triangles over [0, 1]² and the same grid lifted to piecewise
    linear heights ``z`` at its vertices (the remesh's stand-in)."""
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    P = np.column_stack([i.ravel() / k, j.ravel() / k, np.zeros(i.size)])
    idx = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), \
        idx[1:, 1:].ravel()
    F = np.vstack([np.column_stack([a, b, c]), np.column_stack([b, d, c])])
    Q = P.copy()
    Q[:, 2] = 0.05 * np.sin(7 * P[:, 0]) * np.cos(5 * P[:, 1]) + 0.02 * P[:, 0]
    return P, Q, F


def test_default_samples_give_the_exact_rms_and_maximum_of_a_height_field():
    """Over the plane z = 0 and a height field above the same square, each point of the
    field is exactly |z| from the plane (its foot lies in the square), so the one-sided
    distances are known: the largest is the largest |z| of a vertex (z is linear on each
    face), the mean square is ∫ z² dA / A with ∫ z² dA = A_t (Σ z_i² + Σ_{i<j} z_i z_j) / 6
    on a face of area A_t. At the default count the sampled RMS is within three of its
    standard errors of the exact value, and that is within 0.5 %."""
    P, Q, F = height_field()
    d = surface_distance(P, F, Q, F)
    z = Q[F, 2]
    A = np.linalg.norm(np.cross(Q[F[:, 1]] - Q[F[:, 0]], Q[F[:, 2]] - Q[F[:, 0]]), axis=1) / 2
    mean_square = (A * ((z ** 2).sum(axis=1) + z[:, 0] * z[:, 1] + z[:, 1] * z[:, 2]
                        + z[:, 2] * z[:, 0]) / 6).sum() / A.sum()
    side = d["output_to_input"]
    assert side["max"] == pytest.approx(np.abs(Q[:, 2]).max(), rel=1e-12)
    edges = len(Q) + len(F) - 1                                   # a disk: V − E + F = 1
    assert side["samples"] == len(Q) + edges + len(F) + DISTANCE_SAMPLES
    assert d["random_samples_per_side"] == DISTANCE_SAMPLES
    sampled = SampledSurface(Q, F, DISTANCE_SAMPLES).random[:, 2] ** 2
    standard_error = sampled.std() / np.sqrt(len(sampled)) / (2 * mean_square)   # of the RMS
    error = abs(side["rms"] / np.sqrt(mean_square) - 1)
    assert error < 3 * standard_error and error < 0.005


def test_random_samples_are_the_numpy_formula_bit_for_bit():
    """A random sample is ``p0 + u (p1 − p0) + v (p2 − p0)`` of its drawn face, ``(u, v)``
    reflected into the triangle where ``u + v > 1``, evaluated as numpy evaluates it one
    coordinate at a time: the same bits."""
    from pipeline.geometry.laplacian import face_double_areas
    from pipeline.geometry.remesh_quality import _area_weighted_faces, _random_samples

    rng = np.random.default_rng(2)
    V = rng.normal(size=(40, 3)) * [1.0, 1e-3, 1e6]
    F = np.array([rng.choice(40, 3, replace=False) for _ in range(60)])
    got = _random_samples(V, F, 5000, seed=7)
    draws = np.random.default_rng(7)
    f = _area_weighted_faces(face_double_areas(V, F), 5000, draws)
    u, v = draws.random(5000), draws.random(5000)
    flip = u + v > 1
    assert 1000 < flip.sum() < 4000                      # both cases are exercised
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    T = F[f]
    for axis in range(3):
        x = V[:, axis]
        x0 = x[T[:, 0]]
        np.testing.assert_array_equal(got[:, axis],
                                      x0 + u * (x[T[:, 1]] - x0) + v * (x[T[:, 2]] - x0))


def test_area_weighted_faces_are_the_draws_of_numpys_choice():
    from pipeline.geometry.remesh_quality import _area_weighted_faces

    rng = np.random.default_rng(4)
    A = rng.random(3000) ** 8                       # many tiny faces among large ones
    A[::7] = 0.0                                    # and faces of no area, never drawn
    for seed in (0, 1):
        ours, numpys = np.random.default_rng(seed), np.random.default_rng(seed)
        f = _area_weighted_faces(A, 50_000, ours)
        np.testing.assert_array_equal(f, numpys.choice(len(A), size=50_000, p=A / A.sum()))
        assert ours.random() == numpys.random()     # the generator is left in the same state
    # a run of faces far smaller than a guide step: their draws are bisected, same result
    A = np.full(20_000, 1e-9)
    A[-200:] = 1.0
    ours, numpys = np.random.default_rng(5), np.random.default_rng(5)
    np.testing.assert_array_equal(_area_weighted_faces(A, 200_000, ours),
                                  numpys.choice(len(A), size=200_000, p=A / A.sum()))
    with pytest.raises(ValueError, match="no area"):
        _area_weighted_faces(np.zeros(4), 10, rng)


def test_z_order_visits_the_corners_of_a_cube_x_first_then_y_then_z():
    corners = np.array([[x, y, z] for z in (0.0, 2.0) for y in (0.0, 1.0) for x in (0.0, 3.0)])
    shuffled = np.random.default_rng(1).permutation(8)
    np.testing.assert_array_equal(corners[shuffled][z_order(corners[shuffled])], corners)


def brute_force_distance(P, V, F):
    """``(distance, closest face)`` of each point of ``P`` over every triangle of ``(V, F)``
    one by one: the closest point of each (:func:`closest_points_on_triangles`), its squared
    distance summed x, y, z, the smallest, and the lowest face number among equal ones."""
    k, m = len(P), len(F)
    Q = closest_points_on_triangles(np.repeat(P, m, axis=0), *(np.tile(V[F[:, c]], (k, 1))
                                                              for c in range(3)))
    D = np.repeat(P, m, axis=0) - Q
    sq = (D[:, 0] ** 2 + D[:, 1] ** 2 + D[:, 2] ** 2).reshape(k, m)
    face = np.argmin(sq, axis=1)               # the first of equal minima
    return np.sqrt(sq[np.arange(k), face]), face


def wavy_lattice():
    """A lattice bent into a sine sheet, a degenerate face (a repeated corner) and a sliver of
    three collinear corners added."""
    V, F = lattice_mesh(12)
    V[:, 2] = np.sin(V[:, 0]) * np.cos(V[:, 1])
    n = len(V)
    V = np.vstack([V, [[3.0, 20.0, 1.0], [4.0, 21.0, 1.0], [5.0, 22.0, 1.0]]])
    F = np.vstack([F, [[n, n, n + 1], [n, n + 1, n + 2]]])
    return V, F


@pytest.mark.parametrize("threads", [1, 2])
def test_distances_are_those_of_every_triangle_with_the_lowest_face_of_ties(threads,
                                                                            monkeypatch):
    """Far points, points on the surface (corners: ties among the faces around them; edge
    midpoints; inside faces), points above the lattice's corners and scattered ones near the
    sheet: each distance and closest face are brute force's, bit for bit, in one run and
    split between threads."""
    monkeypatch.setattr(MeshDistance, "THREADS", threads)
    monkeypatch.setattr(MeshDistance, "THREAD_POINTS", 10)
    V, F = wavy_lattice()
    rng = np.random.default_rng(2)
    flat = lattice_mesh(12)[0] + [0.0, 0.0, 0.5]
    P = np.vstack([rng.uniform(-40, 50, (300, 3)), V, (V[F[:, 0]] + V[F[:, 1]]) / 2,
                   face_centroids(V, F), flat, rng.uniform(-2, 14, (1500, 3))])
    d, f = MeshDistance(V, F)(P)
    d_all, f_all = brute_force_distance(P, V, F)
    np.testing.assert_array_equal(d, d_all)
    np.testing.assert_array_equal(f, f_all)
    assert np.all(d[300:300 + len(V)] == 0)


def test_a_point_equidistant_from_faces_gets_the_lowest_of_them():
    """On a flat lattice, a point straight above an interior vertex is at the same distance
    (its height, exactly) from the six faces around it: the lowest-numbered one is given, in
    any query order and whatever the previous point's face."""
    V, F = lattice_mesh(6)
    v = 3 * 7 + 3                                    # an interior vertex
    around = np.flatnonzero(np.any(F == v, axis=1))
    assert len(around) == 6
    above = V[v] + [0.0, 0.0, 0.25]
    tree = MeshDistance(V, F)
    for P in (above[None], np.vstack([V[F[around[-1]]].mean(axis=0), above]),
              np.vstack([above, V + [0.0, 0.0, 0.25]])):
        d, f = tree(P)
        row = np.flatnonzero(np.all(P == above, axis=1))
        assert np.all(d[row] == 0.25) and np.all(f[row] == around.min())


def test_an_empty_query_an_empty_mesh_and_a_nan_point():
    V, F = lattice_mesh(3)
    d, f = MeshDistance(V, F)(np.zeros((0, 3)))
    assert d.shape == f.shape == (0,)
    with np.errstate(invalid="ignore"):
        d, f = MeshDistance(V, F)(np.array([[0.5, 0.5, 1.0], [np.nan, 0.5, 1.0], [1.0, 1.0, 2.0]]))
    assert np.isnan(d[1]) and f[1] == -1 and d[0] == 1.0 and d[2] == 2.0 and np.all(f[[0, 2]] >= 0)
    d, f = MeshDistance(V, np.zeros((0, 3), np.int64))(V[:4])
    assert np.all(d == np.inf) and np.all(f == -1)


def test_hausdorff_is_the_largest_distance_of_every_sample():
    """Edge midpoints and centroids that the Lipschitz bound leaves unmeasured never hold the
    maximum: both one-sided maxima equal those of all samples measured, here where the
    farthest samples are centroids (a coarse paraboloid's chords against a fine one)."""
    fine, F = lattice_mesh(48, 0.25)
    coarse, G = lattice_mesh(8, 1.5)
    for V in (fine, coarse):
        V[:, 2] = 0.05 * ((V[:, 0] - 9) ** 2 + (V[:, 1] - 5) ** 2)
    d = surface_distance(fine, F, coarse, G, n_random=500)
    for (Va, Fa, Vb, Fb), key in (((coarse, G, fine, F), "output_to_input"),
                                  ((fine, F, coarse, G), "input_to_output")):
        S, R = surface_samples(Va, Fa, 500)
        every, _ = point_mesh_distance(np.vstack([S, R]), Vb, Fb)
        assert d[key]["max"] == every.max()
        assert d[key]["samples"] == len(S) + len(R)
        if key == "output_to_input":
            assert every[len(Va):len(S)].max() > max(every[:len(Va)].max(), every[len(S):].max())


def test_a_sampled_reference_measures_every_remesh_as_a_fresh_one():
    fine, F = lattice_mesh(24, 0.5)
    fine[:, 2] = 0.1 * np.sin(fine[:, 0])
    reference = SampledSurface(fine, F, 2000, seed=3)
    for k in (5, 8):
        coarse, G = lattice_mesh(k, 12 / k)
        assert surface_distance(fine, F, coarse, G, 2000, 3, reference=reference) == \
            surface_distance(fine, F, coarse, G, 2000, 3)
    with pytest.raises(ValueError, match="n_random=2000"):
        surface_distance(fine, F, coarse, G, 1000, 3, reference=reference)


def test_hausdorff_agrees_with_meshlab():
    pymeshlab = pytest.importorskip("pymeshlab")
    path = require_data("faces", "ict", "ict_A_neutral_disk.obj")
    raw = read_mesh(path)
    mesh = repair_mesh(raw.V, raw.faces)
    p = parameterize_stage(mesh, SEMOptions(mode="paper"))
    r = remesh_stage(mesh, p.uv, RemeshConfig(vertices=3000))
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


def test_turned_over_faces_counts_the_faces_of_a_fold_exactly():
    """A flat lattice (normals +z) against itself: none turned over. With one interior vertex
    pushed across the edge opposite it in its ring (still in the plane), the faces whose
    orientation the push reverses, and only those, are counted; the count is reported with
    the distances."""
    P, F = lattice_mesh(8)
    reference = SampledSurface(P, F, 1000)
    assert turned_over_faces(P, F, reference) == 0
    v = 4 * 9 + 4                                   # an interior vertex of the 9×9 lattice
    ring = F[np.any(F == v, axis=1)]
    Q = P.copy()
    Q[v, 1] += 2.2 * np.sqrt(3) / 2                 # two rows up, past its upper neighbours
    n = np.cross(Q[ring[:, 1]] - Q[ring[:, 0]], Q[ring[:, 2]] - Q[ring[:, 0]])[:, 2]
    expected = int(np.count_nonzero(n < 0))
    assert expected >= 2
    assert turned_over_faces(Q, F, reference) == expected
    assert surface_distance(P, F, Q, F, n_random=1000)["turned_over_faces"] == expected


def test_closest_faces_found_once_give_the_counts_and_maxima_of_fresh_queries():
    """The output's centroid and vertex queries that :func:`surface_distance` shares between
    its output-to-input maximum and the turned-over faces: the same count and maximum as
    queried where each is used (a fold of a coarse paraboloid against a fine one, where the
    farthest samples are centroids)."""
    fine, F = lattice_mesh(48, 0.25)
    coarse, G = lattice_mesh(8, 1.5)
    for V in (fine, coarse):
        V[:, 2] = 0.05 * ((V[:, 0] - 9) ** 2 + (V[:, 1] - 5) ** 2)
    coarse[4 * 9 + 4, 1] += 2.2 * 1.5 * np.sqrt(3) / 2
    reference, ours = SampledSurface(fine, F, 500), SampledSurface(coarse, G, 500)
    d_centroid, centroid_face = reference.distance(face_centroids(coarse, G))
    shared = ours.distances_to(reference, d_centroid)
    fresh = ours.distances_to(reference)
    assert shared[:2] == fresh[:2] and np.array_equal(shared[2], fresh[2])
    folds = turned_over_faces(coarse, G, reference)
    assert folds >= 2
    assert turned_over_faces(coarse, G, reference, centroid_face, shared[2]) == folds
    assert surface_distance(fine, F, coarse, G, n_random=500)["turned_over_faces"] == folds


def test_longest_edge_squared_is_the_largest_squared_edge_of_each_face():
    """Bit for bit the largest of the three squared edge lengths summed over the coordinates
    in order, on random faces, repeated corners and coordinates of very different scales."""
    rng = np.random.default_rng(5)
    V = rng.normal(size=(50, 3)) * np.array([1e-8, 1.0, 1e6])
    F = rng.integers(0, 50, size=(400, 3))
    F[:20, 1] = F[:20, 0]
    E = V[F[:, [1, 2, 0]]] - V[F]
    assert np.array_equal(longest_edge_squared(V, F), (E ** 2).sum(axis=2).max(axis=1))
    assert len(longest_edge_squared(V, F[:0])) == 0


def test_measures_with_given_areas_are_those_computed_afresh():
    fine, F = lattice_mesh(24, 0.5)
    fine[:, 2] = 0.1 * np.sin(fine[:, 0])
    coarse, G = lattice_mesh(6, 2.0)
    coarse[3, :] = coarse[4, :]                      # a collapsed face: one degenerate
    reference = SampledSurface(fine, F, 1000)
    q = remesh_quality(fine, F, coarse, G, 1000, reference=reference)
    fresh = remesh_quality(fine, F, coarse, G, 1000)
    assert q["facts"]["degenerate_faces"] == fresh["facts"]["degenerate_faces"] >= 1
    assert q["distance"] == fresh["distance"]
    given = SampledSurface(fine, F, 1000, double_area=reference.double_area)
    assert np.array_equal(reference.random, given.random)


def _masked_closest_points(P, A, B, C):
    """The Voronoi-region case analysis of Ericson §5.1.5 in numpy, with masks (the face
    interior, then the edges BC, AC, AB, then the corners C, B, A overwrite; a point not
    finite goes to the nearest corner)."""
    def dot(x, y):
        return np.einsum("ij,ij->i", x, y)

    ab, ac, ap, bp, cp = B - A, C - A, P - A, P - B, P - C
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), \
        dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        Q = A + ab * (vb / denom)[:, None] + ac * (vc / denom)[:, None]
        for m, Y in (((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
                      B + (C - B) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None]),
                     ((vb <= 0) & (d2 >= 0) & (d6 <= 0), A + ac * (d2 / (d2 - d6))[:, None]),
                     ((vc <= 0) & (d1 >= 0) & (d3 <= 0), A + ab * (d1 / (d1 - d3))[:, None]),
                     ((d6 >= 0) & (d5 <= d6), C), ((d3 >= 0) & (d4 <= d3), B),
                     ((d1 <= 0) & (d2 <= 0), A)):
            Q[m] = Y[m]
    bad = ~np.isfinite(Q).all(axis=1)
    cand = np.stack([A[bad], B[bad], C[bad]], axis=1)
    Q[bad] = cand[np.arange(bad.sum()), np.argmin(((cand - P[bad][:, None]) ** 2).sum(axis=2), 1)]
    return Q


def test_compiled_closest_points_are_the_masked_case_analysis_bit_for_bit():
    """Random triangles and points, with degenerate triangles (two equal corners, a corner a
    hair off another, a NaN corner) and points on corners and edge middles: the compiled
    closest points are those of the case analysis in numpy, bit for bit (NaN where it gives
    NaN), and every region is reached."""
    rng = np.random.default_rng(4)
    P, A, B, C = (rng.normal(size=(20000, 3)) for _ in range(4))
    B[:50] = A[:50]
    C[50:100] = A[50:100] + 1e-300
    A[100:105] = np.nan
    P[200:300] = B[200:300]
    P[300:400] = (A[300:400] + C[300:400]) / 2
    got = closest_points_on_triangles(P, A, B, C)
    want = _masked_closest_points(P, A, B, C)
    assert np.array_equal(got, want, equal_nan=True)
    on = [np.all(got == X, axis=1).sum() for X in (A, B, C)]
    assert min(on) > 100 and np.all(np.isfinite(got[:100]))
