"""Tangential relaxation with the area-equalising step (pipeline.geometry.remesh.relax)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry.laplacian import face_double_areas
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.relax import AREA_SHARE, area_equalizing_steps, tangential_smoothing
from remesh_helpers import ccw_delaunay, disk_map, disk_points


def reference_steps(X, F, mov, D, mu):
    """:func:`area_equalizing_steps` in numpy, term for term as its docstring states it."""
    n = len(X)
    P = X[F]
    nf = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    A = 0.5 * np.linalg.norm(nf, axis=1)
    nf /= 2 * A[:, None]
    corners = F.T.ravel()
    mean = np.bincount(corners, np.tile(A, 3), n) / np.bincount(corners, minlength=n)
    g = np.concatenate([0.5 * np.cross(nf, P[:, (c + 2) % 3] - P[:, (c + 1) % 3])
                        for c in range(3)]) / mean[corners, None]
    r = AREA_SHARE * (np.tile(A, 3) / mean[corners] - 1.0)
    out = []
    for i, v in enumerate(mov):
        k = corners == v
        H = g[k].T @ g[k]
        beta = mu * np.trace(H) / 2
        out.append(np.linalg.solve(H + beta * np.eye(3), beta * D[i] - g[k].T @ r[k]))
    return np.array(out)


def jittered_disk(seed=0, amount=0.3):
    """A flat disk of 7 rings, its interior points jittered by ``amount`` of the spacing:
    ``(uv, F, interior)``."""
    uv = disk_points(7, 6)
    interior = np.linalg.norm(uv, axis=1) < 1 - 1e-9
    rng = np.random.default_rng(seed)
    uv[interior] += amount / 7 * rng.uniform(-1, 1, (interior.sum(), 2))
    return uv, ccw_delaunay(uv), interior


def test_the_compiled_steps_are_the_formula():
    uv, F, interior = jittered_disk()
    X = np.column_stack([uv, 0.3 * np.sin(3 * uv[:, 0]) * uv[:, 1]])     # a curved sheet
    mov = np.flatnonzero(interior)
    D = np.random.default_rng(1).normal(scale=0.01, size=(len(mov), 3))
    for mu in (0.1, 0.3, 5.0):
        assert np.allclose(area_equalizing_steps(X, F, mov, D, mu),
                           reference_steps(X, F, mov, D, mu), rtol=1e-9, atol=1e-12)


def test_large_mu_is_the_centroid_step():
    uv, F, interior = jittered_disk()
    X = np.column_stack([uv, np.zeros(len(uv))])
    mov = np.flatnonzero(interior)
    D = np.random.default_rng(2).normal(scale=0.01, size=(len(mov), 3))
    assert np.allclose(area_equalizing_steps(X, F, mov, D, 1e9), D, atol=1e-9)


def area_cv(X, F):
    A = face_double_areas(X, F)
    return A.std() / A.mean()


def test_equalizing_evens_out_a_jittered_disk_and_keeps_its_angles():
    """On a flat disk, rings of points jittered by 0.35 of their spacing (area CV 0.35, an
    angle of 13°) relaxed 6 full steps: by the centroid step alone to an area CV of 0.12,
    with the area term (μ = 0.3) below 0.08; every face counter-clockwise, no angle below
    30°, the rim kept."""
    uv_in, F_in, V_in, _, locator = disk_map()
    uv, F, interior = jittered_disk(amount=0.35)
    face, bary = locator.locate(uv)
    X0 = np.column_stack([uv, np.zeros(len(uv))])
    assert area_cv(X0, F) > 0.3
    cv = {}
    for mu in (None, 0.3):
        uv2, _, _, X, moved = tangential_smoothing(V_in, F_in, uv_in, locator, uv, F, face, bary,
                                                   interior, 6, 1.0, equalize=mu)
        assert min(moved) > 0 and np.all(signed_double_areas(uv2, F) > 0)
        assert np.array_equal(uv2[~interior], uv[~interior])
        cv[mu] = area_cv(X, F)
        assert np.degrees(corner_angles(X, F)).min() > 30
    assert cv[None] > 0.1 and cv[0.3] < 0.08


def test_halve_thin_moves_is_the_retest_of_every_moving_face():
    """Random moves of a jittered disk's interior, large enough that many faces would fold:
    the moves halved by :func:`halve_thin_moves` (re-testing only the faces at a halved move)
    are bit for bit those of re-testing every face with a moving corner after each halving,
    and some were halved, some dropped (those of a face too thin whatever they are), some
    kept whole."""
    from pipeline.geometry.remesh.halfedge import double_areas
    from pipeline.geometry.remesh.relax import _too_thin, halve_thin_moves
    from pipeline.geometry.rows import nonzero_rows

    uv, F, interior = jittered_disk(seed=3)
    area_floor = 1e-6 * double_areas(uv, F)
    area_floor[np.flatnonzero(interior[F].all(axis=1))[0]] = np.inf   # too thin at any move
    rng = np.random.default_rng(1)
    du = np.zeros_like(uv)
    du[interior] = 0.25 * rng.normal(size=(interior.sum(), 2)) / 7
    want = du.copy()
    for halving in range(7):
        bad = _too_thin(uv + want, F, area_floor, nonzero_rows(want))
        if len(bad) == 0:
            break
        want[np.unique(F[bad].ravel())] *= 0.0 if halving == 6 else 0.5
    got = du.copy()
    halve_thin_moves(uv, got, F, area_floor)
    assert np.array_equal(got, want)
    kept = np.all(got == du, axis=1) & interior
    dropped = np.all(got == 0, axis=1) & interior
    assert kept.sum() > 10 and dropped.sum() > 0 and (~kept & ~dropped & interior).sum() > 0


def test_compiled_centroid_and_tangential_steps_are_the_numpy_formulas():
    """The relaxation's compiled steps are bit for bit their numpy formulas: the step to the
    ring's centroid ``G/max(W, 1e-300) − X`` and its part across the unit normal
    ``D − (D·n) n`` with ``n = N/max(|N|, 1e-300)``, including rows with no faces (W = 0,
    N = 0)."""
    from pipeline.geometry._kernels import centroid_steps, tangential_parts
    from pipeline.geometry.rows import norms

    rng = np.random.default_rng(9)
    X, G, N = (rng.normal(size=(400, 3)) for _ in range(3))
    W = rng.random(400)
    W[:5], N[:5], G[:5] = 0.0, 0.0, 0.0
    mov = np.r_[0:5, rng.choice(np.arange(5, 400), 200, replace=False)]
    D = centroid_steps(G, W, X, mov)
    want = G[mov] / np.maximum(W[mov], 1e-300)[:, None] - X[mov]
    assert np.array_equal(D, want)
    n = N / np.maximum(norms(N)[:, None], 1e-300)
    want -= np.einsum("ij,ij->i", want, n[mov])[:, None] * n[mov]
    tangential_parts(D, N, mov)
    assert np.array_equal(D, want)


@pytest.mark.parametrize("rows", [2, 3])
def test_compiled_pulled_back_steps_are_the_einsum(rows):
    """``du[mov] = step · einsum("kij,kj->ki", J[face[mov]], D)`` bit for bit (the disk's 2×3
    and the sphere's 3×3 pull-backs), the other rows untouched."""
    from pipeline.geometry._kernels import pulled_back_steps

    rng = np.random.default_rng(10)
    J = rng.normal(size=(300, rows, 3)) * 10.0 ** rng.integers(-4, 4, (300, 1, 1))
    face = rng.integers(0, 300, 500)
    mov = np.sort(rng.choice(500, 350, replace=False))
    D = rng.normal(size=(350, 3))
    want = np.full((500, rows), 7.0)
    want[mov] = 0.75 * np.einsum("kij,kj->ki", J[face[mov]], D)
    got = np.full((500, rows), 7.0)
    pulled_back_steps(J, face, mov, D, 0.75, got)
    assert np.array_equal(got, want)


def test_compiled_disk_double_areas_are_the_cross_product():
    """:func:`.halfedge.double_areas` on the disk is bit for bit the numpy 2D cross product
    ``(u1 − u0)(v2 − v0) − (v1 − v0)(u2 − u0)`` (positions over six orders of magnitude, both
    orientations, a repeated corner), and for a counter-clockwise unit right triangle 1 exactly;
    int32 and non-contiguous faces give the same values."""
    from pipeline.geometry.remesh.halfedge import double_areas

    rng = np.random.default_rng(11)
    uv = rng.normal(size=(500, 2)) * 10.0 ** rng.integers(-3, 3, (500, 1))
    F = rng.integers(0, 500, (900, 3))
    F[0] = [4, 4, 9]
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    want = ((uv[b, 0] - uv[a, 0]) * (uv[c, 1] - uv[a, 1])
            - (uv[b, 1] - uv[a, 1]) * (uv[c, 0] - uv[a, 0]))
    got = double_areas(uv, F)
    assert np.array_equal(got, want) and got[0] == 0.0 and (got > 0).any() and (got < 0).any()
    assert np.array_equal(double_areas(uv, F.astype(np.int32)), want)
    assert np.array_equal(double_areas(uv, F[::-1][::-1]), want)
    assert np.array_equal(double_areas(uv, np.asfortranarray(F)), want)
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert double_areas(tri, np.array([[0, 1, 2]])).tolist() == [1.0]
    assert double_areas(tri, np.zeros((0, 3), np.int64)).shape == (0,)


def test_put_rows_is_the_fancy_assignment():
    """``put_rows(dst, rows, src)`` leaves ``dst`` as ``dst[rows] = src`` does, bit for bit
    (2 and 3 columns, rows in any order, none), the rows outside untouched; a row out of
    range or a src of the wrong shape is refused before anything is written."""
    from pipeline.geometry._kernels import put_rows

    rng = np.random.default_rng(12)
    for d in (2, 3):
        dst = rng.normal(size=(300, d))
        rows = rng.permutation(300)[:120]
        src = rng.normal(size=(120, d)) * 1e-300
        want = dst.copy()
        want[rows] = src
        put_rows(dst, rows, src)
        assert dst.tobytes() == want.tobytes()
        put_rows(dst, rows[:0], src[:0])
        assert dst.tobytes() == want.tobytes()
    with pytest.raises(IndexError):
        put_rows(dst, np.array([0, 300]), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        put_rows(dst, np.array([0, 1]), np.zeros((2, 2)))
    assert dst.tobytes() == want.tobytes()
