"""The input map's per-face quantities of the remesh state (pipeline.geometry.remesh.state) and
the row helpers they use."""

from __future__ import annotations

import numpy as np


def test_pullback_takes_a_displacement_to_the_disk_exactly():
    """On a face whose 3D position is an affine image of its disk position, the pullback of
    ``J e`` is ``e``, and a displacement along the normal pulls back to 0."""
    from pipeline.geometry.remesh.state import pullback_matrices

    uv_in = np.array([[0.1, 0.2], [0.9, 0.3], [0.4, 0.8]])
    J = np.array([[2.0, 0.5], [-0.3, 1.5], [1.0, -0.7]])              # 3×2, rank 2
    V_in = uv_in @ J.T + [1.0, 2.0, 3.0]
    P = pullback_matrices(V_in, np.array([[0, 1, 2]]), uv_in)
    e = np.array([0.3, -0.2])
    assert np.allclose(P[0] @ (J @ e), e, atol=1e-14)
    normal = np.cross(J[:, 0], J[:, 1])
    assert np.allclose(P[0] @ normal, 0.0, atol=1e-14)
    degenerate = pullback_matrices(V_in, np.array([[0, 0, 1]]), uv_in)
    assert np.array_equal(degenerate, np.zeros((1, 2, 3)))


def test_row_helpers_match_numpy():
    from pipeline.geometry.rows import cross, dots, norms

    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(1000, 3)), rng.normal(size=(1000, 3))
    assert np.array_equal(cross(a, b), np.cross(a, b))            # the same arithmetic
    assert np.allclose(norms(a), np.linalg.norm(a, axis=1), rtol=1e-15, atol=0)
    assert np.allclose(dots(a, b), (a * b).sum(1), rtol=1e-13, atol=1e-15)


def test_at_points_finds_the_rows_equal_bit_for_bit():
    """A row is found when all three coordinates have a point's bits: not for a point that
    shares only its first coordinate, nor for -0.0 against 0.0; repeated points and points
    absent from the rows change nothing."""
    from pipeline.geometry.remesh.state import at_points

    X = np.array([[0.0, 1.0, 2.0], [-0.0, 1.0, 2.0], [0.5, 0.25, 0.125], [0.5, 0.25, 0.0],
                  [3.0, 4.0, 5.0], [0.5, 0.25, 0.125]])
    P = np.array([[0.0, 1.0, 2.0], [0.5, 0.25, 0.125], [0.5, 0.25, 0.125], [7.0, 8.0, 9.0],
                  [3.0, 4.0, 5.0 + 1e-15]])
    assert at_points(X, P).tolist() == [True, False, True, False, False, True]
    assert at_points(X, P[:0]).tolist() == [False] * 6
    assert at_points(X[:0], P).tolist() == []
