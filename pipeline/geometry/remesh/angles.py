"""The minimum-angle guarantee: local operations on the faces with a small 3D angle.

The faces left with an angle below the threshold after the improvement's global steps are
few (tens in a 5k remesh) and each has its own reason: a needle on a rim edge between two
boundary corners kept closer than the spacing, a cap whose long edge is on the rim, a cap or
needle where the surface is wrinkled finer than the remesh (a quad folded too much for the
Delaunay flips), a needle at an interior corner. :func:`raise_min_angles` takes them worst
first and tries, on the few vertices around each, the local operations that change it —

* the flip of each of its interior edges,
* a move of each of its free corners (not on the rim, not locked) to a position that raises
  the smallest angle of the corner's star: candidates towards the average of the ideal points
  of the star's faces (the apex of the equilateral triangle on each opposite edge) and towards
  the ring's centroid, made on the domain through the pull-back of the input face under it
  (:func:`.relax.tangential_smoothing`'s step), and the points of a pattern search around it
  on the domain (:func:`pattern_points`: where the map is strongly anisotropic the pull-back's
  step lands far from its aim), each located and lifted by eq. (1),
* the collapse of each of its edges (either way),

all judged on the surface: an operation is made when the smallest 3D angle of the faces it
makes is larger than that of the faces it replaces and no more of them are below the threshold
(a greedy raise of the worst face must not leave more faces below; asked with ``count_below``
False, on the smallest angle alone: at an input corner that forces faces below, sharing its
angle out among them), every new face is counter-clockwise and not thinner than
``DISK_SHAPE_MIN`` in the domain (:func:`.halfedge.disk_shape`), turns no face over in 3D,
gives no face three rim corners, and — the sag guard of the other steps — no new or moved edge
is farther from the surface than the sag tolerance unless it was already. A collapse or a move
also keeps the removed vertex or the old position within the tolerance of the new faces (no tip
or crease cut off), and a collapse removes a rim vertex only along the rim and only when the
chord that replaces its two stays within ``RIM_TOL`` × the tolerance of the input boundary
vertices it spans (or no farther than the two did: :data:`.rim.RIM_TOL`, the rim refinement's
own bound). Each operation raises the smallest angle of the faces it touches, so the pass ends;
it stops earlier after ``OPERATIONS_PER_FACE`` operations per face it started from.

The vertices collapses remove are given back by :func:`split_for_count`: the longest edges
whose split makes no face below the threshold (:func:`keeps_min_angle`).

What is left is classified by :func:`forced_by_corners`: a face whose angle is small at a
remesh vertex on an input vertex (:func:`on_input_corners`: one kept by :mod:`.corners`, a
locked vertex, or a rim vertex on a corner of the image polygon) whose own angle sum is smaller
than the threshold times the fewest faces a vertex there can have (two on the rim, where a
single face would be a leaf, three inside) is forced by the input; any other face is a failure
of the pass, counted apart in the report.
"""

from __future__ import annotations

import heapq
import math
from collections import defaultdict
from functools import partial

import numpy as np

from .._kernels import (area_spread, corners_min_degrees, disk_move_candidates,
                        face_min_degrees, fan_scores, fan_shapes_ok, faces_keep_side,
                        point_faces_distance, replacement_angle, replacement_normals,
                        star_targets)
from ..locate import lift
from ..libm import arccos, cos, sin
from ..metrics import corner_angles
from ..rows import norms, row_max
from ..topology import connected_components
from .domain import project
from .halfedge import DISK_SHAPE_MIN, disk_shape, touching
from .refine import split_long_edges
from .rim import RIM_TOL, polygon_arcs, segment_distances
from .sag import edge_sag_along, lift_samples
from .state import RemeshState

SAG_TS = np.arange(1, 8) / 8.0          # points along an edge where the sag guard looks
MOVE_FRACTIONS = (1.0, 0.5, 0.25)       # of the step towards each relocation target
PATTERN_DIRS = 16                       # and a pattern search around the vertex: directions,
PATTERN_STEPS = (0.03, 0.1, 0.25, 0.5)  # steps × the shortest domain edge of its star
MOVE_WALK = 64                          # walk steps from the vertex's input face to a candidate
#                                         (an input far finer than the remesh puts many faces
#                                         between them; a candidate the walk misses takes the grid)
OPERATIONS_PER_FACE = 20                # the pass stops after this × the faces it started with


def triangle_min_angles(P0: np.ndarray, P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    """The smallest interior angle (degrees) of each triangle ``P0, P1, P2`` (the largest of
    its corners' cosines, compiled: :func:`.._kernels.face_min_degrees`).

    Parameters
    ----------
    P0, P1, P2 : (k, 3) float
        The corners.

    Returns
    -------
    (k,) float
        0 for a triangle with coincident corners.
    """
    k = len(P0)
    P = np.ascontiguousarray(np.stack([P0, P1, P2], axis=1).reshape(3 * k, 3), dtype=np.float64)
    return face_min_angles(P, np.arange(3 * k, dtype=np.int64).reshape(k, 3))


def face_min_angles(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The smallest interior angle (degrees, k) of each face ``T`` (k×3 int) of ``X`` (n×3
    float, C-contiguous), as :func:`triangle_min_angles` of its corners, bit for bit, without
    gathering them first (compiled: :func:`.._kernels.face_min_degrees`)."""
    return face_min_degrees(X, np.ascontiguousarray(T, dtype=np.int64))


def angles_of_cosines(cos: np.ndarray) -> np.ndarray:
    """The angles (degrees) of the cosines ``cos`` (any shape), 0 where one is nan (a face
    with coincident corners)."""
    return np.degrees(arccos(np.clip(np.where(np.isnan(cos), 1.0, cos), -1.0, 1.0)))


def pattern_points(u: np.ndarray, h: float) -> np.ndarray:
    """Domain points around ``u`` for a pattern search of a vertex position: ``PATTERN_DIRS``
    directions at ``PATTERN_STEPS`` × ``h``, in the disk's plane or in the sphere's tangent
    plane at ``u``.

    Parameters
    ----------
    u : (2,) or (3,) float
    h : float
        The step unit (the shortest domain edge around the vertex).

    Returns
    -------
    (PATTERN_DIRS · len(PATTERN_STEPS), 2 or 3) float
        Not yet projected onto the domain.
    """
    if len(u) == 2:
        dirs = _CIRCLE_DIRS
    else:                                           # an orthonormal basis of the tangent plane
        e1 = np.cross(u, np.eye(3)[np.argmin(np.abs(u))])
        e1 /= np.linalg.norm(e1)
        dirs = _CIRCLE_DIRS @ np.vstack([e1, np.cross(u / np.linalg.norm(u), e1)])
    return u + (h * np.asarray(PATTERN_STEPS)[:, None, None] * dirs[None]).reshape(-1, len(u))


#: MOVE_FRACTIONS as the array (1×f×1) that scales each target's step, and PATTERN_STEPS
_MOVE_FRACTIONS = np.asarray(MOVE_FRACTIONS)[None, :, None]
_PATTERN_STEPS = np.asarray(PATTERN_STEPS, dtype=np.float64)

#: :func:`pattern_points`' directions on the disk (unit vectors, PATTERN_DIRS×2)
_CIRCLE_DIRS = np.column_stack([cos(2 * np.pi * np.arange(PATTERN_DIRS) / PATTERN_DIRS),
                                sin(2 * np.pi * np.arange(PATTERN_DIRS) / PATTERN_DIRS)])


def split_for_count(S: RemeshState, k: int, min_angle_deg: float) -> int:
    """Add ``k`` vertices by splitting the longest edges (:func:`.refine.split_long_edges`)
    among those whose split makes no face below ``min_angle_deg`` or below the faces it
    replaces (:func:`keeps_min_angle`): the longest edge can lie along a crease, where its
    lifted middle makes a cap. Returns the number of splits (fewer than ``k`` if too few edges
    qualify)."""
    return split_long_edges(S, 0.0, budget=k, accept=partial(keeps_min_angle, S, min_angle_deg))


def keeps_min_angle(S: RemeshState, min_angle_deg: float, h: np.ndarray, t: np.ndarray
                    ) -> np.ndarray:
    """Which splits of the half-edges ``h`` (``a → b`` in face ``a, b, p``; the face across,
    if any, ``b, a, q``) at ``t`` along them (k, :func:`.refine.split_edges`) make faces whose
    smallest 3D angle is at least ``min_angle_deg`` or that of the faces they replace, and —
    on the rim — no face with three rim corners (k bool). The split point is judged at the
    lift of the domain point at ``t`` (a rim edge's new vertex goes to the polygon next to
    it)."""
    F, X = S.F, S.X
    tw = S.twins()[h]
    a, b, p = F[h // 3, h % 3], F[h // 3, (h % 3 + 1) % 3], F[h // 3, (h % 3 + 2) % 3]
    rim = tw < 0
    g = np.maximum(tw, 0)
    q = np.where(rim, p, F[g // 3, (g % 3 + 2) % 3])
    W, _ = lift_samples(S, a, b, np.asarray(t, dtype=np.float64)[:, None])
    Xa, Xb, Xp, Xq = (X.take(v, axis=0) for v in (a, b, p, q))
    new = np.min([triangle_min_angles(*corners) for corners in
                  ((Xa, W, Xp), (W, Xb, Xp), (Xb, W, Xq), (W, Xa, Xq))], axis=0)
    old = np.minimum(triangle_min_angles(Xa, Xb, Xp), triangle_min_angles(Xb, Xa, Xq))
    return (new >= np.minimum(old, min_angle_deg)) & ~(rim & S.is_rim[p])


def forced_by_corners(S: RemeshState, min_angle_deg: float) -> np.ndarray:
    """Which faces (m bool) have an angle below ``min_angle_deg`` at a vertex on an input
    vertex (:func:`on_input_corners`) too sharp for any fan to do better: its angle sum on the
    input is below ``min_angle_deg`` × the fewest faces a vertex there can have — 3 inside, 2
    on the rim (a rim vertex with one face would make a face with three rim corners, a leaf
    face the remesh never has: paper Def. 4)."""
    return forced_corners(S, min_angle_deg).any(axis=1)


def forced_corners(S: RemeshState, min_angle_deg: float, faces: np.ndarray | None = None
                   ) -> np.ndarray:
    """Which corners of the faces (k×3 bool; ``faces``: k indices, default all) have an angle
    below ``min_angle_deg`` at a vertex :func:`forcing_corners` marks: a face is forced
    (:func:`forced_by_corners`) where one of its corners is."""
    F = S.F if faces is None else S.F[faces]
    return forcing_corners(S, min_angle_deg, faces) & (corner_angles_deg(S.X, F) < min_angle_deg)


def forcing_corners(S: RemeshState, min_angle_deg: float, faces: np.ndarray | None = None
                    ) -> np.ndarray:
    """Which corners of the faces (k×3 bool; ``faces``: k indices, default all) are at a
    vertex on an input vertex (:func:`on_input_corners`) too sharp for any fan to give its
    faces ``min_angle_deg`` (:func:`forced_by_corners`); read at those faces' corners alone."""
    if faces is None:
        return sharp_vertices(S, min_angle_deg)[S.F]
    return sharp_among(S, min_angle_deg, S.F[faces])


def sharp_among(S: RemeshState, min_angle_deg: float, T: np.ndarray) -> np.ndarray:
    """``sharp_vertices(S, min_angle_deg)[T]`` (the shape of ``T``, bool; ``T``: vertex
    indices of any shape), read at the vertices of ``T`` alone."""
    return sharp_vertices(S, min_angle_deg, T.ravel()).reshape(T.shape)


def sharp_vertices(S: RemeshState, min_angle_deg: float, v: np.ndarray | None = None
                   ) -> np.ndarray:
    """The vertices (n bool; given ``v``, k indices: of those, k bool) on an input vertex
    (:func:`on_input_corners`) whose angle sum on the input is below ``min_angle_deg`` × the
    fewest faces a vertex there can have (3 inside, 2 on the rim or a hole's loop,
    :meth:`.state.RemeshState.on_boundary`): the corners of :func:`forcing_corners`. Each
    vertex's answer depends on that vertex alone."""
    v = np.arange(S.n) if v is None else v
    on = np.flatnonzero(on_input_corners(S, v))
    sharp = np.zeros(len(v), bool)
    if len(on):
        sums = S.angle_sums_in()[input_vertex_under(S, v[on])]
        sharp[on] = sums < min_angle_deg * np.where(S.on_boundary(v[on]), 2, 3)
    return sharp


def on_input_corners(S: RemeshState, v: np.ndarray | None = None) -> np.ndarray:
    """The remesh vertices (n bool) that stand on an input vertex for good: the locked ones
    (:mod:`.corners` puts each exactly on its input vertex, and no operation moves or removes
    it) and the rim vertices on a corner of the image polygon (barycentric coordinate 1 at an
    input boundary vertex): no operation moves a rim vertex, so the remesh's rim passes
    through that input corner itself, as through a locked one, and its faces there share the
    corner's angle; a rim collapse would remove the vertex, and with it the corner, only where
    the chord that replaces its two rim edges stays within the rim tolerance of the input's
    boundary (:meth:`_Patch.rim_chord_ok`). An interior vertex that is not locked is not among
    them: the operations can move it off its input vertex. (The barycentrics are read at
    the rim vertices alone, their largest by :func:`..rows.row_max`: a row reduction over
    every vertex costs more than the rest of the minimum-angle bookkeeping.) Given ``v``
    (k indices), of those vertices alone (k bool)."""
    out = S.locked.copy() if v is None else S.locked[v]
    rim = np.flatnonzero(S.is_rim if v is None else S.is_rim[v])
    out[rim] |= row_max(S.bary[rim if v is None else v[rim]]) >= 1.0
    return out


def input_vertex_under(S: RemeshState, v: np.ndarray) -> np.ndarray:
    """The input vertex (k int) each remesh vertex ``v`` (k int) lies on or nearest to in its
    input face (the corner with the largest barycentric coordinate): the own input corner of a
    vertex :func:`on_input_corners` marks."""
    return S.F_in[S.face[v], np.argmax(S.bary[v], axis=1)]


def corner_angles_deg(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The angle (degrees, m×3) at every corner of the faces ``F`` of ``X``."""
    return np.degrees(corner_angles(X, F))


def raise_min_angles(S: RemeshState, min_angle_deg: float, tol: float | None,
                     faces: np.ndarray, memo: dict | None = None,
                     count_below: bool = True, first_enough: bool = False,
                     judge=None, collapses: bool = True, mean_area: float | None = None
                     ) -> int:
    """Flips, vertex moves and collapses around the faces with a 3D angle below
    ``min_angle_deg`` (module docstring), worst first; returns the number made.

    Parameters
    ----------
    S : RemeshState
        Changed in place: faces rewritten, vertices moved, collapsed vertices dropped (the
        others keep their order).
    min_angle_deg : float
    tol : float or None
        The sag tolerance (mesh units); None: no sag or gap guard.
    faces : (k,) int
        The faces to start from (those below ``min_angle_deg``:
        :func:`.improve.skinny_faces`; others are passed over).
    memo : dict, optional
        The answers of earlier judgements, added to here: ``{surroundings: option}``, the
        :meth:`_Patch.surroundings` of a face judged and the index of its best option in
        :meth:`_Patch.options`, or None where none helped. A face whose surroundings are in
        it is not judged again (its options are a function of them alone): only that option
        is made again, or it is passed over. The minimum-angle pass's rounds undo and redo
        the same changes, and the faces at forced corners stay as they were, so most of
        them are judged once instead of in every round.
    count_below : bool
        Whether an operation may leave no more of the faces it touches below
        ``min_angle_deg`` than there were (the default); without, it is judged on their
        smallest angle alone: at an input corner too sharp for any fan
        (:func:`forced_by_corners`) its faces share the corner's angle out, each below the
        threshold, only through states with more of them below (two faces of 18° at a 36°
        rim corner instead of 4° and 32°).
    first_enough : bool
        Whether a face takes the first of its options that lifts its faces' smallest angle
        to ``min_angle_deg`` (the others not judged) instead of the one that lifts it most.
    judge : callable ``judge(T) -> (angle, costs)``, optional
        For faces ``T`` (k×3 vertex rows of ``S``): the smallest angle (k, degrees) of each
        face that counts against the operations (+inf for the others), and costs of each
        face (k×c). Given, the operations are kept or undone per group
        (:meth:`_Patch.undo_worse`: the operations whose faces share an inner vertex): a group
        is undone where its faces after it have more that count, a smaller smallest angle
        among those, or a larger sum of any cost than its faces before.
    collapses : bool
        Whether the collapses are among the operations (without, the vertex count stays).
    mean_area : float, optional
        Given (a mean double face area ``Ā``), an operation that raises the sum of the squared
        relative area deviations ``(A / Ā − 1)²`` of the faces it touches is refused
        (:meth:`_Patch.spread`).

    Returns
    -------
    int
    """
    if len(faces) == 0:
        return 0
    patch = _Patch(S, faces, tol, memo, count_below, first_enough, judge, collapses,
                   mean_area)
    done = patch.run(min_angle_deg, OPERATIONS_PER_FACE * len(faces))
    if judge is not None:
        patch.undo_worse()
    patch.write_back()
    S.tally("min_angle_operations", done)
    return done


class _Patch:
    """The faces within two rings of some faces of ``S``, editable one operation at a time.

    ``faces`` maps a face id (its row in ``S.F``, or a new id past them) to its corners; a
    vertex is *inner* when all its faces are in the patch (the corners of the start faces and
    their neighbours): only inner vertices are moved, removed or have their fans changed.
    Moves are written to ``S`` at once (positions only); faces and removals at the end
    (:meth:`write_back`)."""

    def __init__(self, S: RemeshState, start: np.ndarray, tol: float | None,
                 memo: dict | None = None, count_below: bool = True,
                 first_enough: bool = False, judge=None, collapses: bool = True,
                 mean_area: float | None = None):
        self.S, self.tol = S, tol
        self.collapses = collapses            # whether the options include the collapses
        self.mean_area = mean_area            # the evenness guard's mean double area (spread)
        self.count_below = count_below        # judge the faces left below too (better)
        self.first_enough = first_enough      # take the first option reaching the threshold
        self.memo = memo                      # the answers of earlier judgements (best_option)
        near = np.zeros(S.n, bool)
        near[S.F[start].ravel()] = True
        inner = np.zeros(S.n, bool)
        inner[S.F[touching(S.F, near)].ravel()] = True
        self.rows = np.flatnonzero(touching(S.F, inner))
        self.inner = inner
        self.faces = dict(zip(self.rows.tolist(), S.F[self.rows].tolist()))
        self.vf = defaultdict(set)
        for t, f in self.faces.items():
            for v in f:
                self.vf[v].add(t)
        self.next_id = len(S.F)
        self.removed = np.zeros(S.n, bool)
        self.start = [int(t) for t in start]
        self.boundary = None                  # the input's boundary vertices, when first asked
        self.joined = None                    # S.joined as a set of pairs, when first asked
        self.threshold = 0.0                  # the minimum angle (degrees), set by :meth:`run`
        # a vertex's version counts the operations that changed a face at it (or moved a
        # neighbour); a move refused at a version is refused again until it changes
        self.version = defaultdict(int)
        self.no_move = {}
        self.judge = judge                    # per group of operations (undo_worse)
        if judge is not None:
            self.group = inner_groups(S.F[self.rows], inner)
            self.original = dict(self.faces)
            self.saved_at = self.positions(np.flatnonzero(inner))
            self.before = self.group_measures(self.original)

    def positions(self, at: np.ndarray) -> tuple:
        """``(at, X, uv, face, bary)``: copies of the positions of the vertices ``at`` (k,)."""
        S = self.S
        return at, S.X[at].copy(), S.uv[at].copy(), S.face[at].copy(), S.bary[at].copy()

    def put_positions(self, saved: tuple, put: np.ndarray | None = None) -> None:
        """Put back the positions :meth:`positions` saved in ``saved`` (of its vertices at the
        mask ``put`` (k,) over them, where given)."""
        at, X, uv, face, bary = saved
        if put is not None:
            at, X, uv, face, bary = at[put], X[put], uv[put], face[put], bary[put]
        S = self.S
        S.X[at], S.uv[at], S.face[at], S.bary[at] = X, uv, face, bary

    # ------------------------------------------------------------------------------ measures

    def face_min_angles(self, tris) -> np.ndarray:
        """The smallest 3D angle (degrees) of each face of ``tris`` (lists of 3 vertices)."""
        return face_min_angles(np.ascontiguousarray(self.S.X, dtype=np.float64),
                               np.asarray(tris, dtype=np.int64).reshape(-1, 3))

    def min_angle(self, tris) -> float:
        """The smallest 3D angle (degrees) of the faces ``tris`` (lists of 3 vertices; one
        face compiled in one call: :func:`.._kernels.corners_min_degrees`)."""
        if len(tris) == 0:
            return 180.0
        if len(tris) == 1:
            a, b, c = tris[0]
            return corners_min_degrees(np.ascontiguousarray(self.S.X, dtype=np.float64),
                                       a, b, c)
        return float(self.face_min_angles(tris).min())

    def better(self, old, new) -> float | None:
        """The smallest angle of the faces ``new`` if they beat the faces ``old`` they replace
        (a larger smallest angle and, with :attr:`count_below`, no more faces below the
        threshold; with :attr:`mean_area`, no larger :meth:`spread`), else None (compiled:
        :func:`.._kernels.replacement_angle`)."""
        after = replacement_angle(np.ascontiguousarray(self.S.X, dtype=np.float64),
                                  np.asarray([*old, *new], np.int64).reshape(-1, 3),
                                  len(old), float(self.threshold), bool(self.count_below),
                                  np.nan if self.mean_area is None else float(self.mean_area))
        return None if after != after else after          # nan: not better

    def spread(self, tris) -> float:
        """The sum of the squared relative area deviations ``(A / Ā − 1)²`` of the faces
        ``tris`` (lists of 3 vertices; ``A``: :func:`..laplacian.face_double_areas`, ``Ā``:
        :attr:`mean_area`), summed as numpy sums them (compiled:
        :func:`.._kernels.area_spread`)."""
        return area_spread(np.ascontiguousarray(self.S.X, dtype=np.float64),
                           np.asarray(tris, np.int64).reshape(-1, 3), float(self.mean_area))

    def shapes_ok(self, tris) -> bool:
        """Whether the faces ``tris`` are counter-clockwise and not thinner than
        ``DISK_SHAPE_MIN`` in the domain and have no three rim corners."""
        rim = self.S.is_rim
        if any(rim[a] and rim[b] and rim[c] for a, b, c in tris):
            return False
        return bool((disk_shape(self.S.uv, np.asarray(tris, dtype=np.int64))
                     >= DISK_SHAPE_MIN).all())

    def same_side(self, old, new) -> bool:
        """Whether no new face of ``new`` turns over against the faces ``old`` it replaces
        (:func:`_same_side`)."""
        return _same_side(self.S.X, old, new)

    def sag_ok(self, a, b, before) -> bool:
        """Whether no edge ``a–b`` is farther than the tolerance from the surface, or farther
        than ``before`` (their sag before the operation, or None for new edges with no
        predecessor)."""
        sag = self.sag(a, b)
        if sag is None:
            return True
        limit = np.full(len(sag), self.tol) if before is None else np.maximum(before, self.tol)
        return bool((sag <= limit).all())

    def gap_ok(self, point: np.ndarray, tris) -> bool:
        """Whether ``point`` (3,), a point of the surface the faces being replaced reach (a
        removed or moved vertex), is within the tolerance of the new faces ``tris``: what
        keeps a collapse or a move from cutting off a tip or a crease (the input-to-remesh
        distance)."""
        if self.tol is None:
            return True
        return bool(point_faces_distance(np.ascontiguousarray(point, dtype=np.float64),
                                         np.ascontiguousarray(self.S.X, dtype=np.float64),
                                         np.ascontiguousarray(tris, dtype=np.int64)
                                         ) <= self.tol)

    def sag(self, a, b) -> np.ndarray | None:
        """The sag of the edges ``a–b`` (None without a tolerance)."""
        if self.tol is None or len(a) == 0:
            return None
        return edge_sag_along(self.S, np.asarray(a, np.int64), np.asarray(b, np.int64),
                              SAG_TS)[0]

    def ring(self, v) -> set:
        """The neighbours of ``v``."""
        return {w for t in self.vf[v] for w in self.faces[t] if w != v}

    def is_joined(self, a, b) -> bool:
        """Whether ``a–b`` is a kept edge (``S.joined``, which the patch does not change),
        :meth:`.state.RemeshState.is_joined` of one edge."""
        if self.joined is None:
            self.joined = {(min(p, q), max(p, q)) for p, q in self.S.joined.tolist()}
        return (min(a, b), max(a, b)) in self.joined

    def edge_faces(self, a, b) -> list:
        """The patch faces with the edge ``a–b``."""
        return list(self.vf[a] & self.vf[b])

    # ---------------------------------------------------------------------------- operations

    def run(self, min_angle_deg: float, max_operations: int) -> int:
        """Worst face first: the operation at it that raises the smallest angle most, until
        none is below ``min_angle_deg`` or none helps; returns the number made."""
        self.threshold = min_angle_deg
        heap = [(self.min_angle([self.faces[t]]), t) for t in self.start if t in self.faces]
        heapq.heapify(heap)
        done = 0
        while heap and done < max_operations:
            worst, t = heapq.heappop(heap)
            if t not in self.faces or worst >= min_angle_deg:
                continue
            if self.min_angle([self.faces[t]]) != worst:
                continue                       # changed since: pushed again with its new value
            best = self.best_option(t, worst)
            if best is None or best[0] <= worst:
                continue
            new_faces = best[1]()
            done += 1
            for f in new_faces:
                if f in self.faces:
                    for v in self.faces[f]:
                        self.version[v] += 1
                    a = self.min_angle([self.faces[f]])
                    if a < min_angle_deg:
                        heapq.heappush(heap, (a, f))
        return done

    def best_option(self, t, floor: float):
        """The option of :meth:`options` at face ``t`` that raises the smallest angle most
        (the first of equals), as ``(smallest angle after, commit)``, or None where none
        raises it above ``floor`` (``t``'s own smallest angle: no gain). With a memo, the
        surroundings of ``t`` judged before give the answer found then (which option, or
        none), and only that option is made again."""
        options = self.options(t)
        key = None if self.memo is None else self.surroundings(t)
        if key is not None and key in self.memo:
            i = self.memo[key]
            return None if i is None else options[i](floor)
        best = self._best(options, floor,
                          self.threshold if self.first_enough else np.inf)
        if key is not None:
            self.memo[key] = None if best is None else best[1]
        return None if best is None else best[0]

    @staticmethod
    def _best(options, floor: float, enough: float = np.inf):
        """``(op, index)`` of the first option with the largest smallest angle after it,
        above ``floor``, or of the first one reaching ``enough``; None where none is above
        ``floor``. Each option is asked only for one above the best so far (the guards of
        those that cannot win are not evaluated)."""
        best = None
        for i, option in enumerate(options):
            op = option(floor)
            if op is not None:
                best, floor = (op, i), op[0]
                if floor >= enough:
                    break
        return best

    def surroundings(self, t) -> tuple:
        """Everything :meth:`options` at face ``t`` reads, as a hashable value: the faces at
        its corners and at their inner neighbours (in local labels: their vertices in index
        order, which the edits of ``S`` keep), those vertices' positions on the surface and
        the domain, input faces and barycentrics, and whether each is locked, on the rim and
        inner; ``t``'s corners in its order, which of its edges are kept ones
        (``S.joined``), the threshold, the tolerance and the judgement (:attr:`count_below`).
        Equal surroundings give equal options."""
        S, f, faces, vf = self.S, self.faces[t], self.faces, self.vf
        around = list(set(f).union(*[faces[u] for v in f for u in vf[v]]))
        ids = set().union(*[vf[v] for v, inner in zip(around, self.inner[around].tolist())
                            if inner])
        verts = sorted(set(f).union(*[faces[u] for u in ids]))
        label = {v: i for i, v in enumerate(verts)}
        # each face with its corners rotated so that the smallest label comes first
        tris = sorted([(a, b, c) if a < b and a < c else ((b, c, a) if b < c else (c, a, b))
                       for a, b, c in (map(label.__getitem__, faces[u]) for u in ids)])
        V = np.asarray(verts, np.int64)
        # the vertices' values as floats, column block by column block: equal bytes exactly
        # where their rows would be equal (the number of vertices is in the key)
        values = b"".join(a.take(V, axis=0).astype(np.float64, copy=False).tobytes()
                          for a in (S.X, S.uv, S.bary, S.face, S.locked, S.is_rim, self.inner))
        joined = tuple(self.is_joined(f[i], f[(i + 1) % 3]) for i in range(3))
        return (values, tuple(tris), tuple(label[v] for v in f),
                joined, self.threshold, self.tol, self.count_below, self.first_enough)

    def options(self, t) -> list:
        """The candidate operations at face ``t``, each a function of a ``floor`` that returns
        ``(smallest angle after, commit)``, or None where it is not allowed or the smallest
        angle after it is not above the floor: the flip of each edge and its collapses either
        way (without :attr:`collapses`, the flips alone), then the moves of the corners."""
        f = self.faces[t]
        edges = [(f[i], f[(i + 1) % 3]) for i in range(3)]
        if not self.collapses:
            return [partial(self.flip, a, b) for a, b in edges] + \
                [partial(self.move, v) for v in f]
        return [op for a, b in edges for op in (partial(self.flip, a, b),
                                                partial(self.collapse, a, b),
                                                partial(self.collapse, b, a))] + \
            [partial(self.move, v) for v in f]

    def flip(self, a, b, floor: float = -np.inf):
        """Flip the edge ``a–b`` (both faces in the patch, all four corners inner; not a kept
        edge, ``S.joined``)."""
        tf = self.edge_faces(a, b)
        if len(tf) != 2 or not (self.inner[a] and self.inner[b]) or self.is_joined(a, b):
            return None
        f, g = (self.faces[t] for t in tf)
        p = next(v for v in f if v not in (a, b))
        q = next(v for v in g if v not in (a, b))
        if not (self.inner[p] and self.inner[q]) or q in self.ring(p):
            return None
        # the quad a, q, b, p is counter-clockwise when f has a → b; otherwise swap the ends
        if f[(f.index(a) + 1) % 3] != b:
            tf = tf[::-1]
            f, g, p, q = g, f, q, p
        new = [[a, q, p], [q, b, p]]
        old = [f, g]
        after = self.better(old, new)
        if after is None or after <= floor or not self.shapes_ok(new):
            return None
        if not self.same_side(old, new) or not self.sag_ok([p], [q], self.sag([a], [b])):
            return None

        def commit():
            return self.replace(tf, new)
        return after, commit

    def collapse(self, r, k, floor: float = -np.inf):
        """Collapse ``r`` into ``k``: ``r`` free (not locked; on the rim only along a rim edge,
        under :meth:`rim_chord_ok`); the link condition; the guards of the module
        docstring."""
        S = self.S
        if not (self.inner[r] and self.inner[k]):
            return None
        shared = self.edge_faces(r, k)
        if not self.removable(r, shared):
            return None
        ring_r, ring_k = self.ring(r), self.ring(k)
        if len(ring_r & ring_k) != len(shared):
            return None
        old_ids = list(self.vf[r])
        old = [self.faces[t] for t in old_ids]
        kept = [t for t in old_ids if t not in shared]
        new = [[k if v == r else v for v in self.faces[t]] for t in kept]
        if not new:
            return None
        after = self.better(old, new)
        if after is None or after <= floor or not self.shapes_ok(new):
            return None
        if not self.same_side([self.faces[t] for t in kept], new):
            return None
        if S.is_rim[r] and not self.rim_chord_ok(r, k, new):
            return None
        if self.tol is not None:
            if not self.gap_ok(S.X[r], new):
                return None
            xs = sorted(ring_r - ring_k - {k})
            if not self.sag_ok([k] * len(xs), xs, self.sag([r] * len(xs), xs)):
                return None

        def commit():
            self.removed[r] = True
            out = self.replace(old_ids, new)
            del self.vf[r]
            return out
        return after, commit

    def removable(self, r, shared) -> bool:
        """Whether a collapse may remove ``r`` along the edge of the faces ``shared``: not
        locked, and on the rim only along a rim edge (one face) and with a bound for the chord
        (:meth:`chord_tol`, judged by :meth:`rim_chord_ok`)."""
        if self.S.locked[r]:
            return False
        return not self.S.is_rim[r] or (len(shared) == 1 and self.chord_tol() is not None)

    def chord_tol(self) -> float | None:
        """How far a rim chord may pass from the input boundary vertices it cuts off
        (:meth:`rim_chord_ok`): ``RIM_TOL`` × the tolerance (None without one: no rim vertex
        is removed)."""
        return None if self.tol is None else RIM_TOL * self.tol

    def cut_off(self, r, k):
        """The rim vertex ``x`` (``r``'s other rim neighbour) and the input boundary vertices
        (lifted, j×3) the polygon passes between ``k`` and ``x``: what the rim chord ``k–x``
        that replaces ``k–r`` and ``r–x`` cuts off; None where ``r`` has no other rim neighbour
        inner."""
        x = next((w for w in self.ring(r) if w != k and len(self.edge_faces(r, w)) == 1), None)
        if x is None or not self.inner[x]:
            return None
        if self.boundary is None:
            self.boundary = self.S.of_input(_BoundaryCorners)
        return x, self.boundary.between(self.S.uv[[k, r, x]])

    def rim_chord_ok(self, r, k, new) -> bool:
        """Whether the rim chord ``k–x`` that replaces ``k–r`` and ``r–x`` (:meth:`cut_off`)
        stays within :meth:`chord_tol` of the input boundary vertices the polygon passes
        between ``k`` and ``x``, or no farther from them than the two chords it replaces
        were (``new``: the faces the collapse makes, lists of 3 vertices; read by
        :meth:`.unfold._FoldPatch.rim_chord_ok`)."""
        cut = self.cut_off(r, k)
        if cut is None:
            return False
        x, P = cut
        new, old = self.boundary.chord_gaps(P, self.S.X[[k, r, x]])
        return bool(new <= max(self.chord_tol(), old))

    def move(self, v, floor: float = -np.inf):
        """Move the free inner vertex ``v`` to the candidate position (module docstring) that
        raises the smallest angle of its star most, under the guards: the three best of those
        that keep the star counter-clockwise on the domain (:func:`star_shapes_ok`) are
        tried, those not above ``floor`` not (a refusal for the floor is not remembered).
        With :attr:`count_below`, a position that leaves more faces of the star below the
        threshold is not among them, nor with :attr:`mean_area` one that raises the star's
        :meth:`spread`."""
        S = self.S
        if not self.inner[v] or S.is_rim[v] or S.locked[v]:
            return None
        if self.no_move.get(v) == self.version[v]:
            return None                        # refused, and nothing around it changed since
        self.no_move[v] = self.version[v]
        # v first, in the order of the next corners (the set's order would change the sums
        # below in the last bit, and the outcome with it, from one patch to the next)
        rotated = {t: _rotate_to(self.faces[t], v) for t in self.vf[v]}
        ids = sorted(rotated, key=lambda t: rotated[t][1])
        star = np.asarray([rotated[t] for t in ids], np.int64)
        angles = self.face_min_angles(star)
        before = min(angles.tolist())          # (no nan: face_min_angles gives 0 there)
        x, d = S.X[v].copy(), len(star)
        # the star's corners and normals, the normals' sum and the relocation targets (the
        # mean of the faces' ideal points, that of the worst face, the ring's centroid)
        B, C, N, normal, targets = star_targets(np.ascontiguousarray(S.X, dtype=np.float64),
                                                star, int(angles.argmin()))
        normal /= max(math.sqrt(normal.dot(normal)), 1e-300)   # np.linalg.norm's sum, bit for bit
        D = (_MOVE_FRACTIONS * (targets - x)[:, None, :]).reshape(-1, 3)
        D -= (D @ normal)[:, None] * normal
        J = S.pullback()[S.face[v]]
        # only the candidates that keep the star's shape on the domain are located and lifted
        # (so every candidate tried below passes :meth:`shapes_ok`: it is not asked again)
        M, ok = move_candidates(S.uv, v, star, S.uv[v] + D @ J.T)
        score = np.full(len(M), -1.0)
        mf = np.full(len(M), S.face[v])
        mb = np.zeros((len(M), 3))
        P = np.zeros((len(M), 3))
        f_ok, b_ok, inside = S.locator.relocate(M[ok], mf[ok], walk=MOVE_WALK)
        mf[ok], mb[ok] = f_ok, b_ok
        P_ok = np.ascontiguousarray(lift(S.V_in, S.F_in, f_ok, b_ok), dtype=np.float64)
        P[ok] = P_ok
        # the smallest angle of the star at each, -1 outside the map or against the guards
        # (more faces below the threshold; with the evenness guard, a larger spread)
        score[ok] = fan_scores(P_ok, B, C,
                               np.ascontiguousarray(inside, dtype=np.bool_).view(np.uint8),
                               self.threshold,
                               int((angles < self.threshold).sum()) if self.count_below else -1,
                               np.nan if self.mean_area is None else self.mean_area,
                               np.nan if self.mean_area is None else self.spread(star))
        sag_before = None                      # measured for the first candidate asked
        for j in np.argsort(-score)[:3]:
            if score[j] <= max(before, floor):
                if score[j] > before:          # refused for the floor: not for good
                    del self.no_move[v]
                break
            where = (M[j], mf[j], mb[j], P[j])
            if not _same_side_points(N, P[j], B, C) or not self._moved_ok(v, where, x, star):
                continue
            if sag_before is None:
                sag_before = self.sag([v] * d, star[:, 1])
            if self._moved_ok(v, where, x, star, sag_before):

                def commit(where=where):
                    S.uv[v], S.face[v], S.bary[v], S.X[v] = where
                    return ids
                del self.no_move[v]
                return float(score[j]), commit
        return None

    def _moved_ok(self, v, where, x, star, sag_before=None) -> bool:
        """With ``v`` put at ``where`` (domain point, input face, barycentrics, 3D point) for
        the time of the question: whether its old position ``x`` (3,) stays within the
        tolerance of its star ``star`` (d×3, :meth:`gap_ok`), or, given ``sag_before`` (the
        sag of its edges ``v–star[:, 1]`` before the move), whether those edges pass
        :meth:`sag_ok`."""
        S = self.S
        if sag_before is None:                 # gap_ok reads the surface positions alone
            old = S.X[v].copy()
            S.X[v] = where[3]
            ok = self.gap_ok(x, star)
            S.X[v] = old
            return ok
        old = (S.uv[v].copy(), S.face[v], S.bary[v].copy(), S.X[v].copy())
        S.uv[v], S.face[v], S.bary[v], S.X[v] = where
        ok = self.sag_ok([v] * len(star), star[:, 1], sag_before)
        S.uv[v], S.face[v], S.bary[v], S.X[v] = old
        return ok

    def replace(self, old_ids, new) -> list:
        """Replace the faces ``old_ids`` by ``new`` (lists of corners); returns the new ids
        (the old ones reused first)."""
        for t in old_ids:
            for v in self.faces.pop(t):
                if v in self.vf:
                    self.vf[v].discard(t)
        ids = list(old_ids[:len(new)])
        while len(ids) < len(new):
            ids.append(self.next_id)
            self.next_id += 1
        for t, f in zip(ids, new):
            self.faces[t] = list(f)
            for v in f:
                self.vf[v].add(t)
        return ids

    def face_groups(self, faces: dict) -> np.ndarray:
        """The group (:func:`inner_groups`) of each face of ``faces`` (``{id: corners}``, in
        its order): that of its inner corners."""
        T = np.asarray(list(faces.values()), np.int64).reshape(-1, 3)
        return self.group[T].max(axis=1)

    def group_measures(self, faces: dict) -> np.ndarray:
        """Per group (rows, by :attr:`group`'s labels) of ``faces`` (``{id: corners}``): how
        many count against the operations, minus their smallest angle, and the sums of the
        costs (:attr:`judge`; each column: smaller is better)."""
        T = np.asarray(list(faces.values()), np.int64).reshape(-1, 3)
        g, k = self.face_groups(faces), int(self.group.max(initial=-1)) + 1
        angle, costs = self.judge(T)
        counts = np.isfinite(angle)
        worst = np.full(k, -np.inf)
        np.maximum.at(worst, g[counts], -angle[counts])
        return np.column_stack([np.bincount(g, counts, k), worst] +
                               [np.bincount(g, c, k) for c in np.asarray(costs).T])

    def undo_worse(self) -> int:
        """Put back, group by group, the operations whose faces came out worse than they went
        in on any measure of :meth:`group_measures` (faces, removals and positions); returns
        the number of groups undone."""
        worse = np.flatnonzero((self.group_measures(self.faces) > self.before).any(axis=1))
        if len(worse) == 0:
            return 0
        undo = np.isin(self.group, worse)
        drop = np.isin(self.face_groups(self.faces), worse)
        faces = {t: f for (t, f), d in zip(self.faces.items(), drop) if not d}
        back = np.isin(self.face_groups(self.original), worse)
        faces.update((t, f) for (t, f), b in zip(self.original.items(), back) if b)
        self.faces = faces
        self.put_positions(self.saved_at, undo[self.saved_at[0]])
        self.removed[undo] = False
        return len(worse)

    def write_back(self) -> None:
        """The patch's faces into ``S.F`` (those outside it keep their rows), the removed
        vertices dropped."""
        S = self.S
        keep = np.ones(len(S.F), bool)
        keep[self.rows] = False
        F = np.vstack([S.F[keep], np.asarray(list(self.faces.values()), np.int64).reshape(-1, 3)])
        S.set_faces(F.astype(S.F.dtype, copy=False))
        if self.removed.any():
            S.keep_vertices(~self.removed)


class _BoundaryCorners:
    """The input boundary vertices (the image polygon's corners) of ``S``, lifted, and their
    arc lengths along the polygon."""

    def __init__(self, S: RemeshState):
        f, bary, _ = S.locator.locate_with_inside(S.polygon)
        self.polygon = S.of_input(polygon_arcs)          # arc lengths along S.polygon
        self.X = lift(S.V_in, S.F_in, f, bary)
        self.s = self.polygon.arc_position(S.polygon)
        self.length = float(norms(np.roll(S.polygon, -1, axis=0) - S.polygon).sum())
        self.arcs = {}                        # arc_parameters of the rim points asked
        self.cut = {}                         # between() of the rim point triples asked
        self.gaps = {}                        # chord_gaps() of the chords asked

    def arc(self, uv: np.ndarray) -> list:
        """:func:`.sampling.arc_parameters` of the rim points ``uv`` (k×2), each computed
        once (a rim vertex does not move)."""
        keys = [p.tobytes() for p in uv]
        new = [i for i, key in enumerate(keys) if key not in self.arcs]
        if new:
            for i, s in zip(new, self.polygon.arc_position(uv[new])):
                self.arcs[keys[i]] = s
        return [self.arcs[key] for key in keys]

    def between(self, uv: np.ndarray) -> np.ndarray:
        """The lifted corners (k×3, read-only) strictly inside the arc from ``uv[0]`` to
        ``uv[2]`` (rim points, 3×2) that passes through ``uv[1]``, each triple computed once
        (rim vertices do not move: the collapses ask the same ones again and again)."""
        key = uv.tobytes()
        if key not in self.cut:
            sa, sv, sb = self.arc(uv)
            span = (sb - sa) % self.length
            if (sv - sa) % self.length > span:
                sa, span = sb, (sa - sb) % self.length
            d = (self.s - sa) % self.length
            self.cut[key] = self.X[(d > 0) & (d < span)]
            self.cut[key].flags.writeable = False
        return self.cut[key]

    def chord_gaps(self, P: np.ndarray, X: np.ndarray) -> tuple[float, float]:
        """How far the points ``P`` (j×3: the corners :meth:`between` the rim vertices at
        ``X``, 3×3, ``k, r, x``) lie from the chord ``k–x`` and from the nearer of ``k–r`` and
        ``r–x`` (:func:`.rim.segment_distances`; the largest of each, 0 where ``P`` is empty),
        each computed once."""
        key = (X.tobytes(), P.tobytes())
        if key not in self.gaps:
            new = segment_distances(P, *(np.repeat(X[[w]], len(P), axis=0) for w in (0, 2)))
            old = np.minimum(*(segment_distances(P, *(np.repeat(X[[w]], len(P), axis=0)
                                                      for w in pair))
                               for pair in ((0, 1), (1, 2))))
            self.gaps[key] = (new.max(initial=0.0), old.max(initial=0.0))
        return self.gaps[key]


def inner_groups(T: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """The groups of the ``inner`` vertices (n bool) of the faces ``T`` (k×3): two inner
    vertices are in one group when a chain of faces of ``T`` joins them, each sharing an
    inner vertex with the next (the operations of :class:`_Patch` change only the faces at
    inner vertices, so those of different groups touch no face or vertex in common).

    Returns
    -------
    (n,) int
        The group of each inner vertex of ``T`` (0, 1, ...), -1 for the other vertices.
    """
    n = len(inner)
    apart = np.where(inner[T], T, n + np.arange(T.size).reshape(T.shape))
    _, label = connected_components(apart, n + T.size)
    group = np.full(n, -1, np.int64)
    group[T[inner[T]]] = np.repeat(label, 3)[inner[T].ravel()]
    return group


def move_candidates(uv: np.ndarray, v: int, star: np.ndarray, aimed: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The candidate domain positions of a move of ``v`` (its star ``star``, d×3, ``v``
    first): the positions ``aimed`` (j×2 or j×3) and the :func:`pattern_points` around
    ``uv[v]`` (the step unit: the shortest domain edge of the star), put on the domain
    (:func:`.domain.project`), and the indices of those that keep the star's shape
    (:func:`star_shapes_ok`). On the disk in one compiled pass
    (:func:`.._kernels.disk_move_candidates`, the same values bit for bit).

    Returns
    -------
    M : (k, 2) or (k, 3) float
    ok : (j,) int
    """
    BC = np.ascontiguousarray(star[:, 1:], dtype=np.int64)
    if uv.shape[1] == 2:
        return disk_move_candidates(np.ascontiguousarray(uv, dtype=np.float64), int(v), BC,
                                    np.ascontiguousarray(aimed, dtype=np.float64),
                                    _PATTERN_STEPS, _CIRCLE_DIRS,
                                    DISK_SHAPE_MIN)
    h = norms(uv[BC].reshape(-1, uv.shape[1]) - uv[v]).min()
    M = project(np.vstack([aimed, pattern_points(uv[v], h)]))
    return M, np.flatnonzero(star_shapes_ok(uv, M, BC))


def star_shapes_ok(uv: np.ndarray, M: np.ndarray, BC: np.ndarray) -> np.ndarray:
    """For each candidate domain position ``M[j]`` of a vertex whose star's faces are
    ``(v, B, C)`` (``BC``: d×2 vertex indices, counter-clockwise after ``v``), whether every
    face of the star stays counter-clockwise and not thinner than ``DISK_SHAPE_MIN`` in the
    domain with ``v`` there (j bool): where the map's stretch changes fast, the position best
    on the surface often folds a face on the domain, and the next best must be tried."""
    U = np.vstack([M, uv[BC[:, 0]], uv[BC[:, 1]]]).astype(np.float64, copy=False)
    return fan_shapes_ok(U, len(M), len(BC), DISK_SHAPE_MIN)


def _rotate_to(f, v) -> list:
    """The face ``f`` (3 vertices) with its corners rotated so that ``v`` comes first."""
    i = f.index(v)
    return [f[i], f[(i + 1) % 3], f[(i + 2) % 3]]


def _same_side(X: np.ndarray, old, new) -> bool:
    """Whether each new face's 3D normal agrees (positive dot product) with the summed normal
    of the old faces: no face of the operation turns over on the surface (the normals
    compiled: :func:`.._kernels.replacement_normals`)."""
    n_new, n_old = replacement_normals(np.ascontiguousarray(X, dtype=np.float64),
                                       np.asarray(old, np.int64).reshape(-1, 3),
                                       np.asarray(new, np.int64).reshape(-1, 3))
    return bool((n_new @ n_old > 0).all())


def _same_side_points(n0: np.ndarray, A1: np.ndarray, B: np.ndarray, C: np.ndarray) -> bool:
    """Whether every face ``(A, B, C)`` keeps the side its normal ``n0`` (k×3, ``(B − A) ×
    (C − A)``) points to when ``A`` moves to ``A1`` (3,) (3D; a move that turns a face over
    is refused)."""
    return bool(faces_keep_side(*(np.ascontiguousarray(P, dtype=np.float64)
                                  for P in (n0, A1, B, C))))
