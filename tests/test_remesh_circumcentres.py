"""Graded refinement at off-centres (pipeline.geometry.remesh.circumcentres): the faces beside a
short edge that no flip, move or collapse can raise."""

from __future__ import annotations

import numpy as np

from pipeline.geometry.locate import lift
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.circumcentres import (EDGE_BARY, cap_split, circumcentre_weights,
                                                    encroached, fold_free_round,
                                                    off_centre_weights,
                                                    refine_at_circumcentres, restore_state,
                                                    saved_state, unforced_below,
                                                    unforced_shortfall)
from pipeline.geometry.remesh.improve import _Operations, turned_over_faces
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.rows import norms
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import ccw_delaunay, disk_map, disk_points, remesh_map


def _tri(*P):
    return tuple(np.array([p], float) for p in P)


def test_circumcentre_and_off_centre_weights_are_exact():
    """Right triangle: the circumcentre is the middle of the hypotenuse. Isosceles triangle on
    a base of 2 with apex at height 10 (apex angle 11.4°): its off-centre at 35° is on the
    base's bisector at height 1 / tan(17.5°) = 3.172, at 90° at height 1. With the apex at
    height 1.5 instead, the circumcentre (at height 0.417) is nearer the base than the
    off-centre and is the point."""
    P = _tri([0, 0, 0], [2, 0, 0], [0, 2, 0])
    assert np.allclose(circumcentre_weights(*P), [[0.0, 0.5, 0.5]])
    P = _tri([-1, 0, 0], [1, 0, 0], [0, 10, 0])
    O = off_centre_weights(*P, 35.0) @ np.vstack(P)
    assert np.allclose(O, [[0.0, 1.0 / np.tan(np.radians(17.5)), 0.0]])
    assert np.allclose(off_centre_weights(*P, 90.0) @ np.vstack(P), [[0.0, 1.0, 0.0]])
    P = _tri([-1, 0, 0], [1, 0, 0], [0, 1.5, 0])
    C = circumcentre_weights(*P) @ np.vstack(P)
    assert np.allclose(C, [[0.0, (1.5 ** 2 - 1) / 3, 0.0]])
    assert np.allclose(off_centre_weights(*P, 35.0) @ np.vstack(P), C)


def test_a_triangle_on_one_line_gets_the_middle_of_its_shortest_edge():
    """Corners on one line (exactly, and at 10⁵ scale where rounding leaves a sliver of area):
    no circumcentre, weights (½, ½, 0) on the shortest edge, none of them huge or not finite
    (they were ±10³⁰⁵ and ±10¹⁶, which the domain's coordinates turned into NaN). A needle
    cap 10⁻⁴ high keeps its off-centre on its shortest edge's bisector."""
    P = _tri([0, 0, 0], [10, 0, 0], [30, 0, 0])
    assert np.array_equal(off_centre_weights(*P, 35.0), [[0.5, 0.5, 0.0]])
    a = np.array([0.1, 0.2, 0.3])
    P = _tri(a, a + [1e5, 2e5, 3e5], a + 3 * np.array([1e5, 2e5, 3e5]))
    assert np.array_equal(off_centre_weights(*P, 35.0), [[0.5, 0.5, 0.0]])
    P = _tri([0, 0, 0], [1, 0, 0], [0.6, 1e-4, 0])
    O = off_centre_weights(*P, 35.0) @ np.vstack(P)
    assert np.allclose(norms(O - [[0.8, 0.5e-4, 0.0]]), 0.4 / (2 * np.tan(np.radians(17.5))))


def test_encroached_is_the_open_ball_on_the_diameter():
    A, B = np.array([[0.0, 0, 0]] * 3), np.array([[2.0, 0, 0]] * 3)
    C = np.array([[1.0, 0.99, 0], [1.0, 1.0, 0], [1.0, 0, 1.01]])
    assert encroached(C, A, B).tolist() == [True, False, False]


def test_a_cap_is_split_on_its_long_edge_at_the_foot_of_its_altitude():
    """Face 0 is a cap (its apex (0.5, 0.2) sees the edge (0, 0)–(2, 0) at 150.6°): its
    long edge is half-edge 3·0 + 0 (corner 0 to corner 1), met by the altitude at t = 0.25.
    Face 1 (apex (1, 1), 90°) is no cap. Face 2's apex (0.3, 0.05) sees its edge (0, 0)–(4, 0)
    at 169.8° from over t = 0.075: the split is kept ``EDGE_BARY`` inside the edge."""
    from types import SimpleNamespace

    X = np.array([[0, 0, 0], [2, 0, 0], [0.5, 0.2, 0], [1, 1, 0], [0.3, 0.05, 0.0],
                  [4, 0, 0]], float)
    F = np.array([[0, 1, 2], [0, 1, 3], [0, 5, 4]])
    S = SimpleNamespace(X=X, F=F)
    assert np.degrees(corner_angles(X, F[[0]]))[0, 2] > 120.0
    h, t = cap_split(S, 0)
    assert h == 0 and t == 0.25
    assert cap_split(S, 1) is None
    assert np.degrees(corner_angles(X, F[[2]]))[0, 2] > 120.0
    assert cap_split(S, 2) == (6, EDGE_BARY)


def _short_rim_edge_state(extras=(1,)):
    """A flat disk remesh: the centre, 6 vertices at 0.4, 12 at 0.75 and 24 rim vertices on
    the unit circle (input map points ``loop[::10]``), plus a rim vertex at the input point
    ``loop[e]`` next to one of them for each ``e`` of ``extras`` (a rim edge of 0.026, 1/10 of
    the others), both ends locked (kept boundary corners): the face on that short edge has an
    angle far below 20° at its interior corner."""
    uv_in, F_in, V_in, loop, loc = disk_map(0.0)
    rim = loop[::10]
    inner = np.vstack([np.zeros((1, 2)),
                       0.4 * disk_points(1, 6)[1:], 0.75 * disk_points(2, 6)[7:]])
    uv = np.vstack([inner, uv_in[rim], uv_in[loop[list(extras)]]])
    F = ccw_delaunay(uv)
    face, bary = loc.locate(uv)
    is_rim = np.arange(len(uv)) >= len(inner)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, is_rim, face, bary, V_in, F_in,
                    uv_in, loc, uv_in[loop])
    for i, e in enumerate(extras):
        S.locked[[len(inner) + (e - 1) // 10, len(uv) - len(extras) + i]] = True
    return S


def test_a_face_on_a_short_rim_edge_is_graded_to_the_minimum():
    """Before: one or more faces under 20° at the short rim edge, none forced (the locked
    corners have 180° of input each). After: none under 20°, a counter-clockwise disk, the two
    corners still locked where they were, vertices only added."""
    S = _short_rim_edge_state()
    n0, kept = S.n, S.uv[S.locked].copy()
    count, smallest = unforced_shortfall(S, 20.0)
    assert count >= 1 and smallest < 10.0
    ops = _Operations(S, 0.26, True, 20.0, 0.5, 0.2)
    k = refine_at_circumcentres(S, 20.0, lambda F0: ops.flip(since=F0),
                                lambda: turned_over_faces(S))
    assert k >= 1 and S.n == n0 + k and S.log["circumcentre_insertions"] == k
    assert np.degrees(corner_angles(S.X, S.F)).min() >= 20.0
    assert unforced_shortfall(S, 20.0) == (0, 180.0)
    assert np.all(signed_double_areas(S.uv, S.F) > 0) and is_disk(mesh_facts(S.X, S.F))
    assert np.array_equal(S.uv[S.locked], kept)
    assert np.abs(S.X[:, 2]).max() == 0.0


def test_a_round_that_turns_faces_over_is_made_again_without_the_faces_at_folds():
    """Two short rim edges, at ``loop[1]`` and across the disk at ``loop[121]``; a stand-in
    for the fold test counts as turned over the faces at the first edge's locked end ``v``
    and those with a vertex added within 0.3 of it (an insertion there turns faces over). The
    first round inserts at both edges and adds folds; made again without the faces at a fold,
    it grades the far edge alone: its faces reach 20°, no vertex is added near ``v``, and
    the face on the first edge stays below (judged whole, the round would be undone, no
    vertex kept)."""
    S = _short_rim_edge_state((1, 121))
    n0 = S.n
    v, far, w, far_extra = np.flatnonzero(S.locked)     # loop[0], loop[120], loop[1], loop[121]

    def folds():
        new = (np.arange(S.n) >= n0) & (np.linalg.norm(S.uv - S.uv[v], axis=1) < 0.3)
        return np.flatnonzero((S.F == v).any(axis=1) | new[S.F].any(axis=1))

    ops = _Operations(S, 0.26, True, 20.0, 0.5, 0.2)
    k = refine_at_circumcentres(S, 20.0, lambda F: ops.flip(since=F), folds)
    assert k >= 1 and S.n == n0 + k
    assert np.linalg.norm(S.uv[n0:] - S.uv[v], axis=1).min() >= 0.3
    A = np.degrees(corner_angles(S.X, S.F)).min(axis=1)
    at_w = np.isin(S.F, [far, far_extra]).any(axis=1)
    at_v = (S.F == v).any(axis=1) & (S.F == w).any(axis=1)
    assert A[at_w].min() >= 20.0 and A[at_v].min() < 20.0


def test_rounds_stop_after_patience_rounds_that_beat_no_earlier_state():
    """On the short rim edge, with flips alone after each round, the first round leaves the
    faces worse than the start (the inserted vertex not yet settled): with a patience of one
    the rounds stop there and the remesh is the start, unchanged, no vertex added."""
    S = _short_rim_edge_state()
    F0, X0 = S.F.copy(), S.X.copy()
    before = unforced_shortfall(S, 20.0)
    ops = _Operations(S, 0.26, True, 20.0, 0.5, 0.2)
    k = refine_at_circumcentres(S, 20.0, lambda F: ops.flip(since=F),
                                lambda: turned_over_faces(S), patience=1)
    assert k == 0 and S.log["circumcentre_insertions"] == 0
    assert np.array_equal(S.F, F0) and np.array_equal(S.X, X0)
    assert unforced_shortfall(S, 20.0) == before


def test_rounds_stop_after_one_that_changes_nothing_measurable():
    """On the short rim edge, with a ``flip`` that undoes each round's insertions (as the
    local operations do where they collapse them all again), every round ends where it
    started: the rounds stop after the first (not after ``ROUNDS``, there being no
    patience), no vertex is kept and the remesh is the start."""
    S = _short_rim_edge_state()
    start, F0, X0 = saved_state(S), S.F.copy(), S.X.copy()
    calls = []

    def undo(F_before):
        calls.append(len(S.F) - len(F_before))
        restore_state(S, {key: value.copy() for key, value in start.items()})

    k = refine_at_circumcentres(S, 20.0, undo, lambda: turned_over_faces(S))
    assert len(calls) == 1 and calls[0] > 0
    assert k == 0 and np.array_equal(S.F, F0) and np.array_equal(S.X, X0)


def test_a_round_passes_over_the_faces_at_points_to_avoid():
    """With ``avoid`` at the corners of every face to refine, a round inserts nothing and
    leaves the remesh as it was; without, it inserts. Made again without the faces at folds
    (the two short rim edges and the fold stand-in of the test above), it returns the
    corners of the faces at folds, ``v`` among them, for the later rounds to avoid, and
    keeps the far edge's insertions."""
    S = _short_rim_edge_state()
    F0, X0 = S.F.copy(), S.X.copy()
    ops = _Operations(S, 0.26, True, 20.0, 0.5, 0.2)
    bad, _ = unforced_below(S, 20.0)
    k, near = fold_free_round(S, 20.0, False, lambda F: ops.flip(since=F),
                              lambda: np.zeros(0, np.int64), 0, avoid=S.X[S.F[bad].ravel()])
    assert k == 0 and len(near) == 0
    assert np.array_equal(S.F, F0) and np.array_equal(S.X, X0)
    k, near = fold_free_round(S, 20.0, False, lambda F: ops.flip(since=F),
                              lambda: np.zeros(0, np.int64), 0)
    assert k >= 1 and len(near) == 0

    S = _short_rim_edge_state((1, 121))
    n0, v = S.n, np.flatnonzero(S.locked)[0]

    def folds():
        new = (np.arange(S.n) >= n0) & (np.linalg.norm(S.uv - S.uv[v], axis=1) < 0.3)
        return np.flatnonzero((S.F == v).any(axis=1) | new[S.F].any(axis=1))

    ops = _Operations(S, 0.26, True, 20.0, 0.5, 0.2)
    k, near = fold_free_round(S, 20.0, False, lambda F: ops.flip(since=F), folds,
                              len(folds()))
    assert k >= 1 and S.n == n0 + k
    assert (near == S.X[v]).all(axis=1).any()
    assert np.linalg.norm(S.uv[n0:] - S.uv[v], axis=1).min() >= 0.3


def test_real_mesh_faces_beside_short_rim_edges_are_graded_to_the_minimum():
    """choi_human_brain at 5k vertices on the 2-step paper map (``bench_remesh.py --maps
    paper2``): the local operations alone left 7 faces under 20° (12.08°) beside short rim
    edges, none at a sharp input corner; the refinement inserts vertices there and every face
    reaches 20°, with the count within 2 % and one disk."""
    from conftest import require_data
    from pipeline.stages.load import load_stage
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    mesh = load_stage(require_data("meshes", "choi_human_brain.obj")).mesh
    uv = remesh_map(mesh)
    r = remesh_stage(mesh, uv, RemeshConfig(vertices=5000))
    imp = r.info["improve"]
    assert imp["circumcentre_insertions"] > 0
    assert np.degrees(corner_angles(r.V, r.F)).min() >= 20.0
    assert imp["below_min_angle"]["faces"] == imp["below_min_angle"]["unforced_faces"] == 0
    assert abs(len(r.V) - 5000) <= 0.02 * 5000 and is_disk(mesh_facts(r.V, r.F))


def test_real_mesh_rounds_with_the_local_operations_leave_no_unforced_face():
    """gpp_face at 20k vertices on the map ``sem-pipeline remesh`` makes (``mode: auto``):
    beside a rim edge between two kept boundary corners and at a reflex stretch of its jagged
    rim, faces of 14.9° and 16.9° were left that no operation raised and that single rounds
    of insertions made worse (each new vertex left where it was inserted); with the local
    operations after every round (:meth:`_Operations.flip_and_raise`) the faces under 20°
    left are only those at the corners the input forces (a 27° rim corner)."""
    from conftest import require_data
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.load import load_stage
    from pipeline.stages.parameterize import parameterize_stage
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    mesh = load_stage(require_data("meshes", "gpp_face.obj")).mesh
    p = parameterize_stage(mesh, SEMOptions(mode="auto"))
    r = remesh_stage(mesh, p.image, RemeshConfig(vertices=20000))
    below = r.info["improve"]["below_min_angle"]
    assert r.info["improve"]["circumcentre_insertions"] > 0
    assert below["unforced_faces"] == 0 and below["faces"] == below["at_input_corners"] > 0
    assert abs(len(r.V) - 20000) <= 0.02 * 20000 and is_disk(mesh_facts(r.V, r.F))


def test_a_short_edge_between_kept_vertices_is_graded_on_the_sphere():
    """The sphere's remesh is refined as the disk's: an icosphere (642 vertices) mapped by
    itself, with a vertex added at 1/10 of an edge from vertex 0 and both locked (a short
    edge between kept corners, no input corner: the input is smooth). The faces on that edge
    have their far angle far below 20°; the refinement inserts vertices at their
    off-centres, on the unit sphere, and leaves none below 20°, every face outward, the two
    kept vertices where they were."""
    from test_remesh_sphere import icosphere

    from pipeline.geometry.locate_sphere import SphereLocator
    from pipeline.geometry.remesh.domain import project
    from pipeline.geometry.remesh.sphere import hull_triangulation
    from pipeline.geometry.sphere import triple_products

    V, F = icosphere(3)
    near = np.argsort(np.linalg.norm(V - V[0], axis=1))[1]
    uv = np.vstack([V, project(V[[0]] + 0.1 * (V[[near]] - V[[0]]))])
    T = hull_triangulation(uv)
    loc = SphereLocator(V, F)
    face, bary = loc.locate(uv)
    S = RemeshState(lift(V, F, face, bary), T, uv, np.zeros(len(uv), bool), face, bary, V, F,
                    V, loc, np.zeros((0, 3)), surface_middles=True)
    S.locked[[0, len(V)]] = True
    kept, n0 = S.uv[S.locked].copy(), S.n
    before = unforced_shortfall(S, 20.0)
    assert before[0] >= 2 and before[1] < 10.0
    L = float(np.linalg.norm(V[near] - V[0]))
    ops = _Operations(S, L, True, 20.0, 0.5, 0.2)
    k = refine_at_circumcentres(S, 20.0, lambda F0: ops.flip(since=F0),
                                lambda: turned_over_faces(S))
    assert k >= 1 and S.n == n0 + k
    assert unforced_shortfall(S, 20.0) == (0, 180.0)
    assert np.allclose(np.linalg.norm(S.uv, axis=1), 1.0, atol=1e-12)
    assert np.all(triple_products(S.uv, S.F) > 0)
    assert np.array_equal(S.uv[S.locked], kept)


def test_unforced_below_only_at_points_is_the_full_answer_filtered():
    """``unforced_below`` with ``only`` (points) gives exactly the faces of the full answer
    whose corners are all at these points, with the same angles, worst first: for every face
    of the short rim edge's state alone, for the corners of all faces below (the full answer
    itself), and for points at no vertex (nothing)."""
    S = _short_rim_edge_state()
    bad, worst = unforced_below(S, 20.0)
    assert len(bad) >= 1
    for f in range(len(S.F)):
        got, angles = unforced_below(S, 20.0, only=S.X[S.F[f]])
        hit = bad == f
        assert np.array_equal(got, bad[hit]) and np.array_equal(angles, worst[hit])
    got, angles = unforced_below(S, 20.0, only=S.X[S.F[bad].ravel()])
    assert np.array_equal(got, bad) and np.array_equal(angles, worst)
    got, angles = unforced_below(S, 20.0, only=S.X[S.F[bad[0]]] + 1.0)
    assert len(got) == 0 and len(angles) == 0
