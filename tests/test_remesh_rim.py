"""The rim follows the input boundary (pipeline.geometry.remesh.rim)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import lift
from pipeline.geometry.remesh.halfedge import DISK_SHAPE_MIN, disk_shape
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.refine import split_keeps_shape
from pipeline.geometry.remesh.rim import (fan_edges, open_rim_fans, refine_rim, rim_gaps,
                                          segment_distances)
from pipeline.geometry.remesh.sampling import arc_parameters
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import ccw_delaunay, disk_map


def test_segment_distances_exact():
    A, B = np.zeros((3, 3)), np.array([[2.0, 0, 0]] * 3)
    P = np.array([[1.0, 1.0, 0], [-3.0, 4.0, 0], [5.0, 0, 4.0]])
    assert np.allclose(segment_distances(P, A, B), [1.0, 5.0, 5.0])


def bumped_rim_state(bumps: int, height: float):
    """The unit disk map of ``disk_map`` with ``bumps`` evenly spread boundary vertices raised
    by ``height``, remeshed coarsely: 24 rim samples on the polygon and a centre, every rim
    chord spanning 10 input boundary vertices. Returns the state and the raised vertices."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    V_in = V_in.copy()
    raised = loop[5::len(loop) // bumps][:bumps]          # never a rim sample (those are 0, 10 …)
    V_in[raised, 2] = height
    rim = np.arange(0, len(loop), 10)
    uv = np.vstack([uv_in[loop[rim]], [[0.0, 0.0]]])
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, np.r_[np.ones(len(rim), bool), False],
                    face, bary, V_in, F_in, uv_in, locator, uv_in[loop])
    return S, raised


def test_rim_gaps_find_the_cut_off_boundary_vertex():
    """Each raised vertex sits in the middle of one rim chord: it is that chord's farthest
    cut-off boundary vertex, at distance √(height² + s²) from it, where s = 1 − cos(π/24) is
    the sagitta of a chord spanning 1/24 of the circle (the chord lies in the plane, inside the
    circle); the other cut-off vertices are at most s from their chords."""
    S, raised = bumped_rim_state(4, 0.05)
    f, b, _ = S.locator.locate_with_inside(S.polygon)
    corners_X = lift(S.V_in, S.F_in, f, b)
    h, a, bb, corner, gap = rim_gaps(S, corners_X, arc_parameters(S.polygon, S.polygon))
    assert len(h) == 24 and (corner >= 0).all()
    loop = topo.boundary_loops(S.F_in)[0]
    far = np.flatnonzero(gap > 0.01)
    assert sorted(loop[corner[far]]) == sorted(raised)
    sagitta = 1.0 - np.cos(np.pi / 24)
    assert np.allclose(gap[far], np.hypot(0.05, sagitta))
    assert gap[gap <= 0.01].max() <= sagitta + 1e-12


def test_refine_rim_puts_a_vertex_on_every_cut_off_corner():
    """After the rim refinement the remesh has a vertex exactly at each raised boundary vertex
    (the first round splits there), every input boundary vertex is within the tolerance of
    the rim (the slopes up to each spike take more splits), and the result is a disk,
    counter-clockwise, with no face thinner on the disk than the operations allow."""
    S, raised = bumped_rim_state(6, 0.05)
    n0 = S.n
    done = refine_rim(S, tol=0.01, min_gap=0.02, budget=100)
    assert done > 6 and S.n == n0 + done and S.log["rim_splits"] == done
    assert S.is_rim[n0:].all()
    for v in raised:
        assert np.min(np.linalg.norm(S.X - S.V_in[v], axis=1)) < 1e-12
    f, b, _ = S.locator.locate_with_inside(S.polygon)
    corners_X = lift(S.V_in, S.F_in, f, b)
    *_, gap = rim_gaps(S, corners_X, arc_parameters(S.polygon, S.polygon))
    assert gap.max() <= 0.01
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))
    assert disk_shape(S.uv, S.F).min() >= DISK_SHAPE_MIN


def test_refine_rim_respects_budget_gap_and_closed_meshes():
    S, _ = bumped_rim_state(6, 0.05)
    assert refine_rim(S, tol=0.01, min_gap=0.02, budget=5) == 5
    S, _ = bumped_rim_state(6, 0.05)
    assert refine_rim(S, tol=0.01, min_gap=10.0, budget=100) == 0      # every split a needle
    S, _ = bumped_rim_state(6, 0.05)
    assert refine_rim(S, tol=0.06, min_gap=0.02, budget=100) == 0      # within tolerance
    S.polygon = np.zeros((0, 3))                                       # a sphere: no rim
    assert refine_rim(S, tol=0.001, min_gap=0.0, budget=100) == 0


def polygon_state() -> RemeshState:
    """A 24-gon (every tenth boundary vertex of :func:`remesh_helpers.disk_map`'s disk)
    triangulated without interior vertices: every vertex on the rim."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    uv = uv_in[loop[::10]]
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    return RemeshState(lift(V_in, F_in, face, bary), F, uv, np.ones(len(uv), bool), face, bary,
                       V_in, F_in, uv_in, locator, uv_in[loop])


def test_open_rim_fans_splits_the_edge_across_every_wide_rim_angle():
    """A 24-gon triangulated without interior vertices (every face has three rim corners; the
    Delaunay triangulation of points on a circle has angles up to nearly 180° at rim vertices):
    after opening the fans no angle at a rim vertex is wider than the bound, every new vertex
    is interior, and the result is a counter-clockwise disk."""
    S = polygon_state()
    n0 = S.n
    wide = np.degrees(corner_angles(S.X, S.F)).max()
    assert wide > 150.0
    done = open_rim_fans(S, 120.0, rounds=10)
    assert done > 0 and S.n == n0 + done and not S.is_rim[n0:].any()
    assert np.degrees(corner_angles(S.X, S.F))[S.is_rim[S.F]].max() <= 120.0
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


def test_fan_edges_are_the_interior_half_edges_across_wide_angles_at_the_vertices_asked():
    """On the 24-gon of the test above: :func:`.rim.fan_edges` at every rim vertex gives,
    face by face, the half-edge opposite each corner wider than the bound at a rim vertex,
    those with a twin (interior) whose split keeps the shapes (the formula written out), and
    at one vertex those of its own wide corners alone; at no vertex, none."""
    S = polygon_state()
    wide = np.degrees(corner_angles(S.X, S.F)) > 120.0
    t, c = np.nonzero(wide & S.is_rim[S.F])
    h = 3 * t + (c + 1) % 3
    twin = S.twins()[h]
    h, twin = h[twin >= 0], twin[twin >= 0]
    keep = split_keeps_shape(S, h, twin)
    got_h, got_twin = fan_edges(S, S.is_rim, 120.0)
    assert len(got_h) > 0
    assert got_h.tolist() == h[keep].tolist() and got_twin.tolist() == twin[keep].tolist()
    v = int(S.F[t[0], c[0]])
    at = np.zeros(S.n, bool)
    at[v] = True
    one, _ = fan_edges(S, at, 120.0)
    assert len(one) > 0 and one.tolist() == [x for x in h[keep].tolist()
                                             if S.F[x // 3, (x % 3 + 2) % 3] == v]
    assert len(fan_edges(S, np.zeros(S.n, bool), 120.0)[0]) == 0
