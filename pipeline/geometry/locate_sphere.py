"""Point location in a spherical triangulation (a spherical map's image), for eq. (1) on the sphere.

A fold-free spherical map ``S`` (n, 3) of a closed genus-0 mesh with faces ``F`` (m, 3)
(``det[s0, s1, s2] > 0`` for every face) has flat image triangles whose central projections
tile the unit sphere exactly once. A query point ``q`` (unit vector) therefore lies on the ray
through exactly one flat image triangle ``[s_i, s_j, s_k]`` (two on a shared edge), and its
coordinates on that triangle are the *central* (gnomonic) barycentrics

    μ_i = det[q, s_j, s_k] / det[s_i, s_j, s_k],  μ_j = det[s_i, q, s_k] / …,
    μ_k = det[s_i, s_j, q] / …,        λ = μ / (μ_i + μ_j + μ_k)                       (L1)

(``q = Σ μ_c s_c`` by Cramer's rule; ``λ`` is the point where the ray meets the flat triangle).
``q`` is in the face iff every ``μ_c ≥ 0`` (and then ``Σ μ_c > 0``: the ray meets the front of
the triangle, not its antipode). The lift to the surface is then the disk's eq. (1),
``Σ_c λ_c v_c`` (:func:`pipeline.geometry.locate.lift`): the flat image triangle is mapped
affinely onto its surface triangle, exactly as on the disk, and great-circle arcs inside a
face go to straight segments. (Spherical barycentrics by geodesic areas would make the lift
non-affine on the flat image triangle, i.e. a different inverse of the same piecewise-linear
map.)

Search: the candidates of a query are the faces with the nearest (normalized) centroids (a
KD-tree), ``k = 8`` first, then 64 and 512 for the few queries not settled (thin image
triangles, which an equiareal map has where the surface is strongly curved), then every face.
The face with the largest smallest ``μ`` wins; it is accepted when that is ``≥ −tol`` and its
negative coordinates are clamped to 0. Every query gets a face.

This is a small pure kernel written for the sphere registration; the sphere remesher's point
location (built in parallel) should be merged with it into one module.
"""

from __future__ import annotations

import numpy as np

__all__ = ["central_barycentric", "locate_on_sphere"]

TOL = 1e-10              # smallest coordinate still counted as inside (then clamped to 0)
_ROUNDS = (8, 64, 512)   # candidate faces per query, round by round (then all faces)


def central_barycentric(points: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                        ) -> np.ndarray:
    """Unnormalized central coordinates ``μ`` of eq. (L1), shape (k, 3), for points (k, 3) and
    triangle corners ``A, B, C`` (k, 3) row by row (``q = μ_0 A + μ_1 B + μ_2 C``)."""
    det = np.einsum("ij,ij->i", A, np.cross(B, C))
    mu = np.column_stack([np.einsum("ij,ij->i", points, np.cross(B, C)),
                          np.einsum("ij,ij->i", A, np.cross(points, C)),
                          np.einsum("ij,ij->i", A, np.cross(B, points))])
    return mu / det[:, None]


def _best_of(S, F, points, candidates):
    """Among ``candidates`` (k, c) face indices per query, the face with the largest smallest
    coordinate μ, and that coordinate (rows with ``Σ μ ≤ 0``, the antipodal side, lose)."""
    k, c = candidates.shape
    Fc = F[candidates.ravel()]
    q = np.repeat(points, c, axis=0)
    mu = central_barycentric(q, S[Fc[:, 0]], S[Fc[:, 1]], S[Fc[:, 2]])
    score = np.where(mu.sum(axis=1) > 0, mu.min(axis=1), -np.inf).reshape(k, c)
    j = np.argmax(score, axis=1)
    return candidates[np.arange(k), j], score[np.arange(k), j]


def locate_on_sphere(S: np.ndarray, F: np.ndarray, points: np.ndarray, tol: float = TOL
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The face of the spherical map ``(S, F)`` whose central projection contains each point.

    Parameters
    ----------
    S : (n, 3) float array
        Fold-free spherical map (unit vectors, ``det[s0, s1, s2] > 0`` per face).
    F : (m, 3) int array
    points : (k, 3) float array
        Query points (any non-zero vectors; only their direction matters).
    tol : float
        Smallest coordinate still counted as inside.

    Returns
    -------
    face : (k,) int64 array
    bary : (k, 3) float64 array
        Normalized coordinates ``λ`` of eq. (L1), rows ≥ 0 summing to 1, ordered like
        ``F[face]``; ``lift(V, F, face, bary)`` is eq. (1).
    """
    from scipy.spatial import cKDTree

    S = np.asarray(S, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    P = P / np.linalg.norm(P, axis=1, keepdims=True)
    centres = S[F].sum(axis=1)
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    tree = cKDTree(centres)
    face = np.zeros(len(P), dtype=np.int64)
    score = np.full(len(P), -np.inf)
    todo = np.arange(len(P))
    for c in _ROUNDS:
        if not len(todo):
            break
        c = min(c, len(F))
        _, cand = tree.query(P[todo], k=c)
        f, s = _best_of(S, F, P[todo], np.asarray(cand).reshape(len(todo), c))
        better = s > score[todo]
        face[todo[better]], score[todo[better]] = f[better], s[better]
        todo = todo[score[todo] < -tol]
    for q in todo:                                  # not settled by the nearest faces: all
        f, s = _best_of(S, F, P[q:q + 1], np.arange(len(F))[None, :])
        face[q], score[q] = f[0], s[0]
    Fq = F[face]
    mu = np.maximum(central_barycentric(P, S[Fq[:, 0]], S[Fq[:, 1]], S[Fq[:, 2]]), 0.0)
    bary = mu / mu.sum(axis=1, keepdims=True)
    return face, bary
