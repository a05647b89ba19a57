"""Quality measures of a remeshed surface against its input (pure functions, arrays in, dicts out).

Measured (the units are part of the keys' documentation in :func:`remesh_quality`):

* **Topology** (:func:`mesh_facts`): counts, connected components, boundary loops, Euler
  characteristic ``V − E + F``, non-manifold edges and vertices, consistent orientation, leaf
  faces (three boundary corners), degenerate faces (repeated index, or twice the area
  ≤ 1e-12 × longest edge²). A disk: one component, one loop, χ = 1, everything else 0.
* **Triangle shape** (:func:`triangle_quality`): the smallest angle of each face (60° is
  equilateral): minimum, mean, 5th percentile, fraction below 30°; the largest angle; the
  coefficient of variation (SD / mean) of face areas and edge lengths (0 = all equal).
* **Valence** (:func:`valence_stats`): histogram of the number of edges per vertex, separately
  for interior vertices (regular = 6) and boundary vertices (regular = 4).
* **Distance to the input** (:func:`surface_distance`): samples on each surface — all its
  vertices, edge midpoints and face centroids, plus ``n_random`` points drawn uniformly by area
  (fixed seed) — and the *exact* Euclidean distance of every sample to the other surface's
  triangles (:class:`MeshDistance`; a midpoint or centroid whose distance is bounded below
  the largest distance found — by the distance's Lipschitz bound, then by its distance to the
  other surface's faces closest to its corners — is not measured: it cannot change the
  maximum). One-sided maxima, the two-sided Hausdorff distance ``max(h(A→B), h(B→A))`` (a
  sampled lower bound of the continuous value; with these densities it agrees with MeshLab's
  sampled Hausdorff filter) and the two-sided RMS distance
  ``sqrt((mean_A d² + mean_B d²) / 2)`` over the area-uniform samples only (an area-weighted
  mean). Reported in the input's units and in % of the input's bounding-box diagonal.
* **Turned-over faces** (:func:`turned_over_faces`): faces whose normal points against the
  input's normal where they lie (the input faces closest to their centroid and to each of their
  corners): folds of the surface, which neither the angles nor the distances show.
"""

from __future__ import annotations

import os
import threading
from typing import NamedTuple

import numpy as np

from . import topology as topo
from ._kernels import (closest_points, face_distances, guided_draws, tree_boxes, tree_distances,
                       triangle_points, triangle_tree)
from .laplacian import face_double_areas
from .metrics import corner_angles
from .rows import norms, row_max, row_min

__all__ = ["mesh_facts", "triangle_quality", "valence_stats", "closest_points_on_triangles",
           "MeshDistance", "MiddleOffsets", "middle_offsets", "SampledSurface", "face_centroids",
           "z_order", "point_mesh_distance",
           "surface_samples", "surface_distance", "turned_over_faces", "remesh_quality",
           "degenerate_faces", "bounding_box_diagonal", "is_disk", "is_disk_with_holes",
           "hole_count", "is_sphere", "DISTANCE_SAMPLES"]

DEGENERATE_RTOL = 1e-12      # 2·area ≤ this × longest edge² counts as degenerate

#: area-uniform samples per surface for the distances: the two-sided RMS distance's sampling
#: error is below 0.5 ‰ of its value at this count, and the Hausdorff distance's spread over
#: seeds is the same as at twice as many (the samples that decide it are the structured ones
#: and the few random ones near the farthest place)
DISTANCE_SAMPLES = 100_000


def bounding_box_diagonal(V: np.ndarray) -> float:
    """The length of the diagonal of the bounding box of the points ``V`` (n, d): the extents
    taken column by column (numpy's reductions along the first axis of an n×d array are
    several times slower; the extremes are the same)."""
    V = np.asarray(V)
    return float(np.linalg.norm([V[:, k].max() - V[:, k].min() for k in range(V.shape[1])]))


def degenerate_faces(V: np.ndarray, F: np.ndarray, rtol: float = DEGENERATE_RTOL,
                     double_area: np.ndarray | None = None) -> np.ndarray:
    """Indices of faces with a repeated vertex or (near-)zero area (``double_area``: the
    faces' :func:`.laplacian.face_double_areas` when already computed)."""
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    dA = face_double_areas(V, F) if double_area is None else double_area
    return np.flatnonzero(rep | (dA <= rtol * longest_edge_squared(V, F)))


def longest_edge_squared(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The squared length (m,) of the longest edge of each face of ``F`` (m, 3), summed
    ``(x² + y²) + z²`` per edge, one coordinate at a time (numpy's reductions along the short
    axis of an m×3×3 array are several times slower)."""
    longest = None
    for a, b in ((1, 0), (2, 1), (0, 2)):
        sq = None
        for axis in range(3):
            x = V[:, axis]
            e = x[F[:, a]] - x[F[:, b]]
            sq = e * e if sq is None else sq + e * e
        longest = sq if longest is None else np.maximum(longest, sq)
    return longest


def mesh_facts(V: np.ndarray, F: np.ndarray, double_area: np.ndarray | None = None) -> dict:
    """Topology and validity counts of a triangle mesh (see the module docstring;
    ``double_area``: the faces' doubled areas when already computed)."""
    with topo.kept_edge_groups():           # the counts below group F's edges five times
        return _mesh_facts(V, np.asarray(F, np.int64), double_area)


def _mesh_facts(V: np.ndarray, F: np.ndarray, double_area: np.ndarray | None) -> dict:
    n = len(V)
    ncomp, _ = topo.connected_components(F, n)
    nm_edges = len(topo.nonmanifold_edges(F))
    try:
        loops = topo.boundary_loops(F)
        loop_lengths = [int(len(lp)) for lp in loops]
    except Exception:                                       # pinched / inconsistent boundary
        loops, loop_lengths = [], None
    a, b = topo.half_edges(F)
    twin = topo.interior_edge_twins(F)
    inner = twin >= 0
    oriented = bool(np.array_equal(a[inner], b[twin[inner]]))
    is_b = topo.boundary_vertices_mask(F, n)
    return {
        "vertices": int(n),
        "faces": int(len(F)),
        "unreferenced_vertices": int(n - _referenced_count(F, n)),
        "components": int(ncomp),
        "boundary_loops": None if loop_lengths is None else len(loop_lengths),
        "boundary_vertices": int(is_b.sum()),
        "euler_characteristic": int(topo.euler_characteristic(F, n)),
        "nonmanifold_edges": int(nm_edges),
        "nonmanifold_vertices": int(len(topo.nonmanifold_vertices(F, n))) if nm_edges == 0
        else None,
        "consistently_oriented": oriented,
        "leaf_faces": int(len(topo.leaf_faces(F, is_b))),
        "degenerate_faces": int(len(degenerate_faces(V, F, double_area=double_area))),
    }


def _referenced_count(F: np.ndarray, n: int) -> int:
    """How many distinct indices ``F`` holds (through a mask of at least ``n`` entries:
    cheaper than ``np.unique`` on 3m indices)."""
    if F.size == 0:
        return 0
    return len(topo.distinct_indices(F.ravel(), max(n, int(F.max()) + 1)))


def is_disk(facts: dict) -> bool:
    """One manifold, consistently oriented component with one boundary loop and χ = 1."""
    return is_disk_with_holes(facts, 0)


def is_disk_with_holes(facts: dict, holes: int) -> bool:
    """One manifold, consistently oriented component with 1 + ``holes`` boundary loops and
    χ = 1 − ``holes`` (:func:`is_disk` for no holes)."""
    return (facts["components"] == 1 and facts["boundary_loops"] == 1 + holes
            and facts["euler_characteristic"] == 1 - holes and facts["nonmanifold_edges"] == 0
            and facts["nonmanifold_vertices"] == 0 and facts["consistently_oriented"]
            and facts["unreferenced_vertices"] == 0)


def hole_count(facts: dict) -> int:
    """How many holes a mesh with these :func:`mesh_facts` has besides its outer boundary:
    its boundary loops but one (0 for none or a pinched boundary)."""
    return max((facts["boundary_loops"] or 0) - 1, 0)


def is_sphere(facts: dict) -> bool:
    """One closed (no boundary), manifold, consistently oriented component with χ = 2: a
    genus-0 closed surface."""
    return (facts["components"] == 1 and facts["boundary_vertices"] == 0
            and facts["euler_characteristic"] == 2 and facts["nonmanifold_edges"] == 0
            and facts["nonmanifold_vertices"] == 0 and facts["consistently_oriented"]
            and facts["unreferenced_vertices"] == 0)


def triangle_quality(V: np.ndarray, F: np.ndarray, double_area: np.ndarray | None = None
                     ) -> dict:
    """Angles (degrees) and size uniformity of the faces (see the module docstring;
    ``double_area``: the faces' doubled areas when already computed)."""
    ang = np.degrees(corner_angles(V, F))
    mn, mx = row_min(ang), row_max(ang)
    A = (face_double_areas(V, F) if double_area is None else double_area) / 2
    Eu = _unique_edge_lengths(V, F)
    return {
        "min_angle_deg": float(mn.min()),
        "min_angle_p05_deg": float(np.percentile(mn, 5)),
        "mean_min_angle_deg": float(mn.mean()),
        "fraction_min_angle_below_30": float((mn < 30.0).mean()),
        "max_angle_deg": float(mx.max()),
        "fraction_max_angle_above_120": float((mx > 120.0).mean()),
        "area_cv": float(A.std() / A.mean()),
        "edge_length_cv": float(Eu.std() / Eu.mean()),
        "mean_edge_length": float(Eu.mean()),
        "mean_face_area": float(A.mean()),
        "_per_face_min_angle": mn,                    # array, for figures; dropped in JSON
    }


def _unique_edge_lengths(V, F):
    """The length of every edge of ``F``: ``np.linalg.norm(V[i] − V[j], axis=1)``'s values,
    its sum of squares ``(x² + y²) + z²`` taken column by column."""
    E, _ = topo.edges_with_faces(F)
    sq = None
    for axis in range(V.shape[1]):
        x = V[:, axis]
        d = x[E[:, 0]] - x[E[:, 1]]
        sq = d * d if sq is None else sq + d * d
    return np.sqrt(sq)


def valence_stats(F: np.ndarray, n: int) -> dict:
    """Valence (edges per vertex) histograms for interior and boundary vertices."""
    E, _ = topo.edges_with_faces(F)
    val = np.bincount(E.ravel(), minlength=n)
    is_b = topo.boundary_vertices_mask(F, n)
    vi, vb = val[~is_b], val[is_b]

    def hist(v):
        if len(v) == 0:
            return {}
        c = np.bincount(v)
        return {str(k): int(c[k]) for k in np.flatnonzero(c)}

    return {
        "interior_histogram": hist(vi),
        "boundary_histogram": hist(vb),
        "interior_fraction_6": float((vi == 6).mean()) if len(vi) else float("nan"),
        "interior_fraction_5_to_7": float(((vi >= 5) & (vi <= 7)).mean()) if len(vi)
        else float("nan"),
        "interior_min": int(vi.min()) if len(vi) else None,
        "interior_max": int(vi.max()) if len(vi) else None,
    }


# ------------------------------------------------------------------------ distances


def closest_points_on_triangles(P: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                                ) -> np.ndarray:
    """Closest point of triangle ``(A, B, C)`` to ``P`` (all k×3), row by row.

    The Voronoi-region case analysis of Ericson, *Real-Time Collision Detection* §5.1.5:
    the vertex regions, then the edge regions, then the face interior; a degenerate triangle
    (a point that comes out not finite) gives its corner nearest to ``P``. Compiled
    (:func:`._kernels.closest_points`: the remesher asks it of a few faces at a time, many
    times).
    """
    f64 = [np.ascontiguousarray(x, dtype=np.float64).reshape(-1, 3) for x in (P, A, B, C)]
    return closest_points(*f64)


def _spread_bits(q: np.ndarray) -> np.ndarray:
    """The 10 low bits of each ``q`` (uint32) moved to every third bit position."""
    q = (q | (q << 16)) & 0x030000FF
    q = (q | (q << 8)) & 0x0300F00F
    q = (q | (q << 4)) & 0x030C30C3
    return (q | (q << 2)) & 0x09249249


def z_order(P: np.ndarray) -> np.ndarray:
    """Indices that put the points ``P`` (k×3) in Z-order (Morton order) on a 1024³ grid of
    their bounding box: points close in space come close in the order. (Column by column:
    numpy's reductions and arithmetic along the short axis of a k×3 array are several times
    slower.)"""
    code = np.zeros(len(P), np.uint32)
    for axis in range(3):
        x = P[:, axis]
        if len(x) == 0:
            break
        lo, hi = x.min(), x.max()
        q = np.minimum((x - lo) * (1024 / (hi - lo) if hi > lo else 0.0), 1023)
        code |= _spread_bits(q.astype(np.uint32)) << axis
    return np.argsort(code)


class MeshDistance:
    """Exact Euclidean distances to one triangle mesh ``(V, F)``: a bounding-volume hierarchy
    over its triangles (:func:`._kernels.triangle_tree`, the triangles in Z-order of their
    centroids), built once and queried any number of times (:func:`._kernels.tree_distances`:
    each point's distance is the smallest of its exact point–triangle distances, the closest
    face the lowest-numbered of equals, as if every triangle were measured).

    Each query's points are looked up in Z-order (:func:`z_order`) and the results put back in
    the given order: a point's distance and closest face do not depend on the other points of
    the query, and consecutive nearby points walk the same branches of the tree and start from
    the previous point's face. A query of at least ``THREAD_POINTS`` points is split into
    ``THREADS`` runs measured at once, the first by the calling thread and each other by a
    thread started for it (the kernel runs without the GIL; no pool is kept, so a forked
    process queries as its parent does)."""

    #: threads of a large query; the points a query needs before it is split between them
    THREADS = min(2, os.cpu_count() or 1)
    THREAD_POINTS = 4096

    def __init__(self, V: np.ndarray, F: np.ndarray):
        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self.faces, *tree = triangle_tree(face_centroids(self.V, self.F))
        self.triangles = self.V.take(self.F.take(self.faces, axis=0).ravel(), axis=0
                                     ).reshape(-1, 9)        # V[F[faces]], gathered by take
        self.margin = _TREE_MARGIN * (float(np.abs(self.V).max()) if len(self.V) else 0.0)
        self.tree = (*tree, tree_boxes(self.triangles, *tree[:3], self.margin))

    def __call__(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(distance, closest face)`` of every point of ``P`` (k×3)."""
        P = np.asarray(P, np.float64).reshape(-1, 3)
        if len(P) == 0:
            return np.zeros(0), np.zeros(0, np.int64)
        order = z_order(P)
        Q = P.take(order, axis=0)
        dq, fq = np.empty(len(P)), np.empty(len(P), np.int64)
        runs = self.THREADS if len(P) >= self.THREAD_POINTS else 1
        cuts = np.linspace(0, len(P), runs + 1).astype(int)
        parts = [(Q[a:b], dq[a:b], fq[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
        helpers = [threading.Thread(target=self._measure, args=part) for part in parts[1:]]
        for thread in helpers:
            thread.start()
        self._measure(*parts[0])
        for thread in helpers:
            thread.join()
        d, f = np.empty(len(P)), np.empty(len(P), np.int64)
        d[order], f[order] = dq, fq
        return d, f

    def _measure(self, Q: np.ndarray, d: np.ndarray, f: np.ndarray) -> None:
        """Distances ``d`` and closest faces ``f`` of the points ``Q`` (written in place)."""
        tree_distances(Q, self.triangles, self.faces, *self.tree, d, f)


#: the margin by which the tree's boxes are widened, relative to the largest coordinate
#: (far above the rounding of a point–triangle distance, far below any distance measured)
_TREE_MARGIN = 1e-12


def point_mesh_distance(P: np.ndarray, V: np.ndarray, F: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Exact Euclidean distance of every point of ``P`` to the triangle mesh ``(V, F)`` and the
    index of a closest face (:class:`MeshDistance`: its tree built once per call,
    so the hundreds of thousands of samples of the report's Hausdorff and RMS distances take a
    fraction of a second)."""
    return MeshDistance(V, F)(P)


def surface_samples(V: np.ndarray, F: np.ndarray, n_random: int, seed: int = 0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(structured, random)`` samples: vertices + edge midpoints + face centroids, and
    ``n_random`` points uniform by area (seeded)."""
    E, _ = topo.edges_with_faces(F)
    return _structured_samples(V, F, E), _random_samples(V, F, n_random, seed)


def _structured_samples(V: np.ndarray, F: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Vertices, then midpoints of the edges ``E``, then face centroids."""
    return np.vstack([V, (V[E[:, 0]] + V[E[:, 1]]) / 2, face_centroids(V, F)])


def _random_samples(V: np.ndarray, F: np.ndarray, n_random: int, seed: int,
                    double_area: np.ndarray | None = None) -> np.ndarray:
    """``n_random`` points uniform by area (seeded): a face drawn with probability
    proportional to its area (:func:`_area_weighted_faces`; ``double_area``: the faces'
    doubled areas when already computed), then a point uniform in it,
    ``p0 + u (p1 − p0) + v (p2 − p0)`` with ``(u, v)`` uniform in the unit square and
    reflected into the triangle (computed one coordinate at a time)."""
    rng = np.random.default_rng(seed)
    dA = face_double_areas(V, F) if double_area is None else double_area
    f = _area_weighted_faces(dA, n_random, rng)
    u, v = rng.random(n_random), rng.random(n_random)
    return triangle_points(np.ascontiguousarray(V, dtype=np.float64),
                           np.ascontiguousarray(F, dtype=np.int64), f, u, v)


#: forward steps from the guide table before a draw's face is found by bisection instead
GUIDE_WALK = 8


def _area_weighted_faces(A: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` indices into ``A`` (face areas) drawn with probability proportional to ``A``:
    the draws of ``rng.choice(len(A), k, p=A / A.sum())``, the same indices from the same
    state of ``rng`` (its normalised cumulative sums, then for each of ``k`` uniform draws
    ``u`` the first index whose sum exceeds ``u``). Each search starts from a guide table
    (for the ``m`` equal steps ``j / m`` of [0, 1), the first index whose sum exceeds
    ``j / m``), at the step below the draw's own, which rounding cannot put past the answer,
    and moves forward one index at a time, instead of bisecting the whole table per draw; a
    draw not found within ``GUIDE_WALK`` steps (faces far smaller than a step) is bisected."""
    total = A.sum()
    if not total > 0:
        raise ValueError("a surface with no area has no area-uniform samples")
    cdf = (A / total).cumsum()
    cdf /= cdf[-1]
    u = rng.random(k)
    m = len(cdf)
    guide = cdf.searchsorted(np.arange(m) / m, side="right")
    return guided_draws(cdf, guide, u, GUIDE_WALK)


#: relative margin of the Lipschitz bound below which a structured sample is not queried:
#: far above the rounding of the distances, far below any difference the report shows
_BOUND_MARGIN = 1e-9


def midpoint_bounds(V: np.ndarray, E: np.ndarray, d_vertex: np.ndarray,
                    half_lengths: np.ndarray | None = None) -> np.ndarray:
    """The Lipschitz upper bounds of :func:`middle_bounds` for the edge midpoints alone.

    Parameters
    ----------
    V : (n, 3) float
    E : (e, 2) int
    d_vertex : (n,) float
    half_lengths : (e,) float, optional
        Half the edges' lengths when already computed (:func:`middle_offsets`).

    Returns
    -------
    (e,) float
    """
    a, b = E[:, 0], E[:, 1]
    half = 0.5 * norms(V[b] - V[a]) if half_lengths is None else half_lengths
    return np.minimum(d_vertex[a], d_vertex[b]) + half


class MiddleOffsets(NamedTuple):
    """How far the middles of a mesh's edges and faces are from their corners
    (:func:`middle_offsets`): ``half_lengths`` (e,), half of each edge's length;
    ``centroids`` (m, 3), the faces' centroids; ``to_corners`` (m, 3), each centroid's
    distance to each corner of its face."""

    half_lengths: np.ndarray
    centroids: np.ndarray
    to_corners: np.ndarray


def middle_offsets(V: np.ndarray, F: np.ndarray, E: np.ndarray) -> MiddleOffsets:
    """The distances :func:`middle_bounds` adds to the corners' distances, for the edges ``E``
    (e, 2) and faces ``F`` (m, 3) of ``V`` (n, 3): a function of the mesh alone, computed once
    where the bounds are asked for many distance fields of one mesh. (Corner by corner: the
    values of the norms of an m×3×3 array's rows, faster.)"""
    centroids = face_centroids(V, F)
    to_corners = np.column_stack([norms(centroids - V.take(F[:, c], axis=0)) for c in range(3)])
    return MiddleOffsets(0.5 * norms(V.take(E[:, 1], axis=0) - V.take(E[:, 0], axis=0)),
                         centroids, to_corners)


def middle_bounds(V: np.ndarray, F: np.ndarray, E: np.ndarray, d_vertex: np.ndarray,
                  offsets: MiddleOffsets | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds of the distance to a surface of the edge midpoints and face centroids of
    ``(V, F)`` from their corners' distances ``d_vertex`` (n): the distance is 1-Lipschitz, so
    a point ``x`` is at most ``d(v) + |x − v|`` away for each corner ``v`` of its edge or face.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    E : (e, 2) int
        Edges of ``(V, F)`` (any subset).
    d_vertex : (n,) float
    offsets : MiddleOffsets, optional
        :func:`middle_offsets` of ``(V, F, E)`` when already computed.

    Returns
    -------
    mid_bound : (e,) float
    centroids : (m, 3) float
    centroid_bound : (m,) float
    """
    o = middle_offsets(V, F, E) if offsets is None else offsets
    mid_bound = midpoint_bounds(V, E, d_vertex, o.half_lengths)
    return mid_bound, o.centroids, row_min(d_vertex[F] + o.to_corners)


def face_bounds(P: np.ndarray, corners: np.ndarray, corner_face: np.ndarray,
                distance: MeshDistance) -> np.ndarray:
    """Upper bounds of the distance of the points ``P`` to the surface of ``distance``: each
    point's exact distance to the faces of that surface closest to its corners (compiled:
    :func:`._kernels.face_distances`). A point between corners close to the surface is seldom
    much nearer to any other face, so the bound is tight where the Lipschitz bound of
    :func:`middle_bounds` is loose by half an edge.

    Parameters
    ----------
    P : (k, 3) float
    corners : (k, c) int
        The corners of each point's edge (c = 2) or face (c = 3).
    corner_face : (n,) int
        The face of ``distance``'s surface closest to each vertex.
    distance : MeshDistance

    Returns
    -------
    (k,) float
    """
    return candidate_face_distances(P, corner_face[corners], distance)


def candidate_face_distances(P: np.ndarray, faces: np.ndarray, distance: MeshDistance
                             ) -> np.ndarray:
    """The distance of each point of ``P`` (k, 3) to the nearest of its candidate faces
    ``faces`` (k, c) of the surface of ``distance`` (compiled:
    :func:`._kernels.face_distances`): an upper bound of its distance to that surface."""
    return face_distances(np.ascontiguousarray(P, dtype=np.float64), distance.V, distance.F,
                          np.ascontiguousarray(faces, dtype=np.int64))


def bound_slack(V: np.ndarray) -> float:
    """The absolute margin (:func:`may_reach`) of distance bounds to or from the surface of
    the vertices ``V`` (n, 3): ``_BOUND_MARGIN`` × its bounding-box diagonal."""
    return _BOUND_MARGIN * bounding_box_diagonal(V)


def may_reach(bound: np.ndarray, best: float, slack: float) -> np.ndarray:
    """Whether each upper bound ``bound`` (k,) of a distance may reach ``best``: not below it
    by more than ``_BOUND_MARGIN`` relative and ``slack`` absolute, far above the rounding
    that separates a compiled bound from the tree's distance of the same point."""
    return bound * (1 + _BOUND_MARGIN) + slack >= best


def largest_distance(P: np.ndarray, bound: np.ndarray, distance: MeshDistance, slack: float,
                     first: int = 64) -> float:
    """The largest distance of the points ``P`` to the surface of ``distance``, as if every
    point were measured, from their upper bounds: the ``first`` points of the largest bounds
    are measured, then only those of the others whose bound may reach the largest distance
    found (:func:`may_reach`).

    Parameters
    ----------
    P : (k, 3) float
    bound : (k,) float
        Upper bounds of the points' distances (:func:`face_bounds`).
    distance : MeshDistance
    slack : float
        In the mesh's units (:func:`may_reach`).
    first : int

    Returns
    -------
    float
        0 for no points.
    """
    if len(P) == 0:
        return 0.0
    top = np.argsort(-bound, kind="stable")[:first]
    best = float(distance(P[top])[0].max())
    rest = may_reach(bound, best, slack)
    rest[top] = False
    d, _ = distance(P[rest])
    return max(best, float(d.max(initial=0.0)))


def _structured_max(V: np.ndarray, F: np.ndarray, E: np.ndarray, d_vertex: np.ndarray,
                    f_vertex: np.ndarray, known_max: float, distance: MeshDistance,
                    d_centroid: np.ndarray | None = None) -> float:
    """The largest distance over the vertices, edge midpoints and face centroids of ``(V, F)``
    (``E`` its edges, ``d_vertex`` its vertices' distances, ``f_vertex`` their closest faces
    on the other surface, ``d_centroid`` its face centroids' distances when already measured)
    and ``known_max``.

    A midpoint or centroid whose bound is below the largest distance known cannot raise the
    maximum and is not queried: first the Lipschitz bound (:func:`middle_bounds`), then, for
    those it leaves, the distance to the faces closest to its corners (:func:`face_bounds`).
    The result is the maximum over every sample, as if all had been queried (each queried
    point is the one :func:`_structured_samples` makes)."""
    best = max(known_max, float(d_vertex.max(initial=0.0)))
    if d_centroid is not None:
        best = max(best, float(d_centroid.max(initial=0.0)))
    slack = bound_slack(V)

    def above(bound):
        return may_reach(bound, best, slack)

    if d_centroid is None:
        mid_bound, centroids, centroid_bound = middle_bounds(V, F, E, d_vertex)
        cents = np.flatnonzero(above(centroid_bound))
        cents = cents[above(face_bounds(centroids[cents], F[cents], f_vertex, distance))]
        centroids = centroids[cents]
    else:
        mid_bound = midpoint_bounds(V, E, d_vertex)
        centroids = np.zeros((0, 3))
    mids = np.flatnonzero(above(mid_bound))
    middles = (V[E[mids, 0]] + V[E[mids, 1]]) / 2
    keep = above(face_bounds(middles, E[mids], f_vertex, distance))
    d, _ = distance(np.vstack([middles[keep], centroids]))
    return max(best, float(d.max(initial=0.0)))


class SampledSurface:
    """One side of :func:`surface_distance`: a surface ``(V, F)`` with its edges, its
    ``n_random`` area-uniform samples (seeded), its faces' doubled areas ``double_area`` (m,)
    (given, or computed here) and its distance tree (:class:`MeshDistance`; given, or made on
    first use). The input of a remesh is one such surface for every method it is compared
    with: its samples are drawn and its tree built once (by the remesher, which measures its
    distances to the input, if it did)."""

    def __init__(self, V: np.ndarray, F: np.ndarray, n_random: int, seed: int = 0,
                 double_area: np.ndarray | None = None, distance: MeshDistance | None = None):
        self.V, self.F = V, F
        self.n_random, self.seed = int(n_random), seed
        self.E, _ = topo.edges_with_faces(F)
        self.double_area = face_double_areas(V, F) if double_area is None else double_area
        self.random = _random_samples(V, F, n_random, seed, self.double_area)
        self._distance = distance
        self._normals = None

    @property
    def distance(self) -> MeshDistance:
        if self._distance is None:
            self._distance = MeshDistance(self.V, self.F)
        return self._distance

    @property
    def normals(self) -> np.ndarray:
        """The faces' normals (m×3, twice their area long), made on first use."""
        if self._normals is None:
            R = self.V[self.F]
            self._normals = np.cross(R[:, 1] - R[:, 0], R[:, 2] - R[:, 0])
        return self._normals

    @property
    def sample_count(self) -> int:
        """Vertices, edge midpoints, face centroids and random samples."""
        return len(self.V) + len(self.E) + len(self.F) + len(self.random)

    def distances_to(self, other: SampledSurface, d_centroid: np.ndarray | None = None
                     ) -> tuple[float, float, np.ndarray]:
        """``(largest distance of any sample, mean squared distance of the random samples,
        closest face of ``other`` to each vertex (n,))`` from this surface's samples to
        ``other``; ``d_centroid`` (m,): this surface's face centroids' distances to ``other``
        when already measured."""
        d, f = other.distance(np.vstack([self.V, self.random]))
        d_vertex, d_random = d[:len(self.V)], d[len(self.V):]
        f_vertex = f[:len(self.V)]
        largest = _structured_max(self.V, self.F, self.E, d_vertex, f_vertex,
                                  float(d_random.max()), other.distance, d_centroid)
        return largest, float(np.mean(d_random ** 2)), f_vertex


def face_centroids(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The centroids (m, d) of the faces ``F`` (m, 3) of ``V`` (n, d): the values of
    ``V[F].mean(axis=1)``, summed corner by corner (faster than the mean over the short axis
    of an m×3×d array; the rows gathered by ``take``, faster than the fancy index)."""
    return (V.take(F[:, 0], axis=0) + V.take(F[:, 1], axis=0) + V.take(F[:, 2], axis=0)) / 3


def turned_over_faces(V: np.ndarray, F: np.ndarray, reference: SampledSurface,
                      centroid_face: np.ndarray | None = None,
                      vertex_face: np.ndarray | None = None) -> int:
    """The number of faces of ``(V, F)`` (m×3, oriented as the input) turned over against the
    ``reference``: whose normal has a negative dot product with the normal of the reference face
    closest to their centroid, and with those of the reference faces closest to each of their
    three corners. ``centroid_face`` (m,) and ``vertex_face`` (n,): the reference faces closest
    to ``(V, F)``'s face centroids and vertices when already found (else queried here).

    A surface that follows the input has every face's normal within a right angle of the
    input's beneath it (the input is consistently oriented); a face turned over is a fold, a
    wrinkle where the surface doubles back. The corners keep a face that spans a crease sharper
    than a right angle from being counted (its centroid's closest input face may lie on the
    crease's other side; its corners lie on both sides)."""
    if len(F) == 0:
        return 0
    P = V.take(F, axis=0)
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    below = reference.normals
    if centroid_face is None:
        _, centroid_face = reference.distance(face_centroids(V, F))
    suspect = np.flatnonzero(np.einsum("ij,ij->i", normal, below[centroid_face]) < 0)
    if len(suspect) == 0:
        return 0
    if vertex_face is None:
        _, at_corners = reference.distance(P[suspect].reshape(-1, 3))
    else:
        at_corners = vertex_face[F[suspect]].ravel()
    corner_dots = np.einsum("ij,ikj->ik", normal[suspect],
                            below[at_corners].reshape(len(suspect), 3, 3))
    return int(np.count_nonzero(np.all(corner_dots < 0, axis=1)))


def _one_side(mx: float, mean_square: float, scale: float, samples: int) -> dict:
    """One direction's entry of :func:`surface_distance`."""
    rms = float(np.sqrt(mean_square))
    return {"max": mx, "max_rel": mx / scale, "rms": rms, "rms_rel": rms / scale,
            "samples": int(samples)}


def surface_distance(V_ref: np.ndarray, F_ref: np.ndarray, V: np.ndarray, F: np.ndarray,
                     n_random: int = DISTANCE_SAMPLES, seed: int = 0, scale: float | None = None,
                     reference: SampledSurface | None = None,
                     double_area: np.ndarray | None = None) -> dict:
    """Two-sided sampled Hausdorff and RMS distance between ``(V, F)`` and the reference, and
    the faces of ``(V, F)`` turned over against it (:func:`turned_over_faces`).
    ``double_area``: the doubled areas of ``(V, F)``'s faces when already computed.

    ``scale`` (default: the reference's bounding-box diagonal) turns the distances into the
    ``*_rel`` fractions. ``reference``: the reference ``(V_ref, F_ref)`` already sampled with
    the same ``n_random`` and ``seed`` (:class:`SampledSurface`), to reuse across remeshes of
    one input. See the module docstring for the sampling; the edge midpoints and face
    centroids that cannot be the farthest sample are not measured (:func:`_structured_max`).
    """
    if reference is None:
        reference = SampledSurface(V_ref, F_ref, n_random, seed)
    elif (reference.n_random, reference.seed) != (n_random, seed):
        raise ValueError(f"the reference was sampled with n_random={reference.n_random}, "
                         f"seed={reference.seed}; asked for {n_random}, {seed}")
    scale = bounding_box_diagonal(V_ref) if scale is None else float(scale)
    ours = SampledSurface(V, F, n_random, seed, double_area)
    # the centroids' and vertices' closest input faces serve both the output's distances and
    # the turned-over faces (a point's distance and closest face do not depend on the others
    # of its query)
    d_centroid, centroid_face = reference.distance(face_centroids(V, F))
    mx_out, ms_out, vertex_face = ours.distances_to(reference, d_centroid)
    mx_in, ms_in, _ = reference.distances_to(ours)
    out = {name: _one_side(mx, mean_square, scale, a.sample_count)
           for name, mx, mean_square, a in (("output_to_input", mx_out, ms_out, ours),
                                            ("input_to_output", mx_in, ms_in, reference))}
    ms = [ms_out, ms_in]
    h = max(out["output_to_input"]["max"], out["input_to_output"]["max"])
    rms = float(np.sqrt(np.mean(ms)))
    out.update({"hausdorff": h, "hausdorff_rel": h / scale, "rms": rms, "rms_rel": rms / scale,
                "scale_bbox_diagonal": scale, "random_samples_per_side": int(n_random),
                "turned_over_faces": turned_over_faces(V, F, reference, centroid_face,
                                                       vertex_face)})
    return out


def remesh_quality(V_in: np.ndarray, F_in: np.ndarray, V: np.ndarray, F: np.ndarray,
                   n_random: int = DISTANCE_SAMPLES, seed: int = 0, distance: bool = True,
                   reference: SampledSurface | None = None, facts: dict | None = None,
                   double_area: np.ndarray | None = None) -> dict:
    """All measures of a remesh ``(V, F)`` of the input ``(V_in, F_in)`` as one dict
    (``reference``: the input sampled for the distances, see :func:`surface_distance`;
    ``facts``: :func:`mesh_facts` of ``(V, F)``, ``double_area``: its faces' doubled areas,
    when already computed).

    Keys: ``facts`` (:func:`mesh_facts`), ``is_disk``, ``is_sphere``, ``holes``
    (:func:`hole_count`), ``is_disk_with_holes`` (that many), ``triangles``
    (:func:`triangle_quality`; angles in degrees, CVs dimensionless), ``valence``
    (:func:`valence_stats`), ``distance`` (:func:`surface_distance`; ``*_rel`` = fraction of
    the input's bounding-box diagonal). Keys starting with ``_`` hold per-face arrays.
    """
    with topo.kept_edge_groups():             # every measure below groups F's edges
        dA = face_double_areas(V, F) if double_area is None else double_area
        facts = mesh_facts(V, F, dA) if facts is None else facts
        holes = hole_count(facts)
        out = {"facts": facts, "is_disk": is_disk(facts), "is_sphere": is_sphere(facts),
               "holes": holes, "is_disk_with_holes": is_disk_with_holes(facts, holes),
               "triangles": triangle_quality(V, F, dA),
               "valence": valence_stats(F, len(V))}
        if distance:
            out["distance"] = surface_distance(V_in, F_in, V, F, n_random=n_random, seed=seed,
                                               reference=reference, double_area=dA)
    return out
