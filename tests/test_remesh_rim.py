"""The rim follows the input boundary (pipeline.geometry.remesh.rim)."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.locate import lift
from pipeline.geometry.remesh.halfedge import DISK_SHAPE_MIN, disk_shape
from pipeline.geometry.metrics import corner_angles, signed_double_areas
from pipeline.geometry.remesh.rim import (arc_parameters, open_rim_fans, refine_rim, rim_gaps,
                                          segment_distances)
from pipeline.geometry.remesh.ragged import REACH, straighten_rim
from pipeline.geometry.remesh.state import RemeshState
from pipeline.geometry.rows import norms
from pipeline.geometry.remesh_quality import is_disk, mesh_facts
from remesh_helpers import ccw_delaunay, disk_map


def test_segment_distances_exact():
    A, B = np.zeros((3, 3)), np.array([[2.0, 0, 0]] * 3)
    P = np.array([[1.0, 1.0, 0], [-3.0, 4.0, 0], [5.0, 0, 4.0]])
    assert np.allclose(segment_distances(P, A, B), [1.0, 5.0, 5.0])


def bumped_rim_state(bumps: int, height: float, half_width: int = 0):
    """The unit disk map of ``disk_map`` with ``bumps`` evenly spread boundary vertices raised
    by ``height`` (with ``half_width`` > 0: bumps of tent shape, the ``half_width`` vertices on
    either side raised in proportion), remeshed coarsely: 24 rim samples on the polygon and a
    centre, every rim chord spanning 10 input boundary vertices. Returns the state and the
    raised vertices (the bumps' tops)."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    V_in = V_in.copy()
    at = np.arange(5, len(loop), len(loop) // bumps)[:bumps]   # never a rim sample (0, 10 …)
    raised = loop[at]
    for k in range(-half_width, half_width + 1):
        V_in[loop[at + k], 2] = height * (1.0 - abs(k) / (half_width + 1))
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
    h, a, bb, corner, gap, _ = rim_gaps(S, corners_X, arc_parameters(S.polygon, S.polygon))
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
    the rim, and the result is a disk, counter-clockwise, with no face thinner on the disk than
    the operations allow. The bumps are 7 boundary vertices wide (6 of the chord's 10 input
    edges beyond the tolerance): not narrow teeth."""
    S, raised = bumped_rim_state(6, 0.05, half_width=3)
    n0 = S.n
    done = refine_rim(S, tol=0.01, min_gap=0.02, budget=100)
    assert done >= 6 and S.n == n0 + done and S.log["rim_splits"] == done
    assert S.is_rim[n0:].all()
    for v in raised:
        assert np.min(np.linalg.norm(S.X - S.V_in[v], axis=1)) < 1e-12
    f, b, _ = S.locator.locate_with_inside(S.polygon)
    corners_X = lift(S.V_in, S.F_in, f, b)
    *_, gap, _ = rim_gaps(S, corners_X, arc_parameters(S.polygon, S.polygon))
    assert gap.max() <= 0.01
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))
    assert disk_shape(S.uv, S.F).min() >= DISK_SHAPE_MIN


def test_refine_rim_leaves_the_chords_across_narrow_teeth():
    """Single raised boundary vertices (spikes one input edge wide on each side, a tenth of
    their chord) are teeth narrower than ``TOOTH_WIDTH`` × the chord: no split, the gap at
    each stays the spike's height; tent bumps 3 edges wide on each side are split."""
    S, raised = bumped_rim_state(6, 0.05)
    assert refine_rim(S, tol=0.01, min_gap=0.02, budget=100) == 0
    f, b, _ = S.locator.locate_with_inside(S.polygon)
    corners_X = lift(S.V_in, S.F_in, f, b)
    *_, corner, gap, width = rim_gaps(S, corners_X, arc_parameters(S.polygon, S.polygon), 0.01)
    far = np.flatnonzero(gap > 0.01)
    assert len(far) == 6 and (width[far] < 0.25 * np.linalg.norm(S.X[0] - S.X[1])).all()
    S, _ = bumped_rim_state(6, 0.05, half_width=3)
    assert refine_rim(S, tol=0.01, min_gap=0.02, budget=100) >= 6


def test_refine_rim_respects_budget_gap_and_closed_meshes():
    S, _ = bumped_rim_state(6, 0.05, half_width=3)
    assert refine_rim(S, tol=0.01, min_gap=0.02, budget=5) == 5
    S, _ = bumped_rim_state(6, 0.05, half_width=3)
    assert refine_rim(S, tol=0.01, min_gap=10.0, budget=100) == 0      # every split a needle
    S, _ = bumped_rim_state(6, 0.05, half_width=3)
    assert refine_rim(S, tol=0.06, min_gap=0.02, budget=100) == 0      # within tolerance
    S.polygon = np.zeros((0, 3))                                       # a sphere: no rim
    assert refine_rim(S, tol=0.001, min_gap=0.0, budget=100) == 0


def test_open_rim_fans_splits_the_edge_across_every_wide_rim_angle():
    """A 24-gon triangulated without interior vertices (every face has three rim corners; the
    Delaunay triangulation of points on a circle has angles up to nearly 180° at rim vertices):
    after opening the fans no angle at a rim vertex is wider than the bound, every new vertex
    is interior, and the result is a counter-clockwise disk."""
    uv_in, F_in, V_in, loop, locator = disk_map()
    uv = uv_in[loop[::10]]
    F = ccw_delaunay(uv)
    face, bary = locator.locate(uv)
    S = RemeshState(lift(V_in, F_in, face, bary), F, uv, np.ones(len(uv), bool), face, bary,
                    V_in, F_in, uv_in, locator, uv_in[loop])
    wide = np.degrees(corner_angles(S.X, S.F)).max()
    assert wide > 150.0
    done = open_rim_fans(S, 120.0, rounds=10)
    assert done > 0 and S.n == len(uv) + done and not S.is_rim[len(uv):].any()
    assert np.degrees(corner_angles(S.X, S.F))[S.is_rim[S.F]].max() <= 120.0
    assert (signed_double_areas(S.uv, S.F) > 0).all() and is_disk(mesh_facts(S.X, S.F))


def test_straighten_rim_moves_samples_off_spikes_and_keeps_a_smooth_rim():
    """A 240-gon (the unit circle) whose corners lift onto the circle in the plane, every
    twentieth one pushed 0.1 outward (a spike): of 24 rim samples on every tenth corner, the
    12 on the spikes' tips each move to a corner beside it, the nearest to its neighbours'
    chord (within ``REACH`` × the rim spacing), the others stay; held fixed, the tips stay
    and so does every other sample. Without the spikes, none moves (a tolerance of 0.05 × the
    spacing, the rim's own: sliding a sample along a circle this curved brings it nearer the
    chord by less)."""
    t = 2 * np.pi * np.arange(240) / 240
    polygon = np.column_stack([np.cos(t), np.sin(t)])
    X = np.column_stack([polygon, np.zeros(240)])
    rim = polygon[::10]
    tol = 0.05 * 2 * np.pi / 24
    assert np.array_equal(straighten_rim(rim, polygon, X, tol), rim)
    X[::20, :2] *= 1.1
    out = straighten_rim(rim, polygon, X, tol)
    at = np.argmin(np.linalg.norm(polygon[:, None] - out[None], axis=2), axis=0)
    assert np.array_equal(out[1::2], rim[1::2])
    offset = (at[::2] - 10 * np.arange(0, 24, 2) + 120) % 240 - 120
    assert ((np.abs(offset) >= 1) & (np.abs(offset) <= 3)).all()
    assert np.allclose(out[::2], polygon[at[::2]])
    assert (np.linalg.norm(out - rim, axis=1) <= REACH * 2 * np.pi / 24).all()
    fixed = np.zeros(24, bool)
    fixed[::2] = True
    assert np.array_equal(straighten_rim(rim, polygon, X, tol, fixed), rim)
