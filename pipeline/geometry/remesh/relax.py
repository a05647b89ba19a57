"""Tangential relaxation made on the disk.

Every movable vertex moves part of the way towards the area-weighted centroid of its 1-ring
(the centroids of its faces weighted by their areas, in 3D), with the displacement projected
onto the tangent plane (the area-weighted normal of its faces). With an ``equalize`` weight the
step also evens out the areas of the vertex's faces (:func:`area_equalizing_steps`: a
Gauss–Newton step on their spread, regularised towards the centroid step). The move is made **on the
disk**: the 3D displacement ``d`` is pulled back through the Jacobian ``J`` (3×2) of the input
face under the vertex, ``Δu = J⁺ d`` (:func:`.state.pullback_matrices`), and the vertex is
re-located and lifted by eq. (1), so it stays on the input surface. Moves that would flip a
face on the disk (or shrink it below 10⁻⁶ of its area, or make it thinner than
``DISK_SHAPE_MIN``, :func:`.halfedge.disk_shape`) are halved, up to 6 times, then dropped;
moves that would leave the image polygon are dropped, and so are those a ``veto`` refuses
(:func:`.improve.sag_veto`: the moves that take an edge off the surface). On the sphere
(:mod:`.domain`) the same step is taken in the chordal plane of the input face's spherical
image (``J⁺`` then maps to 3D) and normalised back onto the sphere; the face tests are the
sphere's orientation tests.
"""

from __future__ import annotations

import numpy as np

from .._kernels import area_equalizing_steps as kernel_steps
from .._kernels import (centroid_steps, pulled_back_steps, put_rows, ring_sums,
                       tangential_parts, thin_faces)
from ..locate import PointLocator, lift
from ..rows import nonzero_rows
from .domain import project
from .halfedge import DISK_SHAPE_MIN, double_areas, touching
from .state import pullback_matrices


def tangential_smoothing(V_in: np.ndarray, F_in: np.ndarray, uv_in: np.ndarray,
                         locator: PointLocator, uv: np.ndarray, F: np.ndarray,
                         face: np.ndarray, bary: np.ndarray, movable: np.ndarray,
                         iterations: int = 3, step: float = 0.5, X: np.ndarray | None = None,
                         pullback: np.ndarray | None = None, veto=None,
                         equalize: float | None = None):
    """Tangential smoothing of the remesh ``(uv, F)`` lifted onto the input map.

    Parameters
    ----------
    V_in, F_in, uv_in : (N, 3) float, (M, 3) int, (N, 2) float
        The input mesh and its disk map.
    locator : PointLocator
        Point location in the input map's image.
    uv : (n, 2) float
        Disk positions of the remesh; not modified.
    F : (m, 3) int
        Its faces, counter-clockwise on the disk (unchanged: only vertices move).
    face, bary : (n,) int, (n, 3) float
        Where ``uv`` lies in the input map.
    movable : (n,) bool
        The vertices that may move (not the rim, not locked corners).
    iterations : int
    step : float
        The fraction of the way to the centroid.
    X : (n, 3) float, optional
        The lift of ``uv``, when already computed.
    pullback : (M, 2, 3) float, optional
        :func:`.state.pullback_matrices` of the input, when already computed.
    veto : callable ``veto(uv, face, bary, X) -> (n,) bool``, optional
        Given the remesh with every move made (arrays as above), the vertices whose moves are
        dropped (:func:`.improve.sag_veto`: those that would make an edge leave the surface).
    equalize : float, optional
        The weight ``μ`` of the centroid step against evening out the areas of each vertex's
        faces (:func:`area_equalizing_steps`); None: the centroid step alone.

    Returns
    -------
    uv, face, bary, X : new arrays
        The moved remesh, located and lifted.
    moved : list of int
        Per iteration, the number of vertices that moved.
    """
    uv = np.array(uv, dtype=np.float64, copy=True)
    face, bary = face.copy(), bary.copy()
    X = lift(V_in, F_in, face, bary) if X is None else X.copy()
    J = np.ascontiguousarray(pullback_matrices(V_in, F_in, uv_in) if pullback is None
                             else pullback, dtype=np.float64)
    n = len(uv)
    moved_counts = []
    F64 = np.ascontiguousarray(F, dtype=np.int64)
    mov = np.flatnonzero(movable)
    area_floor = 1e-6 * double_areas(uv, F)          # per face
    for _ in range(iterations):
        # per vertex, over its faces: Σ 2·area, Σ 2·area · centroid, Σ 2·area · normal
        Xc = np.ascontiguousarray(X, dtype=np.float64)
        W, G, N = ring_sums(Xc, F64, n)
        D = centroid_steps(G, W, Xc, mov)
        if equalize is not None:
            D = area_equalizing_steps(Xc, F64, mov, D, equalize)
        tangential_parts(D, N, mov)              # less the part along the unit normal
        du = np.zeros_like(uv)
        pulled_back_steps(J, face, mov, D, float(step), du)
        halve_thin_moves(uv, du, F, area_floor)
        go = np.flatnonzero(nonzero_rows(du))
        # (rows gathered by take: several times faster than the fancy index on 2D rows)
        target = uv.take(go, axis=0) + du.take(go, axis=0)
        f2, b2, inside = locator.relocate(target, face[go])
        du[go[~inside]] = 0.0                    # would leave the image polygon: stays
        inside = np.flatnonzero(inside)
        go, f2, b2 = go[inside], f2[inside], b2.take(inside, axis=0)
        uv_go = project(target.take(inside, axis=0))                      # the moved state
        X_go = lift(V_in, F_in, f2, b2)
        if veto is not None:
            uv2, face2, bary2, X2 = uv.copy(), face.copy(), bary.copy(), X.copy()
            _put_moved(go, (uv2, face2, bary2, X2), (uv_go, f2, b2, X_go))
            du[veto(uv2, face2, bary2, X2)] = 0.0
        while True:                              # dropping moves can flip a face: drop more
            bad = _too_thin(uv + du, F, area_floor, nonzero_rows(du))
            if len(bad) == 0:
                break
            du[F[bad].ravel()] = 0.0
        keep = np.flatnonzero(nonzero_rows(du.take(go, axis=0)))
        _put_moved(go[keep], (uv, face, bary, X),
                   (uv_go.take(keep, axis=0), f2[keep], b2.take(keep, axis=0),
                    X_go.take(keep, axis=0)))
        moved_counts.append(int(len(keep)))
    return uv, face, bary, X, moved_counts


def _put_moved(rows: np.ndarray, state: tuple, values: tuple) -> None:
    """``uv[rows], face[rows], bary[rows], X[rows] = values`` for ``state = (uv, face, bary,
    X)`` (C-contiguous float64, int64, float64, float64; changed in place) and ``values``
    their k new rows, the 2D rows copied by a compiled loop (:func:`.._kernels.put_rows`)."""
    uv, face, bary, X = state
    uv_new, face_new, bary_new, X_new = values
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    face[rows] = face_new
    for dst, src in ((uv, uv_new), (bary, bary_new), (X, X_new)):
        put_rows(dst, rows, np.ascontiguousarray(src, dtype=np.float64))


AREA_SHARE = 1.0 / 3.0   # the part of a face's area error each of its three corners corrects


def area_equalizing_steps(X: np.ndarray, F: np.ndarray, mov: np.ndarray, D: np.ndarray,
                          mu: float) -> np.ndarray:
    """The steps of the vertices ``mov`` that even out the areas of their faces while keeping
    close to the centroid steps ``D``.

    For a vertex ``i`` with faces ``f`` (areas ``A_f``, their mean ``Ā``, gradients
    ``∇A_f = ½ n_f × (x_k − x_j)`` for ``f = (i, j, k)`` counter-clockwise, ``n_f`` its unit
    normal), the step ``d`` minimises the linearised spread plus a pull towards ``D_i``::

        Σ_f (s (A_f − Ā) + ∇A_f · d)² / Ā²  +  β |d − D_i|²,    β = μ tr(H) / 2,

    ``H = Σ_f ∇A_f ∇A_fᵀ / Ā²``: ``(H + β I) d = β D_i − s Σ_f ∇A_f (A_f − Ā) / Ā²``, one
    Gauss–Newton step; ``s = AREA_SHARE``, as every corner of a face moves at once. Moving
    one vertex inside its ring leaves the ring's area as it is, so this evens out the faces
    around it, not the density over larger distances.

    Parameters
    ----------
    X : (n, 3) float
        Positions.
    F : (m, 3) int
        Faces.
    mov : (k,) int
        The moving vertices.
    D : (k, 3) float
        Their centroid steps.
    mu : float
        The weight of the centroid step, > 0 (large: ``D``; small: the area term).

    Returns
    -------
    (k, 3) float

    Notes
    -----
    Compiled (:func:`.._kernels.area_equalizing_steps`).
    """
    return kernel_steps(np.ascontiguousarray(X, dtype=np.float64),
                        np.ascontiguousarray(F, dtype=np.int64),
                        np.ascontiguousarray(mov, dtype=np.int64),
                        np.ascontiguousarray(D, dtype=np.float64), float(mu), AREA_SHARE)


def halve_thin_moves(uv: np.ndarray, du: np.ndarray, F: np.ndarray, area_floor: np.ndarray,
                     halvings: int = 6) -> None:
    """Halve, in place, the moves ``du`` of the corners of every face that the moves would
    make too thin on the disk (:func:`_too_thin`), until none is or ``halvings`` halvings were
    made; then drop the moves still making one.

    Only faces with a moving corner are tested (a face none of whose corners moves keeps its
    shape, and halving its corners' zero moves changes nothing), and after a halving only those
    at a halved move (the others keep the shape that passed).

    Parameters
    ----------
    uv : (n, 2) float
    du : (n, 2) float
        Changed in place.
    F : (m, 3) int
    area_floor : (m,) float
    halvings : int
    """
    moving = nonzero_rows(du)
    tested = np.flatnonzero(touching(F, moving))
    for halving in range(halvings + 1):
        bad = _thin_among(uv + du, F, area_floor, tested)
        if len(bad) == 0:
            return
        verts = np.unique(F[bad].ravel())
        du[verts] *= 0.0 if halving == halvings else 0.5
        tested = np.flatnonzero(touching(F, _marked(len(uv), verts) & moving))


def _too_thin(uv: np.ndarray, F: np.ndarray, area_floor: np.ndarray, moving: np.ndarray
              ) -> np.ndarray:
    """The faces (indices, increasing) with a corner where ``moving`` (n bool) is set that are
    at most ``area_floor`` in twice their disk area, or thinner than ``DISK_SHAPE_MIN`` on the
    disk (:func:`_thin_among` of those faces)."""
    return _thin_among(uv, F, area_floor, np.flatnonzero(touching(F, moving)))


def _thin_among(uv: np.ndarray, F: np.ndarray, area_floor: np.ndarray, faces: np.ndarray
                ) -> np.ndarray:
    """The faces of ``faces`` (k int, increasing) that are at most ``area_floor`` (m) in twice
    their disk area, or thinner than ``DISK_SHAPE_MIN`` on the disk, in the same order
    (compiled: :func:`.._kernels.thin_faces`, the arithmetic of :func:`.halfedge.double_areas`
    and :func:`.halfedge.disk_shape`)."""
    return thin_faces(np.ascontiguousarray(uv, dtype=np.float64),
                      np.ascontiguousarray(F, dtype=np.int64), faces, area_floor,
                      DISK_SHAPE_MIN)


def _marked(n: int, indices: np.ndarray) -> np.ndarray:
    """An n-bool mask set at ``indices``."""
    mark = np.zeros(n, bool)
    mark[indices] = True
    return mark
