"""The minimum-angle guarantee (pipeline.geometry.remesh.angles): local operations on the faces
with a small 3D angle, and the faces an input corner forces."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry import topology as topo
from pipeline.geometry._kernels import star_targets
from pipeline.geometry.locate import PointLocator, lift
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.angles import (face_min_angles, forced_by_corners,
                                             raise_min_angles, triangle_min_angles)
from pipeline.geometry.rows import cross, norms
from pipeline.geometry.remesh.improve import skinny_faces
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh.uniform import below_min_angle
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from test_remesh_improve import _flat_or_tent_state, _moved


def _smallest(S):
    return np.degrees(corner_angles(S.X, S.F)).min()


def _fan_faces(k: int, d: int) -> np.ndarray:
    """The faces ``(i, k + m, k + d + m)`` of ``k`` positions of a vertex with a star of ``d``
    faces, the points stacked as ``[positions (k), B (d), C (d)]``, position by position."""
    T = np.empty((k, d, 3), np.int64)
    T[:, :, 0] = np.arange(k)[:, None]
    T[:, :, 1] = k + np.arange(d)
    T[:, :, 2] = k + d + np.arange(d)
    return T.reshape(-1, 3)


def _fan_angles_areas(Q, B, C):
    """The numpy formulas of the move's scoring: the smallest angle of each face ``(Q[i],
    B[m], C[m])`` (:func:`face_min_angles`) and its double area ``|(B − Q) × (C − Q)|``
    (k×d each)."""
    k, d = len(Q), len(B)
    angle = face_min_angles(np.vstack([Q, B, C]), _fan_faces(k, d)).reshape(k, d)
    Q3 = Q[:, None, :]
    return angle, norms(cross(B[None] - Q3, C[None] - Q3).reshape(-1, 3)).reshape(k, d)


def _ideal_points(A, B, C):
    """The apex over the middle of ``B–C`` at ``√3/2 |C − B|`` along the in-plane normal of
    ``B–C`` turned to ``A``'s side (the equilateral triangle's), as numpy computes it."""
    e, mid = C - B, 0.5 * (B + C)
    w = cross(cross(B - A, C - A), e)
    w /= np.maximum(norms(w), 1e-300)[:, None]
    w *= np.where(np.einsum("ij,ij->i", w, A - mid) >= 0, 1.0, -1.0)[:, None]
    return mid + (np.sqrt(3.0) / 2.0) * norms(e)[:, None] * w


def _apexes(A, B, C):
    """The move's ideal point of each triangle ``(A, B, C)``: :func:`star_targets`' target of
    the worst face of the one-face star ``(A, B, C)``."""
    return np.array([star_targets(np.array([a, b, c]), np.array([[0, 1, 2]], np.int64), 0)[4][1]
                     for a, b, c in zip(A, B, C)])


def test_triangle_min_angles_and_ideal_points_are_exact():
    P0, P1, P2 = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    assert abs(triangle_min_angles(P0, P1, P2)[0] - 45.0) < 1e-12
    # the apex that makes the triangle equilateral, on the side of the given one
    A = _apexes(np.array([[0.5, 0.1, 0.0]]), np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]))
    assert np.allclose(A, [[0.5, np.sqrt(3) / 2, 0.0]])
    A = _apexes(np.array([[0.5, -0.1, 0.0]]), np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]))
    assert np.allclose(A, [[0.5, -np.sqrt(3) / 2, 0.0]])


def test_face_min_angles_are_the_numpy_formula_bit_for_bit():
    """The compiled smallest angle of each face is ``angles_of_cosines`` of the largest of
    its corners' cosines to the bit: random faces, a right and a straight one, and faces
    with coincident corners (0)."""
    from pipeline.geometry._kernels import corner_cosines
    from pipeline.geometry.remesh.angles import angles_of_cosines

    rng = np.random.default_rng(4)
    X = np.vstack([rng.normal(size=(200, 3)), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]]])
    T = np.vstack([rng.integers(0, 200, (3000, 3)),
                   [[200, 201, 202], [200, 201, 203], [200, 200, 201], [201, 201, 201]]])
    got = face_min_angles(X, T)
    assert got.tobytes() == angles_of_cosines(corner_cosines(X, T).max(axis=1)).tobytes()
    assert abs(got[-4] - 45.0) < 1e-12 and got[-3] == 0.0
    assert got[-2] == 0.0 and got[-1] == 0.0


def test_replacement_angle_is_the_numpy_judgement():
    """The compiled judgement of a replacement (old faces by new ones) is the numpy one of
    ``_Patch.better``: the new faces' smallest angle where it is larger than the old faces',
    with no more faces below the threshold and (given a mean area) no larger sum of squared
    relative area deviations, else nan; on random replacements every branch is taken."""
    from pipeline.geometry._kernels import replacement_angle
    from pipeline.geometry.laplacian import face_double_areas

    rng = np.random.default_rng(6)
    X = rng.normal(size=(40, 3))
    taken = set()
    for _ in range(3000):
        n_old, n_new = rng.integers(1, 7, 2)
        T = np.array([rng.choice(40, 3, replace=False) for _ in range(n_old + n_new)])
        threshold, count_below = float(rng.uniform(10, 40)), bool(rng.integers(2))
        mean = float(rng.uniform(0.5, 2.0)) if rng.integers(2) else None
        a = face_min_angles(X, T)
        want = float(a[n_old:].min())
        if a[n_old:].min() <= a[:n_old].min():
            want, why = np.nan, "angle"
        elif count_below and (a[n_old:] < threshold).sum() > (a[:n_old] < threshold).sum():
            want, why = np.nan, "count"
        elif mean is not None and (
                float(((face_double_areas(X, T) / mean - 1) ** 2)[n_old:].sum())
                > float(((face_double_areas(X, T) / mean - 1) ** 2)[:n_old].sum())):
            want, why = np.nan, "spread"
        else:
            why = "better"
        taken.add(why)
        got = replacement_angle(X, T, n_old, threshold, count_below,
                                np.nan if mean is None else mean)
        assert (np.isnan(got) and np.isnan(want)) or got == want
    assert taken == {"angle", "count", "spread", "better"}


def test_ideal_points_are_the_numpy_formula_bit_for_bit():
    # a degenerate triangle among them: its apex is the middle of B-C
    rng = np.random.default_rng(5)
    A, B, C = (rng.standard_normal((9, 3)) * 10.0 ** rng.uniform(-3, 3, (9, 1)) for _ in range(3))
    A[0] = B[0]
    expected = _ideal_points(A, B, C)
    assert np.array_equal(_apexes(A, B, C), expected)
    assert np.array_equal(expected[0], 0.5 * (B[0] + C[0]))


def _with_cap():
    """The flat 37-vertex remesh with an inner vertex pushed almost onto the edge between two of
    its neighbours: a cap (an angle near 180°) and needles around it."""
    S = _flat_or_tent_state(0.0)
    a, b, p = S.F[np.flatnonzero(~S.is_rim[S.F].any(axis=1))[0]]
    S.uv, S.face, S.bary, S.X = _moved(S, p, 0.02 * S.uv[p] + 0.49 * (S.uv[a] + S.uv[b]))
    return S, int(p)


def test_a_cap_is_removed_and_every_face_reaches_the_minimum():
    """Before: the flat remesh is at least 20° everywhere but around the pushed vertex (a cap
    under 5°). After: every face at least 20°, the rim untouched, still a counter-clockwise
    disk on the surface (flat: z = 0)."""
    S0 = _flat_or_tent_state(0.0)
    assert _smallest(S0) >= 20.0
    S, _ = _with_cap()
    rim_before = S.uv[S.is_rim].copy()
    assert _smallest(S) < 5.0 and np.all(signed_double_areas(S.uv, S.F) > 0)
    done = raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0))
    assert done >= 1 and S.log["min_angle_operations"] == done
    assert _smallest(S) >= 20.0
    assert np.all(signed_double_areas(S.uv, S.F) > 0) and is_disk(mesh_facts(S.X, S.F))
    assert np.array_equal(S.uv[S.is_rim], rim_before)
    assert np.abs(S.X[:, 2]).max() == 0.0
    assert not forced_by_corners(S, 20.0).any()


def test_a_locked_vertex_is_neither_moved_nor_removed():
    """The same cap with the pushed vertex locked (an input corner): the pass fixes what it can
    around it with the other vertices and keeps the locked one where it is."""
    S, p = _with_cap()
    S.locked[p] = True
    at, n0 = S.uv[p].copy(), S.n
    assert raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0)) >= 1
    assert S.n == n0 and np.flatnonzero(S.locked).tolist() == [p]
    assert np.array_equal(S.uv[p], at)
    assert np.all(signed_double_areas(S.uv, S.F) > 0)


def _kite(lock_tip: bool):
    """A flat kite: faces (tip, B, C) with a 14.8° angle at the tip (an input boundary corner
    that sharp) and (B, D, C) with angles 24.5°, 77.7°, 77.7°; the remesh is the input itself,
    the tip locked if asked (as :mod:`.corners` does)."""
    uv = np.array([[0.0, 0.0], [1.0, -0.13], [1.6, 0.0], [1.0, 0.13]])
    F = np.array([[0, 1, 3], [1, 2, 3]])
    V = np.column_stack([uv, np.zeros(4)])
    loop = topo.boundary_loops(F)[0]
    loc = PointLocator(uv, F, loop)
    face, bary = loc.locate(uv)
    S = RemeshState(lift(V, F, face, bary), F.copy(), uv.copy(), np.ones(4, bool), face, bary,
                    V, F, uv, loc, uv[loop])
    S.locked[0] = lock_tip
    return S


def test_a_corner_sharper_than_the_minimum_is_reported_not_fixed():
    """The kite's tip is sharper than 20°: its face stays (no operation can raise it), is
    flagged as forced by the input, and the report names the tip; the other face is not
    flagged. Unlocked, the tip is still a rim vertex on the input's corner (no operation
    moves it): the same face is forced; a rim vertex on the rim edge next to the corner,
    off it, forces nothing."""
    S = _kite(lock_tip=True)
    assert abs(np.degrees(corner_angles(S.X, S.F))[0, 0] - 2 * np.degrees(np.arctan(0.13))) < 1e-9
    assert raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0)) == 0
    assert np.array_equal(S.F, [[0, 1, 3], [1, 2, 3]])
    assert forced_by_corners(S, 20.0).tolist() == [True, False]
    below = below_min_angle(S, S.V_in, 20.0)
    tip = 2 * np.degrees(np.arctan(0.13))
    corner = below.pop("input_corners")
    assert below == {"threshold_deg": 20.0, "faces": 1, "at_input_corners": 1,
                     "unforced_faces": 0, "input_corner_vertices": [0]}
    assert len(corner) == 1 and (corner[0]["vertex"], corner[0]["faces"]) == (0, 1)
    assert corner[0]["angle_sum_deg"] == pytest.approx(tip, abs=1e-9)
    assert corner[0]["smallest_angle_deg"] == pytest.approx(tip, abs=1e-9)
    assert forced_by_corners(S, 14.0).tolist() == [False, False]    # 14.8° is not below
    S = _kite(lock_tip=False)
    assert forced_by_corners(S, 20.0).tolist() == [True, False]
    assert below_min_angle(S, S.V_in, 20.0)["at_input_corners"] == 1
    S.uv, S.face, S.bary, S.X = _moved(S, 0, 0.99 * S.uv[0] + 0.01 * S.uv[1])
    assert 0.98 < S.bary[0].max() < 1.0 and skinny_faces(S.X, S.F, 20.0).tolist() == [0]
    assert forced_by_corners(S, 20.0).tolist() == [False, False]
    assert below_min_angle(S, S.V_in, 20.0)["unforced_faces"] == 1


@pytest.mark.parametrize("rel, n", [("meshes/choi_human_face.obj", 20000),
                                   ("meshes/choi_chinese_lion.obj", 20000),
                                   ("meshes/choi_hand.obj", 5000)])
def test_real_mesh_every_face_reaches_the_minimum_but_those_corners_force(rel, n):
    """On the paper-mode map (the map ``sem-pipeline remesh`` uses on a disk), the pass acts
    and every face left under 20° is one the report names as forced by an input corner (here:
    none is left; choi_hand at 5k has a 282° reflex rim corner whose fan the pass's collapses
    leave as two caps of 142° and 140°, which :meth:`_Operations.open_fans` opens)."""
    from conftest import require_data
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.load import load_stage
    from pipeline.stages.parameterize import parameterize_stage
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    mesh = load_stage(require_data(*rel.split("/"))).mesh
    p = parameterize_stage(mesh, SEMOptions(mode="paper"))
    r = remesh_stage(mesh, p.uv, RemeshConfig(vertices=n))
    imp = r.info["improve"]
    smallest = np.degrees(corner_angles(r.V, r.F)).min(axis=1)
    assert imp["min_angle_operations"] > 0
    assert imp["below_min_angle"]["faces"] == int((smallest < 20.0).sum())
    assert imp["below_min_angle"]["faces"] == imp["below_min_angle"]["at_input_corners"]
    assert abs(len(r.V) - n) <= 0.02 * n


def _rim_corner_fan(tip_deg: float, split_deg: float, r: float = 0.5, d: float = 1.3):
    """A flat fan: a rim tip ``O`` of ``tip_deg`` between ``P1`` and ``P2`` (1 from ``O``)
    whose interior vertex ``M`` (``r`` from ``O``) splits it into ``split_deg`` and
    ``tip_deg − split_deg``, the rim's fourth vertex ``D`` at ``d`` on the tip's bisector
    (the defaults: every face at least 20° but the one at the narrow side of the tip); the
    remesh is the input itself, ``O`` locked. Returns the state."""
    h = np.radians(tip_deg / 2)
    m = np.radians(split_deg) - h
    uv = np.array([[0.0, 0.0], [np.cos(h), -np.sin(h)], [d, 0.0], [np.cos(h), np.sin(h)],
                   [r * np.cos(m), r * np.sin(m)]])                      # O P1 D P2 M
    F = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [4, 3, 0]])
    V = np.column_stack([uv, np.zeros(len(uv))])
    loop = topo.boundary_loops(F)[0]
    loc = PointLocator(uv, F, loop)
    face, bary = loc.locate(uv)
    S = RemeshState(lift(V, F, face, bary), F.copy(), uv.copy(), np.arange(5) < 4, face, bary,
                    V, F, uv, loc, uv[loop])
    S.locked[0] = True
    return S


def test_a_rim_corner_under_twice_the_minimum_forces_its_two_faces():
    """A flat fan: a rim tip ``O`` of 30° split by an interior vertex ``M`` into two faces of
    15° (a rim vertex has at least two faces: one would be a leaf). 30° is more than 20° but
    less than 2 × 20°: both faces are forced, no operation changes them, the other two faces
    (at least 22°) are not flagged."""
    S = _rim_corner_fan(30.0, 15.0, 1.0, 1.6)
    F = S.F.copy()
    A = np.degrees(corner_angles(S.X, S.F))
    assert np.allclose([A[0, 0], A[3, 2]], 15.0) and A[[1, 2]].min() > 20.0
    assert raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0)) == 0
    assert np.array_equal(S.F, F)
    assert forced_by_corners(S, 20.0).tolist() == [True, False, False, True]
    below = below_min_angle(S, S.V_in, 20.0)
    assert (below["faces"], below["at_input_corners"], below["input_corner_vertices"]) == (2, 2, [0])
    assert below["unforced_faces"] == 0
    assert [(c["vertex"], c["faces"]) for c in below["input_corners"]] == [(0, 2)]
    assert below["input_corners"][0]["angle_sum_deg"] == pytest.approx(30.0, abs=1e-9)
    assert below["input_corners"][0]["smallest_angle_deg"] == pytest.approx(15.0, abs=1e-9)


@pytest.mark.parametrize("tent", [0.0, 0.5])
def test_splits_for_the_count_add_exactly_k_and_make_no_face_below(tent):
    """``split_for_count`` adds the vertices asked for, and no face it makes is below the
    minimum (or below the faces it replaced): on the flat remesh and over the tent."""
    from pipeline.geometry.remesh.angles import split_for_count

    S = _flat_or_tent_state(tent)
    n0, before = S.n, _smallest(S)
    assert split_for_count(S, 4, 20.0) == 4 and S.n == n0 + 4
    assert _smallest(S) >= min(20.0, before) - 1e-9
    assert np.all(signed_double_areas(S.uv, S.F) > 0) and is_disk(mesh_facts(S.X, S.F))


def test_sharp_input_vertices_close_together_keep_one_vertex_between_them():
    """The ICT face (the disk cut of ``ict_A_neutral``) has sharp input vertices (angle sums
    30° or more from flat) 0.3 L apart at 20k vertices. Each kept corner is a locked vertex, and
    three of them that close made faces of 13° that no operation may change; a corner within
    :data:`.improve.CORNER_GAP` × L of a sharper one keeps none, and every face reaches 20°
    (none forced), with the count within 2 % and one disk."""
    from conftest import require_data
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.load import load_stage
    from pipeline.stages.parameterize import parameterize_stage
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    mesh = load_stage(require_data("faces", "ict", "ict_A_neutral_disk.obj")).mesh
    p = parameterize_stage(mesh, SEMOptions(mode="paper"))
    r = remesh_stage(mesh, p.uv, RemeshConfig(vertices=20000))
    assert np.degrees(corner_angles(r.V, r.F)).min() >= 20.0
    assert r.info["improve"]["below_min_angle"]["faces"] == 0
    assert abs(len(r.V) - 20000) <= 0.02 * 20000 and is_disk(mesh_facts(r.V, r.F))


def test_star_shapes_ok_drops_exactly_the_positions_that_fold_or_flatten_the_star():
    """A vertex inside a unit square ring (4 faces, counter-clockwise): a position inside the
    square keeps every face counter-clockwise; one past an edge folds the face on it; one on an
    edge flattens that face to zero area (below ``DISK_SHAPE_MIN``)."""
    from pipeline.geometry.remesh.angles import star_shapes_ok

    ring = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    BC = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    M = np.array([[0.0, 0.0], [0.3, 0.2], [0.6, 0.6], [0.5, 0.5], [-0.2, -0.7]])
    assert star_shapes_ok(ring, M, BC).tolist() == [True, True, False, False, True]


def _rim_cap_on_a_bump(height: float):
    """The 37-vertex remesh of the unit disk (:func:`test_remesh_improve._flat_or_tent_state`'s
    points) with the inner corner ``p`` of a face on a rim edge ``a–b`` moved (on the disk)
    almost onto that edge, over an input with a cone of ``height`` and radius 0.05 whose apex
    is exactly there (an input vertex): ``p`` stands on the bump's tip, the face a cap with
    small angles at ``a`` and ``b``. Returns the state and ``p``."""
    from remesh_helpers import ccw_delaunay, disk_points

    uv = 0.9 * disk_points(3, 6)
    F = ccw_delaunay(uv)
    rim = np.linalg.norm(uv, axis=1) > 0.85
    t = np.flatnonzero(rim[F].sum(axis=1) == 2)[0]
    p, a, b = np.roll(F[t], -np.flatnonzero(~rim[F[t]])[0])
    uv[p] = 0.02 * uv[p] + 0.49 * (uv[a] + uv[b])
    uv_in = np.vstack([disk_points(40, 6), uv[p]])
    F_in = ccw_delaunay(uv_in)
    V_in = np.column_stack([uv_in, height * np.maximum(
        0.0, 1.0 - np.linalg.norm(uv_in - uv[p], axis=1) / 0.05)])
    loop = topo.boundary_loops(F_in)[0]
    loc = PointLocator(uv_in, F_in, loop)
    face, bary = loc.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, rim, face, bary, V_in, F_in, uv_in, loc,
                    uv_in[loop])
    return S, int(p)


def test_a_cap_on_a_bump_the_guards_keep_is_raised_by_the_last_resort():
    """``p`` is 0.04 above the rim edge it nearly lies on (tolerance 0.02, ``L`` 0.1): its
    faces' smallest angles are under 20° on the surface. On the flat disk the guarded local
    operations raise every face to 20°; on the bump every operation that raises the cap moves
    or removes ``p`` and leaves the bump's tip farther than the tolerance from the remesh (the
    gap guard), so one face stays below, no input corner forcing it.
    :meth:`_Operations.last_resort` (guards 2 and 4 times looser) raises it: every face at
    20° or more, one counter-clockwise disk, the tip within 4 × the tolerance of the
    remesh."""
    from pipeline.geometry.remesh.circumcentres import unforced_shortfall
    from pipeline.geometry.remesh.improve import LAST_RESORT, _Operations
    from pipeline.geometry.remesh_quality import point_mesh_distance

    S, _ = _rim_cap_on_a_bump(0.0)
    assert _smallest(S) < 20.0
    raise_min_angles(S, 20.0, 0.02, skinny_faces(S.X, S.F, 20.0))
    assert _smallest(S) >= 20.0
    S, p = _rim_cap_on_a_bump(0.04)
    tip = S.X[p].copy()
    assert tip[2] == pytest.approx(0.04, abs=1e-12) and _smallest(S) < 20.0
    ops = _Operations(S, 0.1, True, 20.0, 0.5, 0.2)
    assert ops.tol == pytest.approx(0.02)
    raise_min_angles(S, 20.0, ops.tol, skinny_faces(S.X, S.F, 20.0))
    assert unforced_shortfall(S, 20.0)[0] == 1 and _smallest(S) < 20.0
    ops.last_resort(20.0)
    assert _smallest(S) >= 20.0 and unforced_shortfall(S, 20.0) == (0, 180.0)
    assert np.all(signed_double_areas(S.uv, S.F) > 0) and is_disk(mesh_facts(S.X, S.F))
    assert point_mesh_distance(tip[None], S.X, S.F)[0][0] <= LAST_RESORT[-1] * ops.tol


def test_a_forced_rim_corner_is_shared_out_evenly_when_judged_on_the_smallest_angle():
    """A 30° rim tip split 3° + 27° by its interior vertex ``M``: 30 < 2 × 20, so a face
    there must stay below 20°. The usual judgement (no more faces below the minimum) moves
    ``M`` only while the wide side keeps 20°: the narrow face gets at most the 10° left.
    Judged on the smallest angle alone (``count_below`` False), ``M`` moves onto the tip's
    bisector: both faces 15° there (the corner's sum over its two faces), the smallest
    angle of the fan, the rim untouched; both faces forced, the report naming the tip with
    15°. The corner-by-corner step of the pass (:meth:`_Operations.raise_forced`) makes the
    same, its check passing (no face below 20° that no corner forces, no fold)."""
    from pipeline.geometry.remesh.circumcentres import unforced_shortfall
    from pipeline.geometry.remesh.improve import _Operations

    S = _rim_corner_fan(30.0, 3.0)
    A = np.degrees(corner_angles(S.X, S.F))
    assert A[0, 0] == pytest.approx(3.0, abs=1e-9) and A[3, 2] == pytest.approx(27.0, abs=1e-9)
    assert np.delete(A, 0, axis=0).min() > 20.0
    assert forced_by_corners(S, 20.0).tolist() == [True, False, False, False]
    assert raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0)) >= 1
    A = np.degrees(corner_angles(S.X, S.F))
    assert 3.0 < A[0, 0] <= 10.0 and A[3, 2] >= 20.0
    assert A[0, 0] + A[3, 2] == pytest.approx(30.0, abs=1e-9)
    for shared in ("operations", "pass"):
        S = _rim_corner_fan(30.0, 3.0)
        rim = S.X[S.is_rim].copy()
        if shared == "operations":
            assert raise_min_angles(S, 20.0, 0.05, skinny_faces(S.X, S.F, 20.0),
                                    count_below=False) >= 1
        else:
            _Operations(S, 0.5, True, 20.0, 0.5, 0.2).raise_forced(20.0)
        A = np.degrees(corner_angles(S.X, S.F))
        assert np.array_equal(S.F, _rim_corner_fan(30.0, 3.0).F)
        assert np.array_equal(S.X[S.is_rim], rim)
        assert A[0, 0] == pytest.approx(15.0, abs=1e-6) and A[3, 2] == pytest.approx(15.0, abs=1e-6)
        assert A.min() == pytest.approx(15.0, abs=1e-6)
        assert forced_by_corners(S, 20.0).tolist() == [True, False, False, True]
        assert unforced_shortfall(S, 20.0) == (0, 180.0)
        below = below_min_angle(S, S.V_in, 20.0)
        assert [(c["vertex"], c["faces"]) for c in below["input_corners"]] == [(0, 2)]
        assert below["input_corners"][0]["smallest_angle_deg"] == pytest.approx(15.0, abs=1e-6)
        assert below["input_corners"][0]["even_split_deg"] == pytest.approx(15.0, abs=1e-9)


def _same_bits(a, b) -> bool:
    """Equal arrays bit for bit (a -0.0 differs from 0.0)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("d", [1, 5, 8, 13, 140])
def test_fan_scores_are_the_numpy_formula_bit_for_bit(d):
    """:func:`.._kernels.fan_scores` (the move's scoring of its candidate positions): the
    star's smallest angle at each position, -1 outside the map, with more faces below the
    threshold than before, or with a larger sum of squared relative area deviations — the
    numpy formula it replaces, bit for bit, for stars of fewer and more than 8 faces (numpy
    sums a row in blocks of 8 from there) and more than 128 (halves), with a coincident
    corner (nan cosine: angle 0) and a degenerate face among them; every outcome occurs."""
    from pipeline.geometry._kernels import fan_scores

    rng = np.random.default_rng(17)
    k = 40
    Q = rng.standard_normal((k, 3)) * 0.3
    B, C = rng.standard_normal((d, 3)), rng.standard_normal((d, 3))
    Q[3] = B[0]                                   # coincident corners
    C[-1] = B[-1] * 2.0 - Q[5] * 1.0              # on the line of Q[5] and B[-1]: degenerate
    inside = rng.random(k) < 0.8
    each, A2 = _fan_angles_areas(Q, B, C)
    below = int(np.median((each < 30.0).sum(axis=1)))
    mean_area = float(A2.mean())
    dev = ((A2 / mean_area - 1) ** 2).sum(axis=1)
    spread = float(np.median(dev))
    for count, area in [(below, mean_area), (-1, mean_area), (below, np.nan), (-1, np.nan)]:
        more = (each < 30.0).sum(axis=1) > below if count >= 0 else np.zeros(k, bool)
        if area == area:
            more |= dev > spread
        want = np.where(inside & ~more, each.min(axis=1, initial=180.0), -1.0)
        got = fan_scores(Q, B, C, inside.view(np.uint8), 30.0, count, area, spread)
        assert _same_bits(got, want)
    assert (got == -1.0).any() and (got >= 0).any() and got[3] == 0.0
    both = fan_scores(Q, B, C, inside.view(np.uint8), 30.0, below, mean_area, spread)
    assert (both == -1.0).sum() > (got == -1.0).sum()


def test_star_targets_are_the_numpy_formula_bit_for_bit():
    """:func:`.._kernels.star_targets` (what the move computes before its steps): the corners,
    normals ``(B − x) × (C − x)``, their sum and the three targets (mean ideal point, that of
    the worst face, the centroid of the distinct ring vertices in increasing order), bit for
    bit as numpy computes them — a flat star too, whose normals' zero components are -0.0
    where numpy gives -0.0 and summed from 0 as numpy sums them."""
    rng = np.random.default_rng(19)
    for flat in (False, True):
        X = rng.standard_normal((12, 3)) * 10.0 ** rng.uniform(-2, 2, (12, 1))
        if flat:
            X[:, 2] = 0.0
        ring = [4, 9, 2, 7, 11, 5, 1]
        star = np.array([[0, ring[i], ring[(i + 1) % 7]] for i in range(7)]
                        + [[0, 9, 3]], np.int64)              # a repeated ring vertex
        worst = 4
        B, C, N, total, T = star_targets(X, star, worst)
        x = X[0].copy()
        A = np.repeat(x[None], len(star), axis=0)
        wB, wC = X[star[:, 1]], X[star[:, 2]]
        wN = cross(wB - A, wC - A)
        ideal = _ideal_points(A, wB, wC)
        want = np.array([ideal.mean(axis=0), ideal[worst], X[np.unique(star[:, 1:])].mean(axis=0)])
        assert _same_bits(B, wB) and _same_bits(C, wC) and _same_bits(N, wN)
        assert _same_bits(total, wN.sum(axis=0)) and _same_bits(T, want)
    assert np.signbit(N[:, 0]).any() and not np.signbit(total[0])    # -0.0 summed from 0


def test_fan_shapes_ok_and_faces_keep_side_are_the_numpy_formulas():
    """:func:`.._kernels.fan_shapes_ok` is ``disk_shape`` of the faces :func:`_fan_faces`
    makes of the stacked points, all at least ``DISK_SHAPE_MIN`` per position (a NaN
    position fails), and :func:`.._kernels.faces_keep_side` is ``(dots(n0, (B − a1) × (C −
    a1)) > 0).all()``: exactly, with both answers among random cases."""
    from pipeline.geometry._kernels import fan_shapes_ok, faces_keep_side
    from pipeline.geometry.remesh.halfedge import DISK_SHAPE_MIN, disk_shape
    from pipeline.geometry.rows import dots

    rng = np.random.default_rng(23)
    d = 6
    turn = np.arange(d) * 2 * np.pi / d
    ring = np.column_stack([np.cos(turn), np.sin(turn)])
    M = rng.uniform(-1.2, 1.2, (200, 2))
    M[7] = np.nan
    M[8] = ring[2]                                  # on a corner: flat faces
    U = np.vstack([M, ring, np.roll(ring, -1, axis=0)])
    want = (disk_shape(U, _fan_faces(200, d)) >= DISK_SHAPE_MIN).reshape(200, d).all(axis=1)
    got = fan_shapes_ok(U, 200, d, DISK_SHAPE_MIN)
    assert np.array_equal(got, want) and want.any() and not want.all()
    assert not got[7] and not got[8]
    answers = set()
    for _ in range(200):
        n0, B, C = (rng.standard_normal((4, 3)) for _ in range(3))
        a1 = rng.standard_normal(3) * 0.1
        want = bool((dots(n0, cross(B - a1, C - a1)) > 0).all())
        assert faces_keep_side(n0, a1, B, C) == want
        answers.add(want)
    assert answers == {True, False}


def test_replacement_normals_are_the_numpy_formula_bit_for_bit():
    """:func:`.._kernels.replacement_normals` (the normals ``_same_side`` compares): the new
    faces' normals ``cross(X[b] − X[a], X[c] − X[a])`` and the old faces' summed, bit for bit
    as numpy computes them — flat faces too, whose -0.0 components numpy's sum from 0 makes
    +0.0."""
    from pipeline.geometry._kernels import replacement_normals

    rng = np.random.default_rng(29)
    negative_zeros = 0                 # old faces whose normals' x are all -0.0: the sum's is +0.0
    for flat in (False, True):
        X = rng.standard_normal((15, 3)) * 10.0 ** rng.uniform(-2, 2, (15, 1))
        if flat:
            X[:, 2] = 0.0
        for _ in range(50):
            old, new = (np.array([rng.choice(15, 3, replace=False) for _ in range(k)])
                        for k in rng.integers(1, 7, 2))
            n_new, n_old = replacement_normals(X, old, new)
            want_new = cross(X[new[:, 1]] - X[new[:, 0]], X[new[:, 2]] - X[new[:, 0]])
            want_old = cross(X[old[:, 1]] - X[old[:, 0]], X[old[:, 2]] - X[old[:, 0]])
            assert _same_bits(n_new, want_new) and _same_bits(n_old, want_old.sum(axis=0))
            negative_zeros += bool(flat and np.signbit(want_old[:, 0]).all())
    assert negative_zeros > 0


def test_point_faces_distance_is_the_numpy_formula_bit_for_bit():
    """:func:`.._kernels.point_faces_distance` (the gap guard of the collapses and moves): the
    smallest ``norms(p − closest_points_on_triangles(p, …))`` over the faces, bit for bit,
    with degenerate faces (coincident and collinear corners: their nearest corner) and the
    point on a corner (distance 0); NaN if a corner is NaN, inf for no face."""
    from pipeline.geometry._kernels import point_faces_distance
    from pipeline.geometry.remesh_quality import closest_points_on_triangles

    rng = np.random.default_rng(29)
    X = rng.standard_normal((30, 3)) * 10.0 ** rng.uniform(-3, 1, (30, 1))
    X[1] = X[0]                                     # coincident
    X[2] = 2.0 * X[3] - X[4]                        # collinear with 3 and 4
    for _ in range(50):
        T = rng.integers(0, 30, (rng.integers(1, 9), 3))
        T[0] = rng.choice([[0, 1, 5], [2, 3, 4], [6, 7, 8]][rng.integers(0, 3)])
        p = rng.standard_normal(3)
        P = np.repeat(p[None], len(T), axis=0)
        want = norms(P - closest_points_on_triangles(P, X[T[:, 0]], X[T[:, 1]], X[T[:, 2]])).min()
        assert _same_bits(point_faces_distance(p, X, T), want)
    assert point_faces_distance(X[5].copy(), X, np.array([[5, 6, 7]])) == 0.0
    Y = X.copy()
    Y[9] = np.nan
    assert np.isnan(point_faces_distance(np.zeros(3), Y, np.array([[5, 6, 7], [9, 10, 11]])))
    assert point_faces_distance(np.zeros(3), X, np.zeros((0, 3), np.int64)) == np.inf


def test_disk_move_candidates_are_the_numpy_form_bit_for_bit():
    """:func:`.angles.move_candidates` on the disk (compiled) against its numpy form (the
    sphere's branch: :func:`.angles.pattern_points` at the shortest star edge, ``project``,
    :func:`.angles.star_shapes_ok`), bit for bit, on random stars at scales from 1e-4 to 1e2
    (a coincident ring vertex too: ``h`` = 0); some candidates fold the star, some do not."""
    from pipeline.geometry.remesh.angles import (move_candidates, pattern_points,
                                                 star_shapes_ok)

    rng = np.random.default_rng(23)
    folded = kept = 0
    for trial in range(300):
        d = int(rng.integers(3, 11))
        scale = 10.0 ** rng.uniform(-4, 2)
        phi = np.sort(rng.uniform(0, 2 * np.pi, d))
        r = rng.uniform(0.3, 1.5, d)
        uv = np.vstack([rng.standard_normal((1, 2)) * 0.01,
                        np.column_stack([r * np.cos(phi), r * np.sin(phi)])]) * scale
        if trial % 50 == 0:
            uv[2] = uv[0]
        star = np.column_stack([np.zeros(d, np.int64), 1 + np.arange(d),
                                1 + (np.arange(d) + 1) % d])
        aimed = uv[0] + rng.standard_normal((9, 2)) * scale * 0.3
        M, ok = move_candidates(uv, 0, star, aimed)
        h = norms(uv[star[:, 1:]].reshape(-1, 2) - uv[0]).min()
        want = np.vstack([aimed, pattern_points(uv[0], h)])
        assert _same_bits(M, want)
        want_ok = np.flatnonzero(star_shapes_ok(uv, want, star[:, 1:]))
        assert ok.dtype == np.int64 and ok.tolist() == want_ok.tolist()
        folded += len(M) - len(ok)
        kept += len(ok)
    assert folded > 0 and kept > 0


@pytest.mark.parametrize("k", [1, 5, 8, 13, 140])
def test_area_spread_is_the_numpy_sum_bit_for_bit(k):
    """:func:`.._kernels.area_spread` (:meth:`.angles._Patch.spread`): the sum of the squared
    relative deviations of :func:`.laplacian.face_double_areas` from a mean, as numpy sums
    them, bit for bit, for fewer and more than 8 faces (blocks of 8) and more than 128
    (halves), with a degenerate face (area 0: deviation 1) among several."""
    from pipeline.geometry._kernels import area_spread
    from pipeline.geometry.laplacian import face_double_areas

    rng = np.random.default_rng(29)
    for scale in (1e-3, 1.0, 1e3):
        X = rng.standard_normal((3 * k, 3)) * scale
        T = rng.permutation(3 * k).reshape(k, 3).astype(np.int64)
        if k > 1:
            X[T[-1, 2]] = 2.0 * X[T[-1, 1]] - X[T[-1, 0]]    # collinear corners
        A = face_double_areas(X, T)
        mean = float(A.mean()) * rng.uniform(0.5, 2.0)
        want = float(((A / mean - 1) ** 2).sum())
        got = area_spread(X, T, mean)
        assert np.float64(got).tobytes() == np.float64(want).tobytes()


def test_corners_min_degrees_is_face_min_degrees_of_the_one_face():
    """:func:`.._kernels.corners_min_degrees` (one face, :meth:`.angles._Patch.min_angle`):
    the value :func:`.angles.face_min_angles` gives that face, bit for bit, on random faces
    at scales from 1e-6 to 1e6, needles, a coincident corner (0) and collinear corners."""
    from pipeline.geometry._kernels import corners_min_degrees

    rng = np.random.default_rng(31)
    X = rng.standard_normal((600, 3)) * 10.0 ** rng.uniform(-6, 6, (600, 1))
    X[1] = X[0]                                            # coincident corners
    X[5] = 2.0 * X[4] - X[3]                               # collinear corners
    X[8] = X[6] + 1e-9 * (X[7] - X[6])                     # a needle
    T = np.vstack([[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
                   rng.integers(0, 600, (500, 3))]).astype(np.int64)
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])]
    want = face_min_angles(X, T)
    got = np.array([corners_min_degrees(X, *map(int, f)) for f in T])
    assert _same_bits(got, want)
    assert want[0] == 0.0 and want[1] < 1e-6 and want[2] < 1e-4 and (want > 10).any()
