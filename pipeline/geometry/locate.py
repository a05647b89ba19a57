"""Point location in a planar triangulation (a disk map's image) and barycentric lifting, eq. (1).

A disk parameterization ``uv`` (n×2) of a mesh with faces ``F`` (m×3) tiles the image polygon
``f(M)``. For every query point ``z`` in the plane, :func:`locate_points` finds the image face
``[f_i, f_j, f_k]`` that contains it and its barycentric coordinates

    λ_i = |[z, f_j, f_k]| / |[f_i, f_j, f_k]|,  λ_j = |[f_i, z, f_k]| / …,
    λ_k = |[f_i, f_j, z]| / …

(signed areas, so λ ≥ 0 inside the face and λ_i + λ_j + λ_k = 1), and :func:`lift` evaluates
eq. (1) of the paper's §8: the point on the surface is ``Σ_c λ_c v_{F[face, c]}``; the same
formula carries any per-vertex attribute (colours, normals, texture coordinates).

How a point is located (:class:`PointLocator`):

1. **Bucketing.** A uniform grid covers the bounding box of ``uv``; every face is registered in
   the cells its bounding box overlaps (a CSR cell → faces table, built with one sort). The cell
   size is chosen so that there are about as many cells as faces (``cell_factor``).
2. **Vectorised test.** Each query is tested against every face of its cell at once; the face
   with the *largest smallest barycentric* wins. A point inside the image lies inside the
   bounding box of its face, so its face is always among the candidates.
3. **Edges and vertices.** A point on an edge or a vertex has a barycentric of ±1e-17 in each
   face around it; it is accepted when its smallest barycentric is ≥ −``tol`` (1e-10), then
   negative barycentrics are clamped to 0 and the row renormalised. A query exactly at a vertex
   gets exactly (1, 0, 0) (the arithmetic of the numerator is the denominator's).
4. **Outside.** A point whose best smallest barycentric is < −``tol`` lies outside the image
   polygon (for a SEM map the image is a polygon *inscribed* in the unit circle, so points on the
   circle are slightly outside it). It is moved to the closest point of the boundary polygon
   (:func:`project_to_boundary_polygon`) and located exactly on that boundary edge: its face is
   the one face of the edge, its barycentrics ``(1 − t, t, 0)`` on the edge's two vertices. No
   query is ever lost.
5. **Large batches.** With at least half as many queries as image vertices (a remesh's
   samples), each query first walks, up to 8 steps across the edge of its most negative
   barycentric, from a face at its nearest image vertex (a KD-tree); only the queries the walk
   does not settle (outside ones, a few more) go through steps 2–4. A query the walk settles
   lies in the face it stops at (smallest barycentric ≥ −``tol``), so it gets the position
   steps 2–4 would give; only on an edge shared by two faces may the face differ.

Thin image triangles (a SEM map is strongly anisotropic in places) are registered only in the
grid cells they really cross, not in every cell of their bounding box, which keeps the number of
candidates per query small. ``benchmarks/bench_remesh.py --locate`` compares build and query
times with matplotlib's ``TrapezoidMapTriFinder`` on a SEM map of about 1.45·10^6 faces.
"""

from __future__ import annotations

import numpy as np

from . import topology as topo
from ._kernels import grid_candidates, grid_cells, lift_rows, walk_rows, walk_to_faces

__all__ = ["PointLocator", "locate_points", "project_to_boundary_polygon", "lift",
           "barycentric_coordinates"]

TOL = 1e-10              # smallest barycentric still counted as inside (then clamped to 0)
_CHUNK = 65536           # queries per vectorised block (bounds the temporaries)
_WALK_MIN = 4096         # from this many queries, walk from the nearest vertex first
_WALK = 8                # steps of that walk
REDO_CANDIDATES = 64     # nearest segments tried for a point the first 8 do not settle


def barycentric_coordinates(points: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                            ) -> np.ndarray:
    """Barycentric coordinates (k×3) of ``points`` in the triangles ``(A, B, C)`` (each k×2).

    Computed as ratios of signed areas, each from differences to the query point, so that a
    point at a corner gets exactly 1 and 0, 0. Degenerate triangles give non-finite rows.
    """
    ax, ay = A[:, 0] - points[:, 0], A[:, 1] - points[:, 1]
    bx, by = B[:, 0] - points[:, 0], B[:, 1] - points[:, 1]
    cx, cy = C[:, 0] - points[:, 0], C[:, 1] - points[:, 1]
    la = bx * cy - by * cx                                   # 2|[z, b, c]|
    lb = cx * ay - cy * ax                                   # 2|[a, z, c]|
    lc = ax * by - ay * bx                                   # 2|[a, b, z]|
    d = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.column_stack([la, lb, lc]) / d[:, None]


def _clean_rows(bary: np.ndarray) -> np.ndarray:
    """Clamp tiny negatives to 0 and renormalise every row to sum 1."""
    bary = np.clip(bary, 0.0, None)
    return bary / bary.sum(axis=1, keepdims=True)


def _boundary_segments(F: np.ndarray, n: int, boundary: np.ndarray | None):
    """Boundary segments ``(a, b, face, corner_a, corner_b)``: every boundary edge of ``F`` (all
    loops) or, when ``boundary`` is given, the edges of that closed loop."""
    twin = topo.interior_edge_twins(F)
    h = np.flatnonzero(twin < 0)                             # boundary half-edges
    f, c = h // 3, h % 3
    a, b = F[f, c], F[f, (c + 1) % 3]
    if boundary is None:
        return a, b, f, c, (c + 1) % 3
    loop = np.asarray(boundary, dtype=np.int64)
    la, lb = loop, np.roll(loop, -1)
    key = topo.pair_keys(a, b, n)
    order = np.argsort(key)
    want = topo.pair_keys(la, lb, n)
    pos = np.searchsorted(key[order], want)
    pos = np.clip(pos, 0, len(order) - 1)
    hit = order[pos]
    if not np.array_equal(key[hit], want):
        raise ValueError("boundary is not a closed loop of boundary edges of F")
    f, c = f[hit], c[hit]
    ca = np.where(F[f, c] == la, c, (c + 1) % 3)
    cb = np.where(F[f, c] == la, (c + 1) % 3, c)
    return la, lb, f, ca, cb


def _closest_on_segments(points: np.ndarray, A: np.ndarray, B: np.ndarray):
    """For every point, the closest segment ``(A[s], B[s])``, the parameter ``t`` ∈ [0, 1] of
    the closest point ``A + t (B − A)`` and that point (:meth:`Segments.closest`)."""
    return Segments(A, B).closest(points)


class Segments:
    """Segments ``(A[s], B[s])`` (k×d each) asked for the closest one to points, again and
    again: their midpoints' KD-tree is built once, at the first question."""

    def __init__(self, A: np.ndarray, B: np.ndarray):
        self.A, self.D = A, B - A
        self.L2 = np.maximum(np.einsum("ij,ij->i", self.D, self.D), 1e-300)
        self.mid = 0.5 * (A + B)
        self.tree = None

    def _exact(self, P, S):                            # S: (b, j) candidate segments per point
        A, D, L2 = self.A, self.D, self.L2
        DS = D.take(S, axis=0)
        rel = P[:, None, :] - A.take(S, axis=0)
        tt = np.clip(np.einsum("bsj,bsj->bs", rel, DS) / L2[S], 0.0, 1.0)
        d2 = ((rel - tt[..., None] * DS) ** 2).sum(axis=2)
        j = np.argmin(d2, axis=1)
        r = np.arange(len(P))
        return S[r, j], tt[r, j], d2[r, j]

    def closest(self, points: np.ndarray):
        """For every point, the closest segment, the parameter ``t`` ∈ [0, 1] of the closest
        point ``A + t (B − A)`` and that point.

        Candidates are the segments with the ``K`` nearest midpoints (a KD-tree); the answer
        is exact when the K-th midpoint is farther than the best distance plus the longest
        half segment (no other segment can then be closer). The points the first ``K = 8``
        do not settle try the ``REDO_CANDIDATES`` nearest, in index order (a tie goes to the
        lowest index, as in a brute force); the few still left are done by brute force."""
        from scipy.spatial import cKDTree

        A, D, L2, exact = self.A, self.D, self.L2, self._exact
        P = np.asarray(points, dtype=np.float64)
        k = len(P)
        seg = np.empty(k, np.int64)
        t = np.empty(k)
        K = min(8, len(A))
        if k:
            if self.tree is None:
                self.tree = cKDTree(self.mid)          # the segments' midpoints
            tree = self.tree
            dm, S = tree.query(P, k=K)
            S = S.reshape(k, K)
            dm = dm.reshape(k, K)
            seg[:], t[:], d2 = exact(P, S)
            half = 0.5 * np.sqrt(L2.max())
            redo = np.flatnonzero((K < len(A)) & (dm[:, -1] <= np.sqrt(d2) + half))
            K2 = min(REDO_CANDIDATES, len(A))
            if len(redo) and K2 > K:
                # more candidates, in index order so that a tie goes to the lowest index as
                # in the brute force
                dm2, S2 = tree.query(P[redo], k=K2)
                sure = (K2 == len(A)) | (dm2[:, -1] > np.sqrt(d2[redo]) + half)
                r = redo[sure]
                seg[r], t[r], _ = exact(P[r], np.sort(S2[sure], axis=1))
                redo = redo[~sure]
            block = max(1, 4_000_000 // max(len(A), 1))
            allseg = np.arange(len(A))
            for lo in range(0, len(redo), block):
                r = redo[lo:lo + block]
                seg[r], t[r], _ = exact(P[r], np.broadcast_to(allseg, (len(r), len(A))))
        return seg, t, A.take(seg, axis=0) + t[:, None] * D.take(seg, axis=0)


def project_to_boundary_polygon(uv: np.ndarray, boundary: np.ndarray, points: np.ndarray
                                ) -> np.ndarray:
    """Closest point (k×2) of the closed polygon ``uv[boundary]`` to each of ``points`` (k×2).

    For a SEM map the polygon is inscribed in the unit circle; samples meant for the rim should
    be placed on it with this function (or directly on its edges) so that they locate exactly.
    """
    uv = np.asarray(uv, dtype=np.float64)
    loop = np.asarray(boundary, dtype=np.int64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    _, _, q = _closest_on_segments(pts, uv[loop], uv[np.roll(loop, -1)])
    return q


class PointLocator:
    """Build once for an image triangulation ``(uv, F)``, then :meth:`locate` any points.

    ``boundary`` (the loop to project outside points onto) defaults to all boundary edges of
    ``F``. ``cell_factor`` scales the grid: about ``cell_factor × m`` cells.
    """

    def __init__(self, uv: np.ndarray, F: np.ndarray, boundary: np.ndarray | None = None,
                 cell_factor: float = 0.5):
        self.uv = np.ascontiguousarray(np.asarray(uv, dtype=np.float64)[:, :2])
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        n, m = len(self.uv), len(self.F)
        if m == 0:
            raise ValueError("cannot locate points in an empty triangulation")
        T = self.uv[self.F]                                          # (m, 3, 2)
        lo = np.minimum(np.minimum(T[:, 0], T[:, 1]), T[:, 2])        # corner by corner:
        hi = np.maximum(np.maximum(T[:, 0], T[:, 1]), T[:, 2])        # the same, faster
        self.origin = lo.min(axis=0)
        extent = np.maximum(hi.max(axis=0) - self.origin, 1e-300)
        cell = np.sqrt(extent[0] * extent[1] / max(cell_factor * m, 1.0))
        cell = max(cell, float(extent.max()) / 4096.0)               # at most 4096² cells
        self.cell = cell
        self.shape = np.maximum(np.ceil(extent / cell).astype(np.int64), 1)   # (nx, ny)
        # every face in the cells of its bounding box; thin faces (large bounding box, small
        # area) only in the cells they really touch (compiled, a counting sort by cell)
        self.cell_faces, self.cell_start = grid_cells(
            self.uv, self.F, np.ascontiguousarray(lo), np.ascontiguousarray(hi),
            float(self.origin[0]), float(self.origin[1]), float(cell), int(self.shape[0]),
            int(self.shape[1]))
        sa, sb, sf, sca, scb = _boundary_segments(self.F, n, boundary)
        self.seg_a, self.seg_b, self.seg_face = sa, sb, sf
        self.seg_ca, self.seg_cb = sca, scb
        self._rows = None                    # the faces' corners and neighbours, for the walk
        self._tree = None                    # nearest image vertex, for large batches
        self._boundary = None                # the boundary's Segments, for _on_boundary

    def _cell_xy(self, P: np.ndarray) -> np.ndarray:
        ij = np.floor((P - self.origin) / self.cell).astype(np.int64)
        return np.clip(ij, 0, self.shape - 1)

    def _candidates(self, P: np.ndarray):
        """Best face per point among its cell's faces: ``(face, bary, min bary)``; −1/−inf when
        the cell is empty. The first face of the largest smallest barycentric (a non-finite one
        counts as −inf), compiled (:func:`._kernels.grid_candidates`)."""
        return grid_candidates(self.uv, self.F, self.cell_start, self.cell_faces,
                               np.ascontiguousarray(P, dtype=np.float64),
                               float(self.origin[0]), float(self.origin[1]), float(self.cell),
                               int(self.shape[0]), int(self.shape[1]))

    def locate(self, points: np.ndarray, tol: float = TOL) -> tuple[np.ndarray, np.ndarray]:
        """``(face int64 k, bary float64 k×3)`` for every point; see the module docstring."""
        face, bary, _ = self.locate_with_inside(points, tol)
        return face, bary

    def locate_with_inside(self, points: np.ndarray, tol: float = TOL
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Like :meth:`locate`, plus a mask of the points that were inside the image (the
        others were projected onto the boundary polygon). A batch of at least half as many
        points as image vertices first walks from a face at each point's nearest image vertex
        (:meth:`relocate`); the grid takes the rest."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        if len(P) < max(_WALK_MIN, 0.5 * len(self.uv)):        # the tree would not pay
            return self._grid_locate(P, tol)
        return self.relocate(P, self._near_faces(P), tol, walk=_WALK)

    def locate_from_cells(self, points: np.ndarray, tol: float = TOL
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Like :meth:`locate_with_inside`, each point walking ``_WALK`` steps from the first
        face registered in its grid cell (:meth:`relocate`; the grid takes the points the walk
        does not settle and those of empty cells) instead of from a face at its nearest image
        vertex: no tree to build and query, for a large batch located once in a triangulation
        built for it. A point the walk settles lies in the face it stops at, so it gets the
        position :meth:`locate_with_inside` gives; only on an edge may the face differ."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        ij = self._cell_xy(P)
        cell = ij[:, 1] * self.shape[0] + ij[:, 0]
        s, e = self.cell_start[cell], self.cell_start[cell + 1]
        start = self.cell_faces[np.minimum(s, len(self.cell_faces) - 1)]
        face, bary, inside = self.relocate(P, np.where(e > s, start, 0), tol, walk=_WALK)
        return face, bary, inside

    def _near_faces(self, P: np.ndarray) -> np.ndarray:
        """A face at the image vertex nearest to each point (a KD-tree, built once)."""
        if self._tree is None:
            from scipy.spatial import cKDTree

            vface = np.full(len(self.uv), -1, np.int64)
            vface[self.F.ravel()] = np.repeat(np.arange(len(self.F)), 3)
            used = np.flatnonzero(vface >= 0)
            self._tree = (cKDTree(self.uv[used]), vface[used])
        tree, vface = self._tree
        return vface[tree.query(P)[1]]

    def _grid_locate(self, P: np.ndarray, tol: float = TOL, project: bool = True
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps 2–4 of the module docstring for every point (the grid); without ``project``,
        a point outside the image gets face −1 and zero barycentrics instead of its closest
        boundary point's."""
        k = len(P)
        face = np.empty(k, np.int64)
        bary = np.empty((k, 3))
        inside = np.empty(k, bool)
        for lo in range(0, k, _CHUNK):
            f, b, s = self._candidates(P[lo:lo + _CHUNK])
            ins = s >= -tol
            b[ins] = _clean_rows(b[ins])
            out = np.flatnonzero(~ins)
            if len(out) and project:
                f[out], b[out] = self._on_boundary(P[lo + out])
            elif len(out):
                f[out], b[out] = -1, 0.0
            face[lo:lo + _CHUNK], bary[lo:lo + _CHUNK], inside[lo:lo + _CHUNK] = f, b, ins
        return face, bary, inside

    def relocate(self, points: np.ndarray, face: np.ndarray, tol: float = TOL,
                 face2: np.ndarray | None = None, walk: int = 2, project: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Locate points near known faces: ``face`` (and then ``face2``, if given) is tested
        first; a point outside it steps up to ``walk`` times to the neighbouring face across
        the edge of its most negative barycentric coordinate (a walk); only the points still
        not found go through the grid. Returns like :meth:`locate_with_inside`; without
        ``project``, a point outside the image gets face −1 and zero barycentrics (for a
        caller that only needs the inside points' places)."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        face = np.array(face, dtype=np.int64, copy=True)
        bary = np.empty((len(P), 3))
        inside = np.ones(len(P), bool)
        todo = np.arange(len(P))
        # the walk reads a point's start face before it writes that point's face: no copy
        for hint in [face] + ([] if face2 is None else [face2]):
            if len(todo) == 0:
                break
            todo = walk_to_faces(self.walk_table(), P,
                                 np.ascontiguousarray(hint, dtype=np.int64), todo, walk, tol,
                                 face, bary)
        moved = todo
        if len(moved):
            face[moved], bary[moved], inside[moved] = self._grid_locate(P[moved], tol, project)
        return face, bary, inside

    def walk_table(self) -> np.ndarray:
        """The walk's table of the faces (m×8, computed once): each face's corners and the
        faces across its edges in one 64-byte row (:func:`._kernels.walk_rows`); read by the
        compiled walks here and elsewhere (:func:`._kernels.walked_sags`)."""
        if self._rows is None:
            self._rows = walk_rows(self.uv, self.F, topo.interior_edge_twins(self.F))
        return self._rows

    def _on_boundary(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Faces and barycentrics of the closest points of the boundary polygon to ``P``."""
        if self._boundary is None:
            self._boundary = Segments(self.uv[self.seg_a], self.uv[self.seg_b])
        seg, t, _ = self._boundary.closest(P)
        face = self.seg_face[seg]
        bary = np.zeros((len(P), 3))
        rows = np.arange(len(P))
        bary[rows, self.seg_ca[seg]] = 1.0 - t
        bary[rows, self.seg_cb[seg]] += t
        return face, bary


def locate_points(uv: np.ndarray, F: np.ndarray, points: np.ndarray,
                  boundary: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The image face of ``(uv, F)`` containing each query point, and its barycentrics.

    Returns ``(face, bary)``: ``face`` int64 (k), ``bary`` float64 (k×3) with rows ≥ 0 summing
    to 1, ordered like ``F[face]``, so that ``lift(uv, F, face, bary)`` reproduces the points
    (points outside the image polygon are replaced by their closest point on ``boundary``, or on
    any boundary edge of ``F`` when ``boundary`` is None). Every query gets a face. Build a
    :class:`PointLocator` instead when locating several batches in the same map.
    """
    return PointLocator(uv, F, boundary).locate(points)


def lift(values: np.ndarray, F: np.ndarray, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Eq. (1): ``Σ_c bary[:, c] · values[F[face, c]]`` for per-vertex ``values`` (n or n×d).

    With ``values = V`` this maps disk samples to the surface; with colours, normals or any other
    per-vertex attribute it interpolates that attribute linearly (normals need renormalising).
    Compiled, float64 out (the corners summed in order, as ``b0·v0 + b1·v1 + b2·v2``).
    """
    vals = np.asarray(values)
    rows = np.ascontiguousarray(vals.reshape(len(vals), -1), dtype=np.float64)
    out = lift_rows(rows, np.ascontiguousarray(F, dtype=np.int64),
                    np.ascontiguousarray(face, dtype=np.int64),
                    np.ascontiguousarray(bary, dtype=np.float64))
    return out.reshape((len(out),) + vals.shape[1:])
