"""Topology helpers and mesh intake repair: exact facts on small constructed meshes, plus the
shared real meshes (skipped when the data folder is missing)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from conftest import require_data

from pipeline.errors import UserError
from pipeline.geometry import repair, topology as topo
from pipeline.geometry.repair import (RepairOptions, has_interior_neighbour, repair_mesh,
                                     zero_area_mask)
from pipeline.io.meshio import read_mesh

# --------------------------------------------------------------------------------------------
# constructed meshes


def grid(k: int = 4, alternate: bool = True):
    """Planar (k+1)×(k+1) grid in z = 0 with counterclockwise faces.

    ``alternate`` alternates the square diagonals so that no corner triangle has all three
    vertices on the boundary (k even); otherwise every square is cut the same way, which leaves
    exactly two leaf faces (at corners (k, 0) and (0, k)).
    """
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="xy")
    V = np.stack([i.ravel(), j.ravel(), np.zeros(i.size)], axis=1).astype(float)
    F = []
    for jj in range(k):
        for ii in range(k):
            a, b = jj * (k + 1) + ii, jj * (k + 1) + ii + 1
            c, d = b + k + 1, a + k + 1
            if alternate and (ii + jj) % 2:
                F += [[a, b, d], [b, c, d]]
            else:
                F += [[a, b, c], [a, c, d]]
    return V, np.array(F, dtype=np.int64)


def fan_disk(k: int = 8):
    """Centre vertex 0 and a ring of k vertices, counterclockwise faces."""
    t = 2 * np.pi * np.arange(k) / k
    V = np.vstack([[0, 0, 0], np.stack([np.cos(t), np.sin(t), np.zeros(k)], axis=1)])
    F = np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)], dtype=np.int64)
    return V, F


def signed_area_xy(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def face_areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def tetrahedron():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return V, F


def octahedron():
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    px, nx, py, ny, pz, nz = range(6)
    F = np.array([[px, py, pz], [py, nx, pz], [nx, ny, pz], [ny, px, pz],
                  [py, px, nz], [nx, py, nz], [ny, nx, nz], [px, ny, nz]])
    return V, F


def torus(k: int = 6):
    """Periodic k×k grid on a torus (closed, genus 1)."""
    u, v = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a, b = 2 * np.pi * u.ravel() / k, 2 * np.pi * v.ravel() / k
    V = np.stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)], axis=1)
    idx = lambda i, j: (i % k) * k + (j % k)  # noqa: E731
    F = []
    for i in range(k):
        for j in range(k):
            F += [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)],
                  [idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]]
    return V, np.array(F)


def mobius(k: int = 8):
    """Triangulated Möbius strip (non-orientable)."""
    V, F = [], []
    for i in range(k):
        t = 2 * np.pi * i / k
        for s in (-1, 1):
            w = 0.3 * s
            V.append([(1 + w * np.cos(t / 2)) * np.cos(t), (1 + w * np.cos(t / 2)) * np.sin(t),
                      w * np.sin(t / 2)])
    for i in range(k):
        a0, a1 = 2 * i, 2 * i + 1
        if i < k - 1:
            b0, b1 = 2 * i + 2, 2 * i + 3
        else:                                    # the half twist swaps the two sides
            b0, b1 = 1, 0
        F += [[a0, b0, b1], [a0, b1, a1]]
    return np.array(V), np.array(F)


def is_disk(r) -> bool:
    loops = topo.boundary_loops(r.F, r.V)
    is_b = topo.boundary_vertices_mask(r.F, len(r.V))
    return (
        len(loops) == 1
        and topo.euler_characteristic(r.F, len(r.V)) == 1
        and topo.connected_components(r.F, len(r.V))[0] == 1
        and len(topo.leaf_faces(r.F, is_b)) == 0
        and np.array_equal(loops[0], r.boundary)
    )


# --------------------------------------------------------------------------------------------
# topology


def test_edges_with_faces_two_triangles():
    F = np.array([[0, 1, 2], [0, 2, 3]])
    E, counts = topo.edges_with_faces(F)
    assert E.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    assert counts.tolist() == [1, 2, 1, 1, 1]
    assert sorted(map(tuple, topo.boundary_edges(F).tolist())) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    assert topo.nonmanifold_edges(F).shape == (0, 2)


def test_kept_edge_groups_follow_faces_changed_in_place():
    """Inside ``kept_edge_groups`` the groups of the last face array are reused, but not for
    different faces, even the same array changed in place; what callers keep is theirs to
    change; nothing is kept after the block."""
    F = np.array([[0, 1, 2], [2, 1, 3]])
    with topo.kept_edge_groups():
        E, counts = topo.edges_with_faces(F)
        counts[:] = 7
        np.testing.assert_array_equal(topo.edges_with_faces(F)[1], [1, 1, 2, 1, 1])
        assert topo._halfedge_groups(F) is topo._halfedge_groups(F.copy())
        F[1] = [2, 3, 4]
        E, counts = topo.edges_with_faces(F)
        np.testing.assert_array_equal(E, [[0, 1], [0, 2], [1, 2], [2, 3], [2, 4], [3, 4]])
        np.testing.assert_array_equal(counts, [1, 1, 1, 1, 1, 1])
        assert topo.euler_characteristic(F, 5) == 5 - 6 + 2
        assert not any(a.flags.writeable for a in topo._halfedge_groups(F))
    assert topo._halfedge_groups(F) is not topo._halfedge_groups(F)


def test_boundary_loop_of_grid_has_interior_on_left():
    V, F = grid(4)
    loops = topo.boundary_loops(F, V)
    assert len(loops) == 1 and len(loops[0]) == 16
    assert signed_area_xy(V[loops[0]]) == pytest.approx(16.0)   # counterclockwise = positive
    assert loops[0][0] == 0                                     # starts at its smallest vertex
    assert topo.euler_characteristic(F) == 1


def test_boundary_loop_of_fan_is_the_ring_in_order():
    V, F = fan_disk(8)
    (loop,) = topo.boundary_loops(F)
    assert loop.tolist() == list(range(1, 9))
    # reversed faces reverse the loop
    (rloop,) = topo.boundary_loops(F[:, ::-1])
    assert signed_area_xy(V[rloop]) < 0


def test_boundary_loops_sorted_by_length_and_holes_run_clockwise():
    V, F = grid(6)
    centre = [f for f in range(len(F)) if np.all(np.isin(F[f], [17, 18, 24, 25]))]
    Fh = np.delete(F, centre, axis=0)                          # one square hole
    loops = topo.boundary_loops(Fh, V)
    assert [len(lp) for lp in loops] == [24, 4]
    assert signed_area_xy(V[loops[0]]) > 0 and signed_area_xy(V[loops[1]]) < 0


def test_boundary_loops_rejects_pinched_boundary():
    F = np.array([[0, 1, 2], [0, 3, 4]])                       # two triangles sharing vertex 0
    with pytest.raises(UserError, match="non-manifold vertex"):
        topo.boundary_loops(F)
    assert topo.nonmanifold_vertices(F).tolist() == [0]


def test_nonmanifold_vertices_closed_fans_and_any_orientation():
    ring = lambda c, r: [[c, r[i], r[(i + 1) % len(r)]] for i in range(len(r))]  # noqa: E731
    two_closed = np.array(ring(0, [1, 2, 3, 4]) + ring(0, [5, 6, 7]))
    assert topo.nonmanifold_vertices(two_closed).tolist() == [0]
    one_closed = np.array(ring(0, [1, 2, 3, 4]))
    assert topo.nonmanifold_vertices(one_closed).size == 0
    mixed = one_closed.copy()
    mixed[1] = mixed[1, ::-1]                                  # inconsistent orientation
    assert topo.nonmanifold_vertices(mixed).size == 0
    bow = np.r_[mixed, [[0, 5, 6]]]
    assert topo.nonmanifold_vertices(bow).tolist() == [0]


def test_three_faces_on_one_edge_is_nonmanifold_edge():
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert topo.nonmanifold_edges(F).tolist() == [[0, 1]]


def test_nonmanifold_edge_halfedges_are_grouped_by_edge_in_face_order():
    F = np.array([[0, 1, 2], [1, 0, 3], [2, 1, 4], [0, 1, 4], [1, 2, 5], [2, 1, 6]])
    h, start = topo.nonmanifold_edge_halfedges(F)
    a, b = topo.half_edges(F)
    groups = {}
    for k in range(len(a)):
        groups.setdefault((min(a[k], b[k]), max(a[k], b[k])), []).append(k)
    expect = [groups[e] for e in sorted(groups) if len(groups[e]) > 2]
    assert [g.tolist() for g in np.split(h, start[1:])] == expect
    assert topo.nonmanifold_edges(F).tolist() == [[0, 1], [1, 2]]
    assert topo.nonmanifold_edge_halfedges(F[:3])[0].size == 0


def test_connected_components_and_euler():
    V, F = grid(2)
    F2 = np.r_[F, F + len(V)]
    count, labels = topo.connected_components(F2)
    assert count == 2 and labels.tolist() == [0] * len(F) + [1] * len(F)
    assert topo.euler_characteristic(tetrahedron()[1]) == 2
    assert topo.euler_characteristic(torus()[1]) == 0


def test_leaf_faces_of_plain_grid():
    V, F = grid(4, alternate=False)
    is_b = topo.boundary_vertices_mask(F, len(V))
    leaves = topo.leaf_faces(F, is_b)
    assert len(leaves) == 2
    assert np.all(is_b[F[leaves]])
    _, Fa = grid(4)
    assert topo.leaf_faces(Fa, topo.boundary_vertices_mask(Fa)).size == 0


def test_orient_flips_exactly_the_flipped_face():
    V, F = grid(4)
    Fb = F.copy()
    Fb[5] = F[5, [0, 2, 1]]
    Fo, k = topo.orient_faces_consistently(Fb)
    assert k == 1 and np.array_equal(Fo, F)
    Fo, k0 = topo.orient_faces_consistently(F)
    assert k0 == 0 and Fo is F


def test_orient_keeps_majority_per_component():
    V, F = grid(2)
    Fb = F[:, ::-1].copy()          # all faces reversed: consistent, so nothing to flip
    Fo, k = topo.orient_faces_consistently(Fb)
    assert k == 0 and Fo is Fb


def test_mobius_is_not_orientable():
    V, F = mobius()
    with pytest.raises(UserError, match="not orientable"):
        topo.orient_faces_consistently(F)


def test_components_are_the_vertex_sharing_classes_numbered_by_first_face():
    """Faces sharing a vertex are in one component (the partition scipy's graph components
    give on the vertex graph), components numbered in order of their first face; unused
    vertices and a larger ``n`` change nothing; an index outside ``[0, n)`` is an error."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components as graph_components

    rng = np.random.default_rng(5)
    for trial in range(20):
        n = int(rng.integers(5, 200))
        F = rng.integers(0, n, size=(int(rng.integers(1, 120)), 3))
        count, lab = topo.connected_components(F, n + trial % 3)
        r, c = F[:, [0, 1]].ravel(), F[:, [1, 2]].ravel()
        _, vlab = graph_components(sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)),
                                   directed=False)
        flab = vlab[F[:, 0]]
        _, first = np.unique(flab, return_index=True)
        rank = {int(flab[f]): k for k, f in enumerate(sorted(first))}
        assert count == len(first)
        assert lab.tolist() == [rank[int(x)] for x in flab]
    with pytest.raises(ValueError):
        topo.connected_components(np.array([[0, 1, 5]]), 5)


def _scipy_components(r, c, n):
    """SciPy's undirected graph components of the edges ``(r, c)`` on ``n`` vertices: the
    reference :func:`topo.graph_components` stands for."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components as scipy_components

    G = sp.coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n, n)).tocsr()
    return scipy_components(G, directed=False)


def test_graph_components_are_scipys_components_label_for_label():
    """Count and every label as SciPy's ``connected_components(G, directed=False)`` gives
    them: random graphs with repeated edges, loops, isolated vertices and no edges at all,
    and the graphs the intake builds on a real mesh (its vertex-edge graph, its boundary
    edges, the face graph of the orientation check, the corner graph of the fan count); an
    end outside ``[0, n)`` is an error."""
    rng = np.random.default_rng(11)
    graphs = [(np.zeros(0, np.int64), np.zeros(0, np.int64), 0),
              (np.zeros(0, np.int64), np.zeros(0, np.int64), 4),
              (np.array([2, 2]), np.array([2, 0]), 5)]
    for trial in range(40):
        n = int(rng.integers(1, 300))
        k = int(rng.integers(0, 2 * n))
        r, c = rng.integers(0, n, size=k), rng.integers(0, n, size=k)
        graphs.append((np.r_[r, r[:k // 3]], np.r_[c, c[:k // 3]], n))   # repeated edges
    raw = read_mesh(require_data("meshes", "igl_camel_b.obj"))
    n, F = len(raw.V), raw.faces
    m = len(F)
    a, b = topo.half_edges(F)
    be = topo.boundary_edges(F)
    graphs += [(a, b, n), (be[:, 0], be[:, 1], n),
               (np.r_[np.arange(m), np.arange(m) + m], rng.permutation(2 * m), 2 * m),
               (np.arange(3 * m - 1), np.arange(1, 3 * m), 3 * m)]
    for r, c, n in graphs:
        count, labels = topo.graph_components(r, c, n)
        want_count, want_labels = _scipy_components(r, c, n)
        assert count == want_count
        assert labels.dtype == np.int64 and labels.tolist() == want_labels.tolist()
    with pytest.raises(ValueError):
        topo.graph_components(np.array([0, 1]), np.array([1, 3]), 3)
    with pytest.raises(ValueError):
        topo.graph_components(np.array([-1]), np.array([0]), 3)


def test_weld_map_joins_the_points_within_tol_transitively():
    """The representative of every point is the lowest index among the points linked to it
    by steps of at most ``tol`` (brute force over all pairs), whether the tree is asked or the
    coordinate runs prove no pair close (:func:`may_be_near`): a lattice (every coordinate
    repeated), exact copies, copies moved by 0.4·tol (welded, also in chains) and by 3·tol
    along one axis (kept apart)."""
    from scipy.sparse.csgraph import connected_components as graph_components

    from pipeline.geometry.repair import may_be_near, weld_map

    rng = np.random.default_rng(6)
    tol = 1e-3
    L = rng.integers(0, 5, size=(120, 3)).astype(float) * 0.1
    L = L[np.unique(L, axis=0, return_index=True)[1]]
    axis = rng.integers(0, 3, size=len(L))
    shift = np.zeros_like(L)
    shift[np.arange(len(L)), axis] = 1.0
    for P in (L, np.r_[L, L[:7]], np.r_[L, L[:9] + 3 * tol * shift[:9]],
              np.r_[L, L[:9] + 0.4 * tol * shift[:9], L[:9] + 0.8 * tol * shift[:9]]):
        D = np.sqrt(((P[:, None, :] - P[None, :, :]) ** 2).sum(-1))
        _, lab = graph_components(D <= tol, directed=False)
        lowest = {int(c): int(np.flatnonzero(lab == c)[0]) for c in np.unique(lab)}
        assert weld_map(P, tol).tolist() == [lowest[int(c)] for c in lab]
    assert not may_be_near(L[np.lexsort((L[:, 2], L[:, 1], L[:, 0]))], tol)
    Q = np.r_[L, L[:1] + 0.9 * tol * shift[:1]]
    assert may_be_near(Q[np.lexsort((Q[:, 2], Q[:, 1], Q[:, 0]))], tol)


def test_lexicographic_order_is_lexsorts_order():
    """The order of the rows by x, y, z with ties in index order, as ``np.lexsort`` gives it:
    on a grid (every x repeated, runs of equal x and y), with exact duplicate rows, signed
    zeros (equal) and random rows without ties."""
    from pipeline.geometry.repair import lexicographic_order

    rng = np.random.default_rng(3)
    g = rng.integers(0, 4, size=(400, 3)).astype(float)
    g[rng.random(400) < 0.2, 0] = -0.0
    g[rng.random(400) < 0.2, 1] = -0.0
    for P in (g, rng.standard_normal((300, 3)), np.r_[g, g[::-1]], g[:1], g[:0]):
        assert np.array_equal(lexicographic_order(P), np.lexsort((P[:, 2], P[:, 1], P[:, 0])))


def test_duplicate_faces_are_the_repeated_corner_sets():
    """A face is a duplicate when an earlier face has its three vertices in any order: the
    packed-key path and the lexicographic path (indices too large to pack) mark the same
    faces, those of the definition."""
    from pipeline.geometry.repair import _duplicate_mask, sorted_corners

    rng = np.random.default_rng(4)
    F = rng.integers(0, 12, size=(500, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    assert np.array_equal(sorted_corners(F), np.sort(F, axis=1))
    seen, expected = set(), []
    for row in F.tolist():
        key = tuple(sorted(row))
        expected.append(key in seen)
        seen.add(key)
    assert 0 < sum(expected) < len(F)
    assert _duplicate_mask(F).tolist() == expected
    big = F + 2 ** 40                                # n³ does not fit in 62 bits
    assert _duplicate_mask(big).tolist() == expected


# --------------------------------------------------------------------------------------------
# repair on constructed meshes


def test_clean_disk_is_returned_unchanged():
    V, F = grid(4)
    r = repair_mesh(V, F)
    assert np.array_equal(r.V, V) and np.array_equal(r.F, F)
    assert r.V is not V and r.F is not F
    assert np.array_equal(r.source_index, np.arange(len(V)))
    assert r.messages == [] and r.added_vertices.size == 0 and r.closed_holes == []
    changes = {k: v for k, v in r.report.items()
               if v and k not in ("input_vertices", "input_faces", "output_vertices",
                                  "output_faces", "boundary_vertices", "boundary_loops_found",
                                  "components_found")}
    assert changes == {}
    assert r.boundary.tolist() == topo.boundary_loops(F, V)[0].tolist()
    assert signed_area_xy(V[r.boundary]) > 0


def test_flipped_face_is_reoriented():
    V, F = grid(4)
    Fb = F.copy()
    Fb[3] = Fb[3, [0, 2, 1]]
    r = repair_mesh(V, Fb)
    assert r.report["faces_reoriented"] == 1
    assert np.array_equal(r.F, F)
    assert len(r.messages) == 1


def test_two_components_need_keep_largest():
    V1, F1 = grid(4)
    V2, F2 = grid(2)
    V = np.r_[V2 + [10, 0, 0], V1]
    F = np.r_[F2, F1 + len(V2)]
    with pytest.raises(UserError, match="2 connected components.*keep_largest_component"):
        repair_mesh(V, F)
    r = repair_mesh(V, F, options=RepairOptions(keep_largest_component=True))
    assert r.report["components_dropped"] == 1
    assert r.report["component_faces_dropped"] == len(F2)
    assert np.array_equal(r.V, V1) and np.array_equal(r.F, F1)
    assert np.array_equal(r.source_index, np.arange(len(V1)) + len(V2))


def cube(inward: bool = False):
    """The unit cube as 6 quads (fan-triangulated by the repair: 12 triangles), outward CCW
    unless ``inward``."""
    V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    Q = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                  [1, 5, 7, 3]])
    return V, (Q[:, ::-1] if inward else Q)


def signed_volume(V, F):
    return float(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6)


def is_closed_genus_zero(r) -> bool:
    return (r.closed and r.boundary.dtype == np.int64 and r.boundary.shape == (0,)
            and len(topo.boundary_edges(r.F)) == 0
            and topo.euler_characteristic(r.F, len(r.V)) == 2
            and topo.connected_components(r.F, len(r.V))[0] == 1
            and signed_volume(r.V, r.F) > 0)


@pytest.mark.parametrize("make", [tetrahedron, octahedron])
def test_closed_genus_zero_mesh_is_kept_closed_and_outward(make):
    V, F = make()
    r = repair_mesh(V, F)
    assert is_closed_genus_zero(r)
    assert r.report["closed"] is True and r.report["genus"] == 0
    assert r.report["boundary_loops_found"] == 0 and r.report["boundary_vertices"] == 0
    assert r.report["holes_closed"] == 0 and r.report["leaf_faces_split"] == 0
    assert np.array_equal(r.source_index, np.arange(len(V)))
    assert len(r.V) == len(V) and len(r.F) == len(F)
    outward = signed_volume(V, np.asarray(F)) > 0
    assert r.report["faces_flipped_outward"] == (0 if outward else len(F))


def test_inward_cube_is_turned_outward_and_reported():
    V, Q = cube(inward=True)
    r = repair_mesh(V, Q)
    assert is_closed_genus_zero(r) and len(r.F) == 12
    assert r.report["non_triangle_faces_triangulated"] == 6
    assert r.report["faces_flipped_outward"] == 12 and r.report["faces_reoriented"] == 0
    assert any("outward" in m and "12 faces" in m for m in r.messages)
    assert signed_volume(r.V, r.F) == pytest.approx(1.0)
    out = repair_mesh(*cube())
    assert out.report["faces_flipped_outward"] == 0 and not any("outward" in m
                                                                  for m in out.messages)
    P = r.V[r.F]                              # every face normal points away from the centre
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    assert np.all(np.einsum("ij,ij->i", normal, P.mean(axis=1) - 0.5) > 0)


def test_closed_mesh_with_a_few_inward_faces_gets_them_back_then_outward():
    V, F = octahedron()
    Fm = F[:, ::-1].copy()                   # all inward ...
    Fm[:2] = F[:2]                           # ... but two: the majority (inward) is kept first
    r = repair_mesh(V, Fm)
    assert r.report["faces_reoriented"] == 2 and r.report["faces_flipped_outward"] == 8
    cyclic = [tuple(np.roll(f, -int(np.argmin(f)))) for f in r.F]   # same faces, same turn
    assert cyclic == [tuple(np.roll(f, -int(np.argmin(f)))) for f in F]


def test_closed_genus_one_is_rejected_naming_the_genus_and_the_fix():
    with pytest.raises(UserError) as err:
        repair_mesh(*torus(), name="ring.obj")
    msg = str(err.value)
    assert "\n" not in msg
    assert "'ring.obj' is closed with genus 1 (Euler characteristic 0)" in msg
    assert "only genus-0 closed meshes map to the sphere" in msg and "cut its handles" in msg


def test_genus_one_with_boundary_is_rejected():
    V, F = torus()
    with pytest.raises(UserError, match="genus 1"):
        repair_mesh(V, F[1:])


def test_hole_needs_close_holes_and_gets_one_centre_vertex():
    V, F = grid(6)
    hole = [17, 18, 25, 24]                      # square with corners (3,2) and (4,3)
    centre_faces = [f for f in range(len(F)) if np.all(np.isin(F[f], hole))]
    Fh = np.delete(F, centre_faces, axis=0)
    C = np.tile([0.2, 0.4, 0.6], (len(V), 1))
    C[hole] = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 1]]
    with pytest.raises(UserError, match="2 boundary loops; set repair.close_holes: true"):
        repair_mesh(V, Fh)
    r = repair_mesh(V, Fh, colors=C, options=RepairOptions(close_holes=True))
    n = len(V)
    assert r.report["holes_closed"] == 1 and r.report["boundary_loops_found"] == 2
    assert r.added_vertices.tolist() == [n]
    assert r.source_index[n] == -1 and np.array_equal(r.source_index[:n], np.arange(n))
    assert np.allclose(r.V[n], V[hole].mean(axis=0))
    assert np.allclose(r.colors[n], C[hole].mean(axis=0))
    (h,) = r.closed_holes
    assert h["centre_vertex"] == n and sorted(h["loop"]) == sorted(hole)
    assert len(r.F) == len(Fh) + 4
    assert is_disk(r)
    assert face_areas(r.V, r.F).sum() == pytest.approx(36.0)


def pinched_annulus(rings: int = 3, sectors: int = 12):
    """A planar polar grid closing on itself at one vertex: ``rings`` circles of radii 1, 1.5,
    ... and ``sectors`` + 1 spokes over nearly a full turn (the last a tenth of a sector short
    of it), the last spoke's inner vertex the first one's (vertex 0). A disk whose boundary
    touches itself at vertex 0, where two fans meet."""
    r = 1.0 + 0.5 * np.arange(rings)
    t = 2 * np.pi * np.minimum(np.arange(sectors + 1), sectors - 0.1) / sectors
    V = np.column_stack([np.outer(np.cos(t), r).ravel(), np.outer(np.sin(t), r).ravel(),
                         np.zeros(rings * (sectors + 1))])
    idx = np.arange(rings * (sectors + 1)).reshape(sectors + 1, rings)
    idx[sectors, 0] = 0
    F = []
    for j in range(sectors):
        for i in range(rings - 1):
            a, b, c, d = idx[j, i], idx[j, i + 1], idx[j + 1, i + 1], idx[j + 1, i]
            F += [[a, d, c], [a, c, b]] if (i + j) % 2 else [[a, d, b], [d, c, b]]
    used, F = np.unique(np.array(F), return_inverse=True)
    return V[used], F.reshape(-1, 3)


def test_split_vertex_fans_gives_each_fan_its_own_vertex():
    ring = lambda c, r: [[c, r[i], r[(i + 1) % len(r)]] for i in range(len(r))]  # noqa: E731
    F = np.array(ring(0, [1, 2, 3]) + ring(0, [4, 5, 6, 7]) + [[0, 8, 9]] + ring(10, [1, 2, 3]))
    S, parent = topo.split_vertex_fans(F)
    assert parent.tolist() == [0, 0]                           # three fans at 0: two copies
    assert S[3:7, 0].tolist() == [0] * 4                       # the largest fan keeps vertex 0
    assert S[:3, 0].tolist() == [11] * 3 and S[7, 0] == 12     # then by size: 3 faces, 1 face
    assert np.array_equal(np.delete(S, 0, axis=1), np.delete(F, 0, axis=1))
    assert topo.nonmanifold_vertices(S).size == 0
    assert topo.split_vertex_fans(np.array(ring(0, [1, 2, 3])))[1].size == 0


def test_corner_fans_link_corners_across_shared_edges():
    F = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5]])            # two fans at vertex 0
    fans = topo.corner_fans(F).reshape(-1, 3)
    assert fans[0, 0] == fans[1, 0] != fans[2, 0]
    assert fans[0, 2] == fans[1, 1]                            # vertex 2, across edge 0-2
    assert topo.nonmanifold_vertices(F).tolist() == [0]


def test_a_rim_touching_itself_is_split_into_a_disk():
    V, F = pinched_annulus()
    assert topo.nonmanifold_vertices(F, len(V)).tolist() == [0]
    C = np.column_stack([V[:, :2], np.ones(len(V))])
    r = repair_mesh(V, F, colors=C)
    n = len(V)
    assert r.report["nonmanifold_vertices_split"] == 1
    assert is_disk(r) and len(r.V) == n + 1 + len(r.added_vertices)   # + leaf-split midpoints
    assert np.array_equal(r.V[n], V[0]) and np.array_equal(r.colors[n], C[0])
    assert r.source_index[:n + 1].tolist() == list(range(n)) + [0]
    assert n not in r.added_vertices                           # a copy, not an added vertex
    assert any("split 1 non-manifold vertex" in m for m in r.messages)
    assert face_areas(r.V, r.F).sum() == pytest.approx(face_areas(V, F).sum())


def test_bowtie_is_rejected_when_splitting_is_off():
    V, F = pinched_annulus()
    with pytest.raises(UserError, match="non-manifold vertex.*split_nonmanifold_vertices"):
        repair_mesh(V, F, options=RepairOptions(split_nonmanifold_vertices=False))


def test_pieces_meeting_at_a_vertex_become_components():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0]], float)
    F = np.array([[0, 1, 2], [0, 3, 4]])
    with pytest.raises(UserError, match="2 connected components once its 1 non-manifold vertex "
                                        "were split.*keep_largest_component"):
        repair_mesh(V, F)


def test_fin_on_an_edge_is_removed_and_the_flat_pair_kept():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    F = np.array([[0, 1, 4], [0, 1, 2], [1, 0, 3]])            # fin first: not kept for its index
    assert repair.nonmanifold_edge_extras(V, F).tolist() == [True, False, False]
    V2 = V.copy()
    V2[2, 2], V2[4] = 0.5, [0.5, 1, -0.05]                   # face 1 tilted, the fin flatter
    assert repair.nonmanifold_edge_extras(V2, F).tolist() == [False, True, False]
    r = repair_mesh(V, F)
    assert r.report["nonmanifold_edge_faces_removed"] == 1
    assert 4 not in r.source_index and len(r.V) >= 4
    assert any("removed 1 face at 1 non-manifold edge" in m for m in r.messages)


def test_three_faces_sharing_an_edge_are_rejected_when_removal_is_off():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(UserError, match="non-manifold edge.*remove_nonmanifold_edge_faces"):
        repair_mesh(V, F, options=RepairOptions(remove_nonmanifold_edge_faces=False))


def test_two_sheets_crossing_at_an_edge_keep_one_sheet():
    """Four faces on an edge, two flat sheets crossing (the grid's plane and one across it):
    both pairs open 180°, the grid's faces (the lower indices) are kept, the others removed,
    and the repair gives the grid back."""
    V, F = grid(4)
    n = len(V)
    a, b = 12, 13                                              # an interior edge of the grid
    V = np.vstack([V, V[[a, b]].mean(axis=0) + [0, 0, 1], V[[a, b]].mean(axis=0) - [0, 0, 1]])
    F = np.vstack([F, [[a, b, n], [b, a, n + 1]]])
    drop = repair.nonmanifold_edge_extras(V, F)
    assert np.flatnonzero(drop).tolist() == [len(F) - 2, len(F) - 1]   # a tie: lower faces kept
    r = repair_mesh(V, F)
    assert is_disk(r) and np.array_equal(r.V, V[:n]) and np.array_equal(r.F, F[:-2])


def test_landmark_on_a_split_vertex_maps_to_the_vertex_of_its_largest_fan():
    src = np.array([0, 1, 2, 3, 0, 1, -1])
    assert repair.repaired_vertex_of(src, 5).tolist() == [0, 1, 2, 3, -1]


def test_leaf_faces_are_split_at_edge_midpoints():
    V, F = grid(4, alternate=False)
    C = np.c_[V[:, :2] / 4, np.zeros(len(V))]
    r = repair_mesh(V, F, colors=C)
    assert r.report["leaf_faces_split"] == 2
    assert r.report["leaf_split_vertices_added"] == 2
    n = len(V)
    assert r.added_vertices.tolist() == [n, n + 1]
    assert np.all(r.source_index[n:] == -1)
    assert np.array_equal(r.V[:n], V)
    # the split points are exact midpoints of the corner squares' diagonals
    assert sorted(map(tuple, r.V[n:].tolist())) == [(0.5, 3.5, 0.0), (3.5, 0.5, 0.0)]
    assert np.allclose(r.colors[n:], np.c_[r.V[n:, :2] / 4, np.zeros(2)])
    assert len(r.F) == len(F) + 4
    assert face_areas(r.V, r.F).sum() == pytest.approx(16.0)
    assert is_disk(r)
    # boundary unchanged and still counterclockwise
    assert r.boundary.tolist() == topo.boundary_loops(F, V)[0].tolist()


def test_leaf_faces_rejected_when_splitting_is_off():
    V, F = grid(4, alternate=False)
    with pytest.raises(UserError, match="2 leaf faces.*split_leaf_faces"):
        repair_mesh(V, F, options=RepairOptions(split_leaf_faces=False))


def test_single_triangle_is_rejected():
    V = np.eye(3)
    with pytest.raises(UserError, match="single isolated triangle"):
        repair_mesh(V, np.array([[0, 1, 2]]))


def test_duplicated_vertex_is_welded():
    V, F = grid(4)
    v = 12                                        # interior vertex
    Vd = np.r_[V, V[v:v + 1]]
    Fd = F.copy()
    uses = np.flatnonzero((F == v).any(axis=1))[:3]
    Fd[uses] = np.where(Fd[uses] == v, len(V), Fd[uses])
    r = repair_mesh(Vd, Fd)
    assert r.report["vertices_welded"] == 1
    assert np.array_equal(r.V, V) and np.array_equal(r.F, F)
    assert np.array_equal(r.source_index, np.arange(len(V)))


def test_near_duplicate_within_tolerance_is_welded_and_outside_is_not():
    V, F = grid(4)
    v = 12
    uses = np.flatnonzero((F == v).any(axis=1))[:3]
    Fd = F.copy()
    Fd[uses] = np.where(Fd[uses] == v, len(V), Fd[uses])
    near = np.r_[V, V[v:v + 1] + [1e-12, 0, 0]]
    assert repair_mesh(near, Fd).report["vertices_welded"] == 1
    far = np.r_[V, V[v:v + 1] + [1e-3, 0, 0]]
    with pytest.raises(UserError):                # a slit: two boundary loops
        repair_mesh(far, Fd)


def test_seam_that_welds_into_a_closed_genus_zero_surface_is_welded():
    V, F = octahedron()
    # cut along +x → +z → -x: faces on the -y side get a copy of +z
    Vc = np.r_[V, V[4:5]]
    Fc = F.copy()
    for f in range(len(F)):
        if 3 in F[f] and 4 in F[f]:
            Fc[f] = np.where(F[f] == 4, 6, F[f])
    # welding gives a fine closed genus-0 surface (the octahedron): welded, mapped to the sphere
    r = repair_mesh(Vc, Fc)
    assert r.report["vertices_welded"] == 1 and r.report["weld_skipped_vertices"] == 0
    assert is_closed_genus_zero(r) and len(r.V) == 6
    np.testing.assert_array_equal(r.F, F)
    # weld: false keeps the cut disk
    r = repair_mesh(Vc, Fc, options=RepairOptions(weld=False))
    assert len(r.V) == 7 and is_disk(r)
    assert np.array_equal(r.F, Fc)


def test_nan_and_empty_are_rejected():
    V, F = grid(2)
    Vn = V.copy()
    Vn[3, 1] = np.nan
    with pytest.raises(UserError, match="NaN"):
        repair_mesh(Vn, F)
    with pytest.raises(UserError, match="no faces"):
        repair_mesh(V, np.zeros((0, 3), int))
    with pytest.raises(UserError, match="no vertices"):
        repair_mesh(np.zeros((0, 3)), F)
    with pytest.raises(UserError, match="out of range"):
        repair_mesh(V, F + 100)


def test_coordinates_beyond_the_readers_limit_are_rejected_with_a_fix():
    """The limit the reader applies to files (1e60: squared lengths and areas overflow past
    about 1e154, where the weld's KD-tree raised ValueError) holds for arrays given directly;
    a mesh at the limit passes."""
    V, F = grid(2)
    for scale in (1e61, 1e200):
        with pytest.raises(UserError, match=r"up to .* rescale the mesh"):
            repair_mesh(V * scale, F)
    V1 = V / np.abs(V).max() * 1e60
    assert len(repair_mesh(V1, F).F) == len(F)


def test_polygons_degenerate_duplicate_and_unreferenced_faces():
    V, F = grid(2)                 # 3×3 vertices; quads below are the grid squares
    quads = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]
    faces = quads + [[0, 1, 4, 3][:3]] + [[2, 2, 5]] + [[6, 7]]
    V2 = np.r_[V, [[9, 9, 9]]]     # unreferenced vertex
    r = repair_mesh(V2, faces)
    rep = r.report
    assert rep["non_triangle_faces_triangulated"] == 4
    assert rep["invalid_faces_removed"] == 1
    assert rep["degenerate_faces_removed"] == 1
    assert rep["duplicate_faces_removed"] == 1
    assert rep["unreferenced_vertices_removed"] == 1
    assert is_disk(r)
    assert r.report["leaf_faces_split"] == 2        # the quad fans leave two corner leaves
    assert len(r.messages) == 6
    assert np.all(r.source_index[:9] == np.arange(9))


def test_zero_area_cap_is_flipped_away():
    V, F = grid(4)
    # square 0: faces (0,1,6),(0,6,5); replace (0,1,6) by a fan around the diagonal's midpoint
    x = len(V)
    Vc = np.r_[V, [[0.5, 0.5, 0.0]]]
    Fc = np.r_[[[0, 1, x], [x, 1, 6], [0, x, 6]], F[1:]]
    assert zero_area_mask(Vc, Fc).sum() == 1
    r = repair_mesh(Vc, Fc)
    assert r.report["zero_area_faces_flipped"] == 1
    assert not zero_area_mask(r.V, r.F).any()
    assert face_areas(r.V, r.F).sum() == pytest.approx(16.0)
    assert is_disk(r) and len(r.F) == len(F) + 2


def test_zero_area_boundary_cap_is_removed():
    V, F = grid(4)
    # replace the face on boundary edge 1 -> 2 by three faces around a point x on that edge:
    # (1,x,p), (x,2,p) and the cap (1,2,x) whose long edge is the boundary edge
    f12 = [f for f in range(len(F)) if {1, 2} <= set(F[f].tolist())][0]
    rot = np.roll(F[f12], -list(F[f12]).index(1))        # (1, 2, p)
    assert rot[1] == 2
    p, x = rot[2], len(V)
    Vc = np.r_[V, [[1.5, 0.0, 0.0]]]
    Fc = np.r_[np.delete(F, f12, axis=0), [[1, x, p], [x, 2, p], [1, 2, x]]]
    r = repair_mesh(Vc, Fc)
    assert r.report["zero_area_faces_removed"] == 1
    assert not zero_area_mask(r.V, r.F).any()
    assert x in r.boundary.tolist() and len(r.F) == len(F) + 1
    assert face_areas(r.V, r.F).sum() == pytest.approx(16.0)
    assert is_disk(r)


def test_decimation_keeps_a_disk_and_maps_vertices_to_the_input():
    V, F = grid(30)
    V = V.copy()
    V[:, 2] = np.sin(V[:, 0] / 5) * np.cos(V[:, 1] / 7)
    r = repair_mesh(V, F, options=RepairOptions(decimate_to_faces=400))
    assert r.report["decimated_from_faces"] == len(F)
    assert 300 <= r.report["decimated_to_faces"] <= 800
    assert is_disk(r)
    src = r.source_index
    assert np.all(src[src >= 0] < len(V)) and len(np.unique(src[src >= 0])) == np.sum(src >= 0)
    # boundary preserved exactly by the first (border-preserving) attempt
    assert np.array_equal(r.V[r.boundary], V[src[r.boundary]])


def test_decimation_target_too_small_is_rejected():
    # the options are the config section: validated when made, never again in repair_mesh
    with pytest.raises(ValidationError, match="decimate_to_faces"):
        RepairOptions(decimate_to_faces=2)


# --------------------------------------------------------------------------------------------
# real meshes

MESHES = {
    # name: expected non-default report entries
    "c3d_alligator": {"leaf_faces_split": 2, "leaf_split_vertices_added": 2},
    "choi_chinese_lion": {},
    "choi_hand": {},
    "choi_human_brain": {},
    "choi_human_face": {},
    "gpp_bunny": {},
    "gpp_face": {"leaf_faces_split": 123, "leaf_split_vertices_added": 103},
    "igl_camel_b": {"weld_skipped_vertices": 243, "leaf_faces_split": 26,
                    "leaf_split_vertices_added": 19},
    "igl_camelhead": {},
    "igl_lion": {},
}
_COUNTERS = ("non_triangle_faces_triangulated", "invalid_faces_removed",
             "degenerate_faces_removed", "vertices_welded", "duplicate_faces_removed",
             "unreferenced_vertices_removed", "components_dropped", "faces_reoriented",
             "zero_area_faces_flipped", "zero_area_faces_removed", "holes_closed",
             "leaf_faces_split", "leaf_split_vertices_added", "weld_skipped_vertices")


@pytest.mark.parametrize("name", sorted(MESHES))
def test_real_meshes_repair_into_disks(name):
    path = require_data("meshes", f"{name}.obj")
    m = read_mesh(path)
    r = repair_mesh(m.V, m.faces, m.colors, name=name)
    assert is_disk(r)
    got = {k: r.report.get(k) for k in _COUNTERS if r.report.get(k)}
    assert got == MESHES[name]
    n_in = len(m.V)
    assert np.array_equal(r.V[:n_in], m.V)
    assert np.array_equal(r.source_index[:n_in], np.arange(n_in))
    assert len(r.V) == n_in + MESHES[name].get("leaf_split_vertices_added", 0)
    if not MESHES[name]:
        assert np.array_equal(r.F, m.faces)


ICT = ["A_neutral", "A_smile", "B_neutral", "B_smile_jawopen"]


@pytest.mark.parametrize("face", ICT)
def test_ict_holes_close_into_the_disk_files(face):
    holes = read_mesh(require_data("faces", "ict", f"ict_{face}_holes.obj"))
    disk = read_mesh(require_data("faces", "ict", f"ict_{face}_disk.obj"))
    with pytest.raises(UserError, match="4 boundary loops"):
        repair_mesh(holes.V, holes.faces)
    r = repair_mesh(holes.V, holes.faces, options=RepairOptions(close_holes=True))
    assert r.report["holes_closed"] == 3
    assert r.added_vertices.tolist() == [len(holes.V), len(holes.V) + 1, len(holes.V) + 2]
    assert len(r.V) == len(disk.V)
    assert np.array_equal(r.F, disk.faces)               # same fans, same order
    assert np.abs(r.V - disk.V).max() < 1e-6             # the files have 6 decimals
    assert is_disk(r)
    rd = repair_mesh(disk.V, disk.faces)
    assert rd.messages == [] and np.array_equal(rd.boundary, r.boundary)


def test_real_mesh_decimation():
    m = read_mesh(require_data("meshes", "choi_human_face.obj"))
    r = repair_mesh(m.V, m.faces, options=RepairOptions(decimate_to_faces=2000))
    assert is_disk(r)
    assert 1500 <= len(r.F) <= 2500
    assert np.all(r.source_index >= 0)


def _twins_by_dictionary(F: np.ndarray) -> np.ndarray:
    """:func:`topo.interior_edge_twins` from a dictionary of half-edges by undirected edge."""
    by_edge = {}
    for h, (a, b) in enumerate(zip(F.ravel().tolist(), F[:, [1, 2, 0]].ravel().tolist())):
        by_edge.setdefault((min(a, b), max(a, b)), []).append(h)
    expected = np.full(3 * len(F), -1)
    for hs in by_edge.values():
        if len(hs) == 2:
            expected[hs[0]], expected[hs[1]] = hs[1], hs[0]
    return expected, {len(hs) for hs in by_edge.values()}


def test_interior_edge_twins_on_any_triangle_list():
    """Exact against a dictionary of half-edges by undirected edge, on a triangle soup with
    boundary, interior, non-manifold (3, 4 and more faces) and repeated edges, int32 and int64
    faces, and on a real mesh (its faces in file order and shuffled)."""
    rng = np.random.default_rng(8)
    F = rng.integers(0, 25, (300, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
    expected, sizes = _twins_by_dictionary(F)
    assert {1, 2, 3, 4, 5} <= sizes                # the soup has all kinds
    for dtype in (np.int32, np.int64):
        assert np.array_equal(topo.interior_edge_twins(F.astype(dtype)), expected)
    F = read_mesh(require_data("meshes", "igl_lion.obj")).faces
    for faces in (F, F[rng.permutation(len(F))]):
        expected, sizes = _twins_by_dictionary(faces)
        assert sizes == {1, 2}
        assert np.array_equal(topo.interior_edge_twins(faces), expected)


def test_interior_neighbours_are_those_of_the_vertex_adjacency():
    """``has_interior_neighbour``: the vertices with a neighbour off the boundary in the
    adjacency matrix, on a grid with and without leaf faces (whose corner vertex has none)."""
    for alternate in (True, False):
        V, F = grid(4, alternate)
        is_b = topo.boundary_vertices_mask(F, len(V))
        A = topo.vertex_neighbours(F, len(V)).astype(np.int64)
        expected = np.asarray(A @ (~is_b).astype(np.int64)).ravel() > 0
        got = has_interior_neighbour(F, is_b)
        assert np.array_equal(got, expected)
        assert got.all() == alternate               # a leaf's corner has none
