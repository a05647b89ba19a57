"""Distortion measures of §7.1 (pipeline/geometry/metrics.py) on constructed meshes whose values
are known by hand: D(f) eq. (28), face-based area distortion, local area ratio eq. (29), stretch
energy eq. (15) and its normalized ratio (with its Cauchy–Schwarz bound on random flip-free maps of
a planar disk), flipped faces, angular distortion, and the summary."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import height_field, independent_areas, random_flip_free_maps, require_data
from pipeline.geometry import metrics

# Unit square, two counter-clockwise triangles along the diagonal 0–2.
SQUARE_V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])
ID = SQUARE_V[:, :2].copy()
# Vertex 1 moved to (2, 0): image of face 0 = (0,0),(2,0),(1,1), area 1 = twice |τ0| = ½;
# face 1 unchanged (area ½). |M| = 1, |f(M)| = 3/2.
DOUBLED = np.array([[0.0, 0], [2, 0], [1, 1], [0, 1]])
ATAN_HALF = math.degrees(math.atan(0.5))


def test_signed_double_areas_and_flipped_faces():
    np.testing.assert_array_equal(metrics.signed_double_areas(ID, SQUARE_F), [1.0, 1.0])
    np.testing.assert_array_equal(metrics.signed_double_areas(DOUBLED, SQUARE_F), [2.0, 1.0])
    assert metrics.flipped_faces(ID, SQUARE_F).tolist() == []
    reflected = ID.copy()
    reflected[1] = [-0.5, 0.5]           # vertex 1 across the diagonal: face 0 reflected
    np.testing.assert_array_equal(metrics.signed_double_areas(reflected, SQUARE_F), [-1.0, 1.0])
    assert metrics.flipped_faces(reflected, SQUARE_F).tolist() == [0]
    mirror = ID * [1, -1]                # a reflection of the whole map flips every face
    assert metrics.flipped_faces(mirror, SQUARE_F).tolist() == [0, 1]
    collapsed = ID.copy()
    collapsed[1] = [0.5, 0.5]            # on the diagonal: zero area counts as flipped
    assert metrics.flipped_faces(collapsed, SQUARE_F).tolist() == [0]


def test_doubling_one_triangle_hand_values():
    V, F, uv = SQUARE_V, SQUARE_F, DOUBLED
    # face fractions: surface (½, ½), image (⅔, ⅓)
    assert metrics.face_area_distortion(V, F, uv) == pytest.approx(1 / 3, abs=1e-15)
    # fans: v0 and v2 are in both faces (1 vs 1), v1 only in face 0 (½ vs ⅔), v3 only in face 1
    # (½ vs ⅓): D = ⅓ (0 + 1/6 + 0 + 1/6) = 1/9
    assert metrics.total_area_distortion(V, F, uv) == pytest.approx(1 / 9, abs=1e-15)
    np.testing.assert_allclose(metrics.local_area_ratios(V, F, uv), [1.0, 0.75, 1.0, 1.5],
                               rtol=1e-15)
    # E_S = Σ|f(τ)|²/|τ| = 1²/½ + (½)²/½ = 5/2; ratio = E_S |M| / |f(M)|² = (5/2)/(9/4) = 10/9
    assert metrics.stretch_energy(V, F, uv) == pytest.approx(2.5, rel=1e-15)
    assert metrics.energy_ratio(V, F, uv) == pytest.approx(10 / 9, rel=1e-15)
    # angles: face 0 (45°, 90°, 45°) → (45°, 45°, 90°); face 1 unchanged
    np.testing.assert_allclose(metrics.angular_distortion(V, F, uv), [[0, 45, 45], [0, 0, 0]],
                               atol=1e-12)


def test_measures_are_scale_invariant_and_zero_for_equiareal_maps():
    V, F, uv = SQUARE_V, SQUARE_F, DOUBLED
    Vs, uvs = 7.0 * V + [1, 2, 3], 0.3 * uv + [5, -1]
    assert metrics.total_area_distortion(Vs, F, uvs) == pytest.approx(1 / 9, abs=1e-14)
    assert metrics.face_area_distortion(Vs, F, uvs) == pytest.approx(1 / 3, abs=1e-14)
    np.testing.assert_allclose(metrics.local_area_ratios(Vs, F, uvs), [1.0, 0.75, 1.0, 1.5],
                               rtol=1e-13)
    assert metrics.energy_ratio(Vs, F, uvs) == pytest.approx(10 / 9, rel=1e-13)
    # E_S = Σ|f(τ)|²/|τ|: image areas scale by 0.3², surface areas by 7²
    assert metrics.stretch_energy(Vs, F, uvs) == pytest.approx(2.5 * 0.3**4 / 7**2, rel=1e-13)
    # identity, a scaled map, and a mirror (areas are unsigned) have no area distortion
    for m in (ID, 3.0 * ID, ID * [1, -1]):
        assert metrics.total_area_distortion(V, F, m) == 0.0
        assert metrics.face_area_distortion(V, F, m) == 0.0
        np.testing.assert_array_equal(metrics.local_area_ratios(V, F, m), np.ones(4))
        assert metrics.energy_ratio(V, F, m) == pytest.approx(1.0, abs=1e-15)


def _grid(k=5, seed=0):
    """A k×k vertex grid (triangulated squares) bent into 3D, and a random flip-free map."""
    x, y = np.meshgrid(np.arange(k, dtype=float), np.arange(k, dtype=float))
    P = np.column_stack([x.ravel(), y.ravel()])
    F = []
    for i in range(k - 1):
        for j in range(k - 1):
            a = i * k + j
            F += [[a, a + 1, a + k + 1], [a, a + k + 1, a + k]]
    F = np.asarray(F)
    V = np.column_stack([P, 0.3 * np.sin(P[:, 0]) * P[:, 1]])
    rng = np.random.default_rng(seed)
    uv = P + rng.uniform(-0.2, 0.2, size=P.shape)
    assert len(metrics.flipped_faces(uv, F)) == 0
    return V, F, uv


def test_eq28_eq29_and_face_distortion_against_per_vertex_loops():
    V, F, uv = _grid()
    def tri(X, f):
        X3 = np.column_stack([X, np.zeros(len(X))]) if X.shape[1] == 2 else X
        return 0.5 * np.linalg.norm(np.cross(X3[f[1]] - X3[f[0]], X3[f[2]] - X3[f[0]]))

    A = np.array([tri(V, f) for f in F])
    a = np.array([tri(uv, f) for f in F])
    D, R = 0.0, []
    for v in range(len(V)):
        s = sum(A[t] for t in range(len(F)) if v in F[t]) / A.sum()
        i = sum(a[t] for t in range(len(F)) if v in F[t]) / a.sum()
        D += abs(s - i) / 3
        R.append(s / i)
    assert metrics.total_area_distortion(V, F, uv) == pytest.approx(D, rel=1e-12)
    np.testing.assert_allclose(metrics.local_area_ratios(V, F, uv), R, rtol=1e-12)
    assert metrics.face_area_distortion(V, F, uv) == pytest.approx(
        np.abs(A / A.sum() - a / a.sum()).sum(), rel=1e-12)
    assert metrics.stretch_energy(V, F, uv) == pytest.approx(np.sum(a * a / A), rel=1e-12)
    assert metrics.energy_ratio(V, F, uv) == pytest.approx(
        np.sum(a * a / A) * A.sum() / a.sum() ** 2, rel=1e-12)
    assert metrics.energy_ratio(V, F, uv) > 1.0


def test_angular_distortion_of_a_similarity_is_zero():
    V, F, uv = _grid()
    P = V[:, :2]
    V3 = np.column_stack([P, np.zeros(len(P))])
    c, s = math.cos(0.7), math.sin(0.7)
    sim = 2.5 * P @ np.array([[c, -s], [s, c]]).T + [3.0, -1.0]
    np.testing.assert_allclose(metrics.angular_distortion(V3, F, sim), 0, atol=1e-6)
    # a rigid motion of the surface in 3D does not change its angles either
    Q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    np.testing.assert_allclose(metrics.angular_distortion(V3 @ Q.T, F, sim), 0, atol=1e-6)
    # while a general map has some, and all corner angles of a face sum to 180°
    assert metrics.angular_distortion(V, F, uv).max() > 1.0
    np.testing.assert_allclose(metrics.corner_angles(V, F).sum(axis=1), np.pi, atol=1e-12)
    np.testing.assert_allclose(metrics.corner_angles(uv, F).sum(axis=1), np.pi, atol=1e-12)


def test_angular_distortion_of_a_shear():
    """(x, y) → (x + y, y). Face 0 (0,0),(1,0),(1,1) → (0,0),(1,0),(2,1): angles
    (atan ½, 135°, 45° − atan ½) vs (45°, 90°, 45°); face 1 (0,0),(1,1),(0,1) → (0,0),(2,1),(1,1):
    angles (45° − atan ½, atan ½, 135°) vs (45°, 45°, 90°)."""
    shear = ID @ np.array([[1.0, 1.0], [0.0, 1.0]]).T
    a = ATAN_HALF
    expected = [[45 - a, 45, a], [a, 45 - a, 45]]
    got = metrics.angular_distortion(SQUARE_V, SQUARE_F, shear)
    np.testing.assert_allclose(got, expected, atol=1e-12)
    # a shear preserves areas: no area distortion at all
    assert metrics.total_area_distortion(SQUARE_V, SQUARE_F, shear) == 0.0
    assert metrics.energy_ratio(SQUARE_V, SQUARE_F, shear) == pytest.approx(1.0, abs=1e-15)


SUMMARY_KEYS = {
    "total_area_distortion_eq28", "face_area_distortion", "local_area_ratio_mean",
    "local_area_ratio_sd", "angular_distortion_mean_deg", "angular_distortion_sd_deg",
    "flipped_faces", "boundary_self_crossings", "stretch_energy", "energy_ratio",
    "surface_area", "image_area",
    "anisotropy_median", "anisotropy_p90", "anisotropy_area_above_10",
}  # fmt: skip


def test_distortion_summary_hand_values():
    s = metrics.distortion_summary(SQUARE_V, SQUARE_F, DOUBLED)
    assert set(s) == SUMMARY_KEYS
    R = np.array([1.0, 0.75, 1.0, 1.5])
    ang = np.array([0, 45, 45, 0, 0, 0], dtype=float)
    expected = {
        "total_area_distortion_eq28": 1 / 9, "face_area_distortion": 1 / 3,
        "local_area_ratio_mean": 1.0625,
        "local_area_ratio_sd": float(np.sqrt(np.mean((R - 1.0625) ** 2))),
        "angular_distortion_mean_deg": 15.0, "angular_distortion_sd_deg": float(ang.std()),
        "flipped_faces": 0, "boundary_self_crossings": 0, "stretch_energy": 2.5,
        "energy_ratio": 10 / 9,
        "surface_area": 1.0, "image_area": 1.5,
        # face 1 is mapped identically (K = 1); face 0 by A = [[2, −1], [0, 1]]:
        # AᵀA has eigenvalues 3 ± √5, so K = (3 + √5)/2; equal areas → median 1, p90 K
        "anisotropy_median": 1.0, "anisotropy_p90": (3 + math.sqrt(5)) / 2,
        "anisotropy_area_above_10": 0.0,
    }  # fmt: skip
    for k, v in expected.items():
        assert s[k] == pytest.approx(v, rel=1e-14, abs=1e-14), k
    counts = {"flipped_faces", "boundary_self_crossings"}
    assert all(type(s[k]) is int for k in counts)
    assert all(type(v) is float for k, v in s.items() if k not in counts)
    # the shear: mean angular distortion is exactly (2·45 + 2·atan½ + 2·(45 − atan½))/6 = 30°
    sh = metrics.distortion_summary(SQUARE_V, SQUARE_F, ID @ np.array([[1.0, 1.0], [0.0, 1.0]]).T)
    assert sh["angular_distortion_mean_deg"] == pytest.approx(30.0, abs=1e-12)


def test_distortion_summary_matches_individual_functions_and_ignores_unused_vertices():
    V, F, uv = _grid(seed=3)
    s = metrics.distortion_summary(V, F, uv)
    R = metrics.local_area_ratios(V, F, uv)
    ang = metrics.angular_distortion(V, F, uv)
    assert s["total_area_distortion_eq28"] == metrics.total_area_distortion(V, F, uv)
    assert s["face_area_distortion"] == metrics.face_area_distortion(V, F, uv)
    assert s["local_area_ratio_mean"] == pytest.approx(R.mean(), rel=1e-15)
    assert s["local_area_ratio_sd"] == pytest.approx(R.std(), rel=1e-15)
    assert s["angular_distortion_mean_deg"] == pytest.approx(ang.mean(), rel=1e-15)
    assert s["angular_distortion_sd_deg"] == pytest.approx(ang.std(), rel=1e-15)
    assert s["stretch_energy"] == metrics.stretch_energy(V, F, uv)
    assert s["energy_ratio"] == metrics.energy_ratio(V, F, uv)
    assert s["flipped_faces"] == 0
    for k, v in metrics.anisotropy_summary(V, F, uv).items():
        assert s[k] == v, k
    # an unreferenced vertex has no fan: its ratio is undefined and left out of the statistics
    V2 = np.vstack([V, [[10.0, 10, 10]]])
    uv2 = np.vstack([uv, [[10.0, 10]]])
    R2 = metrics.local_area_ratios(V2, F, uv2)
    assert np.isnan(R2[-1]) and np.array_equal(R2[:-1], R)
    s2 = metrics.distortion_summary(V2, F, uv2)
    for k in SUMMARY_KEYS:
        assert s2[k] == pytest.approx(s[k], rel=1e-14, abs=1e-15), k
    # a map with a reflected face is counted
    uv3 = uv.copy()
    p0, p1, p2 = uv[F[0]]
    d = (p2 - p0) / np.linalg.norm(p2 - p0)
    uv3[F[0, 1]] = p0 + 2 * ((p1 - p0) @ d) * d - (p1 - p0)   # vertex 1 mirrored across edge 0–2
    flipped = metrics.flipped_faces(uv3, F)
    assert 0 in flipped.tolist()
    assert metrics.signed_double_areas(uv3, F)[0] == pytest.approx(
        -metrics.signed_double_areas(uv, F)[0], rel=1e-12)
    assert metrics.distortion_summary(V, F, uv3)["flipped_faces"] == len(flipped)


def test_area_distortions_from_face_areas():
    """``area_distortions`` (used for SEM's history) gives (D eq. 28, face-based) from per-face
    areas at any common scale, signed image areas taken unsigned."""
    V, F, uv = _grid(seed=5)
    A2 = 2 * np.array([0.5 * np.linalg.norm(np.cross(V[f[1]] - V[f[0]], V[f[2]] - V[f[0]]))
                       for f in F])
    a2 = metrics.signed_double_areas(uv, F)
    D, face = metrics.area_distortions(F, len(V), 3.0 * A2, -a2)
    assert D == pytest.approx(metrics.total_area_distortion(V, F, uv), rel=1e-12)
    assert face == pytest.approx(metrics.face_area_distortion(V, F, uv), rel=1e-12)
    frac = metrics.vertex_area_fractions(F, len(V), A2)
    assert frac.sum() == pytest.approx(3.0, rel=1e-14)        # every face counted at 3 corners
    assert metrics.area_distortions(F, len(V), A2, a2, surface_fractions=frac) == pytest.approx(
        (D, face), rel=1e-12)
    D_sq, face_sq = metrics.area_distortions(SQUARE_F, 4, np.array([1.0, 1.0]),
                                             metrics.signed_double_areas(DOUBLED, SQUARE_F))
    assert (D_sq, face_sq) == pytest.approx((1 / 9, 1 / 3), abs=1e-15)


def test_stretch_anisotropy_hand_values():
    # identity, a uniform scaling and a rotation are conformal: K = 1 exactly
    rot = np.array([[0.6, -0.8], [0.8, 0.6]])
    for uv in (ID, 3.0 * ID, ID @ rot.T):
        np.testing.assert_allclose(metrics.stretch_anisotropy(SQUARE_V, SQUARE_F, uv), 1.0,
                                   rtol=0, atol=1e-12)
    # an axis stretch (4, ¼) keeps every area and has K = 16 on both faces
    K = metrics.stretch_anisotropy(SQUARE_V, SQUARE_F, ID * [4.0, 0.25])
    np.testing.assert_allclose(K, 16.0, rtol=1e-13)
    s = metrics.anisotropy_summary(SQUARE_V, SQUARE_F, ID * [4.0, 0.25])
    assert s == {"anisotropy_median": pytest.approx(16.0), "anisotropy_p90": pytest.approx(16.0),
                 "anisotropy_area_above_10": 1.0}
    # the shear [[1, 1], [0, 1]]: eigenvalues of AᵀA (3 ± √5)/2, K = (3 + √5)/2
    shear = ID @ np.array([[1.0, 1.0], [0.0, 1.0]]).T
    np.testing.assert_allclose(metrics.stretch_anisotropy(SQUARE_V, SQUARE_F, shear),
                               (3 + math.sqrt(5)) / 2, rtol=1e-13)
    # a face collapsed on the disk has no finite dilatation
    collapsed = ID.copy()
    collapsed[1] = [0.5, 0.5]
    assert np.isinf(metrics.stretch_anisotropy(SQUARE_V, SQUARE_F, collapsed)[0])


def test_stretch_anisotropy_is_the_singular_value_ratio():
    # a curved surface over a jittered grid, a noisy map with flipped and mirrored faces
    # (both pivot orders of the 2×2 inverse) and the two faces of one edge collapsed (the edge's
    # ends on one point)
    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.linspace(-1, 1, 12), np.linspace(-1, 1, 12))
    P = np.column_stack([x.ravel(), y.ravel()]) + 0.01 * rng.standard_normal((144, 2))
    q = np.arange(144).reshape(12, 12)[:-1, :-1].ravel()
    F = np.vstack([np.column_stack([q, q + 1, q + 13]), np.column_stack([q, q + 13, q + 12])])
    V = height_field(P)
    uv = P @ np.array([[0.3, 1.2], [-0.9, 0.4]]) + 0.08 * rng.standard_normal(P.shape)
    uv[F[5, 2]] = uv[F[5, 1]]
    K = metrics.stretch_anisotropy(V, F, uv)
    E = np.stack([V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]], axis=2)
    D = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)
    ok = np.abs(np.linalg.det(D)) > 1e-12
    s = np.linalg.svd(E[ok] @ np.linalg.inv(D[ok]), compute_uv=False)
    assert (metrics.signed_double_areas(uv, F) < 0).sum() > 10 and not ok[5] and ok.sum() == 240
    np.testing.assert_allclose(K[ok], s[:, 0] / s[:, 1], rtol=1e-9)
    assert np.isinf(K[~ok]).all()


def test_area_weighted_quantile():
    v = np.array([3.0, 1.0, 2.0])
    w = np.array([1.0, 1.0, 2.0])       # ascending: 1 (w 1), 2 (w 2), 3 (w 1); total 4
    assert metrics.area_weighted_quantile(v, w, 0.25) == 1.0
    assert metrics.area_weighted_quantile(v, w, 0.5) == 2.0
    assert metrics.area_weighted_quantile(v, w, 0.75) == 2.0
    assert metrics.area_weighted_quantile(v, w, 0.76) == 3.0
    assert metrics.area_weighted_quantile(v, w, (0.25, 0.5, 0.76)) == [1.0, 2.0, 3.0]


def test_energy_ratio_lower_bound_and_equality_for_affine_maps(ddisk):
    """E_S ≥ |f(M)|²/|M| (Cauchy–Schwarz), equality iff σ is constant; f = A·v of a planar
    mesh has σ = 1/|det A| on every face, so the ratio is exactly 1."""
    P, F, _ = ddisk
    X = height_field(P)
    rng = np.random.default_rng(8)
    for uv in random_flip_free_maps(P, F, rng, k=8):
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


def _circle(n: int) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([np.cos(t), np.sin(t)])


def test_boundary_self_crossings_of_constructed_polygons():
    loop = np.arange(40)
    assert metrics.boundary_self_crossings(_circle(40), loop) == 0
    # two neighbours swapped: the boundary runs backwards over one edge; chords 9→11 and
    # 10→12 of the circle cross, the other pairs stay apart
    swapped = loop[[*range(10), 11, 10, *range(12, 40)]]
    assert metrics.boundary_self_crossings(_circle(40), swapped) == 1
    # a figure eight: one crossing point, where one edge of each lobe meets
    t = 2 * np.pi * (np.arange(41) + 0.5) / 41
    assert metrics.boundary_self_crossings(np.column_stack([np.sin(t), np.sin(2 * t)]),
                                           np.arange(41)) == 1
    # a vertex on a non-adjacent edge (touching), and an overlap on one line, both count
    touch = np.array([[0.0, 0], [2, 0], [2, 1], [1, 0], [0, 1]])
    assert metrics.boundary_self_crossings(touch, np.arange(5)) == 2
    overlap = np.array([[0.0, 0], [3, 0], [3, 1], [2, 0], [1, 0], [1, -1]])
    assert metrics.boundary_self_crossings(overlap, np.arange(6)) == 3     # 0–2, 0–3, 0–4
    # a point that is not finite: its two edges count, no k-d tree is asked
    P = _circle(40)
    P[7] = np.nan
    assert metrics.boundary_self_crossings(P, loop) == 2
    # two long edges next to short ones, each cutting across the arc once: found from the
    # long edges' side (the arc's edges look only as far as their own length)
    P = np.vstack([_circle(200)[:101], [[0.0, 2.0]]])
    assert metrics.boundary_self_crossings(P, np.arange(len(P))) == 2


def _corner_cosines_numpy(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The corner cosines (m×3) by the numpy formula of :func:`metrics.corner_angles`: ``u·v``
    summed x, z, then y (einsum's order), over ``|u| |v|``, the norms summed x, y, then z
    (``np.linalg.norm``'s)."""
    o, p, q = (P[np.roll(F, -s, axis=1)] for s in range(3))
    u, v = p - o, q - o
    dot = (u[..., 0] * v[..., 0] + u[..., 2] * v[..., 2]) + u[..., 1] * v[..., 1]
    norm = [np.sqrt((w[..., 0] * w[..., 0] + w[..., 1] * w[..., 1]) + w[..., 2] * w[..., 2])
            for w in (u, v)]
    with np.errstate(divide="ignore", invalid="ignore"):
        return dot / (norm[0] * norm[1])


def test_corner_cosines_and_face_maxima_are_the_numpy_formula_bit_for_bit():
    """The compiled corner cosines (the edge lengths shared by a face's corners) and each
    face's largest (``np.maximum`` folded over the columns) are the numpy formula's to the bit,
    nan bits too: random faces with right, near-zero and straight angles and coincident
    corners (nan), and the faces of a real mesh."""
    from pipeline.geometry._kernels import corner_cosines, face_max_cosines
    from pipeline.io.meshio import read_mesh

    rng = np.random.default_rng(5)
    V = np.vstack([rng.normal(size=(300, 3)), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0],
                                               [1, 1e-13, 0]]])
    F = np.vstack([rng.integers(0, 300, (2000, 3)),
                   [[300, 301, 302], [300, 301, 303], [300, 304, 301], [300, 300, 301]]])
    lion = read_mesh(require_data("meshes", "igl_lion.obj"))
    for P, T in ((V, F), (lion.V, lion.faces)):
        P = np.ascontiguousarray(P, dtype=np.float64)
        T = np.ascontiguousarray(T, dtype=np.int64)
        want = _corner_cosines_numpy(P, T)
        assert corner_cosines(P, T).tobytes() == want.tobytes()
        folded = np.maximum(np.maximum(want[:, 0], want[:, 1]), want[:, 2])   # (row_max's)
        assert face_max_cosines(P, T).tobytes() == folded.tobytes()
    assert not np.isnan(want).any() and np.isnan(_corner_cosines_numpy(V, F)[-1]).any()


def test_min_corner_angles_are_the_row_minima_of_the_corner_angles_bit_for_bit():
    """The smallest angle of each face, taken from its largest cosine, is the row minimum of
    :func:`metrics.corner_angles` to the bit, in 3D and 2D, for faces with a right angle, a
    near-zero angle, a straight angle and coincident corners (nan, of either sign)."""
    rng = np.random.default_rng(3)
    V = np.vstack([rng.normal(size=(300, 3)), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0],
                                               [1, 1e-13, 0]]])
    F = np.vstack([rng.integers(0, 300, (2000, 3)),
                   [[300, 301, 302], [300, 301, 303], [300, 304, 301], [300, 300, 301]]])
    for P in (V, V[:, :2]):
        got = metrics.min_corner_angles(P, F)
        want = metrics.corner_angles(P, F).min(axis=1)
        assert np.array_equal(np.isnan(got), np.isnan(want))
        real = ~np.isnan(want)
        assert got[real].tobytes() == want[real].tobytes()
    assert np.isnan(got[-1]) and got[-4] == metrics.corner_angles(V, F)[-4].min()


def test_min_corner_angles_below_are_those_of_all_faces_bit_for_bit():
    """:func:`metrics.min_corner_angles_below` keeps every face whose smallest angle is below
    the limit (none with a nan angle) and few others, with :func:`metrics.min_corner_angles`'
    values to the bit: compared in radians or in degrees after it, the faces below and their
    angles are those of all faces — at limits with faces at a hair above and below them."""
    rng = np.random.default_rng(31)
    V = np.vstack([rng.normal(size=(300, 3)), [[0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    F = np.vstack([rng.integers(0, 300, (3000, 3)), [[300, 300, 301], [300, 301, 302]]])
    every = metrics.min_corner_angles(V, F)
    finite = np.sort(every[np.isfinite(every)])
    limits = [np.radians(20.0), np.radians(45.0), finite[100], np.nextafter(finite[200], 0.0),
              np.nextafter(finite[300], 1.0), 0.0]
    for limit in limits:
        faces, angles = metrics.min_corner_angles_below(V, F, limit)
        assert angles.tobytes() == every[faces].tobytes()
        assert np.array_equal(faces[angles < limit], np.flatnonzero(every < limit))
        deg = np.degrees(limit)
        assert np.array_equal(faces[np.degrees(angles) < deg],
                              np.flatnonzero(np.degrees(every) < deg))
        assert len(faces) <= (every < limit).sum() + 5
    assert 3000 not in metrics.min_corner_angles_below(V, F, np.pi)[0]      # nan: never
