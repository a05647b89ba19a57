"""Tangential relaxation with the area-equalising step (pipeline.geometry.remesh.relax)."""

from __future__ import annotations

import numpy as np

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


def uneven_rim_state():
    """The flat unit disk map (:func:`remesh_helpers.disk_map`) remeshed by rings of points
    inside radius 0.85 and a rim of 24 of its 240 boundary points taken alternately 6 and 14
    apart: ``S`` (a :class:`RemeshState`) and the rim vertices in order."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.locate import lift
    from pipeline.geometry.remesh.state import RemeshState

    uv_in, F_in, V_in, loop, locator = disk_map()
    picks = np.cumsum(np.tile([6, 14], 12)) % len(loop)
    uv = np.vstack([0.85 * disk_points(3, 6), uv_in[loop[picks]]])
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, topo.boundary_vertices_mask(F, len(uv)),
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
    return S


def rim_edge_lengths(S):
    from pipeline.geometry.remesh.halfedge import edge_table

    _, a, b, twin = edge_table(S.F, twin=S.twins())
    return np.linalg.norm(S.X[a[twin < 0]] - S.X[b[twin < 0]], axis=1)


def test_rim_slides_even_out_the_rim_spacing_on_the_boundary():
    """Rim edges alternately 6 and 14 boundary steps long (ratio 2.3) slid 12 half steps
    along the boundary: the longest at most 1.1 × the shortest, every rim vertex still on the
    input's boundary (the unit circle's 240-gon), every face counter-clockwise on the disk."""
    from pipeline.geometry.remesh.relax import slide_rim

    S = uneven_rim_state()
    d = rim_edge_lengths(S)
    assert d.max() / d.min() > 2.0
    for _ in range(12):
        assert slide_rim(S, S.is_rim.copy(), 0.5, None) > 0
    d = rim_edge_lengths(S)
    assert d.max() / d.min() < 1.1
    r = np.linalg.norm(S.X[S.is_rim, :2], axis=1)
    assert r.min() > np.cos(np.pi / 240) - 1e-9 and r.max() < 1 + 1e-9
    assert np.allclose(S.X[:, 2], 0)
    assert (signed_double_areas(S.uv, S.F) > 0).all()


def test_rim_slides_never_cut_off_more_of_the_boundary():
    """No rim edge leaves a boundary vertex farther from its chord than the gap tolerance
    (here the median gap of the uneven rim) and than it did (:func:`.rim.rim_gaps`); the
    vertices not ``movable`` stay; with a tolerance of 0 on the circle nothing moves (every
    move lengthens an edge, which cuts off more of the circle)."""
    from pipeline.geometry.remesh.relax import rim_arc, slide_rim
    from pipeline.geometry.remesh.rim import rim_gaps
    from pipeline.geometry.remesh.sampling import arc_parameters

    S = uneven_rim_state()
    corners_X = S.of_input(rim_arc)[0]
    corner_s = arc_parameters(S.polygon, S.polygon)
    movable = S.is_rim.copy()
    movable[np.flatnonzero(S.is_rim)[::3]] = False
    X0 = S.X.copy()
    before = rim_gaps(S, corners_X, corner_s)[4]
    assert slide_rim(S, movable, 0.5, 0.0) == 0
    tol = float(np.median(before))
    assert slide_rim(S, movable, 0.5, tol) > 0
    after = rim_gaps(S, corners_X, corner_s)[4]
    assert (after <= np.maximum(before, tol) + 1e-12).all()
    assert (after > before + 1e-9).any()
    assert np.array_equal(S.X[~movable], X0[~movable])
