"""The noise level of a scanned surface: how far its vertices scatter along the normal from
one vertex to the next, apart from the way the surface bends.

A vertex's umbrella offset (the mean of its neighbours minus the vertex, along its normal) is
about ``κ h² / 4`` on a smooth surface of curvature ``κ`` sampled at spacing ``h`` and changes
slowly from a vertex to its neighbours; noise of standard deviation ``σ`` along the normals
adds a part of about ``0.9 σ`` that changes sign from one vertex to the next. :func:`noise_level`
keeps that part: the median, over the interior vertices, of the offset less its neighbours'
mean offset.
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np

from . import topology as topo
from .rows import cross, norms

__all__ = ["neighbour_means", "umbrella_offsets", "noise_level", "noise_beyond"]

#: noise_level ÷ the standard deviation of normal noise it measures (a regular grid)
LEVEL_PER_SIGMA = 0.9


def neighbour_means(A, X: np.ndarray) -> np.ndarray:
    """Per vertex, the mean of ``X`` (n or n×d) over its neighbours in the adjacency ``A``
    (n×n sparse bool, :func:`.topology.vertex_neighbours`); 0 at a vertex without any."""
    degree = np.maximum(np.asarray(A.sum(axis=1)).ravel(), 1)
    means = A.astype(float) @ X
    return means / (degree[:, None] if means.ndim == 2 else degree)


def umbrella_offsets(V: np.ndarray, F: np.ndarray, A=None) -> np.ndarray:
    """Per vertex (n,): the mean of its neighbours minus the vertex, along its area-weighted
    normal (0 at a vertex without faces or neighbours).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    A : (n, n) sparse bool, optional
        :func:`.topology.vertex_neighbours` of ``F`` when already made.
    """
    A = topo.vertex_neighbours(F, len(V)) if A is None else A
    face_normal = cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    normal = topo.vertex_faces(F, len(V)).astype(float) @ face_normal
    normal /= np.maximum(norms(normal), 1e-300)[:, None]
    to_mean = neighbour_means(A, V) - V
    return np.einsum("ij,ij->i", to_mean, normal)


def noise_level(V: np.ndarray, F: np.ndarray) -> float:
    """The median, over the interior vertices, of ``|o − ō|``: a vertex's umbrella offset
    ``o`` (:func:`umbrella_offsets`) less the mean ``ō`` of its neighbours' (mesh units; 0 for
    a mesh without interior vertices). About ``0.9 σ`` for noise of standard deviation ``σ``
    along the normals of a surface sampled finer than it bends; about 0 without noise.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int

    Returns
    -------
    float
    """
    A = topo.vertex_neighbours(F, len(V))
    offset = umbrella_offsets(V, F, A)
    rough = np.abs(offset - neighbour_means(A, offset))
    inner = ~topo.boundary_vertices_mask(F, len(V))
    return float(np.median(rough[inner])) if inner.any() else 0.0


def noise_beyond(level: float, share: float) -> float:
    """The size (mesh units) that a ``share`` (0 < share < 1) of the points of a surface with
    normal noise at :func:`noise_level` ``level`` lie beyond, on either side: ``z σ`` with
    ``σ = level / LEVEL_PER_SIGMA`` and ``P(|N(0, 1)| > z) = share``; 0 for ``level`` 0."""
    if level <= 0:
        return 0.0
    return NormalDist().inv_cdf(1.0 - min(share, 1.0) / 2.0) * level / LEVEL_PER_SIGMA
