"""The remesh follows the input: a vertex on each input point it has drifted too far from.

The sag tests (:mod:`.sag`) look at the remesh's edges from the remesh's side: how far a
straight edge leaves the surface under it. They do not see the input's own thin features —
a crease or a fold narrower than the target length (a nostril's rim, a sulcus' lip, a lip's
corner) — that the remesh cuts across between two vertices on either side: there the remesh
is close to the surface everywhere along its edges, but a point of the input on the crease is
far from it, and the input-to-remesh Hausdorff distance is decided at such points. Where the
input's triangles are larger than the remesh's (a coarse scan remeshed finely), that point is
often not an input vertex but the middle of an input edge or face at the bottom of a fold.
:func:`follow_input` finds the input points — interior vertices, midpoints of interior edges
and centroids of faces (:func:`input_points`) — farther from the remesh than a
tolerance (exact point–triangle distances, :class:`..remesh_quality.MeshDistance`, for the
points a vertex's distance does not already bound) and moves the nearest free remesh vertex
exactly onto each (or inserts one there), locked (:func:`.corners.snap_vertices`), farthest
first, no two closer than a gap on the surface. Each such point lies on the input surface, and
the map is linear on an input face, so its disk position is the same average of its corners'.
A snap next to a feature narrower than the remesh's edges (a spike, a sulcus) tilts the faces
around it over the surface; those that leave an edge farther than the sag tolerance from the
surface are undone (:func:`undo_sagging_snaps`). The counts go to the state's log as
``followed_snapped``, ``followed_inserted``, ``followed_too_close`` and
``follow_snaps_undone``, apart from the corners'.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..locate import lift
from ..metrics import corner_angles
from ..remesh_quality import (MeshDistance, MiddleOffsets, bound_slack,
                              candidate_face_distances, closest_points_on_triangles, face_bounds,
                              face_centroids, largest_distance, may_reach, middle_bounds,
                              middle_offsets)
from ..rows import norms, row_min
from .corners import nearest_rows, snap_vertices
from .domain import locate_once, project
from .halfedge import DISK_SHAPE_MIN, disk_shape, double_areas, edge_table, touching, vertex_faces
from .refine import SAG_TS
from .sag import edge_sag_along, lift_samples
from .state import RemeshState, turned_against


class InputPoints(NamedTuple):
    """The input points the remesh follows (:func:`input_points`): ``P`` (k×3) and their
    domain positions ``P_uv`` (k×2 or k×3), the ``vertices`` first, then the midpoints of the
    ``edges`` (e×2), then the centroids of the ``faces`` (f×3) — input vertex indices — and
    the midpoints' and centroids' ``offsets`` from their corners
    (:func:`..remesh_quality.middle_offsets`, for their distances' Lipschitz bounds)."""

    P: np.ndarray
    P_uv: np.ndarray
    vertices: np.ndarray
    edges: np.ndarray
    faces: np.ndarray
    offsets: MiddleOffsets


def input_points(S: RemeshState) -> InputPoints:
    """The input's interior vertices, the midpoints of its interior edges and the centroids of
    its faces, on the surface and in the map's domain (there the same averages of the
    corners' ``uv_in``; on the sphere put back on it, :func:`.domain.project`). Only the rim's
    own points are left out (:mod:`.rim` follows the boundary): the edges and faces at the rim
    are in, where a coarse input's farthest point can be (igl_camel_b at 20k vertices: the
    middle of an interior edge between two rim vertices)."""
    _, a, b, twin = edge_table(S.F_in)
    is_rim = np.zeros(len(S.V_in), bool)          # the ends of the edges with one face
    is_rim[a[twin < 0]] = is_rim[b[twin < 0]] = True
    a, b = a[twin >= 0], b[twin >= 0]
    v = np.flatnonzero(~is_rim)
    edges = np.column_stack([a, b])
    offsets = middle_offsets(S.V_in, S.F_in, edges)

    def points(Y, centroids):
        return np.concatenate([Y.take(v, axis=0), (Y.take(a, axis=0) + Y.take(b, axis=0)) / 2,
                               centroids])

    return InputPoints(points(S.V_in, offsets.centroids),
                       project(points(S.uv_in, face_centroids(S.uv_in, S.F_in))), v, edges,
                       S.F_in, offsets)


def far_input_points(S: RemeshState, tol: float, memo: FarMemo | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The input points of :func:`input_points` (made once per state,
    :meth:`.state.RemeshState.of_input`) farther than ``tol`` from the remesh ``(S.X, S.F)``,
    farthest first (:func:`input_point_bounds`: only the points its bounds leave are
    measured). Given a ``memo`` of an earlier call (:class:`FarMemo`), only the points whose
    bound from then may reach ``tol`` or no longer holds are measured.

    Parameters
    ----------
    S : RemeshState
    tol : float
        In the mesh's units.
    memo : FarMemo, optional
        Updated in place.

    Returns
    -------
    P_uv : (j, 2) or (j, 3) float
        Their domain positions.
    distance : (j,) float
        In the mesh's units.
    """
    pts = S.of_input(input_points)
    d = searched_bounds(S, pts, tol, MeshDistance(S.X, S.F), memo)[0]
    far = np.flatnonzero(d > tol)
    far = far[np.argsort(-d[far], kind="stable")]
    return pts.P_uv[far], d[far]


#: a search with a memo whose faces are fewer than this share of the remesh's searches afresh
MEMO_MIN_CARRIED = 0.5


def searched_bounds(S: RemeshState, pts: InputPoints, tol: float, measure: MeshDistance,
                    memo: FarMemo | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distances of the input points ``pts`` to the remesh where they may exceed ``tol``
    and upper bounds of them elsewhere, as :func:`input_point_bounds` finds them or, given a
    ``memo`` (:class:`FarMemo`, updated in place) that at least ``MEMO_MIN_CARRIED`` of the
    remesh's faces are still in, from its bounds: those whose faces are gone bounded again
    (:func:`rebound`), those that may reach ``tol`` measured.

    Returns
    -------
    distance : (k,) float
        The memo's own array where there is one (not to be changed).
    measured : (k,) bool
    face : (n,) int
        Per input vertex, a remesh face at its distance (any face on the rim).
    """
    keys = S.X.take(S.F, axis=0).reshape(-1, 9)
    carried = None if memo is None or memo.keys is None else carried_faces(memo.keys, keys)
    if carried is None or np.count_nonzero(carried >= 0) < MEMO_MIN_CARRIED * len(keys):
        bounds = input_point_bounds(S, pts, tol, measure)
        if memo is not None:
            memo.keys, memo.bound, memo.witness = keys, bounds.distance, bound_witnesses(
                pts, bounds)
        return bounds.distance, bounds.measured, bounds.vertex_face
    d, W = carried_bounds(memo, carried)
    rebound(S, pts, d, W, measure)
    ask = np.flatnonzero(may_reach(d, tol, S.of_input(input_slack)))
    d[ask], W[ask, 0] = measure(pts.P[ask])
    W[ask, 1:] = -1
    memo.keys, memo.bound, memo.witness = keys, d, W
    measured = np.zeros(len(d), bool)
    measured[ask] = True
    f_vertex = np.zeros(len(S.V_in), np.int64)
    f_vertex[pts.vertices] = W[:len(pts.vertices), 0]
    return d, measured, f_vertex


@dataclass
class FarMemo:
    """What :func:`far_input_points` keeps between its calls on one remesh as it changes (the
    follow step's rounds): the remesh faces' corner coordinates ``keys`` (m×9) then, and per
    input point an upper bound ``bound`` (k,) of its distance that holds while its
    ``witness`` faces (k×3, numbered then, −1 for none) are all still faces of the remesh —
    the distance to the nearest of them, or a corner's distance to one plus the way to it
    (:func:`bound_witnesses`); a face with the same corners at the same coordinates in the
    same order is the same face (:func:`carried_faces`), at the same distance from each
    point."""

    keys: np.ndarray | None = None
    bound: np.ndarray | None = None
    witness: np.ndarray | None = None


def bound_witnesses(pts: InputPoints, bounds: PointBounds) -> np.ndarray:
    """The faces through which each bound of ``bounds`` holds (:class:`FarMemo`): a measured
    point's closest face; for the others a vertex's face and a midpoint's or centroid's
    corners' faces (its bound is their distance or a corner's distance plus the way to the
    corner, :func:`..remesh_quality.middle_bounds`); (k, 3) int, −1 for none."""
    nv, ne = len(pts.vertices), len(pts.edges)
    f = bounds.vertex_face
    W = np.full((len(pts.P), 3), -1, np.int64)
    W[:nv, 0] = f[pts.vertices]
    W[nv:nv + ne, :2] = f[pts.edges]
    W[nv + ne:] = f[pts.faces]
    W[bounds.measured] = -1
    W[bounds.measured, 0] = bounds.closest[bounds.measured]
    return W


def rebound(S: RemeshState, pts: InputPoints, d: np.ndarray, W: np.ndarray,
            measure: MeshDistance) -> None:
    """New bounds ``d`` (k,) and witnesses ``W`` (k×3) of :class:`FarMemo` for the points
    without a witness left (``W[:, 0] < 0``), in place: such a vertex measured (its closest
    face) or, where :func:`vertex_distances` bounds the vertices, bounded through the remesh
    face over it on the domain, such a midpoint or centroid bounded by its distance to its
    corners' witnesses (:func:`middle_face_bounds`; a rim corner's: any face)."""
    nv, ne = len(pts.vertices), len(pts.edges)
    lost = np.flatnonzero(W[:nv, 0] < 0)
    if nv < VERTICES_PER_FACE_TO_BOUND * len(S.F):
        d[lost], W[lost, 0] = measure(pts.P[lost])
    else:
        W[lost, 0] = locate_once(S.uv, S.F, pts.P_uv[lost])
        d[lost] = candidate_face_distances(pts.P[lost], W[lost, :1], measure)
    f_vertex = np.zeros(len(S.V_in), np.int64)
    f_vertex[pts.vertices] = W[:nv, 0]
    lost = nv + np.flatnonzero(W[nv:, 0] < 0)
    d[lost] = middle_face_bounds(pts, lost, f_vertex, measure)
    mid, cent = lost[lost < nv + ne], lost[lost >= nv + ne]
    W[mid, :2] = f_vertex[pts.edges[mid - nv]]
    W[cent] = f_vertex[pts.faces[cent - nv - ne]]


def carried_bounds(memo: FarMemo, carried: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of ``memo`` (a copy, k) and their witnesses renumbered by ``carried``
    (:func:`carried_faces` of its faces, m₀): a point any of whose witnesses is gone has
    none left (a row of −1; its bound no longer holds)."""
    carried = np.append(carried, -1)                              # W = −1 reads the −1
    renumbered = carried[memo.witness]
    kept = (renumbered >= 0) | (memo.witness < 0)
    renumbered[~(kept[:, 0] & kept[:, 1] & kept[:, 2])] = -1
    return memo.bound.copy(), renumbered


def carried_faces(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """For each face whose corner coordinates are a row of ``old`` (m₀×9), the face of
    ``new`` (m×9) with the very same row, or −1 (matched by a hash of the rows' bits, each
    match checked row for row).

    Returns
    -------
    (m₀,) int
    """
    out = np.full(len(old), -1, np.int64)
    if len(old) == 0 or len(new) == 0:
        return out

    def hashes(K):
        bits = np.ascontiguousarray(K).view(np.uint64)
        h = bits[:, 0] * _ROW_HASH[0]
        for j in range(1, 9):
            h += bits[:, j] * _ROW_HASH[j]
        return h

    h_new, h_old = hashes(new), hashes(old)
    o_new, o_old = np.argsort(h_new), np.argsort(h_old)
    at = np.minimum(np.searchsorted(h_new[o_new], h_old[o_old]), len(new) - 1)
    match = o_new[at]
    same = h_new[match] == h_old[o_old]
    A, B = new.take(match, axis=0), old.take(o_old, axis=0)   # (take: no fancy index)
    for j in range(A.shape[1]):                 # the rows equal, compared column by column
        same &= A[:, j] == B[:, j]
    out[o_old[same]] = match[same]
    return out


#: the multipliers of :func:`carried_faces`' row hash (odd, fixed)
_ROW_HASH = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                      0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53,
                      0x94D049BB133111EB, 0xBF58476D1CE4E5B9, 0x2545F4914F6CDD1D], np.uint64)


class PointBounds(NamedTuple):
    """What :func:`input_point_bounds` found for the ``k`` input points of
    :func:`input_points`: their ``distance`` (k,) to the remesh, exact where ``measured``
    (k,) and an upper bound elsewhere; per input vertex (n,), the remesh face
    ``vertex_face`` at its distance (any face on the rim); and per point the ``closest``
    (k,) remesh face where measured (−1 elsewhere)."""

    distance: np.ndarray
    measured: np.ndarray
    vertex_face: np.ndarray
    closest: np.ndarray


def input_point_bounds(S: RemeshState, pts: InputPoints, tol: float, measure: MeshDistance
                       ) -> PointBounds:
    """The distances of the input points ``pts`` (:func:`input_points`) to the remesh
    ``(S.X, S.F)`` where they may exceed ``tol``, upper bounds of them (at most ``tol``)
    elsewhere.

    The vertices are measured first (:func:`vertex_distances`); a midpoint or centroid is
    measured only if neither its corners' distances (:func:`..remesh_quality.middle_bounds`)
    nor its distance to the faces closest to its corners
    (:func:`..remesh_quality.face_bounds`) already bound it within ``tol``.

    Parameters
    ----------
    S : RemeshState
    pts : InputPoints
    tol : float
        In the mesh's units.
    measure : MeshDistance
        Of ``(S.X, S.F)``.

    Returns
    -------
    PointBounds
    """
    nv = len(pts.vertices)
    d_vertex = np.full(len(S.V_in), np.inf)
    f_vertex = np.zeros(len(S.V_in), np.int64)          # a rim vertex's: any face bounds
    measured = np.zeros(len(pts.P), bool)
    closest = np.full(len(pts.P), -1, np.int64)
    d_vertex[pts.vertices], f_vertex[pts.vertices], measured[:nv] = vertex_distances(
        S, pts, tol, measure)
    closest[:nv][measured[:nv]] = f_vertex[pts.vertices][measured[:nv]]
    mid_bound, _, centroid_bound = middle_bounds(S.V_in, pts.faces, pts.edges, d_vertex,
                                                 pts.offsets)
    d = np.concatenate([d_vertex[pts.vertices], mid_bound, centroid_bound])
    ask = nv + np.flatnonzero(d[nv:] > tol)
    d[ask] = middle_face_bounds(pts, ask, f_vertex, measure)
    ask = ask[d[ask] > tol]
    d[ask], closest[ask] = measure(pts.P[ask])
    measured[ask] = True
    return PointBounds(d, measured, f_vertex, closest)


def middle_face_bounds(pts: InputPoints, ask: np.ndarray, f_vertex: np.ndarray,
                       measure: MeshDistance) -> np.ndarray:
    """The distances of the midpoints and centroids ``ask`` (j,) (indices into ``pts``, past
    its vertices) to the faces of ``measure``'s surface closest to their corners
    (:func:`..remesh_quality.face_bounds`; ``f_vertex`` (n,) per input vertex): upper bounds
    of their distances (j,)."""
    nv, ne = len(pts.vertices), len(pts.edges)
    mid = ask < nv + ne
    out = np.empty(len(ask))
    at_mid, at_face = ask[mid], ask[~mid]
    out[mid] = face_bounds(pts.P.take(at_mid, axis=0), pts.edges.take(at_mid - nv, axis=0),
                           f_vertex, measure)
    out[~mid] = face_bounds(pts.P.take(at_face, axis=0),
                            pts.faces.take(at_face - nv - ne, axis=0), f_vertex, measure)
    return out


class InputBeyond(NamedTuple):
    """What :func:`input_beyond` found: the domain positions ``P_uv`` (j×2 or j×3) and
    ``distances`` (j,) of the input points farther than its ``beyond`` from the remesh,
    farthest first, and ``next``, the largest distance of the others that are farther than
    its ``tol`` (``tol`` where none is)."""

    P_uv: np.ndarray
    distances: np.ndarray
    next: float


def input_beyond(S: RemeshState, tol: float, beyond: float, memo: FarMemo | None = None
                 ) -> InputBeyond:
    """The input points of :func:`far_input_points` (farther than ``tol``) that are farther
    than ``beyond`` from the remesh, farthest first, and the distance of the farthest of the
    others, as :func:`far_input_points` would give them, with fewer points measured: the
    bounds leave only the points that may be farther than ``max(tol, beyond)``
    (:func:`input_point_bounds`); of the others, only those whose bound exceeds the largest
    distance below that found so far are bounded again through their corners' faces and then
    measured, the largest bounds first (:func:`..remesh_quality.largest_distance`). Given a
    ``memo``, the bounds start from it (:func:`searched_bounds`).

    Parameters
    ----------
    S : RemeshState
    tol, beyond : float
        In the mesh's units.
    memo : FarMemo, optional
        Updated in place.

    Returns
    -------
    InputBeyond
    """
    pts = S.of_input(input_points)
    measure = MeshDistance(S.X, S.F)
    top = max(tol, beyond)
    d, measured, f_vertex = searched_bounds(S, pts, top, measure, memo)
    d = d.copy()
    far = np.flatnonzero(d > top)
    far = far[np.argsort(-d[far], kind="stable")]
    nearer = float(tol)
    if top > tol:
        nearer = float(d[measured & (d > tol) & (d <= top)].max(initial=tol))
        ask = np.flatnonzero(~measured & (d > nearer))
        middle = ask[ask >= len(pts.vertices)]
        d[middle] = np.minimum(d[middle], middle_face_bounds(pts, middle, f_vertex, measure))
        ask = ask[d[ask] > nearer]
        if len(ask):
            nearer = max(nearer, largest_distance(pts.P[ask], d[ask], measure,
                                                  S.of_input(input_slack)))
    return InputBeyond(pts.P_uv[far], d[far], nearer)


def input_reach(S: RemeshState, tol: float) -> float:
    """The distance of the input point farthest from the remesh (:func:`far_input_points`),
    or ``tol`` where none is farther than that: the input-to-remesh distance an operation may
    leave at one more place without raising the largest."""
    d = far_input_points(S, tol)[1]
    return float(d[0]) if len(d) else float(tol)


#: from this many input vertices per remesh face, :func:`vertex_distances` bounds them
#: through the remesh face over each on the domain before measuring any
VERTICES_PER_FACE_TO_BOUND = 4.0


def vertex_distances(S: RemeshState, pts: InputPoints, tol: float, measure: MeshDistance
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distances of the input vertices of ``pts`` to the remesh ``(S.X, S.F)`` where they
    may exceed ``tol``, and upper bounds of them elsewhere; a face of the remesh at that
    distance from each.

    Where the input has at least ``VERTICES_PER_FACE_TO_BOUND`` vertices per remesh face (a
    fine input remeshed coarsely), each vertex is first bounded by its exact distance to the
    remesh face over it on the domain (a point location in the remesh's own triangulation,
    :func:`.domain.locate_once`); only the vertices whose bound may reach ``tol``
    (:func:`..remesh_quality.may_reach`) are measured (``measure``). A bound at most ``tol``
    leaves the vertex, and every midpoint or centroid bounded through it, no farther than
    ``tol``, as its distance would.

    Parameters
    ----------
    S : RemeshState
    pts : InputPoints
    tol : float
    measure : MeshDistance
        Of ``(S.X, S.F)``.

    Returns
    -------
    distance : (v,) float
    face : (v,) int
    measured : (v,) bool
        Where ``distance`` is exact.
    """
    nv = len(pts.vertices)
    if nv < VERTICES_PER_FACE_TO_BOUND * len(S.F):
        return *measure(pts.P[:nv]), np.ones(nv, bool)
    face = locate_once(S.uv, S.F, pts.P_uv[:nv])
    d = candidate_face_distances(pts.P[:nv], face[:, None], measure)
    ask = np.flatnonzero(may_reach(d, tol, S.of_input(input_slack)))
    d[ask], face[ask] = measure(pts.P[ask])
    measured = np.zeros(nv, bool)
    measured[ask] = True
    return d, face, measured


def follow_input(S: RemeshState, tol: float, min_gap: float, max_sag: float | None = None,
                 memo: FarMemo | None = None) -> np.ndarray:
    """Snap (or insert) a locked remesh vertex onto every input point of
    :func:`far_input_points` (farther than ``tol`` from the remesh), farthest first, none
    within ``min_gap`` on the surface of one snapped before or of a locked vertex
    (:func:`.corners.snap_vertices`); given ``max_sag``, the snaps that leave an edge farther
    than that from the surface are undone (:func:`undo_sagging_snaps`).

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    tol, min_gap : float
        In the mesh's units.
    max_sag : float, optional
        In the mesh's units.
    memo : FarMemo, optional
        Of the calls before on this remesh (:func:`far_input_points`).

    Returns
    -------
    (j,) int
        The snapped and inserted vertices that stay.
    """
    far, _ = far_input_points(S, tol, memo)
    S.tally("far_input_points", len(far))
    if len(far) == 0:
        return np.zeros(0, np.int64)
    n0 = S.n
    old = S.uv.copy(), S.face.copy(), S.bary.copy(), S.X.copy()
    v = snap_vertices(S, far, min_gap=min_gap, counts="followed")
    if max_sag is not None:
        undone = undo_sagging_snaps(S, v[v < n0], old, max_sag)
        v = np.setdiff1d(v, undone)
    return v


def undo_sagging_snaps(S: RemeshState, moved: np.ndarray, old: tuple, max_sag: float
                       ) -> np.ndarray:
    """Put back the snapped vertices ``moved`` with an edge farther than ``max_sag`` from the
    surface (:func:`.sag.edge_sag_along` at ``SAG_SAMPLES`` points), unlocked, where no face
    turns clockwise on the disk by it (a snap next to a narrow feature tilts its faces over
    the surface around it).

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    moved : (k,) int
    old : tuple of (n₀, 2), (n₀,), (n₀, 3), (n₀, 3) arrays
        ``uv``, ``face``, ``bary`` and ``X`` of the first ``n₀`` vertices before the snaps.
    max_sag : float
        In the mesh's units.

    Returns
    -------
    (j,) int
        The vertices put back.
    """
    if len(moved) == 0:
        return moved
    is_moved = np.zeros(S.n, bool)
    is_moved[moved] = True
    _, a, b, _ = edge_table(S.F, twin=S.twins())
    e = np.flatnonzero(is_moved[a] | is_moved[b])
    sag, _ = edge_sag_along(S, a[e], b[e], SAG_TS)
    back = np.zeros(S.n, bool)
    far = e[sag > max_sag]
    back[a[far]] = back[b[far]] = True
    back &= is_moved
    while back.any():                            # keep the snaps whose undoing folds a face
        uv = S.uv.copy()
        uv[back] = old[0][back[:len(old[0])]]
        faces = np.flatnonzero(touching(S.F, back))
        bad = faces[~(double_areas(uv, S.F[faces]) > 0)]
        if len(bad) == 0:
            break
        back[S.F[bad].ravel()] = False
    r = np.flatnonzero(back)
    S.uv[r], S.face[r], S.bary[r], S.X[r] = (x[r] for x in old)
    S.locked[r] = False
    S.tally("follow_snaps_undone", len(r))
    return r


class Settled(NamedTuple):
    """What :func:`settle_on_far_input` did: the ``vertices`` (j,) it moved onto input points
    and the input's ``reach`` left — the distance of the farthest input point it measured and
    neither took nor skipped next to one taken (the point it stopped at, or the first nearer
    than the remesh's own reach), or its tolerance: an estimate of the farthest distance of an
    input point from the remesh after the moves (:func:`far_input_points`) without another
    search; and the input points from the one it stopped at on that are farther than the
    remesh's own reach (:func:`remesh_reach`), farthest first: their domain positions
    ``left_uv`` (k×2 or k×3), their points ``left`` (k×3) on the surface and their
    ``distances`` (k,) as measured before the moves."""

    vertices: np.ndarray
    reach: float
    left_uv: np.ndarray
    left: np.ndarray
    distances: np.ndarray


def settle_on_far_input(S: RemeshState, tol: float, min_gap: float, floor_deg: float,
                        max_sag: float, fixed: np.ndarray | None = None,
                        candidates: int = 8, memo: FarMemo | None = None) -> Settled:
    """Put a remesh vertex exactly on each input point of :func:`far_input_points` (farther
    than ``tol`` from the remesh), farthest first, skipping those within ``min_gap`` on the
    surface of a vertex put before: the nearest on the surface of the ``candidates`` nearest
    movable vertices on the disk that can move there (:func:`move_keeps_shape`); only points
    farther than the remesh's own farthest edge middle from the input (:func:`remesh_reach`)
    are taken (:func:`input_beyond`). It stops at the first point no vertex can take: the
    Hausdorff distance is a maximum, and vertices on the nearer points after it cannot lower
    it (they would only cost triangle shape).

    Made after the minimum-angle pass, and again after the last smoothing: the follow step's
    snaps (:func:`follow_input`) are free again in the fold repairs and that pass, whose
    collapses take some back, and an input vertex less than the follow tolerance off (a cone
    point of a coarse input that a finer remesh spans with a flat fan) is not followed at all.
    The count goes to the state's log as ``settled_on_input``, the far points taken as
    ``far_input_points_late``.

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    tol, min_gap, max_sag : float
        In the mesh's units.
    floor_deg : float
        No face is left with a smallest angle below this and below what it had.
    fixed : (n,) bool, optional
        Vertices not to move, besides the rim's and the locked ones.
    candidates : int
    memo : FarMemo, optional
        Of the searches before on this remesh (:func:`input_beyond`).

    Returns
    -------
    Settled
        The vertices moved and the input's reach left.
    """
    far, d, nearer = input_beyond(S, tol, remesh_reach(S), memo)
    S.tally("far_input_points_late", len(far))
    movable = ~S.is_rim & ~S.locked
    if fixed is not None:
        movable &= ~fixed
    free = np.flatnonzero(movable)

    def settled(put: list, stop: int, P: np.ndarray) -> Settled:
        return Settled(np.asarray(put, np.int64), float(d[stop]) if stop < len(d) else nearer,
                       far[stop:], P[stop:], d[stop:])

    k = min(candidates, len(free))
    if len(far) == 0:
        return settled([], 0, np.zeros((0, 3)))
    f, b, _ = S.locator.locate_with_inside(far)
    P = lift(S.V_in, S.F_in, f, b)
    if k == 0:
        return settled([], 0, P)
    J = free[nearest_rows(S.uv[free], far, k)]
    floor = np.radians(floor_deg)
    put: list[int] = []
    VF = vertex_faces(S.F, S.n)
    for i in range(len(far)):
        if put and norms(S.X[put] - P[i]).min() < min_gap:
            continue
        cands = J[i][movable[J[i]]]
        cands = cands[np.argsort(norms(S.X[cands] - P[i]), kind="stable")]
        target = (far[i], f[i], b[i], P[i])
        v = next((v for v in cands.tolist()
                  if move_keeps_shape(S, v, VF.indices[VF.indptr[v]:VF.indptr[v + 1]], target,
                                      floor, max_sag, d[i])), None)
        if v is None:
            break
        movable[v] = False
        put.append(v)
    else:
        i = len(far)
    S.tally("settled_on_input", len(put))
    return settled(put, i, P)


def input_distance(S: RemeshState) -> MeshDistance:
    """Exact distances to the input surface (:class:`..remesh_quality.MeshDistance`); made
    once per state (:meth:`.state.RemeshState.of_input`)."""
    return MeshDistance(S.V_in, S.F_in)


def remesh_reach(S: RemeshState) -> float:
    """The largest distance of a remesh edge's middle from the input: a lower bound of the
    remesh-to-input Hausdorff distance (the vertices lie on the input; a face's inside is
    seldom farther than its edges' middles), below which an input point nearer the remesh
    cannot decide the two-sided distance. Measured only at the middles whose distance to the
    input faces under their edge's ends and under its domain midpoint
    (:func:`..remesh_quality.candidate_face_distances`) may reach the largest
    (:func:`..remesh_quality.largest_distance`)."""
    _, a, b, twin = edge_table(S.F, twin=S.twins())
    keep = (twin < 0) | (a < b)
    a, b = a[keep], b[keep]
    M = (S.X[a] + S.X[b]) / 2
    _, under = lift_samples(S, a, b, np.full((len(a), 1), 0.5))
    measure = S.of_input(input_distance)
    bound = candidate_face_distances(M, np.column_stack([S.face[a], S.face[b], under]),
                                     measure)
    return largest_distance(M, bound, measure, S.of_input(input_slack))


def input_slack(S: RemeshState) -> float:
    """The absolute margin of the distance bounds to the input
    (:func:`..remesh_quality.bound_slack`); made once per state
    (:meth:`.state.RemeshState.of_input`)."""
    return bound_slack(S.V_in)


def _shape_kept(S: RemeshState, v: int, faces: np.ndarray, floor_before: np.ndarray,
                max_sag: float) -> bool:
    """Whether the ``faces`` at vertex ``v`` are counter-clockwise on the disk (none thinner
    than ``DISK_SHAPE_MIN``), have smallest 3D angles of at least ``floor_before`` (per face,
    radians), none is turned over against the input (:func:`.state.turned_against`, the first
    test of :func:`.improve.turned_over_faces`) and no edge at
    ``v`` is farther than ``max_sag`` from the surface (:func:`.sag.edge_sag_along` at
    ``SAG_SAMPLES`` points)."""
    ring = S.F[faces]
    if not (np.all(disk_shape(S.uv, ring) >= DISK_SHAPE_MIN)
            and np.all(row_min(corner_angles(S.X, ring)) >= floor_before)
            and not turned_against(S.X, ring, S.normals_in().take(S.face[ring], axis=0)).any()):
        return False
    a, c = ring.ravel(), np.roll(ring, -1, axis=1).ravel()
    at = (a == v) | (c == v)
    sag, _ = edge_sag_along(S, a[at], c[at], SAG_TS)
    return bool(np.all(sag <= max_sag))


#: the input point tree's leaf size: the settle step asks it for a few balls only, so it is
#: built for a quick build (sliding-midpoint splits, no node shrinking) rather than quick
#: queries; a ball's points are the same whatever the tree's shape
POINT_TREE_LEAF = 64


def input_point_tree(S: RemeshState):
    """A KD-tree (:class:`scipy.spatial.cKDTree`, ``POINT_TREE_LEAF`` points a leaf) over the
    input points of :func:`input_points`; made once per state
    (:meth:`.state.RemeshState.of_input`)."""
    from scipy.spatial import cKDTree

    return cKDTree(S.of_input(input_points).P, leafsize=POINT_TREE_LEAF, balanced_tree=False,
                   compact_nodes=False)


def near_input_kept(S: RemeshState, v: int, ring_faces: np.ndarray, was: np.ndarray,
                    limit: float) -> bool:
    """Whether every input point (:func:`input_points`) within the longest edge at ``v`` of
    ``v``'s position or of where it ``was`` (3,) is nearer than ``limit`` to the faces at the
    vertices of ``ring_faces`` (the faces at ``v``): a vertex moved onto one far point must
    not leave another as far where it was."""
    ring = S.F[ring_faces]
    near = np.zeros(S.n, bool)
    near[ring.ravel()] = True
    faces = S.F[touching(S.F, near)]
    reach = norms(S.X[ring.ravel()] - S.X[v]).max()
    tree, P = S.of_input(input_point_tree), S.of_input(input_points).P
    idx = np.unique(np.concatenate(tree.query_ball_point([S.X[v], was], reach)))
    if len(idx) == 0:
        return True
    k, m = len(idx), len(faces)
    Q = np.repeat(P[idx], m, axis=0)
    T = np.tile(faces, (k, 1))
    C = closest_points_on_triangles(Q, *(S.X.take(T[:, c], axis=0) for c in range(3)))
    return bool(norms(Q - C).reshape(k, m).min(axis=1).max() < limit)


def move_keeps_shape(S: RemeshState, v: int, faces: np.ndarray, target: tuple, floor: float,
                     max_sag: float, limit: float) -> bool:
    """Move vertex ``v`` (its faces ``faces``) onto ``target`` — its domain point, input face,
    barycentrics and 3D point — if its faces keep their shape (:func:`_shape_kept`, each
    face's smallest angle at least the smaller of ``floor`` and what it was) and the input
    points around stay nearer than ``limit`` (:func:`near_input_kept`); returns whether it
    moved."""
    before = row_min(corner_angles(S.X, S.F[faces]))
    old = S.uv[v].copy(), S.face[v], S.bary[v].copy(), S.X[v].copy()
    S.uv[v], S.face[v], S.bary[v], S.X[v] = target
    if (_shape_kept(S, v, faces, np.minimum(before, floor), max_sag)
            and near_input_kept(S, v, faces, old[3], limit)):
        return True
    S.uv[v], S.face[v], S.bary[v], S.X[v] = old
    return False
