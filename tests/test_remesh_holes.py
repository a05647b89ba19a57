"""The input's holes kept open by the remesh (:mod:`pipeline.geometry.remesh.holes`): a
constructed disk with a square and a round hole for the exact facts, the ICT face with its eye
and mouth openings for the quality and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import require_data, run_cli
from pipeline.geometry import topology as topo
from pipeline.geometry.remesh_quality import (is_disk, is_disk_with_holes, mesh_facts,
                                              point_mesh_distance, remesh_quality)
from pipeline.geometry.remesh.uniform import uniform_remesh
from pipeline.geometry.repair import RepairOptions, open_mesh, repair_mesh
from pipeline.geometry.rows import norms
from pipeline.stages.remesh import RemeshConfig, remesh_stage
from remesh_helpers import remesh_map

SQUARE = (-0.55, -0.2, -0.2, 0.2)        # x0, x1, y0, y1
ROUND = (0.4, 0.1, 0.22)                 # cx, cy, r


def holed_sheet(holes: int) -> tuple[np.ndarray, np.ndarray]:
    """A gently domed square sheet (a 71 × 71 grid on [−1, 1]²) with the faces inside a
    square hole (``holes`` ≥ 1) and a round one (``holes`` = 2) removed: ``(V, F)``."""
    x = np.linspace(-1, 1, 71)
    X, Y = np.meshgrid(x, x)
    P = np.column_stack([X.ravel(), Y.ravel()])
    i = np.arange(70)
    a = (i[:, None] * 71 + i[None, :]).ravel()
    F = np.vstack([np.column_stack([a, a + 1, a + 72]), np.column_stack([a, a + 72, a + 71])])
    c = P[F].mean(axis=1)
    x0, x1, y0, y1 = SQUARE
    cut = (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)
    if holes > 1:
        cx, cy, r = ROUND
        cut |= np.hypot(c[:, 0] - cx, c[:, 1] - cy) < r
    V = np.column_stack([P, 0.3 * (1 - 0.5 * (P ** 2).sum(axis=1))])
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
    _, mesh, _, r = holed
    loops = topo.boundary_loops(r.F)
    outer = max(loops, key=lambda lp: np.abs(r.V[lp, :2]).max())
    inner = [lp for lp in loops if lp is not outer]
    for Q in hole_polylines(mesh):
        rim = min(inner, key=lambda lp: segment_distance(r.V[lp], Q).max())
        assert segment_distance(r.V[rim], Q).max() <= 1e-9
        length_in = norms(np.diff(Q, axis=0)).sum()
        length_out = norms(r.V[np.r_[rim, rim[:1]][1:]] - r.V[rim]).sum()
        assert abs(length_out / length_in - 1) <= 0.03


def test_no_face_lies_in_a_hole(holed):
    k, _, _, r = holed
    c = r.V[r.F].mean(axis=1)
    x0, x1, y0, y1 = SQUARE
    assert not ((c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)).any()
    if k > 1:
        cx, cy, rr = ROUND
        assert (np.hypot(c[:, 0] - cx, c[:, 1] - cy) > 0.9 * rr).all()


def test_the_remesh_stays_on_the_open_input(holed):
    _, mesh, _, r = holed
    V, F = open_mesh(mesh)
    d, _ = point_mesh_distance(r.V, V, F)
    assert d.max() <= 1e-9


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
