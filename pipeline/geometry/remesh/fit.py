"""The remesh as a least-squares approximation of its input: vertex offsets along the normals.

A remesh whose vertices lie on the input surface interpolates it: each face is a chord of the
surface beneath it and lies on one side of it wherever the surface curves (by up to about
κ L² / 8 on a surface of curvature κ) and along every input crease it spans. Moving each
vertex along its normal by the offset δ that minimises the mean squared distance between the
two surfaces, in both directions as the measure takes it
(:func:`..remesh_quality.surface_distance`), lets the faces cross the surface instead of lying
under it: for a chord of a parabola the mean squared distance drops to a sixth (the chord's
mean sag taken off), the largest distance to two thirds.

To first order a sample's signed distance along the normal ``n`` it is measured along changes
by ``Σ_j b_j δ_j (n · N_j)`` (``b``: its barycentric coordinates in its remesh face, ``N_j``:
the unit normals of that face's corners), so the offsets solve a sparse linear least-squares
problem (:func:`offset_equations`), here its normal equations with a ridge of ``FIT_RIDGE`` ×
their mean diagonal (a vertex few samples see stays where it is), by Jacobi-preconditioned
conjugate gradients. The samples: ``FIT_SAMPLES`` × n area-uniform points of the input
(seeded by ``FIT_SEED``, apart from the measure's own draws), measured to their closest remesh
face, and the points of a three-point quadrature rule on every remesh face (``QUADRATURE``,
weighted by the face's area), measured to the input.

Offsets stay 0 at the vertices locked when the improvement ends (the input corners, feature
lines and landmarks they were put on) and where the remesh folds (a face's normal more than
``FOLD_DEG`` from its vertex's: an averaged normal there points across the fold);
they are clipped to ``OFFSET_CAP × L`` and undone (:func:`guarded_offsets`) at the corners of
every face they turn by more than ``TURN_DEG``, turn against the input, leave with a smallest
angle below the minimum angle and its own before, or whose corner they take nearer another
sheet of the input (across a lip's fold), and at the faces of the samples farther than
``FAR_SHARE`` × the farthest that they take farther still, measured exactly (the fit lowers
the mean distance; the largest is decided at such places, which it must not worsen): the
input's vertices, and where it is no finer than the samples its edges' middles and face
centroids, and the remesh's vertices are measured for the guards beside the samples.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import topology as topo
from ..remesh_quality import (MeshDistance, _random_samples, closest_points_on_triangles,
                              face_centroids)
from ..rows import cross, dots, norms
from ..locate import lift
from ..solvers import pcg
from .angles import face_min_angles
from .halfedge import CSR, vertex_faces
from .state import RemeshState, face_normals

__all__ = ["FIT_SAMPLES", "OFFSET_CAP", "vertex_normals", "offset_equations",
           "least_squares_offsets", "Guards", "guarded_offsets", "input_guard_points",
           "fit_to_input"]

# area-uniform samples of the input per remesh vertex
FIT_SAMPLES = 4
# the input samples' seed (the measure draws its own with seed 0)
FIT_SEED = 7
# the barycentric coordinates of the points measured on each remesh face (the three-point
# rule, exact for quadratics: a face's squared distance from a plane it crosses)
QUADRATURE = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
# the ridge: this × the mean diagonal of the normal equations, on every offset
FIT_RIDGE = 0.03
# offsets at most this × L
OFFSET_CAP = 0.1
# a vertex with a face whose normal is more than this from its own keeps its place (a fold)
FOLD_DEG = 90.0
# the offsets are undone at the corners of a face they turn by more than this
TURN_DEG = 20.0
# no sample farther from the other surface than this × the farthest may get farther (the
# measure's largest distance is taken at other samples than these, around the same places)
FAR_SHARE = 0.75
# the rounding allowed between a distance measured in the fit and measured again
FAR_RTOL = 1e-9
# the solver's relative residual and iteration limit
FIT_RTOL = 1e-6
FIT_MAX_ITER = 200
# undo rounds of the guards
GUARD_ROUNDS = 6


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit vertex normals (n×3): the area-weighted sum of the normals of each vertex's faces
    ``F`` (m×3) of ``V`` (n×3); zero at a vertex of no face."""
    A = V.take(F[:, 0], axis=0)
    area_normals = cross(V.take(F[:, 1], axis=0) - A, V.take(F[:, 2], axis=0) - A)
    N = np.zeros_like(V, dtype=np.float64)
    for j in range(3):
        np.add.at(N, F[:, j], area_normals)
    return N / np.maximum(norms(N), 1e-300)[:, None]


def normal_spread(V: np.ndarray, F: np.ndarray, N: np.ndarray) -> np.ndarray:
    """The largest angle (degrees, n) between a vertex's normal ``N`` (n×3) and the unit
    normals of its faces ``F`` of ``V``: small on a smooth surface, about half the angle a
    fold turns by at the vertices on it."""
    n_face = face_normals(V, F)
    worst = np.ones(len(V))
    for j in range(3):
        np.minimum.at(worst, F[:, j], dots(n_face, N.take(F[:, j], axis=0)))
    return np.degrees(np.arccos(np.clip(worst, -1.0, 1.0)))


def _plane_barycentrics(Q: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray
                        ) -> np.ndarray:
    """Barycentric coordinates (k×3) of the points ``Q`` in the planes of the triangles
    ``(A, B, C)`` (all k×3): sub-triangle areas along the triangle's normal."""
    n = cross(B - A, C - A)
    nn = np.maximum(dots(n, n), 1e-300)
    return np.column_stack([dots(n, cross(B - Q, C - Q)), dots(n, cross(C - Q, A - Q)),
                            dots(n, cross(A - Q, B - Q))]) / nn[:, None]


class Equations:
    """The linearised distances of :func:`offset_equations`. Sample ``s`` lies at (or is
    measured to) the barycentric coordinates ``bary[s]`` of the remesh face ``face[s]``, whose
    corners get the coefficients ``vals[s]`` (3,); its distance after offsets ``δ`` (n,) is
    ``√(t_s² + (r_s − Σ_j vals[s, j] δ[F[face[s], j]])²)`` to first order (``r``: its signed
    distance along the normal it is measured along, ``t``: the part of its distance no normal
    offset changes); ``w``: its weight in the mean squared distance (0 for a sample that only
    the guards read). The first ``len(P_in)`` samples are the input points ``P_in``, measured
    to the remesh; the others are points of the remesh, measured to the input. ``anchor``
    (k×3): each sample's point on the input (the input point itself, or the input's point
    nearest the remesh point); ``vertex_input_face`` (n): the input face nearest each remesh
    vertex (the last n samples are the vertices)."""

    def __init__(self, F: np.ndarray, face: np.ndarray, bary: np.ndarray, vals: np.ndarray,
                 r: np.ndarray, t: np.ndarray, w: np.ndarray, P_in: np.ndarray,
                 anchor: np.ndarray, vertex_input_face: np.ndarray | None = None,
                 corners: np.ndarray | None = None):
        self.F, self.face, self.bary, self.vals = F, face, bary, vals
        self.r, self.t, self.w, self.P_in, self.anchor = r, t, w, P_in, anchor
        self.vertex_input_face = vertex_input_face
        self.corners = F.take(face, axis=0) if corners is None else corners    # (k, 3)
        self.before = np.sqrt(t ** 2 + r ** 2)

    def bounds(self, rows: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Upper bounds (k,) of the distances of the samples ``rows`` when the remesh's
        vertices are at ``Y``: from each one's ``anchor`` to its remesh point moved along."""
        return norms(self.anchor[rows] - lift(Y, self.F, self.face[rows], self.bary[rows]))

    def exact_distances(self, rows: np.ndarray, Y: np.ndarray, around: CSR,
                        to_input: MeshDistance) -> tuple[np.ndarray, np.ndarray]:
        """The exact distances (k,) of the samples ``rows`` (k int) when the remesh's vertices
        are at ``Y`` (n×3), and the remesh face each is then measured at: an input point's
        distance to the nearest of the faces ``around`` (the faces at each vertex) the corners
        of its face before (at most its distance to the whole remesh: the guards err towards
        undoing), a remesh point's to the input (``to_input``)."""
        k_in = len(self.P_in)
        mine, theirs = rows < k_in, rows >= k_in
        d, face = np.empty(len(rows)), self.face[rows].copy()
        if mine.any():
            d[mine], face[mine] = _nearest_among(self.P_in[rows[mine]],
                                                 self.corners[rows[mine]], around, Y, self.F)
        if theirs.any():
            R = lift(Y, self.F, self.face[rows[theirs]], self.bary[rows[theirs]])
            d[theirs] = to_input(R)[0]
        return d, face

    def normal_equations(self, n: int) -> tuple[sp.csr_matrix, np.ndarray]:
        """``(Mᵀ W M, Mᵀ W r)`` (n×n, n) of the weighted least squares ``min Σ_s w_s (r_s −
        (M δ)_s)²``, summed face by face (each sample adds a 3×3 block on its face's
        corners)."""
        m = len(self.F)
        wv = self.vals * self.w[:, None]
        blocks = np.empty((m, 3, 3))
        for i in range(3):
            for j in range(i, 3):
                blocks[:, i, j] = blocks[:, j, i] = np.bincount(
                    self.face, wv[:, i] * self.vals[:, j], minlength=m)
        rows = np.repeat(self.F, 3, axis=1).ravel()
        cols = np.tile(self.F, (1, 3)).ravel()
        A = sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(n, n))
        corner_r = np.column_stack([np.bincount(self.face, wv[:, j] * self.r, minlength=m)
                                    for j in range(3)])
        return A, np.bincount(self.F.ravel(), corner_r.ravel(), minlength=n)


def _nearest_among(P: np.ndarray, corners: np.ndarray, around: CSR, Y: np.ndarray,
                   F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distance (k,) of each point ``P`` (k×3) to the nearest of the faces ``F`` of ``Y``
    that hold one of its ``corners`` (k×3 vertices; ``around``: each vertex's faces), and
    that face (k,)."""
    rid, faces = topo.csr_rows(around.indptr, around.indices, corners.ravel())
    rid //= 3                                  # grouped by point, in order
    T = Y.take(F.take(faces, axis=0), axis=0)
    Q = P.take(rid, axis=0)
    dist = norms(Q - closest_points_on_triangles(Q, T[:, 0], T[:, 1], T[:, 2]))
    starts = np.flatnonzero(np.r_[True, rid[1:] != rid[:-1]])
    least = np.minimum.reduceat(dist, starts)
    at = np.flatnonzero(dist == np.repeat(least, np.diff(np.r_[starts, len(dist)])))
    first = at[np.r_[True, rid[at][1:] != rid[at][:-1]]]
    return least, faces[first]


def offset_equations(X: np.ndarray, F: np.ndarray, N: np.ndarray, P_in: np.ndarray,
                     w_in: np.ndarray, to_remesh: MeshDistance, to_input: MeshDistance,
                     input_normals: np.ndarray) -> Equations:
    """The linearised distances between the remesh ``(X, F)`` (vertex normals ``N``) and the
    input: from the input points ``P_in`` (k×3, weights ``w_in``) to their closest remesh face
    (``to_remesh``), and from the ``QUADRATURE`` points of every remesh face (weighted by its
    area), then from the remesh's vertices (weight 0: for the guards), to their closest input
    face (``to_input``, its unit face normals ``input_normals``). Each side's weights sum to
    1/2, so that the weighted sum of squares is the measure's mean of the two sides' mean
    squared distances."""
    n = len(X)
    tri = X.take(F, axis=0)
    n_face = face_normals(X, F)
    # input → remesh
    _, f_in = to_remesh(P_in)
    T = tri.take(f_in, axis=0)
    Q = closest_points_on_triangles(P_in, T[:, 0], T[:, 1], T[:, 2])
    b_in = np.clip(_plane_barycentrics(Q, T[:, 0], T[:, 1], T[:, 2]), 0.0, 1.0)
    e = P_in - Q
    nf = n_face.take(f_in, axis=0)
    r_in = dots(e, nf)
    # remesh → input: each face's points of the three-point rule, weighted by area
    m = len(F)
    area = norms(cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    f_q = np.repeat(np.arange(m), len(QUADRATURE))
    b_q = np.tile(QUADRATURE, (m, 1))
    w_out = np.repeat(area, len(QUADRATURE)) / (2.0 * len(QUADRATURE) * max(area.sum(), 1e-300))
    # then each vertex (a corner of one of its faces), for the guards alone
    corner = np.zeros(n, np.int64)
    corner[F.ravel()] = np.arange(F.size)
    f_out = np.concatenate([f_q, corner // 3])
    b_out = np.vstack([b_q, np.eye(3)[corner % 3]])
    R = lift(X, F, f_out, b_out)
    _, g = to_input(R)
    G = to_input.V.take(to_input.F.take(g, axis=0), axis=0)
    e_out = R - closest_points_on_triangles(R, G[:, 0], G[:, 1], G[:, 2])
    ng = input_normals.take(g, axis=0)
    r_out = dots(e_out, ng)
    # a sample's signed distance falls by Σ_j b_j (n · N_j) δ_j
    faces = np.concatenate([f_in, f_out])
    normal = np.vstack([nf, ng])
    bary = np.vstack([b_in, b_out])
    corners = F.take(faces, axis=0)
    vals = np.column_stack([bary[:, j] * dots(normal, N.take(corners[:, j], axis=0))
                            for j in range(3)])
    r = np.concatenate([r_in, -r_out])
    t2 = np.concatenate([dots(e, e) - r_in ** 2, dots(e_out, e_out) - r_out ** 2])
    w = np.concatenate([w_in / max(2.0 * w_in.sum(), 1e-300), w_out, np.zeros(n)])
    return Equations(F, faces, bary, vals, r, np.sqrt(np.maximum(t2, 0.0)), w, P_in,
                     np.vstack([P_in, R - e_out]), g[len(f_q):], corners)


def least_squares_offsets(eq: Equations, free: np.ndarray) -> np.ndarray:
    """The offsets (n,) of the ``free`` vertices (n bool; the others 0) that minimise the
    weighted squared distances of ``eq``, with the ridge ``FIT_RIDGE`` (module docstring)."""
    offsets = np.zeros(len(free))
    cols = np.flatnonzero(free)
    if len(cols) == 0:
        return offsets
    A, b = eq.normal_equations(len(free))
    A = A[cols][:, cols]
    diag = A.diagonal()
    ridge = FIT_RIDGE * max(float(diag.mean()), 1e-300)
    d = diag + ridge
    A = A + sp.diags(np.full(len(cols), ridge), format="csr")
    x, _ = pcg(A, b[cols, None], np.zeros((len(cols), 1)), lambda R: R / d[:, None],
               FIT_MAX_ITER, FIT_RTOL)
    if x is not None:
        offsets[cols] = x[:, 0]
    return offsets


class Guards:
    """What the offsets of :func:`guarded_offsets` are checked against, for the remesh
    ``(X, F)`` with vertex normals ``N``: the linearised distances ``eq``, the input's distance
    tree ``to_input`` and its unit face normals ``normals_in``, the smallest angle each face
    may keep (``floor``, m degrees: ``min_angle_deg`` or its own, whichever is less), the
    farthest any sample of ``eq`` was (``reach``) and the faces the measure's fold test finds
    before any offset (``folded_before``).

    :meth:`failed` measures again only what the offsets changed since its last call (the
    vertices whose offset changed, the faces at them); :meth:`start` forgets that."""

    def __init__(self, X: np.ndarray, F: np.ndarray, N: np.ndarray, eq: Equations,
                 to_input: MeshDistance, normals_in: np.ndarray, min_angle_deg: float):
        self.X, self.F, self.N, self.eq = X, F, N, eq
        self.to_input, self.normals_in = to_input, normals_in
        self.floor = np.minimum(face_min_angles(X, F), min_angle_deg)
        self.reach = float(eq.before.max(initial=0.0))
        self.normals = face_normals(X, F)
        nearest = (eq.vertex_input_face if eq.vertex_input_face is not None
                   else to_input(X)[1])
        self.under = normals_in.take(nearest, axis=0)
        self.around = vertex_faces(F, len(X))
        self.folded_before = self._folded(X, np.arange(len(F)), self.under)
        self.start()

    def start(self) -> None:
        """Measure everything again at the next call of :meth:`failed`."""
        self.last = np.zeros(len(self.X))
        self.under_now = self.under.copy()
        self.folded_now = self.folded_before.copy()
        self.distance_now = np.full(len(self.eq.before), np.nan)
        self.face_now = self.eq.face.copy()

    def _folded(self, Y: np.ndarray, faces: np.ndarray, under: np.ndarray) -> np.ndarray:
        """The measure's fold test (:func:`..remesh_quality.turned_over_faces`) of the
        ``faces`` (k,) of ``(Y, F)``: the face's normal against the normals of the input faces
        nearest each of its corners (``under``, n×3) and its centroid (looked up only for the
        faces against all three corners)."""
        corners = self.F.take(faces, axis=0)
        T = Y.take(corners, axis=0)
        normal = cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        against = np.ones(len(faces), bool)
        for j in range(3):
            against &= dots(normal, under.take(corners[:, j], axis=0)) < 0
        k = np.flatnonzero(against)
        if len(k):
            centroid = self.normals_in.take(self.to_input(T[k].mean(axis=1))[1], axis=0)
            against[k] = dots(normal[k], centroid) < 0
        return against

    def failed(self, offsets: np.ndarray) -> dict[str, np.ndarray]:
        """The faces (m bool each) that the ``offsets`` turn by more than ``TURN_DEG``
        (``turned``); that the measure's fold test finds and did not before (``folded``);
        whose corner they take nearer an input face turned against the one it was nearest
        (``sheet``: across a lip's fold to the other lip); that they leave with a smallest
        angle below ``floor`` (``angles``); or that hold a sample farther than ``FAR_SHARE``
        × ``reach`` that they take farther still (``reach``)."""
        F = self.F
        Y = self.X + offsets[:, None] * self.N
        changed = np.flatnonzero(offsets != self.last)
        at = np.zeros(len(F), bool)
        at[topo.csr_rows(self.around.indptr, self.around.indices, changed)[1]] = True
        at = np.flatnonzero(at)
        if len(changed):
            self.under_now[changed] = self.normals_in.take(self.to_input(Y[changed])[1],
                                                           axis=0)
            self.folded_now[at] = self._folded(Y, at, self.under_now)
        self.last = offsets.copy()
        crossed = dots(self.under_now, self.under) < 0
        after = face_normals(Y, F)
        # the offsets of a sample's face's corners move its point (or its closest point) by
        # at most their largest size: only the samples within that of the bound can pass it;
        # measured exactly, again where a vertex of the faces around their corners moved
        bound = FAR_SHARE * self.reach
        reach = np.abs(offsets).take(self.eq.corners).max(axis=1, initial=0.0)
        near = np.flatnonzero(self.eq.before + reach > bound)
        ring = np.zeros(len(Y), bool)
        ring[F[at]] = True
        again = near[np.isnan(self.distance_now[near])
                     | ring.take(self.eq.corners[near]).any(axis=1)]
        self.distance_now[again] = self.eq.bounds(again, Y)      # enough where within
        self.face_now[again] = self.eq.face[again]
        again = again[self.distance_now[again]
                      > np.maximum(self.eq.before[again], bound) * (1 + FAR_RTOL)]
        self.distance_now[again], self.face_now[again] = self.eq.exact_distances(
            again, Y, self.around, self.to_input)
        out = near[self.distance_now[near]
                   > np.maximum(self.eq.before[near], bound) * (1 + FAR_RTOL)]
        farther = np.zeros(len(F), bool)
        farther[self.eq.face[out]] = True
        farther[self.face_now[out]] = True
        return {"turned": dots(after, self.normals) < np.cos(np.radians(TURN_DEG)),
                "folded": self.folded_now & ~self.folded_before,
                "sheet": crossed.take(F, axis=0).any(axis=1),
                "angles": face_min_angles(Y, F) < self.floor,
                "reach": farther}


def guarded_offsets(offsets: np.ndarray, guards: Guards) -> tuple[np.ndarray, dict]:
    """``offsets`` (n,) set to 0 at the corners of the faces that fail one of the ``guards``
    (:meth:`Guards.failed`), repeated (an offset undone changes its neighbours' faces) up to
    ``GUARD_ROUNDS`` times; every offset undone if a guard still fails then. Returns the
    offsets and how many vertices each guard stopped."""
    offsets = offsets.copy()
    F = guards.F
    guards.start()
    stopped: dict[str, int] = {}
    for _ in range(GUARD_ROUNDS):
        failed = guards.failed(offsets)
        bad = np.logical_or.reduce(list(failed.values()))
        if not bad.any():
            return offsets, stopped
        undo = np.unique(F[bad])
        undo = undo[offsets[undo] != 0.0]
        for name, faces in failed.items():
            stopped[name] = stopped.get(name, 0) + int(np.isin(undo, F[faces]).sum())
        offsets[undo] = 0.0
    if np.logical_or.reduce(list(guards.failed(offsets).values())).any():
        offsets[:] = 0.0
    return offsets, stopped


def input_guard_points(V_in: np.ndarray, F_in: np.ndarray, samples: int) -> np.ndarray:
    """The input points the guards measure beside the random samples (k×3): the vertices of
    the faces ``F_in``, and where those faces are no more than the ``samples`` their edges'
    middles and their centroids — where the measure's largest distance from an input coarser
    than the remesh lies (a crease's corner or middle, a face's centre between creases)."""
    used = np.zeros(len(V_in), bool)
    used[F_in.ravel()] = True
    P = V_in[used]
    if len(F_in) > samples:
        return P
    E, _ = topo.edges_with_faces(F_in)
    return np.vstack([P, (V_in[E[:, 0]] + V_in[E[:, 1]]) / 2, face_centroids(V_in, F_in)])


def fit_to_input(S: RemeshState, L: float, min_angle_deg: float, F_in: np.ndarray,
                 to_input: MeshDistance) -> dict:
    """Offset the vertices of ``S`` along their normals to the least-squares fit of the input
    surface ``(S.V_in, F_in)`` (module docstring; ``F_in``: the input faces the remesh covers,
    without those filling the holes it keeps; ``to_input``: their distance tree; ``L``: the
    target edge length). Changes ``S.X`` in place of the lifted positions; returns what the
    remesh's ``info["improve"]["fit"]`` says of it: the vertices moved and kept at folds,
    the largest and RMS offset (in L) and the vertices each guard stopped."""
    X = np.ascontiguousarray(S.X, dtype=np.float64)
    F = np.ascontiguousarray(S.F, dtype=np.int64)
    n = len(X)
    N = vertex_normals(X, F)
    free = ~S.locked & (normal_spread(X, F, N) <= FOLD_DEG)
    normals_in = face_normals(S.V_in, F_in)
    samples = FIT_SAMPLES * n
    guard = input_guard_points(S.V_in, F_in, samples)
    P_in = np.vstack([_random_samples(S.V_in, F_in, samples, FIT_SEED), guard])
    w_in = np.r_[np.ones(samples), np.zeros(len(guard))]
    eq = offset_equations(X, F, N, P_in, w_in, MeshDistance(X, F), to_input, normals_in)
    offsets = np.clip(least_squares_offsets(eq, free), -OFFSET_CAP * L, OFFSET_CAP * L)
    offsets, stopped = guarded_offsets(offsets, Guards(X, F, N, eq, to_input, normals_in,
                                                       min_angle_deg))
    S.X = X + offsets[:, None] * N
    return {"vertices_moved": int(np.count_nonzero(offsets)),
            "kept_at_folds": int(np.count_nonzero(~S.locked & ~free)),
            "largest_offset_L": float(np.abs(offsets).max(initial=0.0) / L),
            "rms_offset_L": float(np.sqrt(np.mean(offsets ** 2)) / L) if n else 0.0,
            "undone": stopped}
