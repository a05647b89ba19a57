"""Pure combinatorics on triangle lists.

Every function takes ``F`` (m×3 int array of vertex indices, one row per triangle) and, where the
number of vertices matters, ``n``. Nothing here looks at coordinates except the optional length
ordering of :func:`boundary_loops`. All work is vectorised with numpy/scipy; python loops only run
over boundary vertices while tracing loops.

Conventions
-----------
* Half-edge ``h`` of face ``t`` is ``h = 3 t + c`` and goes from ``F[t, c]`` to ``F[t, (c+1) % 3]``.
* An undirected edge is *boundary* when exactly one face contains it, *interior* when two do and
  *non-manifold* when more than two do.
* Faces are *consistently oriented* when every interior edge is traversed in opposite directions by
  its two faces. Then the boundary half-edges, followed head to tail, run with the surface on
  their left (for counterclockwise faces seen from the front).
"""

from __future__ import annotations

import threading
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp

from pipeline.errors import UserError

from . import _kernels

__all__ = [
    "half_edges",
    "edges_with_faces",
    "boundary_edges",
    "boundary_vertices_mask",
    "boundary_loops",
    "interior_edge_twins",
    "connected_components",
    "graph_components",
    "nonmanifold_edges",
    "nonmanifold_edge_halfedges",
    "nonmanifold_vertices",
    "corner_fans",
    "split_vertex_fans",
    "leaf_faces",
    "euler_characteristic",
    "csr_rows",
    "distinct_indices",
    "sort_with_index",
    "vertex_faces",
    "vertex_neighbours",
    "orient_faces_consistently",
    "kept_edge_groups",
]


def _as_faces(F) -> np.ndarray:
    F = np.asarray(F, dtype=np.int64)
    if F.size == 0:
        return F.reshape(0, 3)
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"F must be m×3, got shape {F.shape}")
    return F


def _n_of(F: np.ndarray, n: int | None) -> int:
    if n is not None:
        return int(n)
    return int(F.max()) + 1 if F.size else 0


def half_edges(F) -> tuple[np.ndarray, np.ndarray]:
    """Directed half-edges ``(a, b)`` (3m each); half-edge ``3 t + c`` is ``F[t,c] → F[t,c+1]``."""
    F = _as_faces(F)
    return F.ravel(), F.take([1, 2, 0], axis=1).ravel()


def pair_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """One key per edge ``a — b`` (k,) of vertices below ``n``, either way round:
    ``min·n + max`` (k,) int64."""
    return np.minimum(a, b) * np.int64(n) + np.maximum(a, b)


def _edge_keys(F: np.ndarray, n: int) -> np.ndarray:
    """Undirected key ``min·n + max`` for every half-edge (3m)."""
    return pair_keys(*half_edges(F), n)


def _distinct_sorted(x: np.ndarray) -> np.ndarray:
    """Sorted distinct values of a 1-D array (``np.sort`` + diff; ``np.unique`` is much slower on
    large integer arrays in recent numpy)."""
    s = np.sort(np.asarray(x).ravel())
    if len(s) == 0:
        return s
    return s[np.r_[True, s[1:] != s[:-1]]]


def distinct_indices(idx: np.ndarray, size: int) -> np.ndarray:
    """Sorted distinct values of indices in ``[0, size)``, through a boolean mask (cheaper than
    sorting when ``size`` is not much larger than ``len(idx)``, and than ``np.unique``)."""
    mark = np.zeros(size, dtype=bool)
    mark[idx] = True
    return np.flatnonzero(mark)


def sort_with_index(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(sorted_keys, order)`` for non-negative int64 keys.

    Packs ``key << bits | index`` into one int64 and uses ``np.sort`` (much faster than
    ``argsort``) when that fits in 63 bits; equal keys come out in index order (stable).
    """
    k = len(keys)
    if k == 0:
        return keys.copy(), np.zeros(0, np.int64)
    bits = max(int(k - 1).bit_length(), 1)
    if int(keys.max()).bit_length() + bits <= 62:
        packed = np.sort((keys << bits) | np.arange(k, dtype=np.int64))
        return packed >> bits, packed & ((1 << bits) - 1)
    order = np.argsort(keys, kind="stable")
    return keys[order], order


_KEPT = threading.local()     # .on: inside kept_edge_groups(); .last: (F copy, groups)


@contextmanager
def kept_edge_groups():
    """Inside this block the half-edge groups of the last face array are kept (read-only,
    with a private copy of its faces) and returned again while the faces are equal: a mesh's
    repair checks and measures ask for them a dozen times. They are dropped when the
    outermost block ends (no memory held after it), and nothing is kept outside a block."""
    outer = not getattr(_KEPT, "on", False)
    _KEPT.on = True
    try:
        yield
    finally:
        if outer:
            _KEPT.on, _KEPT.last = False, None


def _halfedge_groups(F: np.ndarray, n: int | None = None):
    """Half-edges grouped by undirected edge.

    Returns ``(order, start, size, edge_of)``: ``order`` lists the half-edges sorted by edge (ties
    by half-edge index), the edge ``e`` owns ``order[start[e] : start[e] + size[e]]``, and
    ``edge_of[h]`` is the edge of half-edge ``h``. Edges are numbered in ``(min, max)`` order,
    so the result does not depend on ``n`` (any count above the largest index). Reused inside
    :func:`kept_edge_groups`.
    """
    if not getattr(_KEPT, "on", False):
        return _group_halfedges(F, n)
    last = getattr(_KEPT, "last", None)
    if last is not None and last[0].shape == F.shape and np.array_equal(last[0], F):
        return last[1]
    groups = _group_halfedges(F, n)
    for array in groups:
        array.setflags(write=False)
    _KEPT.last = (F.copy(), groups)
    return groups


def _group_halfedges(F: np.ndarray, n: int | None):
    """:func:`_halfedge_groups` computed: one sort of the half-edges' undirected keys."""
    n = _n_of(F, n)
    keys = _edge_keys(F, n)
    sk, order = sort_with_index(keys)
    m3 = len(sk)
    new = np.empty(m3, dtype=bool)
    if m3:
        new[0] = True
        np.not_equal(sk[1:], sk[:-1], out=new[1:])
    start = np.flatnonzero(new)
    size = np.diff(np.r_[start, m3])
    edge_of = np.empty(m3, dtype=np.int64)
    edge_of[order] = np.cumsum(new) - 1
    return order, start, size, edge_of


def _halfedge_edge_counts(F: np.ndarray) -> np.ndarray:
    """For every half-edge, how many faces contain its undirected edge."""
    _, _, size, edge_of = _halfedge_groups(F)
    return size[edge_of]


def edges_with_faces(F) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges ``E`` (k×2, ``E[:,0] < E[:,1]``, sorted) and the number of faces
    containing each edge (k)."""
    F = _as_faces(F)
    if F.size == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    order, start, size, _ = _halfedge_groups(F)
    a, b = half_edges(F)
    h = order[start]
    E = np.stack([np.minimum(a[h], b[h]), np.maximum(a[h], b[h])], axis=1)
    return E, size.copy()


def boundary_edges(F) -> np.ndarray:
    """Directed boundary half-edges (k×2), oriented as they appear in their face, in face order."""
    F = _as_faces(F)
    if F.size == 0:
        return np.zeros((0, 2), np.int64)
    a, b = half_edges(F)
    on_boundary = _halfedge_edge_counts(F) == 1
    return np.stack([a[on_boundary], b[on_boundary]], axis=1)


def boundary_vertices_mask(F, n: int | None = None) -> np.ndarray:
    """Boolean mask (n) of vertices on at least one boundary edge."""
    F = _as_faces(F)
    mask = np.zeros(_n_of(F, n), dtype=bool)
    mask[boundary_edges(F).ravel()] = True
    return mask


def boundary_loops(F, V=None) -> list[np.ndarray]:
    """Boundary loops as ordered vertex index arrays, longest first.

    Each loop follows the directed boundary half-edges of the faces, so with consistently oriented
    faces the surface lies on the left of the loop: mapping the loop in this order
    counterclockwise onto the unit circle gives positively oriented image triangles. A loop does
    not repeat its first vertex. Loops are sorted by 3D length when ``V`` is given, otherwise by
    vertex count (ties: smallest first vertex first); each loop starts at its smallest vertex index.

    Raises :class:`UserError` when a vertex has more than one outgoing or incoming boundary
    half-edge (the boundary touches itself at a non-manifold vertex) or when the boundary
    half-edges do not close up into loops (inconsistent face orientation).
    """
    F = _as_faces(F)
    be = boundary_edges(F)
    if len(be) == 0:
        return []
    n = _n_of(F, None)
    out_deg = np.bincount(be[:, 0], minlength=n)
    in_deg = np.bincount(be[:, 1], minlength=n)
    pinched = np.flatnonzero((out_deg > 1) | (in_deg > 1))
    if len(pinched):
        raise UserError(
            f"the boundary passes {len(pinched)} vertex/vertices more than once (non-manifold "
            f"vertex, e.g. vertex {int(pinched[0])}); split the mesh there or remove the "
            f"touching faces so the boundary is a simple curve"
        )
    if np.any(out_deg != in_deg):
        raise UserError(
            "boundary edges do not form closed loops because the faces are not consistently "
            "oriented; run the mesh repair (orientation fix) first"
        )
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[be[:, 0]] = be[:, 1]
    nxt_list = nxt.tolist()
    visited = np.zeros(n, dtype=bool)
    loops = []
    for start in np.sort(be[:, 0]).tolist():
        if visited[start]:
            continue
        loop = [start]
        v = nxt_list[start]
        while v != start:
            loop.append(v)
            v = nxt_list[v]
        arr = np.asarray(loop, dtype=np.int64)
        visited[arr] = True
        loops.append(arr)
    if V is not None:
        V = np.asarray(V, dtype=np.float64)
        size = [float(np.linalg.norm(V[np.roll(lp, -1)] - V[lp], axis=1).sum()) for lp in loops]
    else:
        size = [float(len(lp)) for lp in loops]
    order = sorted(range(len(loops)), key=lambda i: (-size[i], int(loops[i][0])))
    return [loops[i] for i in order]


def interior_edge_twins(F) -> np.ndarray:
    """For every half-edge (3m), the other half-edge of its edge when the edge has exactly two
    faces, else −1 (boundary or non-manifold edge). A compiled bucket pass (O(m); remeshing
    asks for the twins of a changed mesh dozens of times)."""
    F = np.ascontiguousarray(_as_faces(F), dtype=np.int64)
    if len(F) == 0:
        return np.full(0, -1, dtype=np.int64)
    return _kernels.interior_edge_twins(F, _n_of(F, None))


def connected_components(F, n: int | None = None) -> tuple[int, np.ndarray]:
    """Connected components of the faces (faces sharing a vertex are connected).

    Returns ``(count, labels)`` with ``labels`` (m) in ``0..count-1``, numbered by first face
    (compiled union-find: :func:`._kernels.face_components`).
    """
    F = _as_faces(F)
    if F.size == 0:
        return 0, np.zeros(0, np.int64)
    return _kernels.face_components(np.ascontiguousarray(F, dtype=np.int64), _n_of(F, n))


def graph_components(r: np.ndarray, c: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """Connected components of the undirected graph on ``n`` vertices with the edges
    ``(r[k], c[k])`` (k,) each.

    Returns ``(count, labels)`` with ``labels`` (n,) in ``0..count-1``, numbered by first
    vertex, as SciPy's ``connected_components(G, directed=False)`` numbers them (compiled
    union-find: :func:`._kernels.graph_components`).
    """
    return _kernels.graph_components(np.ascontiguousarray(r, dtype=np.int64),
                                     np.ascontiguousarray(c, dtype=np.int64), int(n))


def nonmanifold_edges(F) -> np.ndarray:
    """Undirected edges (k×2, i < j) contained in more than two faces."""
    E, counts = edges_with_faces(F)
    return E[counts > 2]


def nonmanifold_edge_halfedges(F) -> tuple[np.ndarray, np.ndarray]:
    """The half-edges of the edges in more than two faces, grouped by edge: ``(h, start)``,
    ``h`` (k,) the half-edges (edge by edge in :func:`edges_with_faces`' order, each edge's
    in half-edge order) and ``start`` (e,) where each edge's begin in ``h``."""
    F = _as_faces(F)
    if F.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order, start, size, _ = _halfedge_groups(F)
    many = size > 2
    h = order[np.repeat(many, size)]
    return h, np.r_[0, np.cumsum(size[many])[:-1]].astype(np.int64)


def nonmanifold_vertices(F, n: int | None = None) -> np.ndarray:
    """Vertices whose incident faces form more than one fan (bowtie / pinch vertices).

    The corners at a vertex are linked when their faces share an edge through that vertex; a
    manifold vertex has exactly one connected group of corners (a closed fan inside, an open fan
    on the boundary). Works for any face orientation and with non-manifold edges; the common
    case (consistently oriented, no edge in more than two faces) takes a faster path.
    """
    F = _as_faces(F)
    if F.size == 0:
        return np.zeros(0, np.int64)
    n = _n_of(F, n)
    a, b = half_edges(F)
    order, start, size, _ = _halfedge_groups(F, n)
    if np.all(size <= 2):
        pair_start = start[size == 2]
        h1, h2 = order[pair_start], order[pair_start + 1]
        if np.array_equal(a[h1], b[h2]):
            twin = np.full(len(a), -1, dtype=np.int64)
            twin[h1] = h2
            twin[h2] = h1
            fans = _fans_per_vertex_oriented(a, twin, n)
            return np.flatnonzero(fans > 1)
    return _nonmanifold_vertices_general(F, n, a, order, start, size)


def _fans_per_vertex_oriented(a: np.ndarray, twin: np.ndarray, n: int) -> np.ndarray:
    """Number of fans at every vertex of a consistently oriented mesh with manifold edges.

    Rotating around the tail ``v`` of half-edge ``h`` (= the corner of ``v`` in ``h``'s face)
    leads to the corner of ``v`` in the face across ``h``: ``succ[h] = next(twin[h])``. Open fans
    are chains of ``succ``, closed fans are cycles; a compiled pass follows each once
    (:func:`._kernels.fans_per_vertex`).
    """
    return _kernels.fans_per_vertex(np.ascontiguousarray(a, dtype=np.int64),
                                    np.ascontiguousarray(twin, dtype=np.int64), int(n))


def _nonmanifold_vertices_general(F, n, a, order, start, size) -> np.ndarray:
    """The vertices of more than one fan by :func:`_corner_fans` (any orientation, any edge
    multiplicity)."""
    lab = _corner_fans(F, a, order, start, size)
    pairs = _distinct_sorted(lab * n + a)                     # distinct (fan, vertex) pairs
    fans = np.bincount(pairs % n, minlength=n)
    return np.flatnonzero(fans > 1)


def corner_fans(F, n: int | None = None) -> np.ndarray:
    """The fan of every corner (3m int64; corner ``3 t + c`` is vertex ``F[t, c]`` in face
    ``t``): two corners at one vertex are in one fan when a chain of faces around the vertex,
    each sharing an edge through the vertex with the next, joins them. A manifold vertex has
    one fan (closed inside, open on the boundary); a bowtie vertex, where fans meet at the
    vertex alone, has several. Labels are numbered by first corner; corners at different
    vertices may share a label. Any face orientation; an edge in more than two faces links
    all its faces' corners."""
    F = _as_faces(F)
    if F.size == 0:
        return np.zeros(0, np.int64)
    order, start, size, _ = _halfedge_groups(F, n)
    return _corner_fans(F, half_edges(F)[0], order, start, size)


def _corner_fans(F, a, order, start, size) -> np.ndarray:
    """:func:`corner_fans` from the half-edge tails ``a`` and groups
    (:func:`_halfedge_groups`): connected components of the corner graph."""
    m3 = 3 * len(F)
    # link every half-edge with the next one of the same edge (chains edges in > 2 faces)
    grp_next = np.ones(m3, dtype=bool)
    grp_next[start + size - 1] = False
    pos = np.flatnonzero(grp_next[:-1] if m3 > 1 else np.zeros(0, bool))
    h1, h2 = order[pos], order[pos + 1]
    nx1 = 3 * (h1 // 3) + (h1 % 3 + 1) % 3        # corner at the head of h1
    nx2 = 3 * (h2 // 3) + (h2 % 3 + 1) % 3
    opposite = a[h1] != a[h2]                     # h2 runs the other way (consistent pair)
    # corners at the same vertex: tail-tail/head-head (same direction) or tail-head (opposite)
    r = np.r_[h1, nx1]
    c = np.r_[np.where(opposite, nx2, h2), np.where(opposite, h2, nx2)]
    return graph_components(r, c, m3)[1].astype(np.int64)


def split_vertex_fans(F, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Give every fan of a vertex its own vertex (:func:`corner_fans`): the fan with the most
    corners keeps the vertex (ties: the fan of its first corner), each other fan gets a new
    vertex ``n, n + 1, ...`` (in vertex order, larger fans first). Afterwards no vertex is a
    bowtie (with no edge in more than two faces); faces, their order and their orientation are
    kept.

    Returns ``(F_split, parent)``: the faces (m×3) and the vertex each new one copies (k)."""
    F = _as_faces(F)
    n = _n_of(F, n)
    if F.size == 0:
        return F.copy(), np.zeros(0, np.int64)
    v = F.ravel()
    pairs, first, pair_of = np.unique(corner_fans(F, n) * n + v, return_index=True,
                                      return_inverse=True)          # first: its first corner
    pair_v = pairs % n
    corners = np.bincount(pair_of, minlength=len(pairs))
    order = np.lexsort((first, -corners, pair_v))             # by vertex, larger fans first
    keeps = np.r_[True, pair_v[order][1:] != pair_v[order][:-1]]
    new_vertex = np.empty(len(pairs), dtype=np.int64)
    new_vertex[order[keeps]] = pair_v[order[keeps]]
    extra = order[~keeps]
    new_vertex[extra] = n + np.arange(len(extra))
    return new_vertex[pair_of].reshape(F.shape), pair_v[extra]


def leaf_faces(F, is_boundary_vertex) -> np.ndarray:
    """Indices of leaf-like faces (paper Def. 4): all three vertices are boundary vertices."""
    F = _as_faces(F)
    mask = np.asarray(is_boundary_vertex, dtype=bool)
    if F.size == 0:
        return np.zeros(0, np.int64)
    return np.flatnonzero(mask[F].all(axis=1))


def euler_characteristic(F, n: int | None = None) -> int:
    """``V − E + F``; ``n`` defaults to the number of vertices referenced by ``F``."""
    F = _as_faces(F)
    nv = len(_distinct_sorted(F)) if n is None else int(n)
    if F.size == 0:
        return nv
    _, start, _, _ = _halfedge_groups(F)
    return int(nv - len(start) + len(F))


def csr_rows(indptr: np.ndarray, indices: np.ndarray, rows: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(row_id, value)`` pairs of the given CSR rows, concatenated (vectorised, no scipy
    indexing: slicing a scipy matrix by rows has a fixed cost per call, whatever its size, that
    dominates for the few rows asked here)."""
    rows = np.asarray(rows, dtype=np.int64)
    start, stop = indptr[rows], indptr[rows + 1]
    cnt = stop - start
    rid = np.repeat(np.arange(len(rows)), cnt)
    pos = np.repeat(start - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())
    return rid, indices[pos]


def vertex_faces(F, n: int | None = None) -> sp.csr_matrix:
    """Vertex–face incidence as a sparse n×m boolean CSR matrix (row ``v`` lists ``v``'s faces)."""
    F = _as_faces(F)
    n = _n_of(F, n)
    m = len(F)
    rows = F.ravel()
    cols = np.repeat(np.arange(m), 3)
    return sp.csr_matrix((np.ones(3 * m, bool), (rows, cols)), shape=(n, m))


def vertex_neighbours(F, n: int | None = None) -> sp.csr_matrix:
    """Symmetric vertex adjacency (n×n boolean CSR): ``A[i, j]`` iff ``ij`` is an edge."""
    F = _as_faces(F)
    n = _n_of(F, n)
    a, b = half_edges(F)
    A = sp.csr_matrix((np.ones(2 * len(a), bool), (np.r_[a, b], np.r_[b, a])), shape=(n, n))
    A.sum_duplicates()
    return A


def orient_faces_consistently(F) -> tuple[np.ndarray, int]:
    """Flip faces so that every interior edge is traversed in opposite directions.

    Works per connected component (via interior edges) and keeps the orientation of the majority
    of the faces of each component (ties: the orientation of its lowest-index face), so a mesh
    with a few flipped faces gets exactly those faces flipped back. Returns ``(F_oriented,
    number_of_flipped_faces)``; ``F`` is returned unchanged (same object) when nothing flips.
    Only edges with exactly two faces are used. Raises :class:`UserError` for a non-orientable
    surface (Möbius strip and the like).

    Implementation: on the orientation double cover (nodes ``(t, s)``, ``s`` = flipped or not) an
    interior edge links ``(t1, s)`` with ``(t2, s)`` when the pair is consistent and with
    ``(t2, 1−s)`` when it is not; the surface is orientable iff ``(t, 0)`` and ``(t, 1)`` always
    land in different components, and the component of ``(t, 0)`` tells the class of ``t``.
    Without inconsistent pairs the two copies are not linked and nothing flips (returned
    before the graph is built).
    """
    F = _as_faces(F)
    m = len(F)
    if m == 0:
        return F, 0
    a, _ = half_edges(F)
    twin = interior_edge_twins(F)
    h1 = np.flatnonzero(twin > np.arange(3 * m))
    h2 = twin[h1]
    t1, t2 = h1 // 3, h2 // 3
    inconsistent = a[h1] == a[h2]
    if not inconsistent.any():          # no copy links to the other: nothing to flip
        return F, 0
    r = np.r_[t1, t1 + m]
    c = np.r_[np.where(inconsistent, t2 + m, t2), np.where(inconsistent, t2, t2 + m)]
    _, lab = graph_components(r, c, 2 * m)
    l0, l1 = lab[:m], lab[m:]
    if np.any(l0 == l1):
        bad = int(np.flatnonzero(l0 == l1)[0])
        raise UserError(
            f"mesh is not orientable (Möbius-like; e.g. face {bad}); cut it along a seam so "
            f"that it becomes an orientable disk"
        )
    comp = np.minimum(l0, l1)
    in_b = l0 > l1                                 # class "B" of its component
    ncomp = int(comp.max()) + 1
    total = np.bincount(comp, minlength=ncomp)
    nb = np.bincount(comp, weights=in_b, minlength=ncomp).astype(np.int64)
    first = np.full(ncomp, m, dtype=np.int64)
    np.minimum.at(first, comp, np.arange(m))
    exists = first < m
    first_in_b = np.zeros(ncomp, bool)
    first_in_b[exists] = in_b[first[exists]]
    # flip class B when it is the minority, or on a tie when the first face is not in B
    flip_b = (2 * nb < total) | ((2 * nb == total) & ~first_in_b)
    flip = in_b == flip_b[comp]
    count = int(flip.sum())
    if count == 0:
        return F, 0
    out = F.copy()
    out[flip] = out[flip][:, [0, 2, 1]]
    return out, count
