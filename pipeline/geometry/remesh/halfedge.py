"""Face-array and half-edge helpers shared by the remeshing operations.

Conventions. ``F`` (m×3 int) lists each face's corners counter-clockwise on the disk. Half-edge
``h = 3·t + c`` (``c`` in 0, 1, 2) runs from corner ``F[t, c]`` to ``F[t, (c + 1) % 3]``;
``twin[h]`` (3m int) is the opposite half-edge of the same edge in the neighbouring face, or −1
on the boundary (:func:`..topology.interior_edge_twins`). Vertex sets are ``n`` bool masks.
"""

from __future__ import annotations

import numpy as np

from .. import topology as topo
from .._kernels import (disk_shapes, domain_double_areas, edge_halves, faces_touching,
                       faces_with_mark, group_by_key, pair_lengths)

DISK_SHAPE_MIN = 1e-8   # no operation makes a face with 2·area < this × longest edge² on the disk


def touching(F: np.ndarray, mark: np.ndarray) -> np.ndarray:
    """Faces with a corner where ``mark`` is set: ``mark[F].any(axis=1)``, compiled (remeshing
    asks this of the whole mesh in every collapse round).

    Parameters
    ----------
    F : (m, 3) int
    mark : (n,) bool

    Returns
    -------
    (m,) bool
    """
    return faces_touching(np.ascontiguousarray(topo._as_faces(F)),
                          np.ascontiguousarray(mark, dtype=bool).view(np.uint8))


def faces_at(F: np.ndarray, mark: np.ndarray) -> np.ndarray:
    """The faces with a corner where ``mark`` is set, in order (k×3): ``F[touching(F,
    mark)]`` compiled in one pass; arguments as for :func:`touching`."""
    return faces_with_mark(np.ascontiguousarray(topo._as_faces(F), dtype=np.int64),
                           np.ascontiguousarray(mark, dtype=bool).view(np.uint8))


def double_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Twice the signed area of each face in the domain, positive when counter-clockwise: on
    the disk ``(u1 − u0)(v2 − v0) − (v1 − v0)(u2 − u0)``; on the unit sphere (``uv`` with
    three columns, unit vectors) the triple product ``det[p0, p1, p2]``
    (:func:`..sphere.triple_products`), the same determinant with the disk's points read as
    ``(u, v, 1)``: positive when the face turns counter-clockwise seen from outside (twice its
    chordal area times the distance of its plane from the centre; unchanged in sign by any
    radial scaling of its corners).

    Parameters
    ----------
    uv : (n, 2) or (n, 3) float
    F : (m, 3) int

    Returns
    -------
    (m,) float
    """
    if uv.shape[1] == 3:
        from ..sphere import triple_products
        return triple_products(uv, F)
    return domain_double_areas(np.ascontiguousarray(uv, dtype=np.float64),
                               np.ascontiguousarray(topo._as_faces(F), dtype=np.int64))


def edge_lengths(X: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 3D lengths ``|X[a] − X[b]|`` (k) of the edges ``a–b`` (k int each): the values of
    :func:`..rows.norms` of ``X[a] − X[b]``, compiled (no k×3 temporaries).

    Parameters
    ----------
    X : (n, 3) float
    a, b : (k,) int

    Returns
    -------
    (k,) float
    """
    return pair_lengths(np.ascontiguousarray(X, dtype=np.float64),
                        np.ascontiguousarray(a, dtype=np.int64),
                        np.ascontiguousarray(b, dtype=np.int64))


def disk_shape(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Twice the signed disk area of each face over its longest disk edge squared (√3/2 for an
    equilateral face, 0 for a degenerate one; on the sphere :func:`double_areas`' triple
    product over the longest chord squared). The operations keep it at least
    ``DISK_SHAPE_MIN`` for every face they make: a face thinner than that on the disk is
    counter-clockwise only up to rounding, and a later split of its long edge can land on its
    third corner (two vertices at one point, a zero-length edge on the surface). Arguments as
    for :func:`double_areas`; (m,) float. Compiled: ``double_areas(uv, F) /
    np.maximum(longest, 1e-300)``, the longest of the squared edges ``((b − a)**2).sum(axis=1)``
    (…) taken as ``np.maximum.reduce`` takes it, operation for operation.
    """
    return disk_shapes(np.ascontiguousarray(uv, dtype=np.float64),
                       np.ascontiguousarray(F, dtype=np.int64))


def edge_table(F: np.ndarray, with_twins: bool = False, twin: np.ndarray | None = None):
    """Every edge once, as its half-edge ``a → b`` with the larger twin (or the only one).

    Parameters
    ----------
    F : (m, 3) int
    with_twins : bool
        Also return the twin of every half-edge.
    twin : (3m,) int, optional
        The twins of ``F`` when the caller has them.

    Returns
    -------
    h, a, b, twin : (e,) int
        The half-edge, its tail and head, and its twin (−1 on the boundary).
    all_twins : (3m,) int
        Only with ``with_twins``.
    """
    F = np.asarray(F)
    twin = topo.interior_edge_twins(F) if twin is None else twin
    h, a, b, t = edge_halves(np.ascontiguousarray(topo._as_faces(F)),
                             np.ascontiguousarray(twin, dtype=np.int64))
    out = (h, a.astype(F.dtype, copy=False), b.astype(F.dtype, copy=False),
           t.astype(twin.dtype, copy=False))       # (the dtypes of F and twin)
    return out + (twin,) if with_twins else out


def independent_by_faces(m: int, f1: np.ndarray, f2: np.ndarray, priority: np.ndarray
                         ) -> np.ndarray:
    """Candidates chosen so that no face has two: a candidate (touching faces ``f1``, ``f2``;
    equal for a boundary edge) is taken when it has the best (smallest) ``priority`` of both
    its faces, ties broken by position (:func:`independent_by`).

    Parameters
    ----------
    m : int
        The number of faces.
    f1, f2, priority : (k,)

    Returns
    -------
    (j,) int
        Indices into the candidates, increasing.
    """
    return independent_by(m, (f1, f2), priority)


def independent_by(m: int, keys, priority: np.ndarray) -> np.ndarray:
    """Candidates chosen so that no key (a face, a vertex; ``0 … m−1``) has two: a candidate
    is taken when it has the best (smallest) ``priority`` at each of its keys, ties broken by
    position.

    Parameters
    ----------
    m : int
        The number of keys.
    keys : sequence of (k,) int
        Per candidate, its keys (repeats allowed).
    priority : (k,)

    Returns
    -------
    (j,) int
        Indices into the candidates, increasing.
    """
    k = len(priority)
    rank = np.empty(k, np.int64)
    rank[np.argsort(priority, kind="stable")] = np.arange(k)
    best = np.full(m, k, np.int64)
    for key in keys:
        np.minimum.at(best, key, rank)
    ok = np.ones(k, bool)
    for key in keys:
        ok &= best[key] == rank
    return np.flatnonzero(ok)


def independent_edges(m: int, h: np.ndarray, twin: np.ndarray, priority: np.ndarray
                      ) -> np.ndarray:
    """:func:`independent_by_faces` for edges given as half-edges ``h`` (k) with their twins
    (k, −1 on the boundary): indices of edges no two of which share a face."""
    f1 = h // 3
    f2 = np.where(twin >= 0, twin // 3, f1)
    return independent_by_faces(m, f1, f2, priority)


class CSR:
    """Rows of a compressed sparse structure: row ``i`` is ``indices[indptr[i]:indptr[i+1]]``."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray):
        self.indptr, self.indices = indptr, indices


def group(keys: np.ndarray, values: np.ndarray, n: int) -> CSR:
    """``values`` grouped by ``keys`` in ``[0, n)``, in their order within a group (a compiled
    stable counting sort)."""
    return CSR(*group_by_key(np.ascontiguousarray(keys, dtype=np.int64),
                             np.ascontiguousarray(values, dtype=np.int64), n))


def adjacency(F: np.ndarray, n: int, twin: np.ndarray | None = None) -> CSR:
    """Vertex neighbours: every half-edge ``a → b`` gives ``b`` to ``a``, and a boundary
    half-edge also ``a`` to ``b`` (its missing direction), so in a manifold disk every
    neighbour appears once."""
    a = F.ravel()
    b = F.take([1, 2, 0], axis=1).ravel()         # (take: ~10x faster than the fancy index)
    if twin is None:
        twin = topo.interior_edge_twins(F)
    lone = twin < 0
    return group(np.concatenate([a, b[lone]]), np.concatenate([b, a[lone]]), n)


def vertex_faces(F: np.ndarray, n: int) -> CSR:
    """The faces around each vertex, in increasing order."""
    return group(F.ravel(), np.repeat(np.arange(len(F)), 3), n)
