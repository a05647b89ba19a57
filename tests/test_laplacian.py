"""Laplacians of SEM (Yueh, Lin, Wu, Yau 2019), ``pipeline/geometry/laplacian.py``: Theorem 1
(the stretch factor, eq. 10–11), cotangent weights (eq. 6), the stretch Laplacian (eq. 12–14),
its blocks, and the stretch energy (eq. 15) as its quadratic form, with gradient 2 L(f) f.

Every expected value comes from the paper's definitions (eq. numbers are the paper's, see
``shared/docs/ALGORITHM.md``) evaluated independently here, or from an exact fact about a
constructed mesh.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import (as_complex, boundary_loop, delaunay_disk, height_field, independent_areas,
                      load_mesh, random_flip_free_maps, stretch_L)
from pipeline.geometry import metrics
from pipeline.geometry.harmonic import harmonic_map
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_blocks, laplacian_matrix, laplacian_pattern,
                                         squared_edge_lengths, stretch_weight_map, unique_edges)
from pipeline.geometry.solvers import make_solver


def cot_by_arccos(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Cotangent of every corner angle, (m, 3), through arccos (independent of the package)."""
    out = np.empty((len(F), 3))
    for c in range(3):
        u = X[F[:, (c + 1) % 3]] - X[F[:, c]]
        v = X[F[:, (c + 2) % 3]] - X[F[:, c]]
        cos = np.sum(u * v, axis=1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        out[:, c] = 1.0 / np.tan(np.arccos(cos))
    return out


# ---------------------------------------------------------------------------- Theorem 1 (eq. 11)


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


# ----------------------------------------------------------------- cotangent weights, patterns


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


# ------------------------------------------------------------------- stretch energy identities


def test_stretch_energy_definition_and_quadratic_form(ddisk):
    """E_S(f) = Σ|f(τ)|²/|τ| (eq. 15) = ½ Σ_coords uvᵀ L(f) uv with the stretch Laplacian."""
    P, F, b = ddisk
    X = height_field(P)
    pattern = laplacian_pattern(F, len(P), b)
    rng = np.random.default_rng(3)
    for uv in random_flip_free_maps(P, F, rng):
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
    uv = random_flip_free_maps(P, F, np.random.default_rng(4), k=1)[0]
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
