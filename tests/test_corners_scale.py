"""Sharp input corners judged at the remesh's scale (pipeline.geometry.remesh.corners):
noise finer than the remesh is not taken for corners, real corners are kept, and where the
input is coarser than the remesh the rule is the vertex-by-vertex one."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.remesh.corners import vertex_turning, boundary_corners, interior_corners


def square_grid(k: int, height) -> tuple[np.ndarray, np.ndarray]:
    """The square [-1, 1]² as a k×k grid of vertices, two faces per cell, lifted by
    ``height(x, y)``."""
    t = np.linspace(-1.0, 1.0, k)
    x, y = (a.ravel() for a in np.meshgrid(t, t))
    idx = np.arange(k * k).reshape(k, k)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(),
                  idx[1:, 1:].ravel())
    F = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return np.column_stack([x, y, height(x, y)]), F


def noisy_cone(k: int, slope: float, sigma: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A square cone patch ``z = −slope · r`` (tip at the middle vertex) with normal noise of
    standard deviation ``sigma`` on every height."""
    noise = np.random.default_rng(seed).normal(0.0, sigma, k * k)
    return square_grid(k, lambda x, y: -slope * np.hypot(x, y) + noise)


def test_noisy_cone_keeps_its_tip_and_square_corners_not_the_noise():
    """A 61×61 cone patch (slope 1.5: a 161° defect at the tip) with height noise 0.75 of the
    grid step: vertex by vertex, 957 interior and 109 boundary vertices are sharper than 30°.
    At a remesh edge of 12 grid steps the tip is a corner with 2 others, and the boundary
    corners are the square's 4 and one more."""
    k = 61
    h = 2.0 / (k - 1)
    V, F = noisy_cone(k, 1.5, 0.75 * h, seed=0)
    loop = topo.boundary_loops(F)[0]
    tip, square = (k * k) // 2, {0, k - 1, k * (k - 1), k * k - 1}
    assert len(interior_corners(V, F, 30.0)) == 957
    assert len(boundary_corners(V, F, loop, 30.0)) == 109
    inner = interior_corners(V, F, 30.0, 12 * h)
    rim = boundary_corners(V, F, loop, 30.0, 12 * h)
    assert tip in inner and len(inner) == 3
    assert square <= set(rim.tolist()) and len(rim) == 5


def test_a_sharp_vertex_next_to_an_opposite_one_stays_a_corner():
    """A fine flat grid (61×61) with a spike (one vertex raised: a cone tip, positive
    defect) and, half a remesh edge away, a saddle vertex (its ring raised and lowered in
    turn: negative defect). Their defects would cancel in a sum over the remesh's scale; at a
    remesh edge of 8 grid steps (the saddle 0.5 L from the spike) the corners are the
    vertex-by-vertex ones, both among them."""
    k = 61
    h = 2.0 / (k - 1)
    V, F = square_grid(k, lambda x, y: np.zeros_like(x))
    spike, saddle = (k * k) // 2, (k * k) // 2 + 4
    V[spike, 2] = 1.5 * h
    ring = topo.vertex_neighbours(F, len(V))[saddle].indices
    ring = ring[np.argsort(np.arctan2(*(V[ring, :2] - V[saddle, :2]).T[::-1]))]
    V[ring, 2] = np.where(np.arange(len(ring)) % 2 == 0, 1.0, -1.0) * 0.8 * h
    value = vertex_turning(V, F)
    assert value[spike] > 60.0 and value[saddle] < -60.0
    each = interior_corners(V, F, 30.0)
    assert {spike, saddle} <= set(each.tolist())
    assert np.array_equal(interior_corners(V, F, 30.0, 8 * h), each)


def test_on_an_input_coarser_than_the_remesh_the_rule_is_vertex_by_vertex():
    """A coarse noisy cone (21×21, noise 0.75 of the grid step) remeshed at an edge of 1.5
    grid steps: fewer than 16 input vertices are within the reach of any vertex, and the
    corners are the vertex-by-vertex ones, in the same order."""
    k = 21
    h = 2.0 / (k - 1)
    V, F = noisy_cone(k, 1.5, 0.75 * h, seed=0)
    loop = topo.boundary_loops(F)[0]
    inner, rim = interior_corners(V, F, 30.0), boundary_corners(V, F, loop, 30.0)
    assert len(inner) > 50 and len(rim) > 20
    assert np.array_equal(interior_corners(V, F, 30.0, 1.5 * h), inner)
    assert np.array_equal(boundary_corners(V, F, loop, 30.0, 1.5 * h), rim)


def test_a_notch_closed_at_its_mouth_is_not_a_corner_a_seam_is_unaffected():
    """A loop touching itself at one point (positions 2 and 6: a notch of four edges closed at
    its mouth) marks both ends when the loop between them is shorter than the reach;
    a cut seam (points coinciding with their neighbours too) is never marked."""
    from pipeline.geometry.remesh.corners import closed_notches

    notch = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [2.5, 1.5, 0], [1.5, 1, 0],
                      [2, 0, 0], [3, 0, 0], [3, -2, 0], [0, -2, 0]], float)
    assert np.flatnonzero(closed_notches(notch, 4.0)).tolist() == [2, 6]
    assert not closed_notches(notch, 3.9).any()              # the notch's loop: 3.94
    seam = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 0, 0], [0, 0, 0], [0, -1, 0],
                     [2, -1, 0]], float)                      # a slit from (0,0) to its tip
    assert not closed_notches(seam, 100.0).any()
