"""Local forms of whole-remesh tests in the minimum-angle pass: each against the formula over
every face or vertex it replaces, on constructed and real remeshes."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.remesh.angles import forcing_corners, sharp_among, sharp_vertices
from pipeline.geometry.remesh.circumcentres import (restore_state, saved_state, unforced_among,
                                                    unforced_below)
from pipeline.geometry.remesh.features import release_features
from pipeline.geometry.remesh.improve import link_edges, link_flip, sharing_edge
from pipeline.geometry.remesh.refine import split_long_edges
from pipeline.geometry.remesh.state import at_points
from pipeline.geometry.rows import norms
from remesh_helpers import coarse_state, disk_map


def _sharing_edge_whole(F, p, q):
    """The whole-face formula :func:`sharing_edge` replaces."""
    return bool(((F == p) & ((np.roll(F, 1, axis=1) == q)
                             | (np.roll(F, -1, axis=1) == q))).any())


def test_sharing_edge_is_the_whole_face_formula():
    """Every pair of vertices of a real remesh (edges and not), and a constructed one with a
    repeated corner and a vertex on no face: the same answer as the formula over all faces."""
    S, _ = coarse_state(*disk_map(0.2), 4)
    n = S.n
    got = [sharing_edge(S.F, p, q) for p in range(n) for q in range(n)]
    assert got == [_sharing_edge_whole(S.F, p, q) for p in range(n) for q in range(n)]
    edges = {(min(a, b), max(a, b)) for f in S.F.tolist() for a, b in zip(f, f[1:] + f[:1])}
    assert sum(got) == 2 * len(edges)
    F = np.array([[0, 1, 2], [2, 2, 3], [3, 1, 0]])
    for p in range(5):
        for q in range(5):
            assert sharing_edge(F, p, q) == _sharing_edge_whole(F, p, q)


def test_restore_puts_back_the_twins_of_the_saved_faces():
    """After splits and flips, a restore (of a state saved with twins known) leaves twins
    known and equal to those computed again from the faces; a state saved without them
    restores none."""
    S, _ = coarse_state(*disk_map(0.2), 5)
    rng = np.random.default_rng(3)
    S.twins()
    for _ in range(20):
        saved = saved_state(S)
        assert "twins" in saved
        if rng.random() < 0.5:
            split_long_edges(S, 0.0, budget=int(rng.integers(1, 4)))
        for h in link_edges(S, int(rng.integers(S.n)))[:2]:
            link_flip(S, int(h))
        if rng.random() < 0.7:
            restore_state(S, saved)
            assert S.cached_twins() is not None
        assert np.array_equal(S.twins(), topo.interior_edge_twins(S.F))
    S.set_faces(S.F.copy())
    saved = saved_state(S)
    assert "twins" not in saved
    restore_state(S, saved)
    assert S.cached_twins() is None


def test_release_features_reads_the_hole_points_at_the_marked_vertices_alone():
    """Kept edges along a real remesh's edges, some of their vertices at ``fixed``: random
    marks free the same vertices, leave the same kept edges and locks as with the marks at
    the hole points dropped over all vertices first (and no hole points), and leave the
    marks as they were."""
    rng = np.random.default_rng(5)
    for trial in range(30):
        S, _ = coarse_state(*disk_map(0.2), 4)
        E = np.sort(S.F[:, :2], axis=1)
        S.joined = E[rng.choice(len(E), 12, replace=False)]
        S.locked[S.joined.ravel()] = True
        S.fixed = S.X[rng.choice(S.joined.ravel(), 3)]
        at = rng.random(S.n) < 0.2
        at_before = at.copy()
        corners = S.X[rng.choice(S.n, 2)] if trial % 2 else None
        T = coarse_state(*disk_map(0.2), 4)[0]          # the marks at the hole points
        T.joined, T.locked = S.joined.copy(), S.locked.copy()   # dropped over all vertices
        whole = release_features(T, at & ~at_points(S.X, S.fixed), corners)
        free = release_features(S, at, corners)
        assert np.array_equal(at, at_before)
        assert np.array_equal(free, whole) and len(whole) > 0
        assert np.array_equal(S.joined, T.joined) and np.array_equal(S.locked, T.locked)


def test_unforced_among_is_the_whole_answer_filtered():
    """On a real remesh with faces below the minimum, and its vertices moved at random: the
    faces among random subsets (and among those near a point, as :meth:`raise_near` takes
    them) are the whole remesh's answer with the others left out, same order, same angles."""
    S, _ = coarse_state(*disk_map(0.2), 5)
    rng = np.random.default_rng(7)
    inner = np.flatnonzero(~S.is_rim)
    for trial in range(20):
        S.X[inner] += rng.normal(0, 0.02, (len(inner), 3)) * (trial > 0)
        bad, worst = unforced_below(S, 30.0)
        assert len(bad) > 0
        for among in (rng.random(len(S.F)) < 0.5,
                      (norms(S.X - S.X[rng.integers(S.n)]) < 0.4)[S.F].any(axis=1)):
            got, got_worst = unforced_among(S, 30.0, np.flatnonzero(among))
            assert np.array_equal(got, bad[among[bad]])
            assert np.array_equal(got_worst, worst[among[bad]])
        full, full_worst = unforced_among(S, 30.0)
        assert np.array_equal(full, bad) and np.array_equal(full_worst, worst)


def test_sharp_vertices_at_some_vertices_are_the_whole_answer_read_there():
    """A real remesh with random vertices locked, rim vertices put on input corners
    (barycentric 1) and hole points at some of them: the sharp vertices read at random
    vertices, at every vertex and at the corners of random faces are those of the whole
    remesh there, for minimum angles that make some of them sharp and some not."""
    rng = np.random.default_rng(11)
    S, _ = coarse_state(*disk_map(0.2), 5)
    S.locked[rng.choice(S.n, 8, replace=False)] = True
    rim = np.flatnonzero(S.is_rim)
    on = rng.choice(rim, len(rim) // 2, replace=False)
    S.bary[on] = np.eye(3)[rng.integers(3, size=len(on))]
    S.fixed = S.X[rng.choice(S.n, 6, replace=False)]
    found = set()
    for angle in (10.0, 40.0, 70.0, 130.0):
        whole = sharp_vertices(S, angle)
        found.update(whole.tolist())
        v = rng.integers(S.n, size=40)
        assert np.array_equal(sharp_vertices(S, angle, v), whole[v])
        assert np.array_equal(sharp_vertices(S, angle, np.arange(S.n)), whole)
        faces = rng.choice(len(S.F), 25)
        assert np.array_equal(sharp_among(S, angle, S.F[faces]), whole[S.F[faces]])
        assert np.array_equal(forcing_corners(S, angle, faces), whole[S.F[faces]])
    assert found == {False, True}
