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
from .._kernels import ring_sums, thin_faces
from ..locate import PointLocator, lift
from ..rows import nonzero_rows, norms
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
    J = pullback_matrices(V_in, F_in, uv_in) if pullback is None else pullback
    n = len(uv)
    moved_counts = []
    F64 = np.ascontiguousarray(F, dtype=np.int64)
    mov = np.flatnonzero(movable)
    area_floor = 1e-6 * double_areas(uv, F)          # per face
    for _ in range(iterations):
        # per vertex, over its faces: Σ 2·area, Σ 2·area · centroid, Σ 2·area · normal
        W, G, N = ring_sums(np.ascontiguousarray(X, dtype=np.float64), F64, n)
        N /= np.maximum(norms(N)[:, None], 1e-300)
        D = G[mov] / np.maximum(W[mov], 1e-300)[:, None] - X[mov]
        if equalize is not None:
            D = area_equalizing_steps(X, F64, mov, D, equalize)
        D -= np.einsum("ij,ij->i", D, N[mov])[:, None] * N[mov]
        du = np.zeros_like(uv)
        du[mov] = step * np.einsum("kij,kj->ki", J[face[mov]], D)
        # halve the moves of vertices of faces that would flip (or nearly collapse) on the disk
        # (only faces with a moving corner are tested: a face none of whose corners moves
        # keeps its shape, and halving or dropping its corners' zero moves changes nothing)
        for _halving in range(7):
            new = uv + du
            bad = _too_thin(new, F, area_floor, nonzero_rows(du))
            if len(bad) == 0:
                break
            verts = np.unique(F[bad].ravel())
            du[verts] *= 0.0 if _halving == 6 else 0.5
        go = np.flatnonzero(nonzero_rows(du))
        f2, b2, inside = locator.relocate(uv[go] + du[go], face[go])
        du[go[~inside]] = 0.0                    # would leave the image polygon: stays
        go, f2, b2 = go[inside], f2[inside], b2[inside]
        uv_go, X_go = project(uv[go] + du[go]), lift(V_in, F_in, f2, b2)   # the moved state
        if veto is not None:
            uv2, face2, bary2, X2 = uv.copy(), face.copy(), bary.copy(), X.copy()
            uv2[go], face2[go], bary2[go], X2[go] = uv_go, f2, b2, X_go
            du[veto(uv2, face2, bary2, X2)] = 0.0
        while True:                              # dropping moves can flip a face: drop more
            bad = _too_thin(uv + du, F, area_floor, nonzero_rows(du))
            if len(bad) == 0:
                break
            du[F[bad].ravel()] = 0.0
        keep = nonzero_rows(du[go])
        go = go[keep]
        uv[go], face[go], bary[go], X[go] = uv_go[keep], f2[keep], b2[keep], X_go[keep]
        moved_counts.append(int(len(go)))
    return uv, face, bary, X, moved_counts


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


def _too_thin(uv: np.ndarray, F: np.ndarray, area_floor: np.ndarray, moving: np.ndarray
              ) -> np.ndarray:
    """The faces (indices, increasing) with a corner where ``moving`` (n bool) is set that are
    at most ``area_floor`` in twice their disk area, or thinner than ``DISK_SHAPE_MIN`` on the
    disk (compiled: :func:`.._kernels.thin_faces`, the arithmetic of :func:`.halfedge.double_areas`
    and :func:`.halfedge.disk_shape`)."""
    F = np.ascontiguousarray(F, dtype=np.int64)
    return thin_faces(np.ascontiguousarray(uv, dtype=np.float64), F,
                      np.flatnonzero(touching(F, moving)), area_floor, DISK_SHAPE_MIN)
