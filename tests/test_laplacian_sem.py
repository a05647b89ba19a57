"""Geometry kernels of SEM (Yueh, Lin, Wu, Yau 2019): Theorem 1, cotangent and stretch
Laplacians, the stretch energy and its gradient, the harmonic start, Algorithm 1 on exact
and real cases, and the sparse SPD solvers.

Every expected value comes from the paper's definitions (eq. numbers are the paper's, see
``shared/docs/ALGORITHM.md``) evaluated independently here, or from an exact fact about a
constructed mesh (planar disk meshes whose identity map is equiareal and harmonic).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import Delaunay

from pipeline.errors import UserError
from pipeline.geometry import metrics
from pipeline.geometry.harmonic import arc_length_circle, clamp_positive, harmonic_map
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_blocks, laplacian_matrix, laplacian_pattern,
                                         squared_edge_lengths, stretch_weight_map, unique_edges)
from pipeline.geometry.sem import (SEMOptions, _Problem, hold_flipping_vertices, sem_step,
                                   stretch_energy_minimization)
from pipeline.geometry.solvers import (NotPositiveDefinite, cholmod_available, make_solver,
                                       solve_complex)

from pipeline.geometry.topology import boundary_loops

IN_CI = os.environ.get("CI") == "true"

# ------------------------------------------------------------------------------------ helpers


def boundary_loop(F: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
    return np.asarray(boundary_loops(F, V)[0], dtype=np.int64)


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", Path(__file__).resolve().parents[1] / ".." / "shared"
                               / "data"))


def load_mesh(name: str) -> tuple[np.ndarray, np.ndarray]:
    """``meshes/<name>.obj`` (v/f only); skip when the data folder is missing (fail in CI)."""
    path = data_dir() / "meshes" / f"{name}.obj"
    if not path.is_file():
        msg = f"test data not found: {path} (set SEM_DATA)"
        if IN_CI:
            pytest.fail(msg)
        pytest.skip(msg)
    V, F = [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                V.append(line.split()[1:4])
            elif line.startswith("f "):
                F.append([s.split("/")[0] for s in line.split()[1:4]])
    return np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64) - 1


def orient_ccw(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    s = metrics.signed_double_areas(P, F)
    F = F.copy()
    F[s < 0] = F[s < 0][:, [0, 2, 1]]
    return F


def delaunay_disk(n_boundary=48, n_interior=200, seed=0):
    """Planar unit-disk mesh: ``n_boundary`` equally spaced vertices on the circle (vertex 0 at
    angle 0, listed first, counter-clockwise), well spaced random interior points, Delaunay
    faces oriented counter-clockwise. Not symmetric."""
    rng = np.random.default_rng(seed)
    th = 2 * np.pi * np.arange(n_boundary) / n_boundary
    pts = [np.array([np.cos(t), np.sin(t)]) for t in th]
    spacing = 0.6 / np.sqrt(n_interior)
    while len(pts) < n_boundary + n_interior:
        p = rng.uniform(-1, 1, 2)
        if np.hypot(*p) < 0.93 and min(np.hypot(*(p - q)) for q in pts) > spacing:
            pts.append(p)
    P = np.asarray(pts)
    F = orient_ccw(P, Delaunay(P).simplices.astype(np.int64))
    return P, F


def polar_disk(n_rings=6, n_per_ring=32):
    """Planar unit-disk mesh with exact ``n_per_ring``-fold rotational symmetry: a centre vertex
    and concentric rings of equally many vertices, each ring rotated half a step against the next.
    The boundary is the last ring (equally spaced, its vertex 0 at angle 0)."""
    P = [np.zeros((1, 2))]
    for k in range(1, n_rings + 1):
        th = 2 * np.pi * (np.arange(n_per_ring) + 0.5 * (n_rings - k)) / n_per_ring
        P.append(k / n_rings * np.column_stack([np.cos(th), np.sin(th)]))
    P = np.vstack(P)
    N = n_per_ring

    def ring(k, j):
        return 1 + (k - 1) * N + j % N

    F = [[0, ring(1, j), ring(1, j + 1)] for j in range(N)]
    for k in range(1, n_rings):
        for j in range(N):
            F.append([ring(k, j), ring(k + 1, j), ring(k + 1, j + 1)])
            F.append([ring(k, j), ring(k + 1, j + 1), ring(k, j + 1)])
    return P, orient_ccw(P, np.asarray(F, dtype=np.int64))


def loop_from_angle_zero(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Boundary loop (counter-clockwise) rolled to start at the boundary vertex at angle 0."""
    b = boundary_loop(F, P)
    k = int(np.flatnonzero(np.abs(P[b, 0] - 1) + np.abs(P[b, 1]) < 1e-12)[0])
    return np.roll(b, -k)


def height_field(P: np.ndarray) -> np.ndarray:
    """A curved 3D surface over the planar disk mesh (a real, non-developable disk surface)."""
    x, y = P[:, 0], P[:, 1]
    return np.column_stack([x, y, 0.4 * np.sin(2.0 * x) * np.cos(1.5 * y) + 0.3 * x * y])


def as_complex(uv: np.ndarray) -> np.ndarray:
    return uv[:, 0] + 1j * uv[:, 1]


def independent_areas(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unsigned triangle areas by numpy's cross product (independent of the package)."""
    if X.shape[1] == 2:
        X = np.column_stack([X, np.zeros(len(X))])
    return 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)


def cot_by_arccos(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    out = np.empty((len(F), 3))
    for c in range(3):
        u = X[F[:, (c + 1) % 3]] - X[F[:, c]]
        v = X[F[:, (c + 2) % 3]] - X[F[:, c]]
        cos = np.sum(u * v, axis=1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        out[:, c] = 1.0 / np.tan(np.arccos(cos))
    return out


def stretch_L(X: np.ndarray, F: np.ndarray, uv: np.ndarray, pattern) -> sp.csr_matrix:
    """The full stretch Laplacian L(f), eq. (12)–(14), as an n×n matrix."""
    w = edge_weights(pattern, corner_dot_over_area(uv, F, face_double_areas(X, F)))
    return laplacian_matrix(F, len(X), w, pattern.edges)


@pytest.fixture(scope="module")
def ddisk():
    P, F = delaunay_disk()
    return P, F, loop_from_angle_zero(P, F)


@pytest.fixture(scope="module")
def pdisk():
    P, F = polar_disk()
    return P, F, loop_from_angle_zero(P, F)


# ------------------------------------------------------------------------- 1. Theorem 1 (eq. 11)


def test_theorem1_stretch_factor_is_sqrt_det_of_first_fundamental_form():
    """σ_{f⁻¹}(τ) = |τ|/|f(τ)| (eq. 10) equals √det I_{f⁻¹} (eq. 11), I = JᵀJ, with J (3×2) the
    Jacobian of the affine map f(τ) → τ, computed two ways: generic solve, and the closed form
    of the paper's proof (centroids at 0: ∂f⁻¹/∂z₁ = (f_j2 v_i − f_i2 v_j)/(f_i1 f_j2 − f_i2 f_j1),
    ∂f⁻¹/∂z₂ = (f_i1 v_j − f_j1 v_i)/(…)). Random triangles, both image orientations."""
    rng = np.random.default_rng(1)
    m = 2000
    v = rng.normal(size=(m, 3, 3)) * rng.uniform(0.01, 100, size=(m, 1, 1))
    f = rng.normal(size=(m, 3, 2)) * rng.uniform(0.01, 100, size=(m, 1, 1))
    F = np.arange(3 * m).reshape(m, 3)
    area_v = face_double_areas(v.reshape(-1, 3), F) / 2
    area_f = face_double_areas(f.reshape(-1, 2), F) / 2
    # well-shaped pairs only (the identity is exact; this keeps round-off at 1e-13)
    def shape(x):
        e = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2)
        return e.max(axis=1) ** 2
    ok = (area_v > 0.05 * shape(v)) & (area_f > 0.05 * shape(f))
    assert ok.sum() > 500
    v, f, area_v, area_f = v[ok], f[ok], area_v[ok], area_f[ok]
    assert np.allclose(area_v, independent_areas(v.reshape(-1, 3), F[: len(v)]), rtol=1e-12)
    sigma = area_v / area_f                                                     # eq. (10)

    Ev = np.stack([v[:, 0] - v[:, 2], v[:, 1] - v[:, 2]], axis=2)               # 3×2
    Ef = np.stack([f[:, 0] - f[:, 2], f[:, 1] - f[:, 2]], axis=2)               # 2×2
    J = Ev @ np.linalg.inv(Ef)
    # the affine map takes the image vertices to the surface vertices
    for a in range(3):
        mapped = np.einsum("tij,tj->ti", J, f[:, a] - f[:, 2]) + v[:, 2]
        assert np.allclose(mapped, v[:, a], rtol=0, atol=1e-9 * np.abs(v).max())

    vc = v - v.mean(axis=1, keepdims=True)
    fc = f - f.mean(axis=1, keepdims=True)
    vi, vj, fi, fj = vc[:, 0], vc[:, 1], fc[:, 0], fc[:, 1]
    det = fi[:, 0] * fj[:, 1] - fi[:, 1] * fj[:, 0]
    dz1 = (fj[:, 1, None] * vi - fi[:, 1, None] * vj) / det[:, None]
    dz2 = (fi[:, 0, None] * vj - fj[:, 0, None] * vi) / det[:, None]
    assert np.allclose(np.stack([dz1, dz2], axis=2), J, rtol=1e-10, atol=1e-10 * np.abs(J).max())

    a = np.sum(dz1 * dz1, axis=1)
    b = np.sum(dz1 * dz2, axis=1)
    c = np.sum(dz2 * dz2, axis=1)
    np.testing.assert_allclose(np.sqrt(a * c - b * b), sigma, rtol=1e-10)
    np.testing.assert_allclose(np.sqrt(np.linalg.det(np.swapaxes(J, 1, 2) @ J)), sigma, rtol=1e-10)


# -------------------------------------------------------------- 2. cotangent weights, patterns


def _random_triangles(rng, m, dim):
    X = rng.normal(size=(3 * m, dim))
    F = np.arange(3 * m).reshape(m, 3)
    ang = metrics.corner_angles(X, F)
    keep = np.all((ang > np.radians(4)) & (ang < np.radians(172)), axis=1)
    return X, F[keep]


@pytest.mark.parametrize("dim", [2, 3])
def test_corner_dot_over_area_is_cot_of_corner_angle(dim):
    rng = np.random.default_rng(2 + dim)
    X, F = _random_triangles(rng, 3000, dim)
    assert len(F) > 1000
    got = corner_dot_over_area(X, F, face_double_areas(X, F))
    np.testing.assert_allclose(got, cot_by_arccos(X, F), rtol=1e-9, atol=1e-11)
    # obtuse corners give negative cotangents
    assert (got < 0).any() and (got > 0).any()


def test_stretch_corner_term_is_cot_of_image_angle_over_sigma():
    """With P = f and the *surface* double area: cot α(f) / σ(τ), σ = |τ|/|f(τ)| (eq. 12)."""
    rng = np.random.default_rng(7)
    X, F = _random_triangles(rng, 3000, 3)
    uv = rng.normal(size=(len(X), 2))
    ang = metrics.corner_angles(uv, F)
    F = F[np.all((ang > np.radians(4)) & (ang < np.radians(172)), axis=1)]
    sigma = independent_areas(X, F) / independent_areas(uv, F)
    got = corner_dot_over_area(uv, F, face_double_areas(X, F))
    np.testing.assert_allclose(got, cot_by_arccos(uv, F) / sigma[:, None], rtol=1e-9, atol=1e-11)


def test_edge_weights_are_half_sums_of_opposite_cotangents(ddisk):
    """w_ij = ½ (cot α_ij + cot α_ji) (eq. 6), against a face loop; boundary edges have one term."""
    P, F, b = ddisk
    pattern = laplacian_pattern(F, len(P), b)
    cot = cot_by_arccos(P, F)
    expected = {}
    for t, face in enumerate(F.tolist()):
        for c in range(3):
            e = tuple(sorted((face[(c + 1) % 3], face[(c + 2) % 3])))
            expected[e] = expected.get(e, 0.0) + 0.5 * cot[t, c]
    assert sorted(expected) == [tuple(e) for e in pattern.edges.tolist()]
    w = edge_weights(pattern, corner_dot_over_area(P, F, face_double_areas(P, F)))
    np.testing.assert_allclose(w, [expected[tuple(e)] for e in pattern.edges.tolist()],
                               rtol=1e-9, atol=1e-12)
    edges, corner_edge = unique_edges(F)
    assert np.array_equal(edges, pattern.edges)
    opp = np.sort(np.stack([F[:, [1, 2, 0]], F[:, [2, 0, 1]]], axis=2), axis=2)
    assert np.array_equal(edges[corner_edge], opp)


def test_unique_edges_on_any_triangle_list():
    """Exact against ``np.unique`` of the keys ``i·n + j`` on a triangle soup: non-manifold and
    repeated edges, unreferenced vertices, and a vertex on 500 edges (a long sort bucket)."""
    rng = np.random.default_rng(3)
    fan = np.column_stack([np.zeros(500, int), rng.integers(1, 60, 500), rng.integers(1, 60, 500)])
    F = np.vstack([rng.integers(0, 60, (400, 3)), fan, [[70, 71, 72], [72, 71, 70]]])
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
    n = int(F.max()) + 1
    a, b = F[:, [1, 2, 0]].ravel(), F[:, [2, 0, 1]].ravel()
    keys, inverse = np.unique(np.minimum(a, b) * n + np.maximum(a, b), return_inverse=True)
    edges, corner_edge = unique_edges(F)
    assert np.array_equal(edges, np.column_stack([keys // n, keys % n]))
    assert np.array_equal(corner_edge, inverse.reshape(-1, 3))


def test_stretch_weight_map_gives_eq12_weights(ddisk):
    """``W ℓ²(f)`` is eq. (12): ``w_ij = ½ Σ cot α_ij(f) / σ(τ)`` over the faces on ij, checked
    against a face loop with arccos cotangents, for a map that folds faces (negative terms)."""
    P, F, b = ddisk
    pattern = laplacian_pattern(F, len(P), b)
    rng = np.random.default_rng(11)
    f = P[:, 0] + 1j * P[:, 1] + 0.02 * (rng.normal(size=len(P)) + 1j * rng.normal(size=len(P)))
    uv = np.column_stack([f.real, f.imag])
    sigma = independent_areas(P, F) / independent_areas(uv, F)
    cot = cot_by_arccos(uv, F)
    expected = np.zeros(len(pattern.edges))
    index = {tuple(e): k for k, e in enumerate(pattern.edges.tolist())}
    for t, face in enumerate(F.tolist()):
        for c in range(3):
            e = tuple(sorted((face[(c + 1) % 3], face[(c + 2) % 3])))
            expected[index[e]] += 0.5 * cot[t, c] / sigma[t]
    W = stretch_weight_map(pattern, face_double_areas(P, F))
    w = W @ squared_edge_lengths(pattern, f)
    np.testing.assert_allclose(w, expected, rtol=1e-8, atol=1e-10)
    assert (w < 0).any()
    # each weight reads the squared lengths of the (at most 5) edges of the faces on its edge
    assert W.getnnz(axis=1).max() <= 5


def test_stretch_weight_map_equals_corner_terms_on_a_real_mesh():
    V, F = load_mesh("igl_camelhead")
    pattern = laplacian_pattern(F, len(V), boundary_loop(F, V))
    A2 = face_double_areas(V, F)
    h = harmonic_map(V, F, pattern, make_solver("scipy")).f
    for f in (h, h * np.exp(0.3j) + 0.1 * h * np.abs(h)):
        by_corners = edge_weights(pattern, corner_dot_over_area(
            np.column_stack([f.real, f.imag]), F, A2))
        by_lengths = stretch_weight_map(pattern, A2) @ squared_edge_lengths(pattern, f)
        assert np.abs(by_lengths - by_corners).max() <= 1e-12 * np.abs(by_corners).max()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_laplacian_blocks_reproduce_the_full_matrix(seed):
    P, F = delaunay_disk(n_boundary=12, n_interior=30, seed=seed)
    n = len(P)
    rng = np.random.default_rng(seed)
    # random split into "boundary" (in random order) and interior
    B = rng.permutation(n)[: rng.integers(5, n - 5)]
    pattern = laplacian_pattern(F, n, B)
    I = pattern.interior
    assert np.array_equal(I, np.setdiff1d(np.arange(n), B))
    assert np.array_equal(pattern.boundary, B)

    w1 = rng.normal(size=len(pattern.edges))        # any sign
    w2 = rng.uniform(0.1, 2, size=len(pattern.edges))
    blocks1 = [M.toarray() for M in laplacian_blocks(pattern, w1)]
    blocks2 = laplacian_blocks(pattern, w2)          # a second call must not alter the first
    for w, blocks in ((w1, blocks1), (w2, [M.toarray() for M in blocks2])):
        L = laplacian_matrix(F, n, w, pattern.edges).toarray()
        # L_ij = −w_ij on edges, 0 off edges, L_ii = Σ_k w_ik: symmetric, rows sum to 0
        W = np.zeros((n, n))
        W[pattern.edges[:, 0], pattern.edges[:, 1]] = w
        W += W.T
        np.testing.assert_allclose(L, np.diag(W.sum(axis=1)) - W, rtol=0, atol=1e-13)
        np.testing.assert_array_equal(L, L.T)
        np.testing.assert_allclose(L.sum(axis=1), 0, atol=1e-12)
        np.testing.assert_allclose(blocks[0], L[np.ix_(I, I)], rtol=0, atol=1e-14)
        np.testing.assert_allclose(blocks[1], L[np.ix_(I, B)], rtol=0, atol=1e-14)
        np.testing.assert_allclose(blocks[2], L[np.ix_(B, B)], rtol=0, atol=1e-14)


# ---------------------------------------------------------------- 3. stretch energy identities


def _random_flip_free_maps(P, F, rng, k=5, scale=0.05):
    """Non-affine flip-free maps of a planar mesh: a smooth random warp plus vertex noise of a
    tenth of the shortest incident edge."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    elen = np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1)
    hmin = np.full(len(P), np.inf)
    np.minimum.at(hmin, E.ravel(), np.repeat(elen, 2))
    out = []
    for _ in range(200):
        K = rng.uniform(-3, 3, size=(2, 2))
        phase = rng.uniform(0, 2 * np.pi, size=2)
        warp = np.sin(P @ K.T + phase)
        uv = P + scale * warp + 0.1 * hmin[:, None] * rng.uniform(-1, 1, size=P.shape)
        if len(metrics.flipped_faces(uv, F)) == 0:
            out.append(uv)
            if len(out) == k:
                return out
    raise AssertionError("could not draw flip-free maps")


def test_stretch_energy_definition_and_quadratic_form(ddisk):
    """E_S(f) = Σ|f(τ)|²/|τ| (eq. 15) = ½ Σ_coords uvᵀ L(f) uv with the stretch Laplacian."""
    P, F, b = ddisk
    X = height_field(P)
    pattern = laplacian_pattern(F, len(P), b)
    rng = np.random.default_rng(3)
    for uv in _random_flip_free_maps(P, F, rng):
        uv = uv * rng.uniform(0.1, 10)
        direct = float(np.sum(independent_areas(uv, F) ** 2 / independent_areas(X, F)))
        E = metrics.stretch_energy(X, F, uv)
        assert E == pytest.approx(direct, rel=1e-12)
        L = stretch_L(X, F, uv, pattern)
        quad = 0.5 * sum(float(uv[:, d] @ (L @ uv[:, d])) for d in range(2))
        assert quad == pytest.approx(direct, rel=1e-11)
        # the same through the blocks: ½ fᴴ L f with f complex
        L_II, L_IB, L_BB = laplacian_blocks(
            pattern, edge_weights(pattern, corner_dot_over_area(uv, F, face_double_areas(X, F))))
        f = as_complex(uv)
        fI, fB = f[pattern.interior], f[pattern.boundary]
        herm = 0.5 * np.vdot(fI, L_II @ fI + L_IB @ fB) + 0.5 * np.vdot(fB, L_IB.T @ fI + L_BB @ fB)
        assert herm.real == pytest.approx(direct, rel=1e-11)
        assert abs(herm.imag) < 1e-11 * direct


def _gradient_check(X, F, uv, pattern, vertices):
    """Central differences of E_S (exact: E_S is quadratic in each single coordinate) against
    2 (L(f) f)_v, for the full L and through the I/B blocks."""
    L = stretch_L(X, F, uv, pattern)
    grad = 2 * (L @ uv)
    L_II, L_IB, L_BB = laplacian_blocks(
        pattern, edge_weights(pattern, corner_dot_over_area(uv, F, face_double_areas(X, F))))
    I, B = pattern.interior, pattern.boundary
    grad_blocks = np.empty_like(uv)
    grad_blocks[I] = 2 * (L_II @ uv[I] + L_IB @ uv[B])
    grad_blocks[B] = 2 * (L_IB.T @ uv[I] + L_BB @ uv[B])
    np.testing.assert_allclose(grad_blocks, grad, rtol=1e-12, atol=1e-12 * np.abs(grad).max())
    A2 = face_double_areas(X, F)
    h = 1e-3 * np.abs(uv).max()
    scale = np.abs(grad).max()
    for v in vertices:
        for d in range(2):
            up, dn = uv.copy(), uv.copy()
            up[v, d] += h
            dn[v, d] -= h
            E_up, E_dn = (metrics.stretch_energy(X, F, g, A2) for g in (up, dn))
            fd = (E_up - E_dn) / (2 * h)
            assert fd == pytest.approx(grad[v, d], rel=1e-7, abs=1e-9 * scale), (v, d)


def test_stretch_energy_gradient_is_twice_L_f_synthetic(ddisk):
    P, F, b = ddisk
    X = height_field(P)
    pattern = laplacian_pattern(F, len(P), b)
    uv = _random_flip_free_maps(P, F, np.random.default_rng(4), k=1)[0]
    rng = np.random.default_rng(5)
    _gradient_check(X, F, uv, pattern, list(rng.choice(pattern.interior, 6, replace=False))
                    + list(rng.choice(b, 6, replace=False)))


def test_stretch_energy_gradient_is_twice_L_f_real_mesh():
    """On gpp_bunny's harmonic map (a real surface and a real map), interior and boundary."""
    V, F = load_mesh("gpp_bunny")
    b = boundary_loop(F, V)
    pattern = laplacian_pattern(F, len(V), b)
    f = harmonic_map(V, F, pattern).f
    uv = np.column_stack([f.real, f.imag])
    rng = np.random.default_rng(6)
    _gradient_check(V, F, uv, pattern, list(rng.choice(pattern.interior, 8, replace=False))
                    + list(rng.choice(b, 8, replace=False)))


def test_energy_ratio_lower_bound_and_equality_for_affine_maps(ddisk):
    """E_S ≥ |f(M)|²/|M| (Cauchy–Schwarz), equality iff σ is constant; f = A·v of a planar
    mesh has σ = 1/|det A| on every face, so the ratio is exactly 1."""
    P, F, _ = ddisk
    X = height_field(P)
    rng = np.random.default_rng(8)
    for uv in _random_flip_free_maps(P, F, rng, k=8):
        r = metrics.energy_ratio(X, F, uv)
        a, A = independent_areas(uv, F), independent_areas(X, F)
        assert r == pytest.approx(np.sum(a * a / A) * A.sum() / a.sum() ** 2, rel=1e-12)
        assert r > 1 + 1e-4
        assert metrics.energy_ratio(X * 3.0, F, uv * 0.2) == pytest.approx(r, rel=1e-12)
        r_planar = metrics.energy_ratio(np.column_stack([P, np.zeros(len(P))]), F, uv)
        assert r_planar > 1 + 1e-6
    # a planar mesh placed in 3D by a rotation; affine maps with positive determinant
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    V3 = np.column_stack([P, np.zeros(len(P))]) @ Q.T + rng.normal(size=3)
    for _ in range(5):
        A = rng.normal(size=(2, 2))
        if np.linalg.det(A) < 0:
            A[:, 0] *= -1
        uv = P @ A.T + rng.normal(size=2)
        assert len(metrics.flipped_faces(uv, F)) == 0
        assert metrics.energy_ratio(V3, F, uv) == pytest.approx(1.0, abs=1e-12)
        E = metrics.stretch_energy(V3, F, uv)
        area_M = independent_areas(V3, F).sum()
        assert E == pytest.approx(np.linalg.det(A) ** 2 * area_M, rel=1e-12)


# ------------------------------------------------------------------------- 4. harmonic map


def test_arc_length_circle_equal_spacing_and_real_loop(ddisk):
    P, F, b = ddisk
    z = arc_length_circle(np.column_stack([P, np.zeros(len(P))]), b)
    np.testing.assert_allclose(z, np.exp(2j * np.pi * np.arange(len(b)) / len(b)), atol=1e-14)
    np.testing.assert_allclose(z, as_complex(P[b]), atol=1e-14)


def test_arc_length_circle_on_real_boundary():
    V, F = load_mesh("igl_lion")
    b = boundary_loop(F, V)
    z = arc_length_circle(V, b)
    np.testing.assert_allclose(np.abs(z), 1, atol=1e-15)
    assert z[0] == 1
    theta = np.unwrap(np.angle(z))
    seg = np.linalg.norm(V[np.roll(b, -1)] - V[b], axis=1)
    np.testing.assert_allclose(np.diff(theta), 2 * np.pi * seg[:-1] / seg.sum(), atol=1e-13)


@pytest.mark.parametrize("mesh", ["delaunay", "polar"])
def test_harmonic_map_of_planar_disk_is_identity(mesh, ddisk, pdisk):
    """Cotangent weights have linear precision: with the boundary already equally spaced on the
    unit circle starting at angle 0, the arc-length boundary is V_B and the harmonic map is the
    identity."""
    P, F, b = ddisk if mesh == "delaunay" else pdisk
    V = np.column_stack([P, np.zeros(len(P))])
    h = harmonic_map(V, F, laplacian_pattern(F, len(P), b))
    assert h.weights == "cotangent"
    assert h.flipped_faces == 0
    np.testing.assert_allclose(np.column_stack([h.f.real, h.f.imag]), P, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", ["igl_lion", "gpp_bunny"])
def test_harmonic_map_of_real_disk_is_flip_free_on_the_unit_circle(name):
    V, F = load_mesh(name)
    b = boundary_loop(F, V)
    pattern = laplacian_pattern(F, len(V), b)
    h = harmonic_map(V, F, pattern)
    uv = np.column_stack([h.f.real, h.f.imag])
    assert len(metrics.flipped_faces(uv, F)) == 0 and h.flipped_faces == 0
    np.testing.assert_allclose(h.f[b], arc_length_circle(V, b), atol=1e-15)
    assert np.abs(h.f[pattern.interior]).max() < 1
    # it is the discrete harmonic map of the weights it reports (eq. 5–6: L_II f_I = −L_IB f_B)
    w = edge_weights(pattern, corner_dot_over_area(V, F, face_double_areas(V, F)))
    assert h.negative_weights == int(np.count_nonzero(w <= 0))
    if h.weights != "cotangent":
        assert h.weights == "cotangent, clamped positive"
        w = clamp_positive(w)
    L_II, L_IB, _ = laplacian_blocks(pattern, w)
    res = L_II @ h.f[pattern.interior] + L_IB @ h.f[b]
    assert np.abs(res).max() < 1e-9 * np.abs(L_IB @ h.f[b]).max()


def _reference_hold(F, f, g, allowed, rounds):
    """The flip-holding rule with full recomputation every round: round 1 holds every vertex of
    every flipped face; a later round holds the new vertices of flipped faces among the faces
    around the vertices held in the round before. Returns ``(map, rounds that held vertices)``."""
    g, held, candidates, used = g.copy(), set(), np.arange(len(F)), 0
    for _ in range(rounds):
        a2 = metrics.signed_double_areas(np.column_stack([g.real, g.imag]), F)
        if np.count_nonzero(a2 <= 0) <= allowed:
            break
        new = {int(v) for t in candidates if a2[t] <= 0 for v in F[t]} - held
        if not new:
            break
        held |= new
        idx = np.array(sorted(new))
        g[idx] = f[idx]
        candidates = np.flatnonzero(np.isin(F, idx).any(axis=1))
        used += 1
    return g, used


def test_flip_holding_follows_its_rule_and_keeps_exact_areas(ddisk):
    """Compiled flip holding against the rule written plainly: the same held vertices, the
    flipped count and energy of the result, bit for bit, for random folding displacements of
    vertex patch (cascades that take several rounds, and cases the rounds cannot fix)."""
    P, F, b = ddisk
    problem = _Problem(height_field(P), F, b, "auto")
    f = as_complex(P)
    rng = np.random.default_rng(4)
    rounds_seen = set()
    for trial in range(40):
        centre = P[rng.integers(len(P))]
        patch = np.flatnonzero(np.linalg.norm(P - centre, axis=1) < rng.uniform(0.1, 0.5))
        g = f.copy()
        # a common shift folds the patch's rim; holding the rim exposes the next layer (cascade)
        turn = rng.random(len(patch)) if trial % 2 else np.full(len(patch), rng.random())
        g[patch] += rng.uniform(0.05, 0.4) * np.exp(2j * np.pi * turn)
        allowed, rounds = int(trial % 3 == 0), int(rng.integers(1, 9))
        held_g, value = hold_flipping_vertices(problem, f, g, allowed, rounds)
        expected, used = _reference_hold(F, f, g, allowed, rounds)
        rounds_seen.add(used)
        np.testing.assert_array_equal(held_g, expected)
        a2 = metrics.signed_double_areas(np.column_stack([expected.real, expected.imag]), F)
        assert value[2] == np.count_nonzero(a2 <= 0)
        assert value[0] == 0.5 * np.sum(a2 * a2 / problem.A2)
        np.testing.assert_array_equal(value[3], a2)
        assert g is not held_g or used == 0          # the input map is never modified
    assert {0, 1, 2} <= rounds_seen and max(rounds_seen) >= 3


# ------------------------------------------------- 5. an equiareal planar disk stays equiareal


def _reference_sem_step(X, F, f, pattern):
    """Eq. (19)–(22) with dense solves, written from the paper."""
    L = stretch_L(X, F, np.column_stack([f.real, f.imag]), pattern).toarray()
    I, B = pattern.interior, pattern.boundary
    fB = np.linalg.solve(L[np.ix_(B, B)], -L[np.ix_(B, I)] @ f[I])       # (19)
    fB = fB - fB.mean()                                                   # (20)
    fB = fB / np.abs(fB)                                                  # (21)
    g = np.empty_like(f)
    g[B] = fB
    g[I] = np.linalg.solve(L[np.ix_(I, I)], -L[np.ix_(I, B)] @ fB)        # (22)
    return g


def test_sem_step_matches_the_paper_equations(ddisk):
    P, F, b = ddisk
    X = height_field(P)
    problem = _Problem(X, F, b, "auto")
    f = as_complex(_random_flip_free_maps(P, F, np.random.default_rng(9), k=1)[0])
    f[b] /= np.abs(f[b])
    w = problem.weights(f)
    g = sem_step(problem, f, w)
    np.testing.assert_allclose(g, _reference_sem_step(X, F, f, problem.pattern), atol=1e-10)


def test_sem_step_fixed_point_on_symmetric_disk_but_not_on_asymmetric(pdisk, ddisk):
    """Facts behind the next test. The identity of a planar mesh is equiareal, but it is a fixed
    point of one SEM step (eq. 19–22) only if L_BB⁻¹ (L V)_B is radial. (L V)_B is radial
    (∝ sin(2π/N) V_B) for equally spaced boundary points; on the N-fold symmetric polar mesh L_BB
    is circulant so V_B is its eigenvector and the step returns the identity. On the Delaunay mesh
    the step moves the boundary along the circle and raises both E_S and the ratio."""
    for (P, F, b), fixed in ((pdisk, True), (ddisk, False)):
        V = np.column_stack([P, np.zeros(len(P))])
        f = as_complex(P)
        g = _reference_sem_step(V, F, f, laplacian_pattern(F, len(P), b))
        if fixed:
            np.testing.assert_allclose(g, f, atol=1e-12)
        else:
            moved = np.abs(np.angle(g[b] / f[b])).max()
            assert moved > 1e-3
            uv = np.column_stack([g.real, g.imag])
            assert metrics.stretch_energy(V, F, uv) > metrics.stretch_energy(V, F, P) * (1 + 1e-6)
            assert metrics.energy_ratio(V, F, uv) > 1 + 1e-5


@pytest.mark.parametrize("mode", ["paper", "converged"])
@pytest.mark.parametrize("mesh", ["delaunay", "polar"])
def test_sem_keeps_an_equiareal_planar_disk(mesh, mode, ddisk, pdisk):
    """The identity (x, y, 0) → (x, y) is equiareal: ratio 1, D(f) = 0. Both modes start from it
    (harmonic = identity) and must return it, unrotated: on the polar mesh it is a fixed point;
    on the Delaunay mesh the SEM step raises E_S, so paper mode stops at once (Remark 3,
    status energy_rose, 0 iterations) and converged mode finds no better flip-free map."""
    P, F, b = ddisk if mesh == "delaunay" else pdisk
    V = np.column_stack([P, np.zeros(len(P))])
    assert metrics.energy_ratio(V, F, P) == pytest.approx(1, abs=1e-15)
    assert metrics.total_area_distortion(V, F, P) < 1e-15
    r = stretch_energy_minimization(V, F, b, SEMOptions(mode=mode))
    assert r.flipped_faces == 0 and len(metrics.flipped_faces(r.uv, F)) == 0
    assert abs(metrics.energy_ratio(V, F, r.uv) - 1) < 1e-9
    assert metrics.total_area_distortion(V, F, r.uv) < 1e-8
    np.testing.assert_allclose(r.uv, P, rtol=0, atol=1e-9)      # no rotation either
    if mesh == "delaunay" and mode == "paper":
        assert r.status == "energy_rose" and r.iterations == 0


# ------------------------------------------------------------------ 6. SEM on real meshes


@pytest.fixture(scope="module")
def face_paper():
    V, F = load_mesh("choi_human_face")
    b = boundary_loop(F, V)
    return V, F, b, stretch_energy_minimization(V, F, b, SEMOptions(mode="paper"))


def test_sem_paper_mode_human_face(face_paper):
    V, F, b, r = face_paper
    assert r.status == "max_iter" and r.iterations == 10
    assert r.flipped_faces == 0 and len(metrics.flipped_faces(r.uv, F)) == 0
    D = metrics.total_area_distortion(V, F, r.uv)
    assert D <= 0.0045
    np.testing.assert_allclose(np.hypot(*r.uv[b].T), 1, atol=1e-12)
    # history: harmonic start + one entry per iteration, E_S non-increasing (Algorithm 1 stops
    # and keeps the previous map when it rises), last entry describes the returned map
    E = [h["stretch_energy"] for h in r.history]
    assert len(E) == r.iterations + 1 and r.history[0]["phase"] == "harmonic"
    assert all(b_ <= a_ for a_, b_ in zip(E, E[1:]))
    assert E[-1] == pytest.approx(metrics.stretch_energy(V, F, r.uv), rel=1e-12)
    assert r.history[-1]["total_area_distortion_eq28"] == pytest.approx(D, rel=1e-12)
    assert r.history[-1]["energy_ratio"] == pytest.approx(metrics.energy_ratio(V, F, r.uv),
                                                          rel=1e-12)
    # SEM improves substantially on the harmonic start
    assert D < 0.05 * r.history[0]["total_area_distortion_eq28"]


@pytest.fixture(scope="module")
def lion_converged():
    V, F = load_mesh("igl_lion")
    b = boundary_loop(F, V)
    # the full default run (≈1400 iterations, ≈20 s here) is too slow for the suite; 200
    # iterations reach face_area_distortion ≈ 0.010
    return V, F, b, stretch_energy_minimization(V, F, b, SEMOptions(mode="converged",
                                                                    max_iter=200))


def test_sem_converged_mode_lion(lion_converged):
    V, F, b, r = lion_converged
    assert r.flipped_faces == 0 and len(metrics.flipped_faces(r.uv, F)) == 0
    assert metrics.face_area_distortion(V, F, r.uv) <= 0.034
    np.testing.assert_allclose(np.hypot(*r.uv[b].T), 1, atol=1e-12)
    assert r.history[-1]["energy_ratio"] == pytest.approx(metrics.energy_ratio(V, F, r.uv),
                                                          rel=1e-12)


def test_sem_converged_mode_history_is_monotone(lion_converged):
    """Phase A records only new flip-free bests; phase B (entries "gradient"/"sem" after the
    phase-A best) accepts only steps that lower the ratio. So the ratio strictly decreases along
    the whole history, every entry is flip-free, and the result is the best map recorded."""
    V, F, b, r = lion_converged
    ratio = [h["energy_ratio"] for h in r.history]
    assert r.history[0]["phase"] == "harmonic" and r.history[0]["flipped_faces"] == 0
    assert all(h["flipped_faces"] == 0 for h in r.history)
    assert all(b_ < a_ for a_, b_ in zip(ratio, ratio[1:]))
    assert {h["phase"] for h in r.history[1:]} <= {"sem", "gradient"}
    assert any(h["phase"] == "gradient" for h in r.history)      # phase B was reached
    assert min(ratio) == ratio[-1]
    its = [h["iteration"] for h in r.history]
    assert its == sorted(its) and its[-1] == r.iterations <= 200


# ------------------------------------------------------------------------------- 7. solvers


@pytest.fixture(scope="module")
def spd_block(ddisk):
    P, F, b = ddisk
    pattern = laplacian_pattern(F, len(P), b)
    w = edge_weights(pattern, corner_dot_over_area(P, F, face_double_areas(P, F)))
    L_II = laplacian_blocks(pattern, w)[0]
    assert np.linalg.eigvalsh(L_II.toarray()).min() > 0
    return L_II


def _kinds():
    if cholmod_available():
        return ["scipy", "cholmod"]
    if IN_CI:
        pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
    return ["scipy"]


def test_solvers_agree_on_spd_block(spd_block):
    A = spd_block
    rng = np.random.default_rng(10)
    b = rng.normal(size=A.shape[0]) + 1j * rng.normal(size=A.shape[0])
    ref = np.linalg.solve(A.toarray(), b)
    sols = {}
    for kind in _kinds():
        s = make_solver(kind)
        sols[kind] = solve_complex(s, A, b)
        np.testing.assert_allclose(sols[kind], ref, rtol=1e-10, atol=0)
        # refactorization with new values on the same pattern (reused analysis)
        A2 = A + sp.diags(rng.uniform(0.1, 1.0, A.shape[0]))
        np.testing.assert_allclose(solve_complex(s, A2, b), np.linalg.solve(A2.toarray(), b),
                                   rtol=1e-10)
    if "cholmod" in sols:
        np.testing.assert_allclose(sols["cholmod"], sols["scipy"], rtol=1e-10, atol=0)
    if not cholmod_available():
        pytest.skip("CHOLMOD part skipped: scikit-sparse not installed")


def test_make_solver_rejects_unknown_kind():
    with pytest.raises(UserError):
        make_solver("bogus")
    assert make_solver("scipy").name == "scipy"
    assert make_solver("auto").name == ("cholmod" if cholmod_available() else "scipy")


def _grid_laplacian(m):
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    return (sp.kron(T, sp.identity(m)) + sp.kron(sp.identity(m), T)).tocsr()


@pytest.mark.parametrize("refactored", [False, True])
@pytest.mark.parametrize("case", ["negative_definite", "indefinite", "negative_definite_large"])
@pytest.mark.parametrize("kind", ["scipy", "cholmod"])
def test_non_spd_matrix_raises_not_positive_definite(kind, case, refactored, spd_block):
    """Remark 1: the blocks are SPD only for positive weights; the solvers must say when they are
    not (sem.py catches NotPositiveDefinite). CHOLMOD is supernodal LLᵀ by default and
    simplicial LDLᵀ for refactored systems below SIMPLICIAL_BELOW unknowns (all three cases
    here), where only the pivot check can tell. "large" = 10⁴ unknowns."""
    if kind == "cholmod" and not cholmod_available():
        if IN_CI:
            pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
        pytest.skip("scikit-sparse not installed")
    A = spd_block
    if case == "negative_definite":
        M = -A
    elif case == "negative_definite_large":
        M = -_grid_laplacian(100)
    else:  # shift so that about half the spectrum is negative
        lam = np.linalg.eigvalsh(A.toarray())
        M = (A - np.median(lam) * sp.identity(A.shape[0])).tocsr()
    with pytest.raises(NotPositiveDefinite):
        make_solver(kind, refactored=refactored).factorize(M)


@pytest.mark.parametrize("refactored", [False, True])
def test_cholmod_refactor_to_indefinite_raises_and_drops_the_factor(refactored, spd_block):
    """SEM refactors one pattern with new values: an indefinite matrix after an SPD one must
    raise (not solve with negative LDLᵀ pivots) and leave no usable factor; the next SPD matrix
    is factored again on the kept analysis and solved exactly."""
    if not cholmod_available():
        if IN_CI:
            pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
        pytest.skip("scikit-sparse not installed")
    A = spd_block
    lam = np.linalg.eigvalsh(A.toarray())
    solver = make_solver("cholmod", refactored=refactored)
    solver.factorize(A)
    assert solver.has_factor()
    with pytest.raises(NotPositiveDefinite):
        solver.factorize((A - np.median(lam) * sp.identity(A.shape[0])).tocsr())
    assert not solver.has_factor()
    A2 = (A + sp.identity(A.shape[0])).tocsr()
    solver.factorize(A2)
    X = np.random.default_rng(1).standard_normal((A.shape[0], 2))
    np.testing.assert_allclose(solver.solve(A2 @ X), X, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kind", ["scipy", "cholmod"])
def test_singular_matrix_raises_not_positive_definite(kind):
    if kind == "cholmod" and not cholmod_available():
        pytest.skip("scikit-sparse not installed")
    M = sp.csr_matrix(np.diag([2.0, 1.0, 3.0, 0.0]))
    with pytest.raises(NotPositiveDefinite):
        make_solver(kind).factorize(M)
