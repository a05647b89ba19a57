"""Edge collapses and their guards (pipeline.geometry.remesh.collapse)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import lift
from pipeline.geometry.remesh.collapse import collapse_short_edges
from pipeline.geometry.remesh.sag import edge_sag
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh_quality import is_disk, mesh_facts, point_mesh_distance
from remesh_helpers import ccw_delaunay, disk_map, disk_points, face_map  # noqa: F401


@pytest.mark.parametrize("max_gap", [None, 0.02])
def test_collapse_gap_guard_keeps_removed_vertices_near_the_result(max_gap):
    """A unit disk with a tent (height 0.3, radius 0.25) at its centre, parameterized by xy;
    a coarse remesh of it collapsed as far as the rules allow. With the guard every original
    vertex stays within the gap of the result; without it the tent's flanks are cut."""
    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.3)
    uv = np.vstack([disk_points(8, 6), [[0.004, 0.003]]])
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    X0 = lift(V_in, F_in, face, bary)
    S = RemeshState(X0.copy(), F, uv, topo.boundary_vertices_mask(F, len(uv)), face, bary,
                    V_in, F_in, uv_in, locator, uv_in[loop])
    k = collapse_short_edges(S, np.inf, np.inf, max_gap=max_gap)
    assert k > 50 and is_disk(mesh_facts(S.X, S.F))
    d, _ = point_mesh_distance(X0, S.X, S.F)
    if max_gap is None:
        assert d.max() > 2 * 0.02
    else:
        assert d.max() <= max_gap


def test_collapse_sag_guard_creates_no_edge_off_the_surface():
    """The tent again: with ``max_sag`` every edge farther than it from the surface after the
    collapses was there before (a collapse never creates one); without it some are new."""
    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.3)
    tol = 0.01

    def far_edges(S):
        E = np.sort(np.vstack([S.F[:, [0, 1]], S.F[:, [1, 2]], S.F[:, [2, 0]]]), axis=1)
        E = np.unique(E, axis=0)
        far = edge_sag(S, E[:, 0], E[:, 1]) > tol
        return {tuple(S.uv[i].round(12)) + tuple(S.uv[j].round(12)) for i, j in E[far]}

    new_far = {}
    for max_sag in (None, tol):
        uv = disk_points(8, 6)
        F = ccw_delaunay(uv)
        face, bary = locator.locate(uv)
        S = RemeshState(lift(V_in, F_in, face, bary), F, uv,
                        topo.boundary_vertices_mask(F, len(uv)), face, bary, V_in, F_in, uv_in,
                        locator, uv_in[loop])
        before = far_edges(S)
        k = collapse_short_edges(S, np.inf, np.inf, max_sag=max_sag)
        assert k > 20 and is_disk(mesh_facts(S.X, S.F))
        new_far[max_sag] = far_edges(S) - before
    assert len(new_far[None]) > 0 and len(new_far[tol]) == 0


def test_collapse_only_between_marked_vertices(face_map):
    """``at``: only edges with both ends marked collapse; every other vertex stays."""
    from pipeline.geometry.locate import PointLocator, lift
    from pipeline.geometry.remesh.sampling import sample_disk, triangulate_samples
    from pipeline.geometry.remesh.state import RemeshState

    _, mesh, p = face_map
    s = sample_disk(1500, polygon=p.uv[mesh.boundary])
    L = PointLocator(p.uv, mesh.F, mesh.boundary)
    face, bary = L.locate(s.points)
    X = lift(mesh.V, mesh.F, face, bary)
    rim = np.arange(len(X)) < s.n_rim
    S = RemeshState(X, triangulate_samples(s), s.points, rim, face, bary, mesh.V, mesh.F, p.uv,
                    L, p.uv[mesh.boundary])
    at = np.zeros(S.n, bool)
    at[np.flatnonzero(~rim)[:40]] = True
    before = {tuple(x) for x in S.X[~at]}
    done = collapse_short_edges(S, np.inf, np.inf, at=at)
    assert done > 0 and S.n == len(X) - done
    assert before <= {tuple(x) for x in S.X}


def test_collapse_never_removes_a_rim_vertex_into_a_locked_interior_one():
    """A vertex just inside the rim, locked (a kept input corner), with the short interior edge
    to its rim neighbour the only one below ``L_min``: the locked end cannot go, and the rim
    end may go only along a rim edge, so nothing collapses and the disk keeps its rim (removing
    the rim vertex made the locked one a second rim vertex there: a non-manifold pinch)."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    rings = disk_points(4, 6)                 # the centre, rings at r = 0.25 … 1 (the rim)
    uv = np.vstack([0.97 * rings[-24:-23], rings])   # first: the end the edge starts from
    F = ccw_delaunay(uv)
    # the face with the half-edge locked → rim first, so that it is the edge's candidate
    rim_end = len(uv) - 24
    starts = ((F == 0) & (np.roll(F, -1, axis=1) == rim_end)).any(axis=1)
    F = np.vstack([F[starts], F[~starts]])
    face, bary = locator.locate(uv)
    is_rim = topo.boundary_vertices_mask(F, len(uv))
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, is_rim, face, bary, V_in, F_in,
                    uv_in, locator, uv_in[loop])
    S.locked[0] = True
    rim_before = S.uv[S.is_rim].copy()
    k = collapse_short_edges(S, 0.05, np.inf)
    assert k == 0 and is_disk(mesh_facts(S.X, S.F))
    np.testing.assert_array_equal(S.uv[S.is_rim], rim_before)


def test_refused_edges_are_found_either_way_round_until_a_ring_at_an_end_changes():
    """A strip of four triangles (vertices 0–5): the refused edges 0–1 and 4–5 are found as
    pairs in both directions and stand in both ends' rows; removing vertex 3 (closed ring
    1, 2, 3, 4, 5) forgets both, removing vertex 0 (ring 0, 1, 2) only 0–1."""
    from pipeline.geometry.remesh.collapse import RefusedEdges
    from pipeline.geometry.remesh.halfedge import adjacency

    F = np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]], np.int64)
    A = adjacency(F, 6)

    def refused():
        R = RefusedEdges(6)
        R.add(np.array([0, 5]), np.array([1, 4]))
        return R

    R = refused()
    assert R.has(np.array([1, 0, 4, 0, 2]), np.array([0, 1, 5, 2, 3])).tolist() == [
        True, True, True, False, False]
    indptr, indices = R.rows()
    assert [sorted(indices[indptr[v]:indptr[v + 1]].tolist()) for v in range(6)] == [
        [1], [0], [], [], [5], [4]]
    assert sorted(R.forget_at(np.array([3]), A).ravel().tolist()) == [0, 1, 4, 5]
    assert not R.has(np.array([0, 4]), np.array([1, 5])).any()
    R = refused()
    R.forget_at(np.array([0]), A)
    assert R.has(np.array([0, 4]), np.array([1, 5])).tolist() == [False, True]


def test_short_edge_ends_marks_tails_and_rim_heads_of_edges_not_refused():
    """Two triangles 0-1-2, 2-1-3 with 0–1 and 1–2 short (0.1 long, the rest at least 0.14;
    threshold 0.12); rim vertex 0. Looking at vertex 3 only (face 2-1-3): the short half-edge
    2→1 alone, tail 2. Looking everywhere: 0→1 (rim tail: both ends), 1→2 and 2→1; with 0–1
    refused, only 1→2 and 2→1."""
    from pipeline.geometry._kernels import short_edge_ends
    from pipeline.geometry.remesh.collapse import RefusedEdges

    F = np.array([[0, 1, 2], [2, 1, 3]], np.int64)
    X = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [5, 5, 0]], float)
    rim = np.array([1, 0, 0, 0], np.uint8)
    R = RefusedEdges(4)
    count, ends = short_edge_ends(F, np.array([0, 0, 0, 1], np.uint8), X, 0.12, rim, *R.rows())
    assert count == 1 and ends.tolist() == [False, False, True, False]
    count, ends = short_edge_ends(F, np.ones(4, np.uint8), X, 0.12, rim, *R.rows())
    assert count == 3 and ends.tolist() == [True, True, True, False]
    R.add(np.array([1]), np.array([0]))
    count, ends = short_edge_ends(F, np.ones(4, np.uint8), X, 0.12, rim, *R.rows())
    assert count == 2 and ends.tolist() == [False, True, True, False]


def _numpy_sag_along(S, a, b, ts):
    """:func:`edge_sag_along`'s arithmetic in numpy: the offsets of every sample from the
    straight edge, their largest absolute component along the input normals there and at the
    ends, the first ``t`` of the largest per edge."""
    from pipeline.geometry.remesh.sag import lift_samples
    from pipeline.geometry.rows import dots

    ts = np.asarray(ts, dtype=np.float64)
    s, k = len(ts), len(a)
    T = np.repeat(ts, k)[:, None]
    ea, eb = np.tile(a, s), np.tile(b, s)
    P, mf = lift_samples(S, ea, eb, T)
    D = P - ((1.0 - T) * S.X[ea] + T * S.X[eb])
    sag = np.abs(dots(D, S.normals_in()[mf]))
    for v in (a, b):
        sag = np.maximum(sag, np.abs(dots(D, np.tile(S.normals_in()[S.face[v]], (s, 1)))))
    sag = sag.reshape(s, k)
    j = np.argmax(sag, axis=0)
    return sag[j, np.arange(k)], ts[j]


@pytest.mark.parametrize("ts", [(0.5,), (0.25, 0.5, 0.75), tuple(np.arange(1, 8) / 8)])
def test_edge_sag_along_is_the_numpy_formula_bit_for_bit(ts):
    """The compiled sag (:func:`.._kernels.sag_along_block`) of every edge of a coarse remesh
    of the tent gives the very values and ``t`` of the numpy formula it replaces, and some
    edges do leave the surface (the tent's flanks)."""
    from pipeline.geometry.remesh.sag import edge_sag_along
    from remesh_helpers import coarse_state

    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.3)
    S, _ = coarse_state(uv_in, F_in, V_in, loop, locator, rings=6)
    E = topo.edges_with_faces(S.F)[0]
    a, b = E[:, 0].copy(), E[:, 1].copy()
    sag, t = edge_sag_along(S, a, b, ts)
    want_sag, want_t = _numpy_sag_along(S, a, b, ts)
    assert np.array_equal(sag, want_sag) and np.array_equal(t, want_t)
    assert np.count_nonzero(sag > 1e-3) > 5


@pytest.mark.parametrize("dim", [2, 3])
def test_points_along_edges_are_the_numpy_formula_bit_for_bit(dim):
    """:func:`.._kernels.points_along` (the domain points of :func:`.sag.lift_samples`):
    ``(1 − t)·uv[a] + t·uv[b]`` with ``t`` a column, bit for bit, on the disk and on the
    sphere's 3D domain, and the face under the nearer end (``a``'s at ``t = 1/2``)."""
    from pipeline.geometry._kernels import points_along

    rng = np.random.default_rng(11)
    uv = rng.normal(size=(300, dim))
    face = rng.integers(0, 1000, 300)
    a, b = rng.integers(0, 300, 5000), rng.integers(0, 300, 5000)
    T = np.r_[rng.random(4997), 0.5, 0.0, 1.0][:, None]
    M, hint = points_along(uv, face, a, b, T[:, 0].copy())
    assert np.array_equal(M, (1.0 - T) * uv[a] + T * uv[b])
    assert np.array_equal(hint, np.where(T[:, 0] <= 0.5, face[a], face[b]))
    assert hint[-3] == face[a[-3]] and hint[-1] == face[b[-1]]


def test_samples_located_along_a_chain_are_those_located_from_the_ends():
    """:func:`.sag.lift_along` locates the samples of many edges one ``t`` at a time from the
    previous sample's face: on a coarse remesh of the tent (more than ``CHAIN_MIN`` edges) it
    gives the very lifts and faces of :func:`.sag.lift_samples` (every walk from the nearer
    end), bit for bit; the chains are the ``t ≤ 1/2`` upwards, the rest downwards."""
    from pipeline.geometry.remesh.sag import CHAIN_MIN, lift_along, lift_samples, sample_chains
    from remesh_helpers import coarse_state

    low, high = sample_chains(np.array([0.875, 0.5, 0.125, 0.625, 0.25]))
    assert low.tolist() == [2, 4, 1] and high.tolist() == [0, 3]
    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.3)
    S, _ = coarse_state(uv_in, F_in, V_in, loop, locator, rings=6)
    E = topo.edges_with_faces(S.F)[0]
    a, b = E[:, 0].copy(), E[:, 1].copy()
    assert len(a) >= CHAIN_MIN
    ts = np.arange(1, 8) / 8.0
    P, mf = lift_along(S, a, b, ts)
    s = len(ts)
    want_P, want_f = lift_samples(S, np.tile(a, s), np.tile(b, s), np.repeat(ts, len(a))[:, None])
    assert np.array_equal(P, want_P) and np.array_equal(mf, want_f)


def test_walked_sags_of_a_few_edges_are_the_numpy_formula_bit_for_bit():
    """The sag of fewer than ``CHAIN_MIN`` edges in one kernel (:func:`.._kernels.walked_sags`:
    every sample walked from the face under the nearer end, lifted, measured) gives the very
    values and ``t`` of the numpy formula, and some of those edges leave the surface; a walk
    that does not reach its point (no step allowed) makes the kernel give up, and
    :func:`.sag.edge_sag_along` then gives the same values the general way."""
    from pipeline.geometry._kernels import walked_sags
    from pipeline.geometry.locate import TOL
    from pipeline.geometry.remesh.sag import CHAIN_MIN, SAG_WALK, edge_sag_along
    from remesh_helpers import coarse_state

    uv_in, F_in, V_in, loop, locator = disk_map(tent=0.3)
    S, _ = coarse_state(uv_in, F_in, V_in, loop, locator, rings=6)
    E = topo.edges_with_faces(S.F)[0]
    ts = np.arange(1, 8) / 8.0
    sags = edge_sag_along(S, E[:, 0].copy(), E[:, 1].copy(), ts)[0]
    pick = np.argsort(-sags, kind="stable")[:CHAIN_MIN - 1]     # the edges that sag most
    a, b = E[pick, 0].copy(), E[pick, 1].copy()
    want_sag, want_t = _numpy_sag_along(S, a, b, ts)
    assert np.count_nonzero(want_sag > 1e-3) > 5

    def walked(walk):
        best, t_best = np.empty(len(a)), np.empty(len(a))
        done = walked_sags(S.locator.walk_table(), S.uv, S.face.astype(np.int64), a, b, ts,
                           walk, TOL, S.V_in, F_in.astype(np.int64), S.normals_in(),
                           S.X, best, t_best)
        return done, best, t_best

    done, best, t_best = walked(SAG_WALK)
    assert done and np.array_equal(best, want_sag) and np.array_equal(t_best, want_t)
    assert not walked(0)[0]
    sag, t = edge_sag_along(S, a, b, ts)
    assert np.array_equal(sag, want_sag) and np.array_equal(t, want_t)


def _independent_passes_numpy(n, pr, pv, prank, passes, keep):
    """The numpy formula of :func:`_independent_collapses`' passes: each pass's winners, the
    ``keep`` of them taken; returns the winners of every pass and the last open and taken
    masks."""
    c = int(pr.max()) + 1
    open_, taken, out = np.ones(c, bool), np.zeros(n, bool), []
    for _ in range(passes):
        live = open_[pr]
        best = np.full(n, c, np.int64)
        np.minimum.at(best, pv[live], prank[live])
        lost = np.bincount(pr[live & (best[pv] != prank)], minlength=c)
        w = np.flatnonzero(open_ & (lost == 0))
        open_[w] = False
        out.append(w)
        mark = np.zeros(c, bool)
        mark[keep(w)] = True
        taken[pv[mark[pr]]] = True
        open_ &= np.bincount(pr[taken[pv]], minlength=c) == 0
    return out, open_, taken


def _independent_passes_compiled(n, pr, pv, prank, passes, keep):
    """The passes of :func:`_independent_passes_numpy` by the compiled kernels."""
    from pipeline.geometry._kernels import close_rings_of, ring_minima

    c = int(pr.max()) + 1
    open_, taken, best, out = np.ones(c, np.uint8), np.zeros(n, np.uint8), np.full(n, c), []
    for _ in range(passes):
        w = ring_minima(pr, pv, prank, open_, best)
        assert (best == c).all()
        out.append(w)
        close_rings_of(pr, pv, keep(w), taken, open_)
    return out, open_.astype(bool), taken.astype(bool)


def _closed_rings(A, r):
    """Candidate ``i``'s closed ring (``r[i]`` and its neighbours in ``A``) as pairs."""
    pr, pv = topo.csr_rows(A.indptr, A.indices, r)
    return np.concatenate([pr, np.arange(len(r))]), np.concatenate([pv, r])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ring_minima_and_close_rings_of_are_the_numpy_passes(face_map, seed):
    """On the face's mesh (a third of its vertices as candidates, random ranks, every other
    winner or all of them taken) and on a path 0–1–2–3 whose middle candidates tie for a
    vertex: the compiled passes give the winners, open and taken masks of the numpy formula
    (winners in increasing order)."""
    from pipeline.geometry.remesh.halfedge import adjacency

    _, mesh, _ = face_map
    n = len(mesh.V)
    A = adjacency(np.ascontiguousarray(mesh.F, dtype=np.int64), n)
    rng = np.random.default_rng(seed)
    r = np.sort(rng.choice(n, n // 3, replace=False)).astype(np.int64)
    pr, pv = _closed_rings(A, r)
    prank = rng.permutation(len(r))[pr]
    for keep in (lambda w: w[::2], lambda w: w):
        a = _independent_passes_numpy(n, pr, pv, prank, 4, keep)
        b = _independent_passes_compiled(n, pr, pv, prank, 4, keep)
        assert len(a[0][0]) > 10
        for wa, wb in zip(a[0], b[0]):
            np.testing.assert_array_equal(wa, wb)
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[2], b[2])
    # a path: candidates 1 (rank 0) and 2 (rank 1) share 1 and 2; 1 wins, then 2 is closed
    pr = np.array([0, 0, 1, 1, 0, 1], np.int64)
    pv = np.array([0, 2, 1, 3, 1, 2], np.int64)
    prank = np.array([0, 0, 1, 1, 0, 1], np.int64)
    b = _independent_passes_compiled(4, pr, pv, prank, 2, lambda w: w)
    assert [w.tolist() for w in b[0]] == [[0], []]
    assert b[1].tolist() == [False, False] and b[2].tolist() == [True, True, True, False]
