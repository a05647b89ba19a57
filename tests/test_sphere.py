"""Spherical equiareal maps (:mod:`pipeline.geometry.sphere`, :mod:`pipeline.geometry.sphere_newton`):
exact facts on constructed meshes, the genus check on real closed meshes, and issue #22's
numbers (0 folds, face-based area distortion ≤ 0.02, converged) on the real genus-0 meshes of
``shared/data/closed`` and on a constructed mesh with long spikes. The 10 s budget at 40k faces
is ``benchmarks/bench_sphere.py``'s (seconds on a shared machine scatter too much for a test)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import pytest

from conftest import require_data
from pipeline.errors import UserError
from pipeline.geometry import sphere, sphere_newton
from pipeline.geometry.repair import triangulate_polygons
from pipeline.io.meshio import read_mesh


def icosphere(level: int = 2):
    """Unit icosphere: the icosahedron with ``level`` midpoint subdivisions, outward faces
    (``trimesh.creation.icosphere``)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=level)
    return np.array(m.vertices, dtype=np.float64), np.array(m.faces, dtype=np.int64)


def torus(n=12, k=8, R=2.0, r=0.7):
    u, v = np.meshgrid(np.arange(n), np.arange(k), indexing="ij")
    a, b = 2 * np.pi * u / n, 2 * np.pi * v / k
    V = np.column_stack([((R + r * np.cos(b)) * np.cos(a)).ravel(),
                         ((R + r * np.cos(b)) * np.sin(a)).ravel(), (r * np.sin(b)).ravel()])
    idx = lambda i, j: (i % n) * k + (j % k)
    F = []
    for i in range(n):
        for j in range(k):
            F += [(idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)),
                  (idx(i, j), idx(i + 1, j + 1), idx(i, j + 1))]
    return V, np.array(F, dtype=np.int64)


def load_closed(name):
    mesh = read_mesh(require_data("closed", f"{name}.obj"))
    F, _, _ = triangulate_polygons(mesh.faces, len(mesh.V))
    return np.asarray(mesh.V, float), F


# -- exact facts ---------------------------------------------------------------------------------

def test_icosphere_identity_is_equiareal_and_fold_free():
    V, F = icosphere(2)
    assert sphere.genus(F) == 0
    F2 = sphere.check_genus_zero(V, F)
    np.testing.assert_array_equal(F2, F)              # already outward
    m = sphere.sphere_measures(V, F, V)
    assert m["folded_faces"] == 0 and m["face_area_distortion"] == pytest.approx(0.0)
    # geodesic triangles of the subdivided icosahedron are not all equal: small, not zero
    assert 0 < m["face_area_distortion_spherical"] < 0.01
    assert m["energy_ratio"] == pytest.approx(1.0)
    assert sphere.spherical_triangle_areas(V, F).sum() == pytest.approx(4 * np.pi)
    # a reflection reverses every face
    assert sphere.folded_faces(V * [1, 1, -1], F) == len(F)


def test_inward_faces_are_reoriented():
    V, F = icosphere(1)
    np.testing.assert_array_equal(sphere.check_genus_zero(V, F[:, [0, 2, 1]]), F)


def test_stereographic_round_trip_and_orientation():
    V, F = icosphere(2)
    h = sphere.stereographic(V[V[:, 2] < 0.99])
    np.testing.assert_allclose(sphere.inverse_stereographic(h), V[V[:, 2] < 0.99], atol=1e-12)
    # southern faces stay counter-clockwise in the plane (the conjugate in eq. S1)
    south = F[(V[F][:, :, 2] < 0).all(axis=1)]
    assert len(south) > 0
    H = sphere.stereographic(V[:, :] * [1, 1, 0.999])   # the north pole itself is a vertex
    a, b, c = H[south[:, 0]], H[south[:, 1]], H[south[:, 2]]
    assert np.all(((b - a).conjugate() * (c - a)).imag > 0)


def test_icosphere_start_and_map_have_no_fold():
    V, F = icosphere(3)
    S, info = sphere.tutte_sphere_start(V * 2.0, F)
    assert info["folded_faces"] == sphere.folded_faces(S, F) == 0
    np.testing.assert_allclose(np.linalg.norm(S, axis=1), 1.0, atol=1e-12)
    r = sphere.spherical_sem(V * 2.0, F)
    assert r.measures["folded_faces"] == 0
    assert r.measures["face_area_distortion"] < 0.05
    assert r.measures["face_area_distortion"] < r.start["face_area_distortion"]


@pytest.mark.parametrize("level", [2, 3])
def test_icosphere_map_to_itself_is_a_rotation(level):
    """The map of an icosphere (scaled ×2) onto the unit sphere: energy ratio 1 to 1e-6 and,
    although equiareal maps are not unique, the minimizer reached from the Tutte start is the
    identity up to a rotation (Procrustes; a proper rotation, no reflection) within 0.03."""
    V, F = icosphere(level)
    r = sphere.spherical_sem(V * 2.0, F)
    assert r.status == "converged" and r.measures["folded_faces"] == 0
    assert r.measures["energy_ratio"] == pytest.approx(1.0, abs=1e-6)
    U, _, Wt = np.linalg.svd(r.S.T @ V)
    R = U @ Wt
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.linalg.norm(V @ R.T - r.S, axis=1).max() < 0.03


def test_newton_leaves_an_equiareal_map_in_place():
    """From the identity map of an icosphere (``R = 1`` exactly: flat image = surface), the
    Gauss–Newton minimization stays put with the ratio at 1: it moves only by the last barrier
    weight's pull towards orientations ∝ areas (1e-5 here)."""
    V, F = icosphere(2)
    A2 = sphere.face_double_areas(V, F)
    S, status, _ = sphere_newton.minimize(F, A2, V.copy())
    assert status == "converged"
    assert np.abs(S - V).max() < 1e-5
    assert sphere.energy_ratio(A2, S, F) == pytest.approx(1.0, abs=1e-9)


def test_objective_is_infinite_on_a_fold_and_barrier_free_at_kappa_0():
    V, F = icosphere(1)
    A2 = sphere.face_double_areas(V, F)
    assert sphere_newton.objective(A2, V, F, 0.0) == pytest.approx(0.0, abs=1e-14)
    # flat areas of the identity are the surface's; the orientations det[...] are not
    # proportional to them (the planes lie at different depths), so the barrier is > 0
    assert sphere_newton.objective(A2, V, F, 1.0) > 0
    S = V.copy()
    S[0] = -0.2 * V[0] + V[1]
    S[0] /= np.linalg.norm(S[0])
    assert sphere.folded_faces(S, F) > 0
    assert sphere_newton.objective(A2, S, F, 0.0) == np.inf


def perturbed_gauss_newton(level: int, noise: float, rng):
    """``(F, S, A2, SphereGaussNewton)``: an icosphere map moved by ``noise`` and renormalized,
    with the surface areas of the icosphere stretched along x (so the map is not equiareal)."""
    V, F = icosphere(level)
    S = V + noise * rng.standard_normal(V.shape)
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    A2 = sphere.face_double_areas(V * (1 + 0.3 * V[:, :1] ** 2), F)
    return F, S, A2, sphere_newton.SphereGaussNewton(F, len(S), A2)


@pytest.mark.parametrize("kappa", [0.0, 0.5])
def test_gauss_newton_gradient_matches_finite_differences(kappa):
    """The gradient of ``Φ_κ`` in tangent coordinates against central differences along
    random tangent steps ``normalize(s + t δ)`` of a perturbed icosphere map; the Gauss–Newton
    matrix is symmetric positive semidefinite with the rotations in its null space, and the
    Laplacian damping positive definite."""
    rng = np.random.default_rng(1)
    F, S, A2, gn = perturbed_gauss_newton(1, 0.03, rng)
    gn.linearize(S, kappa)
    data, g, e1, e2, damp = gn._system
    for _ in range(3):
        x = rng.standard_normal(2 * len(S))
        D = x[0::2, None] * e1 + x[1::2, None] * e2

        def phi(t):
            C = S + t * D
            return sphere_newton.objective(A2, C / np.linalg.norm(C, axis=1, keepdims=True),
                                           F, kappa)
        eps = 1e-6
        assert g @ x == pytest.approx((phi(eps) - phi(-eps)) / (2 * eps), rel=1e-5)
    ev = np.linalg.eigvalsh(_symmetric(gn.H, data))
    assert ev[0] > -1e-12 * ev[-1] and np.sum(ev < 1e-10 * ev[-1]) >= 3
    assert np.linalg.eigvalsh(_symmetric(gn.H, damp))[0] > 0


def _symmetric(upper, data) -> np.ndarray:
    """The dense symmetric matrix whose upper triangle has ``upper``'s pattern and ``data``."""
    U = upper.copy()
    U.data = data
    return (U + sp.triu(U, 1).T).toarray()


# -- genus ---------------------------------------------------------------------------------------

def test_constructed_torus_is_refused_naming_genus_1():
    V, F = torus()
    with pytest.raises(UserError, match=r"genus 1 \(Euler characteristic 0\)"):
        sphere.check_genus_zero(V, F)


def test_open_mesh_is_refused():
    V, F = icosphere(1)
    with pytest.raises(UserError, match="boundary edges"):
        sphere.check_genus_zero(V, F[1:])


@pytest.mark.parametrize("name,g,chi", [("c3d_rocker_arm_genus1", 1, 0),
                                        ("igl_fertility_genus4", 4, -6)])
def test_real_higher_genus_meshes_are_refused(name, g, chi):
    V, F = load_closed(name)
    with pytest.raises(UserError, match=rf"closed with genus {g} \(Euler characteristic {chi}\); "
                                        r"spherical maps need genus 0"):
        sphere.spherical_sem(V, F)


# -- real genus-0 meshes -------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["igl_bunny", "igl_arm", "igl_bumpy_cube", "igl_decimated_max",
                                  "igl_elephant"])
def test_real_genus0_maps_meet_the_issue_target(name):
    """Issue #22: no folded face and face-based area distortion ≤ 0.02, converged (the time
    limit is generous here: the machine is shared; seconds are the benchmark's)."""
    V, F = load_closed(name)
    r = sphere.spherical_sem(V, F, time_limit=120.0)
    assert r.status == "converged"
    assert r.measures["folded_faces"] == 0
    assert r.measures["face_area_distortion"] <= 0.02
    # the stopping rule R − 1 ≤ 1e-4 bounds the distortion by √(R − 1) (Cauchy–Schwarz)
    assert r.measures["face_area_distortion"] <= np.sqrt(r.measures["energy_ratio"] - 1) + 1e-12
    assert r.measures["max_radius_error"] < 1e-12
    assert r.history[-1]["energy_ratio"] <= r.history[0]["energy_ratio"]
    assert all(h["folded_faces"] == 0 for h in r.history if h.get("phase") == "newton")


def test_spiky_sphere_with_long_limbs_meets_the_issue_target():
    """A constructed stand-in for meshes we do not have: an icosphere pushed out into six
    spikes three radii long, which a near-conformal start crowds into tiny areas."""
    V, F = icosphere(4)
    D = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    theta = np.arccos(np.clip(V @ D.T, -1, 1))
    V = V * (1 + 3.0 * np.exp(-(theta / 0.3) ** 2).sum(axis=1))[:, None]
    r = sphere.spherical_sem(V, F, time_limit=120.0)
    assert r.status == "converged" and r.measures["folded_faces"] == 0
    assert r.measures["face_area_distortion"] <= 0.02
    assert r.start["face_area_distortion"] > 1.0


def test_hemisphere_method_is_kept_and_fold_free():
    V, F = icosphere(3)
    r = sphere.spherical_sem(V * 2.0, F, method="hemisphere", time_limit=2.0)
    assert r.measures["folded_faces"] == 0
    assert r.measures["face_area_distortion"] < r.start["face_area_distortion"]
    assert "newton" not in r.timings
    with pytest.raises(UserError, match="unknown spherical method"):
        sphere.spherical_sem(V, F, method="conformal")


def test_fold_test_is_exact_for_tiny_triangles():
    """A tiny positive triangle far from the pole: the edge-vector form of the determinant keeps
    its sign where ``s0 · (s1 × s2)`` cancels to noise."""
    p = np.array([0.6, 0.0, 0.8])
    e1, e2 = np.array([0.0, 1.0, 0.0]), np.cross(p, [0.0, 1.0, 0.0])
    S = np.array([p, p + 1e-9 * e1, p + 1e-9 * e2])
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    F = np.array([[0, 1, 2], [0, 2, 1]])
    d = sphere.triple_products(S, F)
    assert d[0] > 0 and d[1] < 0
    assert d[0] == pytest.approx(-d[1]) and d[0] == pytest.approx(1e-18, rel=1e-3)


def test_unfold_removes_a_pushed_vertex_fold():
    """An icosphere vertex pushed across its neighbours folds faces; smoothing the vertices of
    folded faces removes every fold and moves only vertices near the fold."""
    V, F = icosphere(2)
    S = V.copy()
    S[0] = -0.2 * V[0] + V[1]
    S[0] /= np.linalg.norm(S[0])
    assert sphere.folded_faces(S, F) > 0
    U, left = sphere.unfold(S, F)
    assert left == 0 == sphere.folded_faces(U, F)
    far = np.linalg.norm(V - V[0], axis=1) > 1.0
    np.testing.assert_array_equal(U[far], V[far])


def test_ratio_gradient_matches_finite_differences():
    """:func:`sphere.ratio_gradient` against central differences of the energy ratio along
    tangent directions of a perturbed icosphere map."""
    rng = np.random.default_rng(0)
    V, F = icosphere(1)
    S = V + 0.05 * rng.standard_normal(V.shape)
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    A2 = sphere.face_double_areas(V * (1 + 0.3 * V[:, :1] ** 2), F)   # a non-uniform surface
    g = sphere.ratio_gradient(A2, S, F)
    for _ in range(3):
        D = rng.standard_normal(S.shape)
        D -= np.sum(D * S, axis=1, keepdims=True) * S
        eps = 1e-6
        fd = (sphere.energy_ratio(A2, S + eps * D, F) - sphere.energy_ratio(A2, S - eps * D, F)) \
            / (2 * eps)
        assert np.sum(g * D) == pytest.approx(fd, rel=1e-5)


@pytest.mark.parametrize("kappa", [0.0, 0.7])
def test_compiled_gauss_newton_terms_match_numpy(kappa):
    """The compiled per-face pass against its numpy reference, to rounding."""
    _, S, _, gn = perturbed_gauss_newton(3, 0.02, np.random.default_rng(2))
    gn.linearize(S, kappa)
    compiled = gn._system
    gn._linearize_numpy(S, kappa)
    for a, b in zip(compiled, gn._system):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * np.abs(b).max())


# -- crowded starts: the area continuation and the "stalled" status ------------------------------

@pytest.fixture(scope="module")
def decimated_arm():
    """igl_arm decimated by fast_simplification (70 %): its Tutte start crowds the hand into
    triangles ~1e-10 of their share, from which the direct Gauss–Newton minimization stalls
    with the energy ratio near 95."""
    import fast_simplification

    V, F = load_closed("igl_arm")
    return fast_simplification.simplify(V, F, target_reduction=0.7)


def test_decimated_arm_meets_the_issue_target(decimated_arm):
    V, F = decimated_arm
    r = sphere.spherical_sem(V, F, time_limit=120.0)
    assert r.status == "converged" and r.measures["folded_faces"] == 0
    assert r.measures["face_area_distortion"] <= 0.02
    assert r.measures["energy_ratio"] - 1 <= 1e-3                # the "converged" bound
    assert r.start["energy_ratio"] > 10                           # the crowded start
    assert "continuation" in r.timings
    assert all(h["folded_faces"] == 0 for h in r.history
               if h.get("phase") in ("newton", "continuation"))


def test_a_stalled_minimization_is_not_reported_converged(decimated_arm):
    """Without the continuation the direct minimization stalls far from the bound: the status
    says so (also the hemisphere method's); with a tiny iteration cap it is "max_iter"."""
    V, F = decimated_arm
    r = sphere.spherical_sem(V, F, continuation=0, time_limit=120.0)
    assert r.measures["energy_ratio"] > 2 and r.status == "stalled"
    r = sphere.spherical_sem(V, F, newton_iter=2, continuation=0)
    assert r.status == "max_iter"
    r = sphere.spherical_sem(V, F, method="hemisphere", time_limit=10.0)
    assert r.measures["energy_ratio"] > 2 and r.status != "converged"
    V, F = icosphere(2)
    A2 = sphere.face_double_areas(V * (1 + 0.5 * V[:, :1] ** 2), F)   # R − 1 ≈ 0.02 at V
    # a damping so strong that the steps barely move: a stall, not convergence
    S, status, _ = sphere_newton.minimize(F, A2, V.copy(), mu=1e7, patience=1, restarts=0,
                                          kappas=(0.02,))
    assert status == "stalled" and sphere.energy_ratio(A2, S, F) - 1 > 1e-3
