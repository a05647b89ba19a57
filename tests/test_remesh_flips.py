"""Delaunay flips on the lifted surface (pipeline.geometry.remesh.flips)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.flips import flip_edges
from pipeline.geometry.remesh_quality import is_disk, mesh_facts


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
    F, flips, rounds = flip_edges(X, F0, uv, max_rounds=500)
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
    full, k_full, _ = flip_edges(X, F0, uv, max_rounds=500)
    twin = interior_edge_twins(F0)
    F1, k1, _ = flip_edges(X, F0, uv, max_rounds=500, active=np.ones(len(uv), bool),
                               twin=twin)
    assert k1 == k_full > 100 and np.array_equal(F1, full)
    assert np.array_equal(twin, interior_edge_twins(F1))
    F2, k2, _ = flip_edges(X, F0, uv, active=np.zeros(len(uv), bool))
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
    F3, k3, _ = flip_edges(X, Fs, uv, active=active)
    assert k3 == 1
    assert {tuple(sorted(t)) for t in F3.tolist()} == {tuple(sorted(t)) for t in F_D.tolist()}


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
    F0, _, _ = flip_edges(X, F, uv)
    assert _has_edge(F0, a, b) and not _has_edge(F0, p, q)       # held by the dihedral limit

    def sag(new_closer):
        def measure(i, j):
            pq = np.isin(i, [p, q]) & np.isin(j, [p, q])
            return np.where(pq, 0.01 if new_closer else 0.09, 0.05)
        return measure

    F1, _, _ = flip_edges(X, F, uv, sag=sag(True))
    assert _has_edge(F1, p, q) and not _has_edge(F1, a, b)
    assert np.all(signed_double_areas(uv, F1) > 0) and is_disk(mesh_facts(X, F1))
    F2, _, _ = flip_edges(X, F, uv, sag=sag(False))
    assert _has_edge(F2, a, b) and not _has_edge(F2, p, q)


def test_valence_flips_undo_a_flip_in_a_regular_lattice():
    """An equilateral lattice on a hexagon (every interior vertex of valence 6) with one
    interior edge flipped (two vertices of valence 5, two of 7; faces of 30°): the valence
    flips flip it back, and only it — the result is the lattice again."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh.flips import valence_flips
    from remesh_helpers import ccw_delaunay

    ij = np.array([(i, j) for i in range(-4, 5) for j in range(-4, 5) if abs(i + j) <= 4])
    uv = np.column_stack([ij[:, 0] + 0.5 * ij[:, 1], np.sqrt(3) / 2 * ij[:, 1]])
    F0 = ccw_delaunay(uv)
    X = np.column_stack([uv, np.zeros(len(uv))])
    rim = topo.boundary_vertices_mask(F0, len(uv))
    twin = topo.interior_edge_twins(F0)
    h = next(h for h in range(3 * len(F0)) if twin[h] > h
             and not rim[F0[h // 3]].any() and not rim[F0[twin[h] // 3]].any())
    f, c, g, d = h // 3, h % 3, twin[h] // 3, twin[h] % 3
    a, b, p, q = F0[f, c], F0[f, (c + 1) % 3], F0[f, (c + 2) % 3], F0[g, (d + 2) % 3]
    F1 = F0.copy()
    F1[f], F1[g] = [p, a, q], [q, b, p]
    assert sorted(np.bincount(F1.ravel())[[a, b, p, q]]) == [5, 5, 7, 7]
    assert np.degrees(corner_angles(X, F1)).min() < 31
    F2, flips = valence_flips(X, F1, uv, rim)
    assert flips == 1
    assert {tuple(sorted(t)) for t in F2.tolist()} == {tuple(sorted(t)) for t in F0.tolist()}
    assert np.all(signed_double_areas(uv, F2) > 0)


def test_valence_flips_keep_the_twins():
    """A jittered disk triangulated with every third interior edge flipped where it can be
    (valences off 6): the twins given to :func:`valence_flips`, updated in place over its
    rounds, are those of the faces it returns, after many flips."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh.flips import valence_flips
    from remesh_helpers import ccw_delaunay, disk_points

    uv = disk_points(12, 6)
    inner = np.linalg.norm(uv, axis=1) < 1 - 1e-9
    uv[inner] += 0.02 * np.random.default_rng(2).uniform(-1, 1, (inner.sum(), 2))
    F = ccw_delaunay(uv)
    X = np.column_stack([uv, np.zeros(len(uv))])
    rim = topo.boundary_vertices_mask(F, len(uv))
    F, _ = valence_flips(X, F, uv, rim, min_angle_deg=0.0, max_rounds=1)   # a valid start
    twin = topo.interior_edge_twins(F)
    F2, flips = valence_flips(X, F, uv, rim, min_angle_deg=0.0, max_rounds=3, twin=twin)
    assert flips > 0
    assert np.array_equal(twin, topo.interior_edge_twins(F2))


def test_compiled_valence_gains_are_the_numpy_formula():
    """The valence flips' candidates (every interior edge once, ``twin > h``) and their gains
    ``2 (dev[a] + dev[b] − dev[p] − dev[q]) − 4``, the positive ones, are those of the numpy
    formula over a jittered disk with valences off 6 (rim vertices' target 4)."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry._kernels import valence_gains
    from remesh_helpers import ccw_delaunay, disk_points

    uv = disk_points(10, 6)
    inner = np.linalg.norm(uv, axis=1) < 1 - 1e-9
    uv[inner] += 0.05 * np.random.default_rng(4).uniform(-1, 1, (inner.sum(), 2))
    F = ccw_delaunay(uv).astype(np.int64)
    rim = topo.boundary_vertices_mask(F, len(uv))
    twin = topo.interior_edge_twins(F)
    dev = np.bincount(F.ravel(), minlength=len(uv)) - np.where(rim, 4, 6)
    h = np.flatnonzero(twin > np.arange(3 * len(F)))
    f, c, t = h // 3, h % 3, twin[h]
    gain = 2 * (dev[F[f, c]] + dev[F[f, (c + 1) % 3]] - dev[F[f, (c + 2) % 3]]
                - dev[F[t // 3, (t % 3 + 2) % 3]]) - 4
    got_h, got_gain = valence_gains(F, twin, dev)
    assert np.array_equal(got_h, h[gain > 0]) and np.array_equal(got_gain, gain[gain > 0])
    assert 0 < len(got_h) < len(h)


def _roof_quad():
    """A quad ``a, b, p, q`` inside a square ring on the roof ``z = 1 − |x|`` (its ridge on
    ``x = 0``, the disk the plane ``(x, y)``): ``p–q`` lies on the ridge, ``a–b`` crosses
    it a whole unit below the ridge, and the angles opposite ``a–b`` (70.5° each) make it
    Delaunay. Returns the corners' indices, ``uv``, ``X``, ``F`` and the exact sag of an
    edge (the largest height of the roof above or below it at 33 points)."""
    a, b, p, q, T1, T2, B1, B2 = range(8)
    uv = np.array([[-1.0, 0], [1, 0], [0, 1], [0, -1], [-2, 2], [2, 2], [-2, -2], [2, -2]])
    F = np.array([[a, b, p], [b, a, q], [a, p, T1], [p, T2, T1], [p, b, T2], [a, T1, B1],
                  [a, B1, q], [q, B1, B2], [q, B2, b], [b, B2, T2]])
    X = np.column_stack([uv, 1 - np.abs(uv[:, 0])])

    def sag(i, j):
        t = np.linspace(0, 1, 33)[None, :, None]
        M = (1 - t) * X[np.asarray(i)][:, None] + t * X[np.asarray(j)][:, None]
        return np.abs(1 - np.abs(M[..., 0]) - M[..., 2]).max(axis=1)

    return (a, b, p, q), uv, X, F, sag


def test_sag_flips_turn_an_edge_across_a_crease_onto_it():
    """On the roof quad the Delaunay flips keep ``a–b``, a unit below the ridge; the sag flips
    turn it into ``p–q`` on the ridge (the faces still counter-clockwise on the disk, the
    twins given updated in place), and keep it below a threshold of the sag, on a fixed
    edge or where a screen says it cannot be farther than the threshold."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh.flips import sag_flips

    (a, b, p, q), uv, X, F, sag = _roof_quad()
    assert np.all(signed_double_areas(uv, F) > 0)
    assert np.allclose(sag([a, p], [b, q]), [1.0, 0.0])
    rim = topo.boundary_vertices_mask(F, len(uv))
    F0, _, _ = flip_edges(X, F, uv)
    assert _has_edge(F0, a, b)
    twin = topo.interior_edge_twins(F)
    F1, flips = sag_flips(X, F, uv, rim, sag, 0.5, 20.0, twin=twin)
    assert flips == 1 and _has_edge(F1, p, q) and not _has_edge(F1, a, b)
    assert np.all(signed_double_areas(uv, F1) > 0) and is_disk(mesh_facts(X, F1))
    assert np.array_equal(twin, topo.interior_edge_twins(F1))
    assert sag_flips(X, F, uv, rim, sag, 1.5, 20.0)[1] == 0
    assert sag_flips(X, F, uv, rim, sag, 0.5, 20.0,
                     fixed=lambda i, j: np.ones(len(i), bool))[1] == 0
    assert sag_flips(X, F, uv, rim, sag, 0.5, 20.0,
                     screen=lambda i, j: np.zeros(len(i), bool))[1] == 0
    assert sag_flips(X, F, uv, rim, sag, 0.5, 20.0,
                     screen=lambda i, j: np.ones(len(i), bool))[1] == 1


def test_sag_flips_make_no_face_below_the_floor():
    """The roof quad with ``q`` moved out to ``y = −8``: ``p–q`` would still lie on the ridge,
    but the new faces would have 10° angles at ``q`` (the old faces' smallest is 14°): under a
    12° floor it stays, with no floor it flips."""
    from pipeline.geometry import topology as topo
    from pipeline.geometry.remesh.flips import sag_flips

    (a, b, p, q), uv, X, F, sag = _roof_quad()
    uv[q], X[q] = [0, -8], [0, -8, 1]
    uv[6:, 1] = X[6:, 1] = -9
    assert np.all(signed_double_areas(uv, F) > 0)
    rim = topo.boundary_vertices_mask(F, len(uv))
    assert sag_flips(X, F, uv, rim, sag, 0.5, 12.0)[1] == 0
    assert sag_flips(X, F, uv, rim, sag, 0.5, 0.0)[1] == 1
