"""The input's holes kept open by the remesh (:mod:`pipeline.geometry.remesh.holes`): a
constructed disk with a square and a round hole for the exact facts, the ICT face with its eye
and mouth openings for the quality and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import require_data, run_cli
from pipeline.geometry import topology as topo
from pipeline.geometry.remesh_quality import (bounding_box_diagonal, is_disk,
                                              is_disk_with_holes, mesh_facts,
                                              point_mesh_distance, remesh_quality)
from pipeline.geometry.remesh.uniform import uniform_remesh
from pipeline.geometry.repair import RepairOptions, open_mesh, repair_mesh
from pipeline.geometry.rows import norms
from pipeline.stages.remesh import RemeshConfig, remesh_stage
from remesh_helpers import off_surface_limit, remesh_map

SQUARE = (-0.55, -0.2, -0.2, 0.2)        # x0, x1, y0, y1
ROUND = (0.4, 0.1, 0.22)                 # cx, cy, r


def grid_sheet() -> tuple[np.ndarray, np.ndarray]:
    """A gently domed square sheet, a 71 × 71 grid on [−1, 1]²: ``(V, F)``."""
    x = np.linspace(-1, 1, 71)
    X, Y = np.meshgrid(x, x)
    P = np.column_stack([X.ravel(), Y.ravel()])
    i = np.arange(70)
    a = (i[:, None] * 71 + i[None, :]).ravel()
    F = np.vstack([np.column_stack([a, a + 1, a + 72]), np.column_stack([a, a + 72, a + 71])])
    return np.column_stack([P, 0.3 * (1 - 0.5 * (P ** 2).sum(axis=1))]), F


def holed_sheet(holes: int) -> tuple[np.ndarray, np.ndarray]:
    """The sheet of :func:`grid_sheet` with the faces inside a square hole (``holes`` ≥ 1)
    and a round one (``holes`` = 2) removed: ``(V, F)``."""
    V, F = grid_sheet()
    c = V[F].mean(axis=1)
    x0, x1, y0, y1 = SQUARE
    cut = (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)
    if holes > 1:
        cx, cy, r = ROUND
        cut |= np.hypot(c[:, 0] - cx, c[:, 1] - cy) < r
    return V, F[~cut]


@pytest.fixture(scope="module", params=[1, 2])
def holed(request):
    """The holed sheet repaired with its holes closed, its map, and its remesh at 1,500
    vertices keeping the holes: ``(k, mesh, uv, remesh)``."""
    V, F = holed_sheet(request.param)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    uv = remesh_map(mesh)
    return request.param, mesh, uv, remesh_stage(mesh, uv, RemeshConfig(vertices=1500))


def hole_polylines(mesh) -> list:
    """The input's hole loops as closed polylines, (k + 1, 3) each."""
    return [mesh.V[np.r_[lp, lp[:1]]] for lp in mesh.hole_loops()]


def segment_distance(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The distance of each point ``P`` (p×3) from the closed polyline ``Q`` (q×3)."""
    A, B = Q[:-1], Q[1:]
    d = B - A
    t = np.clip(((P[:, None] - A[None]) * d[None]).sum(axis=2) / (d ** 2).sum(axis=1), 0, 1)
    return np.linalg.norm(A[None] + t[..., None] * d[None] - P[:, None], axis=2).min(axis=1)


def test_holes_stay_open_with_the_input_topology(holed):
    k, mesh, _, r = holed
    f = mesh_facts(r.V, r.F)
    assert is_disk_with_holes(f, k) and not is_disk(f)
    assert f["boundary_loops"] == 1 + k and f["euler_characteristic"] == 1 - k
    assert r.info["holes_kept"] == k


def test_the_count_is_the_output_count(holed):
    _, _, _, r = holed
    assert abs(len(r.V) - 1500) <= 0.02 * 1500
    assert r.info["vertices_with_holes_filled"] > 1500


def test_hole_rims_lie_on_the_input_loops_and_keep_their_length(holed):
    """The square hole's rim follows its loop (the same length); the round one, a staircase
    of grid edges (a ragged loop, :func:`.holes.is_ragged`), has its rim's chords cut across
    the steps where they run beyond them by less than the tolerances of
    :func:`.holes.followed_stops`: its length is between the circle's and the staircase's."""
    from pipeline.geometry.remesh.holes import is_ragged

    _, mesh, _, r = holed
    loops = topo.boundary_loops(r.F)
    outer = max(loops, key=lambda lp: np.abs(r.V[lp, :2]).max())
    inner = [lp for lp in loops if lp is not outer]
    for Q, square in zip(hole_polylines(mesh), (True, False)):
        rim = min(inner, key=lambda lp: segment_distance(r.V[lp], Q).max())
        assert segment_distance(r.V[rim], Q).max() <= 1e-9
        assert is_ragged(Q[:-1]) != square
        length_in = norms(np.diff(Q, axis=0)).sum()
        length_out = norms(r.V[np.r_[rim, rim[:1]][1:]] - r.V[rim]).sum()
        if square:
            assert abs(length_out / length_in - 1) <= 0.03
        else:
            assert 2 * np.pi * ROUND[2] <= 1.03 * length_out and length_out < 0.95 * length_in


def test_no_face_lies_in_a_hole(holed):
    k, _, _, r = holed
    c = r.V[r.F].mean(axis=1)
    x0, x1, y0, y1 = SQUARE
    assert not ((c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)).any()
    if k > 1:
        cx, cy, rr = ROUND
        assert (np.hypot(c[:, 0] - cx, c[:, 1] - cy) > 0.9 * rr).all()


def test_the_plain_lift_leaves_the_kept_holes_out(holed):
    """The plain lift (before the improvement) has no face with its three corners in a hole
    (its hole rims run along its own edges, across the loops), keeps every vertex it uses and
    is cut: more boundary than its disk's rim."""
    k, _, _, r = holed
    X, F = r.lifted
    P = X[F]
    x0, x1, y0, y1 = SQUARE
    inside = (P[..., 0] > x0) & (P[..., 0] < x1) & (P[..., 1] > y0) & (P[..., 1] < y1)
    if k > 1:
        cx, cy, rr = ROUND
        inside |= np.hypot(P[..., 0] - cx, P[..., 1] - cy) < rr
    assert not inside.all(axis=1).any()
    assert len(np.unique(F)) == len(X)
    assert len(topo.boundary_loops(F)) >= 1 + k


def test_the_remesh_stays_on_the_open_input(holed):
    """Every vertex within the fit's cap of the input with its holes open (the fit samples
    the open input: none is pulled towards the fans' surface)."""
    _, mesh, _, r = holed
    V, F = open_mesh(mesh)
    d, _ = point_mesh_distance(r.V, V, F)
    assert d.max() / bounding_box_diagonal(V) <= off_surface_limit(r, mesh)


def test_cover_holes_is_the_remesh_of_the_filled_disk(holed):
    """``keep_holes: false`` remeshes the disk the fans fill as before: the same remesh, bit
    for bit, as the disk remesher given no holes, with one boundary loop."""
    _, mesh, uv, _ = holed
    r = remesh_stage(mesh, uv, RemeshConfig(vertices=1500, keep_holes=False))
    plain = uniform_remesh(mesh.V, mesh.F, uv, mesh.boundary, vertices=1500,
                           **RemeshConfig(vertices=1500).improve.model_dump())
    assert np.array_equal(r.V, plain.V) and np.array_equal(r.F, plain.F)
    assert is_disk(mesh_facts(r.V, r.F))


def test_open_mesh_drops_the_fans_and_their_centres():
    V, F = holed_sheet(2)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    Vo, Fo = open_mesh(mesh)
    centres = [h["centre_vertex"] for h in mesh.closed_holes]
    fans = mesh.fan_faces()
    assert len(Vo) == len(mesh.V) - 2 and len(Fo) == len(mesh.F) - fans.sum()
    assert np.isin(mesh.F[fans], centres).any(axis=1).all()
    assert not np.isin(mesh.F[~fans], centres).any()
    assert not np.isin(mesh.V[centres], Vo).all(axis=1).any()
    assert is_disk_with_holes(mesh_facts(Vo, Fo), 2)


@pytest.fixture(scope="module")
def ict_holes_5k(tmp_path_factory):
    """The ICT neutral face with its eyes and mouth open, remeshed at 5,000 vertices by the
    command line (measures and report on)."""
    path = require_data("faces", "ict", "ict_A_neutral_holes.obj")
    out = tmp_path_factory.mktemp("ict_holes") / "out"
    code, stdout, err = run_cli("remesh", path, "--close-holes", "--vertices", 5000, "-o", out)
    return code, stdout, err, out


def test_ict_holes_cli_keeps_the_holes(ict_holes_5k):
    code, stdout, err, out = ict_holes_5k
    assert code == 0, err
    assert "one disk with 3 holes, as the input" in stdout
    m = json.loads((out / "remesh_metrics.json").read_text())
    sem = m["methods"]["sem"]
    assert sem["facts"]["boundary_loops"] == 4 and sem["facts"]["euler_characteristic"] == -2
    assert abs(sem["facts"]["vertices"] - 5000) <= 0.02 * 5000
    assert m["input"]["faces"] == m["methods"]["input"]["facts"]["faces"]
    assert m["methods"]["input"]["facts"]["boundary_loops"] == 4        # the open input
    assert not any("covers" in w for w in m["warnings"])
    assert "yes, a disk with 3 holes" in (out / "report.html").read_text()


def test_ict_holes_quality(ict_holes_5k):
    """Measured: mean smallest angle 50.7°, no unforced face below 20°, Hausdorff 0.30 % of
    the diagonal against the input with its holes (pymeshlab: 50.0°, 0.41 %)."""
    code, _, err, out = ict_holes_5k
    assert code == 0, err
    m = json.loads((out / "remesh_metrics.json").read_text())
    sem = m["methods"]["sem"]
    assert sem["triangles"]["mean_min_angle_deg"] >= 50.0
    assert m["remesh"]["improve"]["below_min_angle"]["unforced_faces"] == 0
    assert sem["distance"]["hausdorff_rel"] <= 0.005


def test_ict_holes_remesh_lies_on_the_rims():
    from pipeline.stages.load import load_stage

    path = require_data("faces", "ict", "ict_A_neutral_holes.obj")
    intake = load_stage(path, RepairOptions(close_holes=True))
    r = remesh_stage(intake.mesh, remesh_map(intake.mesh), RemeshConfig(vertices=5000))
    q = remesh_quality(*open_mesh(intake.mesh), r.V, r.F, n_random=20_000)
    assert q["holes"] == 3 and q["is_disk_with_holes"]
    on_rim = np.zeros(len(r.V), bool)
    on_rim[np.concatenate(topo.boundary_loops(r.F))] = True
    rims = np.vstack([segment_distance(r.V[on_rim], Q) for Q in hole_polylines(intake.mesh)])
    outer = topo.boundary_loops(r.F)
    assert (rims.min(axis=0) <= 1e-9).sum() == on_rim.sum() - max(map(len, outer))


def test_a_loop_the_flips_cannot_join_is_split_on_the_loop(monkeypatch):
    """With every flip refused, the loop's pairs are joined by the fallbacks alone: the one
    edge a pair's segment crosses split where the loop crosses it, or the loop's midpoint
    put in; the hole is kept all the same, its rim on the input loop."""
    import pipeline.geometry.remesh.holes as holes

    monkeypatch.setattr(holes, "turned_outside", lambda S, fans, T: np.ones(len(T), bool))
    monkeypatch.setattr(holes, "_nothing_turned", lambda T: np.ones(len(T), bool))
    V, F = holed_sheet(1)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    r = remesh_stage(mesh, remesh_map(mesh), RemeshConfig(vertices=1500))
    log = r.info["improve"]
    assert log["hole_joins_failed"] > 0
    assert log.get("hole_edges_split", 0) + log.get("hole_midpoints_snapped", 0) \
        + log.get("hole_midpoints_inserted", 0) > 0
    assert is_disk_with_holes(mesh_facts(r.V, r.F), 1)
    rim = min(topo.boundary_loops(r.F), key=len)
    assert segment_distance(r.V[rim], hole_polylines(mesh)[0]).max() <= 1e-9


def test_crossings_are_proper_crossings_only():
    from pipeline.geometry.remesh.holes import crossings

    P, Q = np.array([[0.0, 0.0], [0.0, 0.0]]), np.array([[1.0, 1.0], [1.0, 0.0]])
    A, B = np.array([[0.0, 1.0], [1.0, 0.0], [2.0, 0.0]]), np.array([[1.0, 0.0], [1.0, 1.0],
                                                                     [3.0, 0.0]])
    assert crossings(P, Q, A, B).tolist() == [[True, False, False], [False, False, False]]


def test_untangled_adds_the_loop_vertices_where_a_chord_crosses_a_loop():
    """A square loop with points on two opposite corners only: its chords (the diagonal, both
    ways) cross a small loop's edge, so the square's other corners go back in; the small
    loop's points, on all its vertices, are left."""
    from pipeline.geometry.remesh.holes import untangled

    uv = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [0.8, 1.2], [1.2, 0.8], [1.2, 1.2]], float)
    square, small = np.r_[0, 1, 2, 3, 0], np.r_[4, 5, 6, 4]
    loops = []
    for vs, stops in ((square, [0, 2]), (small, [0, 1, 2])):
        seg = np.linalg.norm(np.diff(uv[vs], axis=0), axis=1)
        loops.append((vs, seg, np.r_[0.0, np.cumsum(seg)][stops]))
    (_, seg, t), (_, seg_small, t_small) = untangled(uv, loops)
    assert np.allclose(t, np.r_[0.0, np.cumsum(seg)][:4])
    assert np.allclose(t_small, loops[1][2])


def test_spaced_stops_cut_across_the_teeth_of_a_ragged_loop():
    """A circle of radius 1 with teeth 0.05 deep every 0.02 of arc: the stops are loop
    vertices about L = 0.3 apart in space, some ten times fewer than the vertices, and each
    consecutive pair's chord within L / 2 of L."""
    from pipeline.geometry.remesh.holes import spaced_stops

    a = np.linspace(0, 2 * np.pi, 315)[:-1]
    r = 1 + 0.05 * (np.arange(len(a)) % 2)
    Q = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)])
    Q = np.vstack([Q, Q[:1]])
    stops = spaced_stops(Q, 0.3)
    gaps = norms(np.roll(Q[stops], -1, axis=0) - Q[stops])
    assert stops[0] == 0 and (np.diff(stops) > 0).all() and stops[-1] < len(Q) - 1
    assert 15 <= len(stops) <= 25
    assert (np.abs(gaps - 0.3) <= 0.15).all()


def test_untangled_lets_a_chord_cut_across_its_own_teeth():
    """A square whose bottom side zigzags across the chord between its bottom corners: the
    chord crosses only its own stretch of loop, so no vertex is added; a second loop that
    the chord crosses adds the zigzag's vertex nearest the middle of the stretch."""
    from pipeline.geometry.remesh.holes import untangled

    uv = np.array([[0, 0], [0.3, 0.2], [0.6, -0.2], [1, 0], [1, 1], [0, 1],
                   [0.75, -0.05], [0.85, 0.05], [0.8, 0.1]], float)
    square = np.r_[0, 1, 2, 3, 4, 5, 0]
    seg = np.linalg.norm(np.diff(uv[square], axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    t = s[[0, 3, 4, 5]]
    ((_, _, alone),) = untangled(uv, [(square, seg, t)])
    assert np.array_equal(alone, t)
    small = np.r_[6, 7, 8, 6]
    seg_small = np.linalg.norm(np.diff(uv[small], axis=0), axis=1)
    (_, _, got), _ = untangled(uv, [(square, seg, t),
                                   (small, seg_small, np.r_[0.0, np.cumsum(seg_small)][:3])])
    assert np.allclose(got, np.sort(np.r_[t, s[1]])) or np.allclose(got, np.sort(np.r_[t, s[2]]))


def test_a_hole_that_cannot_be_kept_is_covered_with_a_warning(monkeypatch):
    """With the first hole's loop failing to join, that hole is covered (its fan's faces stay,
    its loop size in ``holes_covered``) and the other kept: a disk with one hole; the
    warnings name the covered hole."""
    import pipeline.geometry.remesh.holes as holes
    from pipeline.geometry.remesh.state import RemeshFailed
    from pipeline.report.remesh import remesh_warnings

    join_loop, calls = holes.join_loop, []

    def failing_first(S, *args):
        calls.append(1)
        if len(calls) == 1:
            raise RemeshFailed("forced")
        return join_loop(S, *args)

    monkeypatch.setattr(holes, "join_loop", failing_first)
    V, F = holed_sheet(2)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    r = remesh_stage(mesh, remesh_map(mesh), RemeshConfig(vertices=1500))
    log = r.info["improve"]
    size = len(mesh.hole_loops()[0])
    assert log["hole_loops_not_placed"] == 1
    assert log["holes_covered"] == [size] and log["holes_covered_index"] == [0]
    assert r.info["holes_kept"] == 1
    assert is_disk_with_holes(mesh_facts(r.V, r.F), 1)
    rim = min(topo.boundary_loops(r.F), key=len)
    assert segment_distance(r.V[rim], hole_polylines(mesh)[1]).max() <= 1e-9
    warnings = remesh_warnings({}, {}, holes_covered=log["holes_covered"])
    assert any(f"{size}-vertex loop could not be kept open" in w for w in warnings)


def state_at_move_each(monkeypatch):
    """The remesh state (a copy) as the face-by-face star moves get it on the sheet with the
    square hole (:func:`holed_sheet`) remeshed at 1,500 vertices keeping it."""
    import copy

    import pipeline.geometry.remesh.improve as improve

    states, move_each = [], improve._Operations.move_each

    def capture(ops, min_angle_deg):
        states.append(copy.deepcopy(ops.S))
        return move_each(ops, min_angle_deg)

    monkeypatch.setattr(improve._Operations, "move_each", capture)
    V, F = holed_sheet(1)
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    remesh_stage(mesh, remesh_map(mesh), RemeshConfig(vertices=1500))
    return states[-1]


def test_the_face_by_face_moves_skip_the_faces_in_a_kept_hole(monkeypatch):
    """With every hole loop whole, :func:`.improve.each_unforced_face` (as the star moves ask
    it) yields no face whose disk centroid is in a hole's fan, even the worst one: a vertex
    inside the square hole moved onto the chord of two of its neighbours squashes faces that
    the cut removes; asked to keep the holes' faces, it yields one of them first."""
    import pipeline.geometry.remesh.improve as improve
    from pipeline.geometry.remesh.holes import all_loops_whole, in_fans

    S = state_at_move_each(monkeypatch)
    assert all_loops_whole(S)
    star_in = np.array([in_fans(S, np.flatnonzero((S.F == v).any(axis=1))).all()
                        for v in range(S.n)])
    v = int(np.flatnonzero(star_in & ~S.is_rim & ~S.locked)[0])
    f = np.flatnonzero((S.F == v).any(axis=1))[0]
    a, b = (w for w in S.F[f] if w != v)
    S.X[v] = 0.5 * (S.X[a] + S.X[b])                     # a face of 0° at a and b
    inside = lambda g: bool(in_fans(S, np.array([g]))[0])  # noqa: E731
    first = [g for g, _ in improve.each_unforced_face(S, 20.0, 1, outside_holes=False)]
    assert len(first) == 1 and inside(first[0])
    yielded = [g for g, _ in improve.each_unforced_face(S, 20.0, 50, outside_holes=True)]
    assert not any(inside(g) for g in yielded)


def test_followed_stops_bound_the_loop_beyond_each_chord():
    """A circle of radius 1 (the hole inside) whose every fourth vertex is pushed out by 0.09
    (a notch of the hole into the surface) and every fourth, two further on, in by 0.08 (a
    tooth of the surface): between the stops L = 0.3 apart the notches run beyond the chords
    by more than ``NOTCH_TOL × L``; once followed, every vertex between two consecutive stops
    lies within ``NOTCH_TOL × L`` of their chord outside it, ``TOOTH_TOL × L`` inside it, or
    within ``LOOP_GAP × L`` of an end, and the spaced stops are all kept."""
    from pipeline.geometry.remesh.holes import (LOOP_GAP, NOTCH_TOL, TOOTH_TOL,
                                                followed_stops, spaced_stops)
    from pipeline.geometry.remesh.rim import segment_distances

    L = 0.3
    a = np.linspace(0, 2 * np.pi, 201)[:-1]
    r = 1 + 0.09 * (np.arange(200) % 4 == 1) - 0.08 * (np.arange(200) % 4 == 3)
    P = np.column_stack([r * np.cos(a), r * np.sin(a)])
    P = np.vstack([P, P[:1]])
    Q = np.column_stack([P, np.zeros(len(P))])

    def beyond(stops):
        """Per vertex between consecutive stops: (outside its chord, distance, near an end)."""
        rows = []
        for s, e in zip(stops, np.r_[stops[1:], len(Q) - 1]):
            i = np.arange(s + 1, e)
            d = P[e] - P[s]
            side = d[0] * (P[i, 1] - P[s, 1]) - d[1] * (P[i, 0] - P[s, 0])
            dist = segment_distances(Q[i], np.repeat(Q[[s]], len(i), 0),
                                     np.repeat(Q[[e]], len(i), 0))
            near = np.minimum(norms(Q[i] - Q[s]), norms(Q[i] - Q[e])) < LOOP_GAP * L
            rows += list(zip(side < 0, dist, near))
        return rows

    spaced = spaced_stops(Q, L)
    assert any(out and d > NOTCH_TOL * L and not near for out, d, near in beyond(spaced))
    stops = followed_stops(Q, P, spaced, NOTCH_TOL * L, TOOTH_TOL * L, LOOP_GAP * L)
    assert np.isin(spaced, stops).all() and (np.diff(stops) > 0).all()
    assert all(near or d <= (NOTCH_TOL if out else TOOTH_TOL) * L
               for out, d, near in beyond(stops))


def ragged_holes_sheet() -> tuple[np.ndarray, np.ndarray, list]:
    """The sheet of :func:`grid_sheet` with the faces inside two ragged polygons
    removed, a star of 8 teeth (star-shaped) and a ragged crescent (not star-shaped: its
    centroid lies outside it): ``(V, F, polygons)``, each polygon (k×2) in the xy plane."""
    from matplotlib.path import Path

    V, F = grid_sheet()
    th = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    r = np.where(np.arange(16) % 2, 0.3, 0.18)
    star = np.column_stack([-0.45 + r * np.cos(th), r * np.sin(th)])
    th = np.linspace(0.25 * np.pi, 1.75 * np.pi, 14)
    r = 0.35 * np.where(np.arange(14) % 2, 1.0, 0.85)
    crescent = np.vstack([np.column_stack([0.45 + r * np.cos(th), r * np.sin(th)]),
                          np.column_stack([0.45 + 0.19 * np.cos(th[::-1]),
                                           0.19 * np.sin(th[::-1])])])
    c = V[F].mean(axis=1)[:, :2]
    cut = Path(star).contains_points(c) | Path(crescent).contains_points(c)
    return V, F[~cut], [star, crescent]


def test_no_face_covers_a_ragged_hole():
    """The sheet with a ragged star and a ragged crescent remeshed at 800 vertices keeping
    both: a disk with 2 holes, and no face's centroid inside a hole's loop deeper than
    ``NOTCH_TOL × L`` (the rims' chords cross none of a notch deeper); no face near the star
    turned over against the input."""
    from matplotlib.path import Path

    from pipeline.geometry.remesh.holes import NOTCH_TOL
    from pipeline.geometry.remesh_quality import SampledSurface, turned_over_faces

    V, F, (star, _) = ragged_holes_sheet()
    mesh = repair_mesh(V, F, options=RepairOptions(close_holes=True))
    r = remesh_stage(mesh, remesh_map(mesh), RemeshConfig(vertices=800))
    assert is_disk_with_holes(mesh_facts(r.V, r.F), 2)
    L = r.info["spacing_mesh_units"]
    c = r.V[r.F].mean(axis=1)
    for Q in hole_polylines(mesh):
        inside = Path(Q[:, :2]).contains_points(c[:, :2])
        depth = segment_distance(np.column_stack([c[inside, :2], np.zeros(inside.sum())]),
                                 np.column_stack([Q[:, :2], np.zeros(len(Q))]))
        assert (depth <= NOTCH_TOL * L).all()
    Vo, Fo = open_mesh(mesh)
    near_star = np.hypot(c[:, 0] + 0.45, c[:, 1]) < 0.45
    reference = SampledSurface(Vo, Fo, 0, 0)
    assert turned_over_faces(r.V, r.F[near_star], reference) == 0


@pytest.mark.parametrize("radius, spaced, kept", [
    (0.7, False, False),     # a flat tooth (angles below 1°): dropped
    (0.3, False, True),      # a deep tooth (30°, 30°, 120°): kept
    (1.01, False, True),     # a flat notch: its triangle lies in the hole, kept
    (0.7, True, True),       # a flat tooth among the spaced stops: kept
])
def test_thin_teeth_lose_their_added_tip(radius, spaced, kept):
    """A unit circle of 40 vertices (the hole inside) with vertex 10 moved to ``radius``,
    stops every fifth vertex: vertex 10 is dropped by :func:`.holes.without_thin_teeth`
    where it is an added stop at the tip of a tooth (inside the circle) whose triangle with
    stops 5 and 15 has an angle below ``TOOTH_MIN_DEG``, and only there."""
    from pipeline.geometry.metrics import min_corner_angles
    from pipeline.geometry.remesh.holes import TOOTH_MIN_DEG, without_thin_teeth

    a = np.linspace(0, 2 * np.pi, 41)
    r = np.where(np.arange(41) == 10, radius, 1.0)
    P = np.column_stack([r * np.cos(a), r * np.sin(a)])
    P[-1] = P[0]
    Q = np.column_stack([P, np.zeros(41)])
    stops = list(range(0, 40, 5))
    base = set(stops) if spaced else set(stops) - {10}
    thin = np.degrees(min_corner_angles(Q, np.array([[5, 10, 15]])))[0] < TOOTH_MIN_DEG
    assert thin == (radius == 0.7)
    out = without_thin_teeth(Q, P, stops, base, 1.0)
    assert list(out) == (stops if kept else [s for s in stops if s != 10])


def test_on_boundary_of_some_vertices_is_the_whole_row_indexed(monkeypatch):
    """:meth:`.state.RemeshState.on_boundary` of given vertices equals its whole row
    indexed by them, bit for bit, on a remesh whose hole loop's vertices are on it besides
    the rim's (the minimum-angle pass asks it of the vertices on input corners alone)."""
    S = state_at_move_each(monkeypatch)
    whole = S.on_boundary()
    assert whole.sum() > S.is_rim.sum()
    v = np.random.default_rng(0).permutation(S.n)[: S.n // 2]
    v = np.r_[v, np.flatnonzero(whole & ~S.is_rim)]
    assert np.array_equal(S.on_boundary(v), whole[v])
    assert np.array_equal(S.on_boundary(np.arange(S.n)), whole)


def test_across_unjoined_are_the_free_vertices_beyond_the_edges_not_kept(monkeypatch):
    """:func:`.improve.across_unjoined` of each face with a hole loop's vertex among its
    corners: for each of its edges in order that is not kept (``S.joined``) and has a face
    across it, the vertex of that face off the edge where it is free (not on the rim, not
    locked), found by a search of the faces; some of those faces have a kept edge."""
    import pipeline.geometry.remesh.improve as improve

    S = state_at_move_each(monkeypatch)
    free = ~S.is_rim & ~S.locked
    near = np.flatnonzero((~free[S.F]).any(axis=1))
    kept_any = False
    for f in near.tolist():
        want = []
        for i in range(3):
            a, b = int(S.F[f, i]), int(S.F[f, (i + 1) % 3])
            kept = bool(S.is_joined(np.array([a]), np.array([b]))[0])
            kept_any |= kept
            other = [g for g in np.flatnonzero((S.F == a).any(axis=1) & (S.F == b).any(axis=1))
                     if g != f]
            if not kept and other:
                q = next(int(w) for w in S.F[other[0]] if w not in (a, b))
                want += [q] if free[q] else []
        assert improve.across_unjoined(S, f).tolist() == want
    assert kept_any
