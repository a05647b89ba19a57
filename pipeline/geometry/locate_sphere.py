"""Point location in a spherical triangulation (a sphere map's image) for lifting by eq. (1).

A bijective sphere map ``S`` (n×3 unit vectors) of a closed genus-0 mesh with faces ``F`` (m×3,
every spherical triangle positively oriented: ``det[s_i, s_j, s_k] > 0``) tiles the unit sphere.
For a query direction ``p`` the face ``[s_i, s_j, s_k]`` whose cone contains it has

    λ_i ∝ det[p, s_j, s_k],  λ_j ∝ det[s_i, p, s_k],  λ_k ∝ det[s_i, s_j, p],

normalised to sum 1: the barycentric coordinates of the point where the ray through ``p``
crosses the plane of the chordal triangle (central, gnomonic projection; the plane analogue of
the signed-area ratios of eq. 1). All three are ≥ 0 exactly when ``p`` is in the cone, they do
not change when ``p`` is scaled, and :func:`.locate.lift` then evaluates eq. (1): the point on
the surface is ``Σ_c λ_c v_{F[face, c]}``.

How a batch is located (:class:`SphereLocator`): from a start face (a face at the nearest map
vertex, a KD-tree, or a face the caller knows), each query walks across the edge of its most
negative coordinate (compiled, one query after the other); a query still unsettled walks on from
where it stopped, then from a face at its nearest map vertex, and one unsettled after all that
(a walk can circle where the triangulation is far from Delaunay) tests the faces whose centroid
lies within the largest face radius of it (a KD-tree on the face centroids), which always
contains its face. A point on an edge or at a vertex has coordinates of
±1e-17 there and is accepted with ``min λ ≥ −tol`` (then clamped to 0 and renormalised); a query
exactly at a map vertex gets exactly ``(1, 0, 0)`` on that corner. The sphere has no outside:
every query is located.
"""

from __future__ import annotations

import numpy as np

from . import topology as topo
from ._kernels import sphere_walk_to_faces
from .locate import TOL

__all__ = ["SphereLocator", "locate_on_sphere", "sphere_barycentrics"]

_WALK = 8                # walk steps of a large batch from its nearest vertex's face
_FAR_WALK = 64           # further walk steps of a query its hint's walk missed
_CHUNK = 65536           # queries per brute-force block


def sphere_barycentrics(P: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                        ) -> np.ndarray:
    """Central-projection barycentrics (k×3) of the directions ``P`` in the spherical
    triangles ``(A, B, C)`` (all k×3; module docstring). Rows whose chordal plane does not face
    ``P`` (the ray misses it) are ``-inf``.

    Parameters
    ----------
    P, A, B, C : (k, 3) float

    Returns
    -------
    (k, 3) float
    """
    # det[p, b, c] = p · ((b − p) × (c − p)) and cyclically: differences to the query keep
    # their precision in the tiny triangles a sphere map crowds limbs into, and a query at a
    # corner gets exactly 0 for the other two
    Ap, Bp, Cp = A - P, B - P, C - P
    lam = np.column_stack([np.einsum("ij,ij->i", P, np.cross(Bp, Cp)),
                           np.einsum("ij,ij->i", P, np.cross(Cp, Ap)),
                           np.einsum("ij,ij->i", P, np.cross(Ap, Bp))])
    s = lam.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = lam / s[:, None]
    out[~(s > 0)] = -np.inf
    return out


def _clean_rows(bary: np.ndarray) -> np.ndarray:
    """Clamp tiny negatives to 0 and renormalise every row to sum 1."""
    bary = np.clip(bary, 0.0, None)
    return bary / bary.sum(axis=1, keepdims=True)


class SphereLocator:
    """Build once for a spherical triangulation ``(S, F)``, then locate any directions.

    The same calls as :class:`.locate.PointLocator` (``locate``, ``locate_with_inside``,
    ``relocate``), so the remesher's operations run on the sphere unchanged; ``inside`` is
    always True.

    Parameters
    ----------
    S : (n, 3) float
        Unit vectors.
    F : (m, 3) int
        Faces, positively oriented on the sphere, a closed manifold.
    """

    def __init__(self, S: np.ndarray, F: np.ndarray):
        from scipy.spatial import cKDTree

        self.S = np.ascontiguousarray(S, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        if len(self.F) == 0:
            raise ValueError("cannot locate points in an empty triangulation")
        self.twin = topo.interior_edge_twins(self.F)
        vface = np.full(len(self.S), -1, np.int64)
        vface[self.F.ravel()] = np.repeat(np.arange(len(self.F)), 3)
        self._used = np.flatnonzero(vface >= 0)
        self._vface = vface
        self._vtree = cKDTree(self.S[self._used])
        self._faces = None        # (k-d tree on the face centroids, largest face radius)

    def _face_tree(self):
        """The k-d tree on the faces' centroid directions and the largest face radius, built
        when :meth:`_near` first needs them (most locators never do)."""
        if self._faces is None:
            from scipy.spatial import cKDTree

            T = self.S[self.F]
            c = T.mean(axis=1)
            c /= np.maximum(np.linalg.norm(c, axis=1), 1e-300)[:, None]
            radius = float(np.linalg.norm(T - c[:, None, :], axis=2).max()) * (1 + 1e-9) + 1e-12
            self._faces = (cKDTree(c), radius)
        return self._faces

    def bary(self, P: np.ndarray, face: np.ndarray) -> np.ndarray:
        """:func:`sphere_barycentrics` of ``P`` (k×3) in the faces ``face`` (k)."""
        T = self.F[face]
        return sphere_barycentrics(P, self.S[T[:, 0]], self.S[T[:, 1]], self.S[T[:, 2]])

    def locate(self, points: np.ndarray, tol: float = TOL) -> tuple[np.ndarray, np.ndarray]:
        """``(face int64 k, bary float64 k×3)`` for every direction (k×3)."""
        face, bary, _ = self.locate_with_inside(points, tol)
        return face, bary

    def locate_with_inside(self, points: np.ndarray, tol: float = TOL
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Locate from a face at the nearest map vertex; a query exactly at a vertex gets
        exactly that corner. Returns ``(face, bary, inside)``, ``inside`` all True."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        unit = P / np.maximum(np.linalg.norm(P, axis=1), 1e-300)[:, None]
        dist, j = self._vtree.query(unit)
        v = self._used[np.asarray(j, np.int64).reshape(-1)]
        face, bary, inside = self.relocate(P, self._vface[v], tol, walk=_WALK)
        at = np.flatnonzero(np.all(P == self.S[v], axis=1))          # exactly at a vertex
        if len(at):
            face[at] = self._vface[v[at]]
            bary[at] = (self.F[face[at]] == v[at, None]).astype(np.float64)
        return face, bary, inside

    def relocate(self, points: np.ndarray, face: np.ndarray, tol: float = TOL,
                 face2: np.ndarray | None = None, walk: int = 2, project: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Locate directions near known faces: ``face`` (then ``face2``, if given) is tested
        first and a query outside it walks up to ``walk`` steps across the edge of its most
        negative coordinate; a query still unsettled walks on up to ``_FAR_WALK`` steps from
        where it stopped, then as many from a face at its nearest map vertex, and the few left
        are found among the faces near them (module docstring). Returns ``(face, bary,
        inside)``, ``inside`` all True (``project``, the disk locator's choice for outside
        points, changes nothing: no direction is outside the sphere)."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        out_face = np.array(face, dtype=np.int64, copy=True).reshape(-1)
        bary = np.empty((len(P), 3))
        todo = np.arange(len(P))
        # the walk reads a point's start face before it writes that point's face: no copy
        for hint in [out_face] + ([] if face2 is None else [face2]):
            if len(todo) == 0:
                break
            todo = sphere_walk_to_faces(self.S, self.F, self.twin, P,
                                        np.ascontiguousarray(hint, dtype=np.int64).reshape(-1),
                                        todo, walk, tol, out_face, bary)
        if len(todo):            # on from the face where each walk stopped
            todo = sphere_walk_to_faces(self.S, self.F, self.twin, P, out_face, todo, _FAR_WALK,
                                        tol, out_face, bary)
        if len(todo):            # from a face at the nearest map vertex
            todo = sphere_walk_to_faces(self.S, self.F, self.twin, P, self._nearest_faces(P, todo),
                                        todo, _FAR_WALK, tol, out_face, bary)
        if len(todo):
            out_face[todo], bary[todo] = self._near(P[todo], tol)
        return out_face, bary, np.ones(len(P), bool)

    def _nearest_faces(self, P: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """A face at the map vertex nearest to each direction ``P[rows]``, as a start (len(P),
        set at ``rows`` only) for a walk."""
        start = np.zeros(len(P), np.int64)
        unit = P[rows] / np.maximum(np.linalg.norm(P[rows], axis=1), 1e-300)[:, None]
        _, j = self._vtree.query(unit)
        start[rows] = self._vface[self._used[np.asarray(j, np.int64).reshape(-1)]]
        return start

    def _near(self, P: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
        """Every face whose centroid is within the largest face radius of a query is tested;
        the one with the largest smallest coordinate wins (the face containing the query is
        among them)."""
        k = len(P)
        face = np.empty(k, np.int64)
        bary = np.empty((k, 3))
        unit = P / np.maximum(np.linalg.norm(P, axis=1), 1e-300)[:, None]
        tree, radius = self._face_tree()
        for lo in range(0, k, _CHUNK):
            hi = min(lo + _CHUNK, k)
            lists = tree.query_ball_point(unit[lo:hi], radius)
            cnt = np.fromiter((len(x) for x in lists), np.int64, hi - lo)
            cand = np.fromiter((f for x in lists for f in x), np.int64, int(cnt.sum()))
            pt = np.repeat(np.arange(hi - lo), cnt)
            lam = self.bary(P[lo:hi][pt], cand)
            score = lam.min(axis=1)
            order = np.lexsort((-score, pt))                 # per point, best first
            first = order[np.r_[True, pt[order][1:] != pt[order][:-1]]]
            face[lo + pt[first]] = cand[first]
            bary[lo + pt[first]] = _clean_rows(lam[first])
        return face, bary


def locate_on_sphere(S: np.ndarray, F: np.ndarray, points: np.ndarray, tol: float = TOL
                     ) -> tuple[np.ndarray, np.ndarray]:
    """One-off location of ``points`` (k, 3) in the spherical map ``(S, F)``: ``(face (k,),
    bary (k, 3))`` with ``lift(V, F, face, bary)`` = eq. (1) (:class:`SphereLocator`)."""
    return SphereLocator(S, F).locate(points, tol)
