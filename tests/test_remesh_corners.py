"""Sharp input corners keep a vertex (pipeline.geometry.remesh.corners)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry.locate import PointLocator, _closest_on_segments
from pipeline.geometry.metrics import signed_double_areas
from pipeline.geometry.remesh.corners import NEAR_DIRECT, _kept_apart, insert_vertices, nearest_rows
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import coarse_state, disk_map


def test_insert_vertices_puts_locked_vertices_exactly_on_targets_inside_and_beyond_the_rim():
    """A flat unit disk (the image polygon: 240 points on the circle) remeshed coarsely with
    its rim on every 10th polygon point. Targets: inside a face, a second in the same face (it
    waits a round), and one between a rim chord and the polygon — beyond the remesh, where
    only a rim split (its vertex on the polygon) brings it inside. Each gets a locked vertex
    exactly there, and the result is still a counter-clockwise disk."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    S, ring = coarse_state(uv_in, F_in, V_in, loop, locator, 3)
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


def test_kept_apart_is_the_greedy_pass_over_every_pair():
    """The KD-tree pass keeps exactly what comparing each point with every kept one keeps
    (a pair exactly ``gap`` apart counts as apart), on clustered points with exact ties."""
    rng = np.random.default_rng(5)
    P = np.vstack([rng.random((300, 3)), rng.random((200, 3)) * 0.05,
                   [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.2, 0.0, 0.0]]])
    for gap in (0.0, 0.01, 0.1, 0.3):
        kept_pts, expected = [], []
        for p in P:
            ok = all(np.linalg.norm(p - q) >= gap for q in kept_pts)
            expected.append(ok)
            if ok:
                kept_pts.append(p)
        assert np.array_equal(_kept_apart(P, gap), expected)


def test_nearest_rows_are_the_trees_and_ties_go_to_the_tree():
    """For a few points, the rows nearest by all the distances are the KD-tree's, in its
    order (random points, k from 1 to all rows); a point with tied distances (the centre of a
    lattice square, four rows equally near) gets the tree's answer too; many points go to the
    tree."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(4)
    P = rng.uniform(-1.0, 1.0, (3000, 2))
    T = rng.uniform(-1.1, 1.1, (NEAR_DIRECT, 2))
    for k in (1, 4, 24, len(P)):
        want = np.asarray(cKDTree(P).query(T, k=k)[1]).reshape(len(T), k)
        assert np.array_equal(nearest_rows(P, T, k), want)
    g = np.arange(20.0)
    lattice = np.column_stack([np.repeat(g, 20), np.tile(g, 20)])
    centre = np.array([[4.5, 7.5]])
    d = np.sort(np.linalg.norm(lattice - centre, axis=1))
    assert d[0] == d[3] < d[4]                                  # four equally near rows
    for k in (2, 4):
        want = cKDTree(lattice).query(centre, k=k)[1]
        assert np.array_equal(nearest_rows(lattice, centre, k), want)
    many = rng.uniform(-1.0, 1.0, (NEAR_DIRECT + 1, 2))
    assert np.array_equal(nearest_rows(P, many, 3), cKDTree(P).query(many, k=3)[1])


def test_interior_landmarks_keep_the_order_once_each_and_leave_the_rim_out():
    from pipeline.geometry.remesh.uniform import interior_landmarks

    got = interior_landmarks({"a": 7, "b": 3, "c": 7, "d": 0, "e": 9, "f": 3}, np.array([0, 9, 4]))
    assert got.dtype == np.int64 and got.tolist() == [7, 3]
    assert interior_landmarks(None, np.array([0, 1])).tolist() == []
    assert interior_landmarks({}, []).tolist() == []
