"""Mesh intake repair: turn what the user gave into one clean topological disk, or into one
clean closed genus-0 surface (whose domain is the sphere: :mod:`.sphere`).

:func:`repair_mesh` runs these steps in this order (each step that changes something adds one
line to ``messages`` and counts to ``report``; problems that cannot be repaired automatically, or
only on request, are a :class:`~pipeline.errors.UserError` naming the option or fix):

1.  **validate** — empty vertex/face lists, NaN/inf coordinates, bad colour shapes, face indices
    out of range → error.
2.  **triangulate** polygons by a fan from their first corner (``non_triangle_faces_triangulated``);
    faces with fewer than 3 corners are dropped (``invalid_faces_removed``).
3.  **degenerate faces** (a repeated vertex index) are removed (``degenerate_faces_removed``).
4.  **weld** (``options.weld``) referenced vertices closer than ``weld_tolerance`` × bounding-box
    diagonal (exact duplicates by a lexicographic sort, near ones via ``cKDTree.query_pairs``,
    merged transitively); the lowest input index of a group is kept with its position and colour
    (``vertices_welded``). Faces that became degenerate are removed (counted in
    ``degenerate_faces_removed``). Exception — *cut seams*: when the unwelded mesh is already
    fine (one component, manifold, genus 0, open or closed) but the welded one is not (e.g.
    ``igl_camel_b``: welding its 243 seam vertices closes the surface and pinches a vertex), the
    coincident vertices are an intentional cut and are left apart (``weld_skipped_vertices``).
    A seam whose welding gives a fine *closed* genus-0 surface is welded (the mesh then maps to
    the sphere; ``weld: false`` keeps the cut disk).
5.  **duplicate faces** (same vertex set, any order or orientation): the first is kept
    (``duplicate_faces_removed``).
6.  **unreferenced vertices** are removed; the remaining vertices keep their relative order
    (``unreferenced_vertices_removed``, not counting welded vertices).
7.  **non-manifold edges and vertices**: at an edge in more than two faces, the two faces that
    continue each other most nearly flat (the widest opening between their half-planes) are
    kept and the others removed (``nonmanifold_edge_faces_removed``; a fin, a stray sheet);
    then a vertex whose faces form several fans (a bowtie: a ragged rim touching itself,
    pieces meeting at a point) gets one vertex per fan, the largest fan keeping it and each
    other one a copy with the same position, colour and ``source_index``
    (``nonmanifold_vertices_split``: vertices split). With ``remove_nonmanifold_edge_faces``
    or ``split_nonmanifold_vertices`` false, each is an error instead. Vertices left without a
    face are removed.
8.  **components** (faces sharing a vertex are connected): more than one is an error unless
    ``keep_largest_component`` (largest by face count; ``components_dropped``,
    ``component_faces_dropped``; the dropped components' vertices are removed too).
9.  **orientation** made consistent, keeping the majority orientation of the faces
    (``faces_reoriented``); non-orientable → error.
10. **zero-area faces** (three distinct vertices but twice the area ≤ 1e-12 × longest edge², i.e.
    collinear "caps"): a cap whose longest edge is interior is fixed by flipping that edge — the
    cap's middle vertex then splits the neighbouring triangle, so the geometry is unchanged and
    both new triangles are proper; a cap on the boundary whose removal keeps the surface a
    manifold (its opposite vertex is interior, or it is an ear) is removed. Counted in
    ``zero_area_faces_flipped`` / ``zero_area_faces_removed``; any zero-area face that cannot be
    fixed this way → error (the cotangent weights would be infinite).
11. **decimation** (``decimate_to_faces``) with ``fast_simplification`` when the mesh has more
    faces. Quadric decimation can pinch the surface, so the settings ``(preserve_border, agg)``
    = (True, 7), (False, 7), (True, 5), (False, 5), (True, 3), (False, 3) are tried in turn and
    the first output that is manifold, genus 0, connected, with the same number of boundary
    loops and at most about twice the target face count is kept (else an error); steps 3, 5–10
    are re-run on it. ``source_index`` of a decimated vertex is the
    input vertex, among those the collapse history (``replay_simplification``) merged into it,
    that lies nearest to its new position (nearest input vertex by ``cKDTree`` if the replay
    does not reproduce the triangles).
12. **boundary**: genus ``g = (2 − loops − χ) / 2`` from the Euler characteristic ``χ``;
    ``g > 0`` → error naming the genus (closed or not). A **closed** genus-0 surface (no boundary
    loop, ``χ = 2``) is kept as it is: steps 12's hole closing and 13 do not apply; its faces are
    turned outward (positive enclosed signed volume, :func:`.sphere.signed_volume`), all of them
    reversed if needed (``faces_flipped_outward``). Otherwise
    more than one boundary loop → error unless ``close_holes``: every loop but the longest (3D
    length) gets a fan to one appended vertex at the mean of the loop's vertices (colour = mean
    colour). Holes are closed in the order of their smallest vertex index, each fan starting at
    the hole's first boundary half-edge in face order, which reproduces the ICT ``*_disk`` files
    exactly.
13. **leaf faces** (paper Def. 4, all three corners on the boundary): the longest interior edge
    of each leaf is split at its 3D midpoint together with the face across it (the midpoint is an
    interior vertex, so neither half is a leaf; no new leaves can appear); repeated until no leaf
    is left (``leaf_faces_split`` = leaves found, ``leaf_split_vertices_added``). With
    ``split_leaf_faces: false`` leaves are an error. No leaves also means every boundary vertex
    has an interior neighbour (paper Def. 1(ii)). Then **flap necks**: an interior vertex
    whose neighbours are all boundary vertices is a *flap* hanging on the rest by the interior
    edges of its link (both ends on the boundary); the map would have to squeeze it into the
    circular segment of such an edge and wraps it twice around the vertex instead (the
    boundary image runs backwards). Each such edge is split at its 3D midpoint with its two
    faces (``flap_necks_split``; the new faces all have the interior midpoint as a corner, so
    no leaf appears). Only flaps of the mesh before the leaf splits count (a leaf split's
    midpoint may have only boundary neighbours; it lies inside its leaf's triangle).
14. **final invariants** (one component, manifold, consistently oriented; for a disk: one
    boundary loop, Euler characteristic 1, no leaves, every boundary vertex next to an interior
    one; for a closed surface: Euler characteristic 2 and outward faces) are checked; a failure
    there is a bug in this module (``RuntimeError``), not a user error.

A hole fan is exact topology but only as good geometrically as the hole is star-shaped around its
centroid (true for eye/mouth openings).

``report`` keys (all present, ints unless noted): ``input_vertices``, ``input_faces``,
``non_triangle_faces_triangulated``, ``invalid_faces_removed``, ``degenerate_faces_removed``,
``vertices_welded``, ``weld_skipped_vertices``, ``duplicate_faces_removed``,
``unreferenced_vertices_removed``, ``components_found``, ``components_dropped``,
``component_faces_dropped``, ``nonmanifold_edge_faces_removed``, ``nonmanifold_vertices_split``,
``faces_reoriented``, ``zero_area_faces_flipped``,
``zero_area_faces_removed``, ``decimated_from_faces`` / ``decimated_to_faces`` (``None`` when not
decimated), ``boundary_loops_found``, ``closed`` (bool: no boundary, the sphere is the
domain), ``genus``, ``faces_flipped_outward``, ``holes_closed``, ``flap_necks_split``,
``leaf_faces_split``, ``leaf_split_vertices_added``, ``output_vertices``, ``output_faces``,
``boundary_vertices``.

A closed result has ``boundary`` = an empty int64 array (:attr:`RepairedMesh.closed`).
If the input is already a clean disk or an outward closed genus-0 surface, ``V``/``F`` are
returned unchanged (copies, same order) and ``source_index = arange(n)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from pipeline.errors import UserError
from pipeline.geometry import topology as topo
from pipeline.geometry.laplacian import face_double_areas
from pipeline.geometry.remesh_quality import longest_edge_squared
from pipeline.geometry.rows import dots, norms
from pipeline.io.meshio import refuse_huge_coordinates

__all__ = ["RepairOptions", "RepairedMesh", "repair_mesh", "triangulate_polygons",
           "weld_map", "zero_area_mask", "has_interior_neighbour", "disk_blockers",
           "count_boundary_loops", "genus_of", "nonmanifold_edge_extras",
           "repaired_vertex_of"]

ZERO_AREA_RTOL = 1e-12   # 2·area ≤ ZERO_AREA_RTOL · (longest edge)² counts as zero area


class RepairOptions(BaseModel):
    """What :func:`repair_mesh` may change (see the module docstring); also the ``repair``
    section of a run config (validated once, here); NaN and infinite numbers are errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    weld: bool = True
    weld_tolerance: float = Field(1e-9, ge=0.0)   # relative to the bounding-box diagonal
    keep_largest_component: bool = False
    close_holes: bool = False          # close every boundary loop but the longest
    split_leaf_faces: bool = True      # paper Def. 4; if False and leaves exist -> UserError
    remove_nonmanifold_edge_faces: bool = True   # if False, an edge in > 2 faces -> UserError
    split_nonmanifold_vertices: bool = True      # if False, a bowtie vertex -> UserError
    decimate_to_faces: Optional[int] = Field(   # fast_simplification target face count
        None, ge=4, json_schema_extra={"flag": "--decimate"})


@dataclass
class RepairedMesh:
    """A clean disk (or, with ``boundary`` empty, a closed genus-0 surface) and how it relates
    to the input mesh."""

    V: np.ndarray
    F: np.ndarray
    colors: np.ndarray | None
    source_index: np.ndarray      # int64 n: input vertex of each output vertex, −1 if added
    boundary: np.ndarray          # the boundary loop, interior on the left
    added_vertices: np.ndarray    # output indices of added vertices (hole centres, midpoints)
    closed_holes: list = field(default_factory=list)   # {"centre_vertex", "loop"} per hole
    report: dict = field(default_factory=dict)
    messages: list = field(default_factory=list)

    @property
    def closed(self) -> bool:
        """True for a closed genus-0 surface (no boundary loop): its domain is the sphere."""
        return len(self.boundary) == 0

    def fan_faces(self) -> np.ndarray:
        """Which faces (m bool) are those of the fans that closed the input's holes (a face at
        a hole's centre vertex)."""
        return fan_faces(self.F, [h["centre_vertex"] for h in self.closed_holes])

    def hole_loops(self) -> list:
        """The loops (vertex indices, (k,) int each) of the holes the repair closed, each as
        its fan runs round it."""
        return [np.asarray(h["loop"], np.int64) for h in self.closed_holes]


def fan_faces(F: np.ndarray, centres) -> np.ndarray:
    """Which faces of ``F`` (m×3) are at one of the ``centres`` (vertex indices), (m,) bool:
    the fans :func:`repair_mesh` closes holes with."""
    if len(centres) == 0:
        return np.zeros(len(F), bool)
    return np.isin(F, np.asarray(centres, np.int64)).any(axis=1)


def open_mesh(mesh, covered=()) -> tuple[np.ndarray, np.ndarray]:
    """A :class:`RepairedMesh` with the holes the repair closed open again but those whose
    indices (into ``mesh.closed_holes``) are in ``covered``: its vertices (n', 3) without the
    opened fans' centres and its faces (m', 3) without those fans (:func:`display_faces`),
    renumbered; ``(mesh.V, mesh.F)`` where it opens none."""
    F = display_faces(mesh, covered)
    if F is mesh.F:
        return mesh.V, mesh.F
    V, F, _ = used_vertices_only(mesh.V, F)
    return V, F


def used_vertices_only(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """``(V, F)`` (n×3, m×3) without the vertices no face uses, the rest in their order:
    the vertices (n', 3), the faces renumbered (m, 3) and each old vertex's new index (n,
    int, −1 for a dropped one)."""
    used = np.zeros(len(V), bool)
    used[F.ravel()] = True
    new = np.where(used, np.cumsum(used) - 1, -1)
    return V[used], new[F], new


def display_faces(mesh, covered=()) -> np.ndarray:
    """The faces of a :class:`RepairedMesh` minus the fans of the holes the repair closed (the
    input's holes open again) but those whose indices are in ``covered``, (m', 3) int;
    ``mesh.F`` itself where it opens none."""
    centres = [h["centre_vertex"] for i, h in enumerate(mesh.closed_holes) if i not in covered]
    if not centres:
        return mesh.F
    return mesh.F[~fan_faces(mesh.F, centres)]


# --------------------------------------------------------------------------------------------
# small pure helpers


def triangulate_polygons(faces, n: int, name: str = "mesh") -> tuple[np.ndarray, int, int]:
    """Fan-triangulate polygons (array m×k or list of index arrays) from their first corner.

    Returns ``(F, non_triangle_faces, invalid_faces)``: faces with fewer than 3 corners are
    dropped and counted as invalid. Raises :class:`UserError` for indices outside ``0..n-1``.
    """
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        arr = faces
        if arr.size and not np.issubdtype(arr.dtype, np.integer):
            if np.any(arr != np.round(arr)):
                raise UserError(f"mesh '{name}': face indices are not integers; fix the face list")
        arr = arr.astype(np.int64)
        counts = np.full(len(arr), arr.shape[1], dtype=np.int64)
        flat = arr.ravel()
    else:
        polys = [np.asarray(p).ravel() for p in faces]
        counts = np.fromiter((len(p) for p in polys), dtype=np.int64, count=len(polys))
        flat = np.concatenate(polys).astype(np.int64) if polys else np.zeros(0, np.int64)
    if flat.size and (flat.min() < 0 or flat.max() >= n):
        bad = int(flat.min() if flat.min() < 0 else flat.max())
        raise UserError(
            f"mesh '{name}': face index {bad} is out of range for {n} vertices; fix the face list"
        )
    invalid = int(np.count_nonzero(counts < 3))
    non_tri = int(np.count_nonzero(counts > 3))
    if non_tri == 0 and invalid == 0:
        return flat.reshape(-1, 3), 0, 0
    offs = np.r_[0, np.cumsum(counts)[:-1]]
    ntri = np.maximum(counts - 2, 0)
    owner = np.repeat(np.arange(len(counts)), ntri)
    k = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    base = offs[owner]
    F = np.stack([flat[base], flat[base + k], flat[base + k + 1]], axis=1)
    return F, non_tri, invalid


def _degenerate_mask(F: np.ndarray) -> np.ndarray:
    return (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])


def _duplicate_mask(F: np.ndarray) -> np.ndarray:
    """True for every face whose vertex set already occurred in an earlier face.

    Each face's sorted corners ``(i, j, k)`` packed into one key ``(i·n + j)·n + k`` (``n``
    above the largest index) when it fits in int64, and the keys sorted with their face
    indices (:func:`.topology.sort_with_index`: equal keys in face order), else the corners
    sorted lexicographically (stable): both put the faces of one vertex set together, earliest
    first."""
    if len(F) == 0:
        return np.zeros(0, bool)
    s = sorted_corners(F)
    n = int(s[:, 2].max()) + 1
    if int(s[:, 0].min()) >= 0 and 3 * n.bit_length() <= 62:
        keys, order = topo.sort_with_index((s[:, 0] * n + s[:, 1]) * n + s[:, 2])
        same = np.r_[False, keys[1:] == keys[:-1]]
    else:
        order = np.lexsort((s[:, 2], s[:, 1], s[:, 0]))
        ss = s[order]
        same = np.r_[False, np.all(ss[1:] == ss[:-1], axis=1)]
    dup = np.zeros(len(F), bool)
    dup[order[same]] = True
    return dup


def sorted_corners(F: np.ndarray) -> np.ndarray:
    """Each row of ``F`` (m, 3) sorted ascending (m, 3): ``np.sort(F, axis=1)``'s values, by
    minimum, maximum and the remaining corner (faster than sorting the short rows)."""
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    lo = np.minimum(np.minimum(a, b), c)
    hi = np.maximum(np.maximum(a, b), c)
    return np.stack([lo, a + b + c - lo - hi, hi], axis=1)


def lexicographic_order(P: np.ndarray) -> np.ndarray:
    """The stable lexicographic order of the rows of ``P`` (k, 3) floats: the order of
    ``np.lexsort((P[:, 2], P[:, 1], P[:, 0]))`` (ties in index order). A stable sort of the
    first column, then the rows of equal first coordinates (few in measured data) sorted by
    the other two."""
    order = np.argsort(P[:, 0], kind="stable")
    xs = P[order, 0]
    tie = xs[1:] == xs[:-1]
    if tie.any():
        pos = np.flatnonzero(np.r_[tie, False] | np.r_[False, tie])
        run = np.cumsum(np.r_[True, ~tie])[pos]           # equal-x run of each tied position
        sub = order[pos]                                   # in index order within a run
        order[pos] = sub[np.lexsort((P[sub, 2], P[sub, 1], run))]
    return order


def weld_map(V: np.ndarray, tol: float, active: np.ndarray | None = None) -> np.ndarray:
    """Representative vertex for every vertex: the lowest index among the (``active``) vertices
    within ``tol`` of it, transitively. Exact duplicates are grouped by a lexicographic sort of
    the coordinates; near duplicates with ``cKDTree.query_pairs`` on one vertex per exact group
    (skipped when ``tol`` is 0, or when no two of them are that close in every coordinate:
    :func:`may_be_near`). Inactive vertices map to themselves.
    """
    n = len(V)
    rep = np.arange(n, dtype=np.int64)
    idx = np.arange(n) if active is None else np.flatnonzero(active)
    k = len(idx)
    if k < 2:
        return rep
    P = V[idx]
    order = lexicographic_order(P)                         # stable: lowest index first in a group
    Ps = P[order]
    new = np.r_[True, np.any(Ps[1:] != Ps[:-1], axis=1)]
    group = np.cumsum(new) - 1
    first_sorted = order[new]                              # lowest local index of each group
    local_rep = np.empty(k, np.int64)
    local_rep[order] = first_sorted[group]
    rows, cols = [np.arange(k)], [local_rep]
    if tol > 0 and len(first_sorted) > 1 and may_be_near(P[first_sorted], tol):
        from scipy.spatial import cKDTree

        pairs = cKDTree(P[first_sorted]).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            rows.append(first_sorted[pairs[:, 0]])
            cols.append(first_sorted[pairs[:, 1]])
    if len(rows) == 1:
        rep[idx] = idx[local_rep]
        return rep
    r, c = np.concatenate(rows), np.concatenate(cols)
    _, lab = topo.graph_components(r, c, k)
    lowest = np.full(lab.max() + 1, k, dtype=np.int64)
    np.minimum.at(lowest, lab, np.arange(k))   # idx is sorted: lowest local = lowest input
    rep[idx] = idx[lowest[lab]]
    return rep


#: relative margin of :func:`may_be_near` over ``tol``: far above the rounding of a coordinate
#: difference and of the tree's squared distances
NEAR_MARGIN = 1e-6


def nonmanifold_edge_extras(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Which faces (m bool) to drop so that no edge is in more than two faces: at every such
    edge the two faces that continue each other most nearly flat are kept — the pair whose
    half-planes from the edge open widest (towards their third corners, any orientation) —
    and the others dropped (a fin, a stray sheet through the edge). Ties: the lower face
    indices. ``V`` (n×3), ``F`` (m×3)."""
    h, starts = topo.nonmanifold_edge_halfedges(F)
    drop = np.zeros(len(F), dtype=bool)
    if len(h) == 0:
        return drop
    a, b = topo.half_edges(F)
    P, Q = V[a[h]], V[b[h]]
    O = V[F[h // 3, (h % 3 + 2) % 3]]                          # the corner opposite the edge
    e = Q - P
    e = e / np.maximum(norms(e), np.finfo(float).tiny)[:, None]
    w = O - P
    u = w - dots(w, e)[:, None] * e                            # towards it, across the edge
    u = u / np.maximum(norms(u), np.finfo(float).tiny)[:, None]
    for lo, hi in zip(starts.tolist(), np.r_[starts[1:], len(h)].tolist()):
        cosines = u[lo:hi] @ u[lo:hi].T                        # −1: the two continue flat
        np.fill_diagonal(cosines, np.inf)
        i, j = np.unravel_index(int(np.argmin(cosines)), cosines.shape)
        faces = h[lo:hi] // 3
        drop[np.delete(faces, [i, j])] = True
    return drop


def repaired_vertex_of(source_index: np.ndarray, n_input: int) -> np.ndarray:
    """For every input vertex (n_input int64), the repaired vertex on it — the first, where a
    split bowtie gave it several (the one that kept its largest fan) — or −1 where the repair
    removed it; ``source_index`` (n) as in :class:`RepairedMesh`."""
    src = np.asarray(source_index, dtype=np.int64)
    ok = np.flatnonzero((src >= 0) & (src < n_input))
    first = np.full(max(n_input, 0), len(src), dtype=np.int64)
    np.minimum.at(first, src[ok], ok)
    return np.where(first < len(src), first, -1)


def may_be_near(P: np.ndarray, tol: float) -> bool:
    """Whether two of the distinct points ``P`` (k, 3), sorted by their first coordinate, may
    lie within ``tol`` of each other: whether two differ by at most ``tol·(1 + NEAR_MARGIN)``
    in every coordinate. Necessary for a distance ≤ ``tol``; False proves there is no such
    pair. Found coordinate by coordinate: the runs of the sorted first coordinates with steps
    within the margin, in them the runs of the second, then of the third (few points are left
    after the first in measured data)."""
    reach = tol * (1 + NEAR_MARGIN)
    idx = np.arange(len(P))
    group = np.zeros(len(P), np.int64)
    for axis in range(P.shape[1]):
        if axis:
            order = np.lexsort((P[idx, axis], group))
            idx, group = idx[order], group[order]
        x = P[idx, axis]
        close = (x[1:] - x[:-1] <= reach) & (group[1:] == group[:-1])
        if not close.any():
            return False
        keep = np.r_[close, False] | np.r_[False, close]
        run = np.cumsum(np.r_[True, ~close])
        idx, group = idx[keep], run[keep]
    return True


def count_boundary_loops(F: np.ndarray) -> int:
    """Number of boundary loops of a manifold mesh (components of the boundary-edge graph);
    unlike :func:`topology.boundary_loops` it does not need a consistent orientation."""
    be = topo.boundary_edges(F)
    if len(be) == 0:
        return 0
    n = int(F.max()) + 1
    nb = int(np.count_nonzero(np.bincount(be.ravel(), minlength=n)))
    return topo.graph_components(be[:, 0], be[:, 1], n)[0] - (n - nb)


def disk_blockers(F: np.ndarray, n: int | None = None) -> list[str]:
    """What keeps ``F`` (degenerate/duplicate faces already removed) from being repairable
    without options into a disk or a closed genus-0 surface: several components, non-manifold
    edges or vertices, genus > 0. Empty list = fine. Used to decide whether welding helps or
    hurts, and whether a decimation kept the topology."""
    out = []
    ncomp, _ = topo.connected_components(F, n)
    if ncomp > 1:
        out.append(f"{ncomp} components")
    if len(topo.nonmanifold_edges(F)):
        out.append("non-manifold edges")
        return out
    if len(topo.nonmanifold_vertices(F, n)):
        out.append("non-manifold vertices")
        return out
    if ncomp == 1:
        g = genus_of(F, count_boundary_loops(F))
        if g > 0:
            out.append(f"genus {g}")
    return out


def genus_of(F: np.ndarray, loops: int, n: int | None = None) -> int:
    """Genus ``(2 − loops − χ) / 2`` of a connected orientable manifold with ``loops`` boundary
    loops and Euler characteristic ``χ = V − E + F`` (``n`` vertices; default: those in ``F``)."""
    return (2 - loops - topo.euler_characteristic(F, n)) // 2


def has_interior_neighbour(F: np.ndarray, is_b: np.ndarray) -> np.ndarray:
    """Whether each vertex shares an edge of ``F`` (m, 3) with a vertex off the boundary
    (``is_b``: (n,) bool, the boundary vertices); (n,) bool."""
    a, b = topo.half_edges(F)
    out = np.zeros(len(is_b), bool)
    out[a[~is_b[b]]] = True
    out[b[~is_b[a]]] = True
    return out


def zero_area_mask(V: np.ndarray, F: np.ndarray, rtol: float = ZERO_AREA_RTOL) -> np.ndarray:
    """Faces whose doubled area is at most ``rtol`` × (longest edge)² (collinear or collapsed)."""
    if len(F) == 0:
        return np.zeros(0, bool)
    return face_double_areas(V, F) <= rtol * longest_edge_squared(V, F)


# --------------------------------------------------------------------------------------------
# the mutable state threaded through the steps


class _Mesh:
    """Working copy: positions, faces, colours and the input index of every vertex."""

    def __init__(self, V, F, C, src):
        self.V, self.F, self.C, self.src = V, F, C, src

    @property
    def n(self) -> int:
        return len(self.V)

    def keep_vertices(self, keep: np.ndarray) -> None:
        """Drop vertices with ``keep == False`` (faces must not use them), keeping order."""
        new = np.cumsum(keep) - 1
        self.F = new[self.F]
        self.V = self.V[keep]
        self.src = self.src[keep]
        if self.C is not None:
            self.C = self.C[keep]

    def copy_vertices(self, parent: np.ndarray) -> None:
        """Append a copy of each vertex ``parent`` (k): position, colour and input vertex."""
        self.V = np.vstack([self.V, self.V[parent]])
        self.src = np.r_[self.src, self.src[parent]]
        if self.C is not None:
            self.C = np.vstack([self.C, self.C[parent]])

    def append_vertices(self, P: np.ndarray, C: np.ndarray | None) -> np.ndarray:
        start = self.n
        self.V = np.vstack([self.V, P])
        self.src = np.r_[self.src, np.full(len(P), -1, np.int64)]
        if self.C is not None:
            self.C = np.vstack([self.C, C])
        return np.arange(start, self.n)


def _plural(k: int, word: str) -> str:
    if k == 1:
        return f"{k} {word}"
    return f"{k} {word[:-2]}ices" if word.endswith("vertex") else f"{k} {word}s"


def _bump(report: dict, key: str, k: int) -> None:
    report[key] = int(report.get(key) or 0) + int(k)


# --------------------------------------------------------------------------------------------
# steps


def _remove_bad_faces(M: _Mesh, report: dict, messages: list, when: str) -> None:
    for mask_of, key, noun, note in (
            (_degenerate_mask, "degenerate_faces_removed", "degenerate face", " (repeated vertex)"),
            (_duplicate_mask, "duplicate_faces_removed", "duplicate face", "")):
        bad = mask_of(M.F)
        if bad.any():
            M.F = M.F[~bad]
            k = int(bad.sum())
            _bump(report, key, k)
            messages.append(f"removed {_plural(k, noun)}{note}{when}")
    if len(M.F) == 0:
        raise UserError(
            f"mesh has no valid faces left after removing degenerate/duplicate faces{when}; "
            f"pass a surface mesh"
        )


def _components(M: _Mesh, opts: RepairOptions, report: dict, messages: list, name: str,
                when: str) -> None:
    ncomp, lab = topo.connected_components(M.F, M.n)
    report["components_found"] = max(int(report.get("components_found") or 0), ncomp)
    if ncomp <= 1:
        return
    sizes = np.bincount(lab, minlength=ncomp)
    big = int(np.argmax(sizes))
    if not opts.keep_largest_component:
        raise UserError(
            f"mesh '{name}' has {ncomp} connected components{when} (largest: {int(sizes[big])} of "
            f"{len(M.F)} faces); set repair.keep_largest_component: true "
            f"(CLI: --keep-largest-component) or pass one connected patch"
        )
    keep = lab == big
    dropped = int((~keep).sum())
    M.F = M.F[keep]
    _bump(report, "components_dropped", ncomp - 1)
    _bump(report, "component_faces_dropped", dropped)
    messages.append(
        f"kept the largest of {ncomp} connected components ({int(sizes[big])} faces), dropped "
        f"{_plural(dropped, 'face')}{when}"
    )


def _compact(M: _Mesh) -> int:
    """Remove unreferenced vertices; returns how many."""
    used = np.zeros(M.n, bool)
    used[M.F.ravel()] = True
    k = int(M.n - used.sum())
    if k:
        M.keep_vertices(used)
    return k


def _nonmanifold_edges(M: _Mesh, opts: RepairOptions, report: dict, messages: list, name: str,
                       hint: str) -> None:
    """An edge in more than two faces: its extra faces removed
    (:func:`nonmanifold_edge_extras`) or, with ``remove_nonmanifold_edge_faces`` off, an
    error."""
    bad_e = topo.nonmanifold_edges(M.F)
    if len(bad_e) == 0:
        return
    i, j = (int(x) for x in bad_e[0])
    what = (f"{_plural(len(bad_e), 'non-manifold edge')} (in more than two faces, e.g. "
            f"vertices {i}-{j}){hint}")
    if not opts.remove_nonmanifold_edge_faces:
        raise UserError(
            f"mesh '{name}' has {what}; set repair.remove_nonmanifold_edge_faces: true or "
            f"remove the extra faces (e.g. in MeshLab) and pass a manifold surface"
        )
    drop = nonmanifold_edge_extras(M.V, M.F)
    M.F = M.F[~drop]
    k = int(drop.sum())
    _bump(report, "nonmanifold_edge_faces_removed", k)
    messages.append(f"removed {_plural(k, 'face')} at {what}, keeping at each edge the two "
                    f"faces that continue each other most nearly flat")


def _nonmanifold_vertices(M: _Mesh, opts: RepairOptions, report: dict, messages: list,
                          name: str, hint: str) -> int:
    """A vertex whose faces form several fans (bowtie): one vertex per fan
    (:func:`.topology.split_vertex_fans`; the copies keep the position, colour and input
    vertex) or, with ``split_nonmanifold_vertices`` off, an error. Returns how many were
    split."""
    bad_v = topo.nonmanifold_vertices(M.F, M.n)
    if len(bad_v) == 0:
        return 0
    what = (f"{_plural(len(bad_v), 'non-manifold vertex')} (bowtie: faces meet only at the "
            f"vertex, e.g. vertex {int(bad_v[0])}){hint}")
    if not opts.split_nonmanifold_vertices:
        raise UserError(
            f"mesh '{name}' has {what}; set repair.split_nonmanifold_vertices: true or split "
            f"or remove the touching faces and pass a manifold surface"
        )
    M.F, parent = topo.split_vertex_fans(M.F, M.n)
    M.copy_vertices(parent)
    _bump(report, "nonmanifold_vertices_split", len(bad_v))
    copies = "1 copy" if len(parent) == 1 else f"{len(parent)} copies"
    messages.append(f"split {what} into one vertex per fan ({copies} added at the same place)")
    return len(bad_v)


def _orient(M: _Mesh, report: dict, messages: list, when: str, name: str) -> None:
    try:
        F, k = topo.orient_faces_consistently(M.F)
    except UserError as exc:
        raise UserError(f"mesh '{name}': {exc}") from None
    if k:
        M.F = F
        _bump(report, "faces_reoriented", k)
        messages.append(f"re-oriented {_plural(k, 'face')} to match their neighbours{when}")


def _fix_zero_area(M: _Mesh, report: dict, messages: list, name: str, when: str) -> None:
    """Flip the longest edge of interior caps, remove removable boundary caps (see module doc)."""
    bad = np.flatnonzero(zero_area_mask(M.V, M.F))
    if len(bad) == 0:
        return
    flipped = removed = 0
    for _ in range(10):
        bad = np.flatnonzero(zero_area_mask(M.V, M.F))
        if len(bad) == 0:
            break
        F = M.F.copy()
        twin = topo.interior_edge_twins(F)
        is_b = topo.boundary_vertices_mask(F, M.n)
        edges = set(map(tuple, np.sort(topo.edges_with_faces(F)[0], axis=1).tolist()))
        touched = np.zeros(len(F), bool)
        remove = []
        progress = False
        for t in bad.tolist():
            if touched[t]:
                continue
            P = M.V[F[t]]
            l2 = ((P[[1, 2, 0]] - P) ** 2).sum(1)          # edge c: F[t,c] -> F[t,c+1]
            c = int(np.argmax(l2))
            h = 3 * t + c
            u, w, x = F[t, c], F[t, (c + 1) % 3], F[t, (c + 2) % 3]
            tw = int(twin[h])
            if tw >= 0 and not touched[tw // 3]:
                t2 = tw // 3
                y = F[t2, (tw % 3 + 2) % 3]
                new = np.array([[x, u, y], [y, w, x]])
                if x != y and (min(x, y), max(x, y)) not in edges and \
                        not zero_area_mask(M.V, new).any():
                    F[t], F[t2] = new[0], new[1]
                    edges.add((min(x, y), max(x, y)))
                    touched[[t, t2]] = True
                    flipped += 1
                    progress = True
                    continue
            on_b = [k for k in range(3) if twin[3 * t + k] < 0]
            if len(on_b) == 2 or (len(on_b) == 1 and not is_b[F[t, (on_b[0] + 2) % 3]]):
                remove.append(t)                 # an ear, or a cap whose apex is interior
                touched[t] = True
                removed += 1
                progress = True
        if remove:
            keep = np.ones(len(F), bool)
            keep[remove] = False
            F = F[keep]
        M.F = F
        if remove:
            _compact(M)
        if not progress:
            break
    left = np.flatnonzero(zero_area_mask(M.V, M.F))
    if flipped:
        _bump(report, "zero_area_faces_flipped", flipped)
        messages.append(
            f"fixed {_plural(flipped, 'zero-area face')} by flipping its longest edge{when}"
        )
    if removed:
        _bump(report, "zero_area_faces_removed", removed)
        messages.append(f"removed {_plural(removed, 'zero-area boundary face')}{when}")
    if len(left):
        raise UserError(
            f"mesh '{name}' has {_plural(len(left), 'zero-area face')} that cannot be repaired "
            f"automatically (e.g. face {int(left[0])}){when}; remesh or clean the mesh (e.g. "
            f"MeshLab 'Remove Zero Area Faces') and pass it again"
        )


def _clean(M: _Mesh, opts: RepairOptions, report: dict, messages: list, name: str,
           when: str = "", welded: int = 0) -> None:
    """Steps 5–10 (after triangulation, degenerate removal and welding)."""
    _remove_bad_faces(M, report, messages, when)
    unref = _compact(M)
    _bump(report, "unreferenced_vertices_removed", max(unref - welded, 0))
    if unref - welded > 0:
        messages.append(f"removed {_plural(unref - welded, 'unreferenced vertex')}{when}")
    hint = (f" after welding {_plural(welded, 'vertex')} (repair.weld: false keeps them "
            f"apart)" if welded else when)
    _nonmanifold_edges(M, opts, report, messages, name, hint)
    split = _nonmanifold_vertices(M, opts, report, messages, name, hint)   # manifold edges
    _compact(M)
    _components(M, opts, report, messages, name, when + (
        f" once its {_plural(split, 'non-manifold vertex')} were split" if split else ""))
    _compact(M)
    _orient(M, report, messages, when, name)          # needs manifold edges only
    _fix_zero_area(M, report, messages, name, when)


def _decimate(M: _Mesh, target: int, report: dict, messages: list, name: str) -> bool:
    """Quadric decimation to about ``target`` faces; returns whether the mesh changed."""
    m = len(M.F)
    if target is None or target >= m:
        return False
    try:
        import fast_simplification as fs
    except ImportError:
        raise UserError(
            "repair.decimate_to_faces needs the 'fast-simplification' package; "
            "pip install fast-simplification or unset decimate_to_faces"
        ) from None
    loops_before = count_boundary_loops(M.F)
    # Quadric decimation is not topology-safe: try border-preserving first, then less
    # aggressive/unconstrained settings, and keep the first result that is still a manifold
    # genus-0 mesh with the same number of boundary loops.
    attempts = [(True, 7.0), (False, 7.0), (True, 5.0), (False, 5.0), (True, 3.0), (False, 3.0)]
    result = None
    for preserve, agg in attempts:
        try:
            P, T, coll = fs.simplify(M.V, M.F, target_count=int(target), agg=agg,
                                     preserve_border=preserve, return_collapses=True)
        except TypeError:              # fast-simplification without ``preserve_border``
            if preserve:
                continue
            P, T, coll = fs.simplify(M.V, M.F, target_count=int(target), agg=agg,
                                     return_collapses=True)
        T = np.asarray(T, np.int64).reshape(-1, 3)
        if len(T) == 0 or len(T) > max(2 * int(target), int(target) + 100):
            continue                                   # failed or far from the target
        Tc = T[~_degenerate_mask(T)]
        Tc = Tc[~_duplicate_mask(Tc)]
        if len(Tc) and not disk_blockers(Tc) and count_boundary_loops(Tc) == loops_before:
            result = (np.asarray(P, np.float64), T, coll)
            break
    if result is None:
        raise UserError(
            f"mesh '{name}': decimating to {target} faces breaks the mesh topology (non-manifold "
            f"or merged boundaries); raise repair.decimate_to_faces or unset it"
        )
    P, T, coll = result
    chosen = None
    try:
        _, T2, mapping = fs.replay_simplification(M.V, M.F, coll)
        mapping = np.asarray(mapping, np.int64)
        if np.array_equal(np.asarray(T2, np.int64).reshape(-1, 3), T) and \
                mapping.min() >= 0 and mapping.max() < len(P):
            d = np.linalg.norm(M.V - P[mapping], axis=1)
            order = np.lexsort((d, mapping))              # per output vertex: nearest first
            firsts = np.r_[True, mapping[order][1:] != mapping[order][:-1]]
            chosen = np.full(len(P), -1, np.int64)
            chosen[mapping[order][firsts]] = order[firsts]
            if np.any(chosen < 0):
                chosen = None
    except Exception:   # pragma: no cover - replay is an optional refinement
        chosen = None
    if chosen is None:
        from scipy.spatial import cKDTree

        chosen = cKDTree(M.V).query(P)[1].astype(np.int64)
    M.V, M.F = np.ascontiguousarray(P), T
    M.src = M.src[chosen]
    if M.C is not None:
        M.C = M.C[chosen]
    report["decimated_from_faces"] = m
    report["decimated_to_faces"] = int(len(T))
    messages.append(f"decimated from {m} to {len(T)} faces (fast_simplification)")
    return True


def _close_holes(M: _Mesh, loops: list, report: dict, messages: list) -> list:
    """Fan every loop but ``loops[0]`` to a new vertex at the mean of its vertices.

    Holes are closed in the order of their smallest vertex index; each fan starts at the hole's
    first boundary half-edge in face order (this reproduces the ICT ``*_disk`` files exactly).
    """
    holes = sorted(loops[1:], key=lambda lp: int(lp.min()))
    be = topo.boundary_edges(M.F)
    pos = np.full(M.n, len(be), dtype=np.int64)
    pos[be[:, 0]] = np.arange(len(be))                  # face-order rank of each boundary tail
    closed = []
    new_faces = []
    for lp in holes:
        lp = np.roll(lp, -int(np.argmin(pos[lp])))
        Cc = M.C[lp].mean(axis=0)[None] if M.C is not None else None
        c = int(M.append_vertices(M.V[lp].mean(axis=0)[None], Cc)[0])
        new_faces.append(np.stack([np.roll(lp, -1), lp, np.full(len(lp), c)], axis=1))
        closed.append({"centre_vertex": c, "loop": lp.tolist()})
    M.F = np.vstack([M.F] + new_faces)
    k = len(holes)
    report["holes_closed"] = k
    messages.append(
        f"closed {_plural(k, 'hole')} (boundary loops of {', '.join(str(len(h)) for h in holes)} "
        f"vertices) with a fan to a new centre vertex each"
    )
    return closed


def _split_leaves(M: _Mesh, name: str) -> tuple[int, int]:
    """Split the longest interior edge of every leaf face (and its neighbour) at the midpoint.

    Returns ``(leaf_faces_found, vertices_added)``. Python loops run over leaf faces only.
    """
    is_b = topo.boundary_vertices_mask(M.F, M.n)
    found = len(topo.leaf_faces(M.F, is_b))
    added = 0
    while True:
        F = M.F
        leaves = topo.leaf_faces(F, is_b)
        if len(leaves) == 0:
            break
        twin = topo.interior_edge_twins(F)
        used = np.zeros(len(F), bool)
        splits = []                                        # (half-edge, twin)
        for t in leaves.tolist():
            if used[t]:
                continue
            hs = [3 * t + c for c in range(3) if twin[3 * t + c] >= 0]
            if not hs:
                raise UserError(
                    f"mesh '{name}' is a single isolated triangle (all three edges on the "
                    f"boundary); pass a mesh with interior vertices"
                )
            P = M.V[F[t]]
            l2 = ((P[[1, 2, 0]] - P) ** 2).sum(1)
            hs = [h for h in sorted(hs, key=lambda h: -l2[h % 3]) if not used[twin[h] // 3]]
            if not hs:
                continue                                   # neighbours busy: next round
            h = hs[0]
            used[[t, twin[h] // 3]] = True
            splits.append((h, int(twin[h])))
        if not splits:  # pragma: no cover - every round splits at least the first free leaf
            raise RuntimeError("leaf splitting made no progress")
        added += _split_edges(M, np.asarray(splits, np.int64))
        is_b = np.r_[is_b, np.zeros(M.n - len(is_b), bool)]
    return found, added


def _split_edges(M: _Mesh, S: np.ndarray) -> int:
    """Split interior edges at their 3D midpoints, each with its two faces (two faces → four).

    ``S`` (k×2) holds a half-edge ``3·face + corner`` (corner → next corner) of each edge and
    its twin; no two rows may share a face. The midpoints (interior vertices) are appended.
    Returns k."""
    F = M.F
    t1, c1 = S[:, 0] // 3, S[:, 0] % 3
    t2, c2 = S[:, 1] // 3, S[:, 1] % 3
    u, w, x = F[t1, c1], F[t1, (c1 + 1) % 3], F[t1, (c1 + 2) % 3]
    y = F[t2, (c2 + 2) % 3]
    Cm = 0.5 * (M.C[u] + M.C[w]) if M.C is not None else None
    mid = M.append_vertices(0.5 * (M.V[u] + M.V[w]), Cm)
    F = F.copy()
    F[t1] = np.stack([u, mid, x], axis=1)
    F[t2] = np.stack([w, mid, y], axis=1)
    extra = np.vstack([np.stack([mid, w, x], axis=1), np.stack([mid, u, y], axis=1)])
    M.F = np.vstack([F, extra])
    return len(mid)


def _flap_vertices(F: np.ndarray, is_b: np.ndarray) -> np.ndarray:
    """Whether each vertex of ``F`` (m×3) is interior with only boundary neighbours (n,) bool,
    given which are on the boundary (``is_b``, n bool)."""
    return ~is_b & ~has_interior_neighbour(F, is_b)


def _split_flap_necks(M: _Mesh, among: np.ndarray) -> tuple[int, int]:
    """Split the *neck* of every flap: an interior vertex all of whose neighbours are boundary
    vertices has a star hanging on the rest of the disk by the link edges that are interior
    (chords, both ends on the boundary). A disk map with the boundary on the circle must put
    the star inside the circular segment cut off by such a chord, far too thin for its area,
    and an equiareal map then wraps the star twice around the vertex (angle sum 4π: every
    face positive, but the boundary image runs backwards and overlaps itself). Splitting each
    chord at its midpoint (with its two faces) gives the neck an interior vertex that the map
    can move inwards, as a leaf split does (:func:`_split_leaves`). Only the flaps among the
    first ``len(among)`` vertices where ``among`` (bool) is true are split: the input's own
    flaps, not the leaf splits' midpoints (those the map lays out inside their leaf).

    Returns ``(flap_vertices, vertices_added)``; ``(0, 0)`` leaves ``M`` untouched."""
    if not among.any():
        return 0, 0
    F = M.F
    flap = _flap_vertices(F, topo.boundary_vertices_mask(F, M.n))
    flap[len(among):] = False
    flap[:len(among)] &= among
    if not flap.any():
        return 0, 0
    twin = topo.interior_edge_twins(F)
    h = (3 * np.arange(len(F))[:, None] + np.arange(3)).ravel()
    opposite = flap[F[:, [2, 0, 1]]].ravel()               # the corner opposite each half-edge
    h = h[opposite & (twin >= 0)]                          # interior edges facing a flap vertex
    h = np.where(twin[h] < h, twin[h], h)                  # one half-edge per edge
    h = np.unique(h)
    if len(h) == 0:
        return 0, 0                                        # the star is the whole disk
    added = _split_edges(M, np.column_stack([h, twin[h]]))
    return int(np.count_nonzero(flap)), added


def _check_genus(M: _Mesh, loops: int, name: str) -> None:
    """A one-line :class:`UserError` naming the genus when the (connected, manifold, oriented)
    mesh has handles: a closed one maps to the sphere only at genus 0, an open one to the disk."""
    g = genus_of(M.F, loops, M.n)
    if g <= 0:
        return
    chi = topo.euler_characteristic(M.F, M.n)
    if loops == 0:
        raise UserError(
            f"mesh '{name}' is closed with genus {g} (Euler characteristic {chi}); only genus-0 "
            f"closed meshes map to the sphere: cut its handles open or pass a genus-0 mesh"
        )
    raise UserError(
        f"mesh '{name}' has genus {g} (Euler characteristic {chi} with "
        f"{_plural(loops, 'boundary loop')}); cut its handles open to get a disk"
    )


def _orient_outward(M: _Mesh, report: dict, messages: list) -> None:
    """Reverse every face of a consistently oriented closed surface whose enclosed signed volume
    ``Σ det[v0, v1, v2] / 6`` is negative (faces pointing inward), so that its spherical map is
    positively oriented (:mod:`.sphere`)."""
    from .sphere import signed_volume

    vol = signed_volume(M.V, M.F)
    if vol >= 0:
        return
    M.F = np.ascontiguousarray(M.F[:, [0, 2, 1]])
    report["faces_flipped_outward"] = int(len(M.F))
    messages.append(f"reversed all {_plural(len(M.F), 'face')} of the closed surface so that "
                    f"they face outward (its enclosed signed volume was {vol:.4g})")


def _ensure(ok, what: str) -> None:
    if not ok:  # pragma: no cover - a bug in this module, not the user's input
        raise RuntimeError(f"mesh repair bug: {what}")


def _final_checks(M: _Mesh, changed_topology: bool, closed: bool) -> np.ndarray:
    """Check the invariants of a disk, or of a closed genus-0 surface (a failure is a bug
    here); returns the boundary loop (empty for a closed surface).

    Bowtie vertices were split by the cleaning step and neither hole fans nor edge splits can
    create one, so that (costlier) test is repeated only when vertices were added or split.
    """
    F, n = M.F, M.n
    _ensure(topo.connected_components(F, n)[0] == 1, "several components left")
    _ensure(len(topo.nonmanifold_edges(F)) == 0, "non-manifold edges left")
    if changed_topology:
        _ensure(len(topo.nonmanifold_vertices(F, n)) == 0, "non-manifold vertices left")
    a, b = topo.half_edges(F)
    twin = topo.interior_edge_twins(F)
    inner = twin >= 0
    _ensure(np.array_equal(a[inner], b[twin[inner]]), "inconsistent orientation left")
    _ensure(np.all(np.bincount(F.ravel(), minlength=n) > 0), "unreferenced vertices left")
    if closed:
        from .sphere import signed_volume

        _ensure(inner.all(), "boundary edges left on a closed surface")
        _ensure(topo.euler_characteristic(F, n) == 2, "Euler characteristic is not 2")
        _ensure(signed_volume(M.V, F) > 0, "faces not outward")
        return np.zeros(0, np.int64)
    loops = topo.boundary_loops(F, M.V)
    _ensure(len(loops) == 1, f"{len(loops)} boundary loops left")
    _ensure(topo.euler_characteristic(F, n) == 1, "Euler characteristic is not 1")
    is_b = np.zeros(n, bool)
    is_b[loops[0]] = True
    _ensure(len(topo.leaf_faces(F, is_b)) == 0, "leaf faces left")
    _ensure(np.all(has_interior_neighbour(F, is_b)[loops[0]]),
            "a boundary vertex has no interior neighbour")
    return loops[0]


# --------------------------------------------------------------------------------------------


def repair_mesh(V, faces, colors=None, options: RepairOptions | None = None,
                name: str = "mesh") -> RepairedMesh:
    """Repair ``(V, faces)`` into one consistently oriented disk without leaf faces, or one
    outward closed genus-0 surface.

    ``faces`` is an m×3 (or m×k) int array or a list of polygons. See the module docstring for
    the steps, their order and the ``report`` keys. Raises :class:`UserError` for everything that
    cannot be (or may not be, per ``options``) repaired.
    """
    with topo.kept_edge_groups():        # the checks below group one mesh's edges many times
        return _repair_mesh(V, faces, colors, options, name)


def _repair_mesh(V, faces, colors, options: RepairOptions | None, name: str) -> RepairedMesh:
    """:func:`repair_mesh`'s steps."""
    opts = options if options is not None else RepairOptions()
    report: dict = {
        "input_vertices": 0, "input_faces": 0,
        "non_triangle_faces_triangulated": 0, "invalid_faces_removed": 0,
        "degenerate_faces_removed": 0, "vertices_welded": 0, "weld_skipped_vertices": 0,
        "duplicate_faces_removed": 0,
        "unreferenced_vertices_removed": 0, "components_found": 0, "components_dropped": 0,
        "component_faces_dropped": 0, "nonmanifold_edge_faces_removed": 0,
        "nonmanifold_vertices_split": 0, "faces_reoriented": 0, "zero_area_faces_flipped": 0,
        "zero_area_faces_removed": 0, "decimated_from_faces": None, "decimated_to_faces": None,
        "boundary_loops_found": 0, "closed": False, "genus": 0, "faces_flipped_outward": 0,
        "holes_closed": 0, "flap_necks_split": 0, "leaf_faces_split": 0,
        "leaf_split_vertices_added": 0, "output_vertices": 0, "output_faces": 0,
        "boundary_vertices": 0,
    }
    messages: list[str] = []

    # 1. validate -----------------------------------------------------------------------------
    V = np.array(V, dtype=np.float64, copy=True)
    if V.ndim != 2 or V.shape[0] == 0:
        raise UserError(f"mesh '{name}' has no vertices; pass a non-empty mesh")
    if V.shape[1] != 3:
        raise UserError(f"mesh '{name}' has {V.shape[1]}-D vertices; pass 3-D coordinates (n×3)")
    finite = np.isfinite(V).all(axis=1)
    if not finite.all():
        raise UserError(
            f"mesh '{name}' has {_plural(int((~finite).sum()), 'vertex')} with NaN/inf "
            f"coordinates (e.g. vertex {int(np.argmin(finite))}); fix or remove them"
        )
    refuse_huge_coordinates(V, f"mesh '{name}'")
    n0 = len(V)
    C = None
    if colors is not None:
        C = np.array(colors, dtype=np.float64, copy=True)
        if C.ndim != 2 or C.shape[0] != n0 or C.shape[1] not in (3, 4) or not np.isfinite(C).all():
            raise UserError(
                f"mesh '{name}': vertex colours must be finite {n0}×3 or {n0}×4; fix or drop them"
            )
    if faces is None or len(faces) == 0:
        raise UserError(f"mesh '{name}' has no faces; pass a surface mesh, not a point cloud")
    report["input_vertices"] = n0
    report["input_faces"] = int(len(faces))

    # 2. triangulate --------------------------------------------------------------------------
    F, non_tri, invalid = triangulate_polygons(faces, n0, name)
    if non_tri:
        report["non_triangle_faces_triangulated"] = non_tri
        messages.append(f"fan-triangulated {_plural(non_tri, 'non-triangle face')}")
    if invalid:
        report["invalid_faces_removed"] = invalid
        messages.append(f"removed {_plural(invalid, 'face')} with fewer than 3 vertices")
    if len(F) == 0:
        raise UserError(f"mesh '{name}' has no valid faces; pass a surface mesh")
    M = _Mesh(V, np.array(F, dtype=np.int64, copy=True), C, np.arange(n0, dtype=np.int64))

    # 3. degenerate faces ---------------------------------------------------------------------
    deg = _degenerate_mask(M.F)
    if deg.any():
        M.F = M.F[~deg]
        k = int(deg.sum())
        report["degenerate_faces_removed"] = k
        messages.append(f"removed {_plural(k, 'degenerate face')} (repeated vertex)")
        if len(M.F) == 0:
            raise UserError(f"mesh '{name}' has only degenerate faces; pass a surface mesh")

    # 4. weld ---------------------------------------------------------------------------------
    welded = 0
    if opts.weld:
        used = np.zeros(M.n, bool)
        used[M.F.ravel()] = True
        diag = float(np.linalg.norm(M.V[used].max(0) - M.V[used].min(0)))
        rep = weld_map(M.V, opts.weld_tolerance * diag, active=used)
        moved = int(np.count_nonzero(rep != np.arange(M.n)))
        if moved:
            Fw = rep[M.F]
            Fw = Fw[~_degenerate_mask(Fw)]
            Fw = Fw[~_duplicate_mask(Fw)]
            Fu = M.F[~_duplicate_mask(M.F)]
            # Coincident vertices can be an intentional cut (a seam that opens a closed surface
            # into a disk). Keep them apart when welding would break an otherwise fine mesh.
            hurt = disk_blockers(Fw, M.n) if len(Fw) else ["no faces"]
            if hurt and not disk_blockers(Fu, M.n):
                report["weld_skipped_vertices"] = moved
                messages.append(
                    f"kept {_plural(moved, 'coincident vertex')} unwelded: they form a cut seam "
                    f"(welding would leave {' and '.join(hurt)})"
                )
            else:
                welded = moved
                M.F = rep[M.F]
                report["vertices_welded"] = welded
                messages.append(
                    f"welded {_plural(welded, 'duplicated vertex')} (within "
                    f"{opts.weld_tolerance:g} × bounding-box diagonal)"
                )

    # 5–10. duplicates, components, unreferenced, manifold, orientation, zero-area -------------
    _clean(M, opts, report, messages, name, when="", welded=welded)

    # 11. decimation --------------------------------------------------------------------------
    if opts.decimate_to_faces is not None:
        # handles are the input's, not the decimation's: named before it is tried (a
        # decimation is kept only if it leaves a genus-0 mesh)
        _check_genus(M, count_boundary_loops(M.F), name)
        if _decimate(M, opts.decimate_to_faces, report, messages, name):
            _clean(M, opts, report, messages, name, when=" after decimation")

    # 12. boundary, genus, holes --------------------------------------------------------------
    loops = topo.boundary_loops(M.F, M.V)
    report["boundary_loops_found"] = len(loops)
    _check_genus(M, len(loops), name)
    report["closed"] = not loops
    closed_holes: list = []
    if not loops:
        _orient_outward(M, report, messages)
    elif len(loops) > 1:
        if not opts.close_holes:
            raise UserError(
                f"mesh '{name}' has {len(loops)} boundary loops; set repair.close_holes: true "
                f"(CLI: --close-holes; closes all but the longest) or pass a mesh with one boundary"
            )
        closed_holes = _close_holes(M, loops, report, messages)

    # 13. leaf faces, then flap necks (none on a closed surface) ------------------------------
    is_b = topo.boundary_vertices_mask(M.F, M.n)
    flaps_found = _flap_vertices(M.F, is_b) if loops else np.zeros(M.n, bool)
    n_leaves = len(topo.leaf_faces(M.F, is_b)) if loops else 0
    if n_leaves:
        if not opts.split_leaf_faces:
            raise UserError(
                f"mesh '{name}' has {_plural(n_leaves, 'leaf face')} (all three vertices on the "
                f"boundary); set repair.split_leaf_faces: true or remesh the boundary"
            )
        found, added = _split_leaves(M, name)
        report["leaf_faces_split"] = found
        report["leaf_split_vertices_added"] = added
        messages.append(
            f"split {_plural(found, 'leaf face')} (all corners on the boundary) by inserting "
            f"{_plural(added, 'edge midpoint')}"
        )
    if loops:
        flaps, added = _split_flap_necks(M, flaps_found)
        report["flap_necks_split"] = added
        if added:
            messages.append(
                f"split the {_plural(added, 'neck edge')} of {_plural(flaps, 'flap')} (an "
                f"interior vertex with only boundary neighbours) at the midpoint"
            )

    # 14. final invariants --------------------------------------------------------------------
    edited = bool(np.any(M.src < 0)) or bool(report["nonmanifold_vertices_split"]) \
        or bool(report["zero_area_faces_flipped"]) \
        or bool(report["zero_area_faces_removed"])
    boundary = _final_checks(M, changed_topology=edited, closed=not loops)
    report["output_vertices"] = M.n
    report["output_faces"] = int(len(M.F))
    report["boundary_vertices"] = int(len(boundary))
    return RepairedMesh(
        V=M.V, F=M.F, colors=M.C, source_index=M.src, boundary=boundary,
        added_vertices=np.flatnonzero(M.src < 0), closed_holes=closed_holes,
        report=report, messages=messages,
    )
