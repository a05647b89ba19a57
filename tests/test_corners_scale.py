"""Sharp input corners judged at the remesh's scale (pipeline.geometry.remesh.corners):
noise finer than the remesh is not taken for corners, real corners are kept, and where the
input is coarser than the remesh the rule is the vertex-by-vertex one."""

from __future__ import annotations

import numpy as np

from pipeline.geometry import topology as topo
from pipeline.geometry.remesh.corners import (NOISE_NEIGHBOURS, _nan_median_rows, _nearest,
                                              _peaks, _unsorted, boundary_corners,
                                              interior_corners, vertex_turning)


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


def test_a_noisy_input_finer_than_the_remesh_but_sparse_at_its_reach_drops_noise_spikes():
    """The 61×61 cone patch (slope 1.5) with noise 0.5 of the grid step, judged at a remesh
    edge of 3 grid steps: the input's mean edge (about 1.7 steps) is the shorter, yet fewer
    than 16 input vertices lie within the reach of the tip: vertex by vertex all 284 sharp
    interior vertices would be corners. Judged as noisy over their 16 nearest, the tip stays
    a corner and fewer than 60 % of them do."""
    k = 61
    h = 2.0 / (k - 1)
    V, F = noisy_cone(k, 1.5, 0.5 * h, seed=0)
    tip = (k * k) // 2
    assert np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=2).mean() < 3 * h
    dist = _nearest(V, np.array([tip]), 3 * h)[0]
    assert (dist[0, 1:] < 3 * h).sum() < 16
    every = interior_corners(V, F, 30.0)
    assert len(every) == 284
    kept = interior_corners(V, F, 30.0, 3 * h)
    assert tip in kept and len(kept) < 0.6 * len(every)


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


def ict_face() -> tuple[np.ndarray, np.ndarray]:
    """The shared ICT face ict_A_neutral_disk (a real input)."""
    from conftest import require_data

    from pipeline.io.meshio import read_mesh

    mesh = read_mesh(require_data("faces", "ict", "ict_A_neutral_disk.obj"))
    return mesh.V, np.asarray(mesh.faces)


def test_nan_median_rows_is_numpys_nanmedian():
    """Rows with NaNs in random places (even and odd counts of numbers, ties among them, one
    row with a single number) and the noise deviations of a real face's sharp vertices: the
    same medians as ``np.nanmedian(x, axis=1)``, bit for bit."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(500, 65))
    x[rng.random(x.shape) < 0.2] = np.nan
    x[::7, :10] = 0.25                                       # ties
    x[3, 1:] = np.nan                                        # one number left
    assert np.array_equal(_nan_median_rows(x), np.nanmedian(x, axis=1))
    V, F = ict_face()
    value = vertex_turning(V, F)
    sharp = np.flatnonzero(np.abs(value) > 1.0)
    dist, near, order = _nearest(V, sharp, 1.0)
    around = np.where(near != sharp[order][:, None], value[near], np.nan)
    dev = np.abs(around - np.nanmean(around, axis=1)[:, None])
    assert len(sharp) > 1000
    assert np.array_equal(_nan_median_rows(dev), np.nanmedian(dev, axis=1))


def test_nearest_is_the_trees_answer_row_by_row():
    """Queries in a scrambled order (and on a grid, where distances tie): row ``i`` is the
    tree's answer for ``at[order[i]]``, ``order`` a permutation putting ``at`` in the mesh's
    order; per-row values put back by :func:`_unsorted` are in the queries' own order."""
    from scipy.spatial import cKDTree

    V, _ = square_grid(31, lambda x, y: np.zeros_like(x))
    at = np.random.default_rng(1).permutation(len(V))[:400]
    for P in (V, ict_face()[0]):
        dist, near, order = _nearest(P, at, 1.0)
        want_dist, want_near = cKDTree(P).query(P[at], k=NOISE_NEIGHBOURS + 1)
        assert np.array_equal(np.sort(order), np.arange(len(at)))
        assert np.all(np.diff(at[order]) > 0)
        assert np.array_equal(dist, want_dist[order]) and np.array_equal(near, want_near[order])
        assert np.array_equal(_unsorted(near[:, 1], order), want_near[:, 1])


def test_peaks_of_the_asked_points_are_those_of_all_points():
    """Only some points asked: their answers are those :func:`_peaks` gives when every point
    is judged (the others still compete), on random scores with ties and on a face's held
    defects; the points not asked come back True."""
    rng = np.random.default_rng(2)
    P = rng.random((3000, 3))
    sign = rng.choice([-1.0, 1.0], len(P))
    score = np.round(rng.random(len(P)), 2)                  # ties
    asked = rng.random(len(P)) < 0.3
    every = _peaks(P, sign, score, 0.1)
    some = _peaks(P, sign, score, 0.1, asked)
    assert np.array_equal(some[asked], every[asked]) and some[~asked].all()
    assert 0 < every[asked].sum() < asked.sum()
    V, F = ict_face()
    value = vertex_turning(V, F)
    at = np.flatnonzero(np.abs(value) > 5.0)
    asked = np.abs(value[at]) > 15.0
    every = _peaks(V[at], value[at], np.abs(value[at]), 0.5)
    some = _peaks(V[at], value[at], np.abs(value[at]), 0.5, asked)
    assert np.array_equal(some[asked], every[asked]) and some[~asked].all()
    assert 0 < every[asked].sum() < asked.sum()
