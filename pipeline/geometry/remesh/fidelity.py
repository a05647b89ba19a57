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

from typing import NamedTuple

import numpy as np

from .. import topology as topo
from ..remesh_quality import MeshDistance, face_bounds, middle_bounds
from .corners import snap_vertices
from .domain import project
from .halfedge import double_areas, edge_table, touching
from .refine import SAG_SAMPLES
from .sag import edge_sag_along
from .state import RemeshState


class InputPoints(NamedTuple):
    """The input points the remesh follows (:func:`input_points`): ``P`` (k×3) and their
    domain positions ``P_uv`` (k×2 or k×3), the ``vertices`` first, then the midpoints of the
    ``edges`` (e×2), then the centroids of the ``faces`` (f×3) — input vertex indices."""

    P: np.ndarray
    P_uv: np.ndarray
    vertices: np.ndarray
    edges: np.ndarray
    faces: np.ndarray


def input_points(S: RemeshState) -> InputPoints:
    """The input's interior vertices, the midpoints of its interior edges and the centroids of
    its faces, on the surface and in the map's domain (there the same averages of the
    corners' ``uv_in``; on the sphere put back on it, :func:`.domain.project`). Only the rim's
    own points are left out (:mod:`.rim` follows the boundary): the edges and faces at the rim
    are in, where a coarse input's farthest point can be (igl_camel_b at 20k vertices: the
    middle of an interior edge between two rim vertices)."""
    is_rim = topo.boundary_vertices_mask(S.F_in, len(S.V_in))
    _, a, b, twin = edge_table(S.F_in)
    a, b = a[twin >= 0], b[twin >= 0]
    v = np.flatnonzero(~is_rim)

    def points(Y):
        return np.concatenate([Y[v], (Y[a] + Y[b]) / 2, Y[S.F_in].mean(axis=1)])

    return InputPoints(points(S.V_in), project(points(S.uv_in)), v, np.column_stack([a, b]),
                       S.F_in)


def far_input_points(S: RemeshState, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The input points of :func:`input_points` (made once per state,
    :meth:`.state.RemeshState.of_input`) farther than ``tol`` from the remesh ``(S.X, S.F)``,
    farthest first.

    The vertices are measured first; a midpoint or centroid is measured only if neither its
    corners' distances (:func:`..remesh_quality.middle_bounds`) nor its distance to the faces
    closest to its corners (:func:`..remesh_quality.face_bounds`) already bound it within
    ``tol``.

    Parameters
    ----------
    S : RemeshState
    tol : float
        In the mesh's units.

    Returns
    -------
    P_uv : (j, 2) or (j, 3) float
        Their domain positions.
    distance : (j,) float
        In the mesh's units.
    """
    pts = S.of_input(input_points)
    measure = MeshDistance(S.X, S.F)
    nv = len(pts.vertices)
    d_vertex = np.full(len(S.V_in), np.inf)
    f_vertex = np.zeros(len(S.V_in), np.int64)          # a rim vertex's: any face bounds
    d_vertex[pts.vertices], f_vertex[pts.vertices] = measure(pts.P[:nv])
    mid_bound, _, centroid_bound = middle_bounds(S.V_in, pts.faces, pts.edges, d_vertex)
    d = np.concatenate([d_vertex[pts.vertices], mid_bound, centroid_bound])
    ask = nv + np.flatnonzero(d[nv:] > tol)
    ne = len(pts.edges)
    mids, cents = ask[ask < nv + ne], ask[ask >= nv + ne]
    d[mids] = face_bounds(pts.P[mids], pts.edges[mids - nv], f_vertex, measure)
    d[cents] = face_bounds(pts.P[cents], pts.faces[cents - nv - ne], f_vertex, measure)
    ask = ask[d[ask] > tol]
    d[ask] = measure(pts.P[ask])[0]
    far = np.flatnonzero(d > tol)
    far = far[np.argsort(-d[far], kind="stable")]
    return pts.P_uv[far], d[far]


def follow_input(S: RemeshState, tol: float, min_gap: float, max_sag: float | None = None
                 ) -> np.ndarray:
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

    Returns
    -------
    (j,) int
        The snapped and inserted vertices that stay.
    """
    far, _ = far_input_points(S, tol)
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
    sag, _ = edge_sag_along(S, a[e], b[e], np.arange(1, SAG_SAMPLES + 1) / (SAG_SAMPLES + 1))
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

