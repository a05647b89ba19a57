"""The far-point trace of benchmarks/trace_far.py: distances to the input's boundary and the
structured samples (exact facts on a unit square)."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO

from pipeline.geometry.remesh_quality import SampledSurface

sys.path.insert(0, str(REPO / "benchmarks"))
from trace_far import boundary_distances, structured_samples  # noqa: E402


def unit_square() -> tuple:
    """The unit square in the z = 0 plane as two triangles: its boundary is its four sides."""
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    return V, np.array([[0, 1, 2], [0, 2, 3]])


def test_boundary_distances_are_those_to_the_nearest_side():
    V, F = unit_square()
    P = np.array([[0.5, 0.5, 0.0], [0.25, 0.5, 0.0], [0.5, 0.1, 0.3], [2.0, 0.5, 0.0],
                  [-3.0, -4.0, 0.0]])
    np.testing.assert_allclose(boundary_distances(P, V, F),
                               [0.5, 0.25, np.hypot(0.1, 0.3), 1.0, 5.0], rtol=1e-15)


def test_structured_samples_are_vertices_midpoints_and_centroids():
    V, F = unit_square()
    S = SampledSurface(V, F, n_random=4)
    P = structured_samples(S)
    assert len(P) == 4 + 5 + 2
    np.testing.assert_array_equal(P[:4], V)
    assert {tuple(p) for p in P[4:9]} == {(0.5, 0.0, 0.0), (1.0, 0.5, 0.0), (0.5, 1.0, 0.0),
                                          (0.0, 0.5, 0.0), (0.5, 0.5, 0.0)}
    np.testing.assert_allclose(P[9:], [[2 / 3, 1 / 3, 0.0], [1 / 3, 2 / 3, 0.0]], rtol=1e-15)
