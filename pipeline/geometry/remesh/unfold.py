"""Folds undone by local operations judged on the folds themselves.

A face counter-clockwise on the domain can lift to one turned over against the input
(:func:`turned_over`): its lift is the triangle through the lifts of its corners, not the
image of the domain triangle, and where the map is strongly anisotropic and its stretch turns
from one input face to the next (an input vertex where long thin faces meet, a narrow strip
or the tip of a thin tube squeezed into little domain area) a face across a few input faces
doubles back over the surface; and where the input folds back sharper than a right angle
within less than an edge of the remesh (a lip's fold), a face with its corners on the creases
lies over one side on the domain and turns against the other in 3D. Its angles do not show
it (a fold can be equilateral), so the minimum-angle operations, which judge angles, leave it;
collapsing it removes the surface it stands on and turns its neighbours over in turn.

:func:`unfold_locally` takes the folds one at a time and makes, among the local operations of
:mod:`.angles` at the fold — the flip of each of its interior edges, the collapse of each of
its edges either way, the move of each of its free corners — the one that removes the most
folds from the faces it changes, then leaves the largest smallest 3D angle
(:class:`_FoldPatch`). Given a ``chord`` bound, a collapse may also remove a rim corner that
stands on a reflex corner of the input boundary (locked or not) along the rim, where that
leaves the input no farther than ``chord`` from the remesh either way
(:meth:`_FoldPatch.removable`, :meth:`_FoldPatch.rim_chord_ok`): at a notch's end of a ragged
rim, the fold across the notch has no other undoing. A move goes to the point of the corner's
star on the domain with the fewest faces of the star turned over, then the largest smallest
angle (:func:`star_grid`: a barycentric grid over each face of the star, and the input
vertices under the star — where the map is that anisotropic the good positions are a small
part of the domain star, often at the input vertex where the stretch turns, which a pull-back
step would miss), among those that keep the star counter-clockwise and not thinner than
``DISK_SHAPE_MIN`` on the domain (:func:`.angles.star_shapes_ok`). Every operation (and every
two-step, below) removes a fold, so the pass ends; no sag or gap guard but the rim collapses'
(the folds are where the remesh already leaves the surface) and no angle floor (the
minimum-angle pass comes after and raises what the operations leave skinny).

Where the input's boundary turns back on itself (a notch's end of a ragged rim, an input
vertex whose faces span up to 360° squeezed into half a turn on the domain) and the remesh is
finer than the notch, the faces around it are counter-clockwise on the domain while a ring of
them doubles back over the notch's end on the surface, and no one of these operations undoes
the group: each leaves another of its faces turned over. Where it removes more folds than the
best of them, the chart triangulation (:meth:`_FoldPatch.chart`) is made instead: the faces
within one to ``CHART_RINGS`` rings of the fold laid out anew, their vertices kept, as the
surface lays them out — the Delaunay triangulation of the vertices projected onto the plane
across the input's normals there with the region's outline flipped in
(:func:`chart_triangulation`, :func:`recover_edges`) — where the outline is a simple polygon in
that plane and the faces are counter-clockwise and not thin on the domain; of the rings, the
one with the best score.

Where neither removes the fold — at a ragged rim's notch end beside a locked spike tip, the
fold's rim corners the locked tip and a vertex on the notch, each operation there leaving the
fold count as it was — a rim collapse at the fold that keeps the count is made
(:meth:`_FoldPatch.two_step`, under the rim collapses' guards) where an operation at the faces
it makes then removes a fold and the two push no face below the minimum angle where none of
those they replaced was, and the two are made together; where none does, the collapse is put
back. The two-steps come last, once the single operations and charts have done what they can at
every other fold: a fold set aside may be removed by an operation at a neighbouring one, and a
two-step made earlier sets the later operations on another course.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from ...errors import UserError
from .. import topology as topo
from ..locate import lift
from ..remesh_quality import closest_points_on_triangles, degenerate_faces
from ..rows import cross, dots, norms
from .angles import (_Patch, face_min_angles, input_vertex_under, star_shapes_ok,
                     triangle_min_angles)
from .domain import project
from .fidelity import input_distance
from .halfedge import DISK_SHAPE_MIN, disk_shape, double_areas, touching
from .state import RemeshState

GRID = 6                   # the barycentric grid over each face of a star: steps of 1/GRID
OPERATIONS_PER_FOLD = 10   # the pass stops after this × the folds it started with
FOLD_WEIGHT = 180.0        # an operation's score: this × the folds it removes + the smallest
                           # angle (degrees) of the faces it makes
CHART_RINGS = 3            # the region of a chart triangulation: the faces within this many
                           # rings of a fold's corners at most
ON_EDGE = 1e-9             # a barycentric coordinate at most this puts a point on the edge of
                           # its input face opposite that corner (and two, on a vertex)
CENTROID_WALK = 64         # walk steps from a corner's input face to a face's domain centroid
                           # or to a candidate of unfolding_position (an input far finer than
                           # the remesh puts many faces between them; a point the walk misses
                           # takes the grid)


def turned_over(S: RemeshState, P: np.ndarray, U: np.ndarray, under: np.ndarray,
                bary: np.ndarray, ties: bool = False) -> np.ndarray:
    """Whether each face with corners ``P`` on the surface, ``U`` on the domain and in the input
    faces ``under`` at the barycentrics ``bary`` is turned over against the input: its normal
    points against the input's normal at each of its corners and at its centroid.

    A corner is judged at the input face ``under`` it or, with ``ties``, against every input
    face it lies on (:func:`least_dots`: on an input edge or vertex, turned against the input
    where the normal points against any of them). Where the input folds sharper than a right
    angle, the face the map puts a point on the crease in is one of two that turn against each
    other, and the closest-point query of the report's test
    (:func:`..remesh_quality.turned_over_faces`) may pick the other; with ``ties`` the test
    does not depend on either choice. The centroid is judged at the input face under the domain
    centroid (located in the input map, from the input face of the first corner) and, where
    that passes, at the input face closest to the 3D centroid (:func:`.fidelity.input_distance`):
    a face across a fold narrower than itself lies over one side of the fold on the domain and
    nearer the other in 3D. With ``ties``, a face the report's test counts is counted here too
    (but for a tie at its centroid, or a corner nearer than ``ON_EDGE`` to an input edge).
    The fold repair leaves ``ties`` off: with it, it also takes up faces at the creases of a
    noisy scan that the report's test, at its ties, does not count, and the settle step's
    insertions at such a crease count as folds and are undone, which leaves the remesh farther
    from the input there; the joins of feature points, which make such faces, use it
    (:func:`.features.join_edges`).

    Parameters
    ----------
    S : RemeshState
        Its input map (normals, adjacency, locator, distance tree).
    P : (k, 3, 3) float
    U : (k, 3, 2) or (k, 3, 3) float
    under : (k, 3) int
    bary : (k, 3, 3) float
    ties : bool

    Returns
    -------
    (k,) bool
    """
    k = len(P)
    normal = cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    if ties:
        least = least_dots(S, np.repeat(normal, 3, axis=0), under.reshape(-1),
                           bary.reshape(-1, 3)).reshape(k, 3)
    else:
        least = np.einsum("ij,ikj->ik", normal, S.normals_in().take(under, axis=0))
    out = np.all(least < 0, axis=1)
    suspect = np.flatnonzero(out)
    if len(suspect):
        at, _, _ = S.locator.relocate(project(U[suspect].mean(axis=1)), under[suspect, 0],
                                      walk=CENTROID_WALK)
        out[suspect] = dots(normal[suspect], S.normals_in().take(at, axis=0)) < 0
        across = suspect[~out[suspect]]
        if len(across):
            _, nearest = S.of_input(input_distance)(P[across].mean(axis=1))
            out[across] = dots(normal[across], S.normals_in().take(nearest, axis=0)) < 0
    return out


def least_dots(S: RemeshState, normal: np.ndarray, under: np.ndarray, bary: np.ndarray
               ) -> np.ndarray:
    """The smallest dot product of each ``normal`` with the normals of the input faces its
    point lies on: the input face ``under`` it and, where a barycentric coordinate is at most
    ``ON_EDGE``, the face across that edge (one such coordinate) or every face at that vertex
    (two).

    Parameters
    ----------
    S : RemeshState
    normal : (k, 3) float
    under : (k,) int
    bary : (k, 3) float

    Returns
    -------
    (k,) float
    """
    N = S.normals_in()
    out = dots(normal, N.take(under, axis=0))
    zero = bary <= ON_EDGE
    count = zero.sum(axis=1)
    twin, indptr, indices = S.of_input(input_incidence)
    e = np.flatnonzero(count == 1)
    if len(e):
        across = twin[3 * under[e] + (zero[e].argmax(axis=1) + 1) % 3]
        e, across = e[across >= 0], across[across >= 0]
        out[e] = np.minimum(out[e], dots(normal[e], N[across // 3]))
    v = np.flatnonzero(count >= 2)
    if len(v):
        corner = S.F_in[under[v], (~zero[v]).argmax(axis=1)]
        row, f = topo.csr_rows(indptr, indices, corner)
        np.minimum.at(out, v[row], dots(normal[v[row]], N[f]))
    return out


def input_incidence(S: RemeshState) -> tuple:
    """The input's half-edge twins (3M, :func:`..topology.interior_edge_twins`) and its
    vertex–face incidence (the CSR ``indptr``, ``indices`` of :func:`..topology.vertex_faces`):
    what :func:`least_dots` reads, made once per input (:meth:`.state.RemeshState.of_input`)."""
    incidence = topo.vertex_faces(S.F_in, len(S.V_in))
    return topo.interior_edge_twins(S.F_in), incidence.indptr, incidence.indices


def turned_over_rows(S: RemeshState, T: np.ndarray, ties: bool = False) -> np.ndarray:
    """:func:`turned_over` for faces ``T`` (k×3 vertex indices) of ``S``; k bool."""
    T = np.asarray(T, np.int64).reshape(-1, 3)
    return turned_over(S, S.X.take(T, axis=0), S.uv.take(T, axis=0), S.face[T],
                       S.bary.take(T, axis=0), ties)


def star_grid(uv: np.ndarray, star: np.ndarray, steps: int = GRID) -> np.ndarray:
    """Domain points spread over the star of a vertex: for each face ``(v, B, C)`` of
    ``star`` (the vertex first), the points ``(i·uv[v] + j·uv[B] + k·uv[C]) / steps`` with
    ``i + j + k = steps`` and ``i ≥ 1`` (the opposite edge left out), projected onto the domain.

    Parameters
    ----------
    uv : (n, 2) or (n, 3) float
    star : (d, 3) int
    steps : int

    Returns
    -------
    (d · steps · (steps + 1) / 2, 2 or 3) float
    """
    ijk = np.array([(i, j, steps - i - j) for i in range(1, steps + 1)
                    for j in range(steps - i + 1)], float) / steps
    return project(np.einsum("gc,dck->dgk", ijk, uv[star]).reshape(-1, uv.shape[1]))


def unfold_locally(S: RemeshState, folds: np.ndarray, chord: float | None = None,
                   floor: float = 0.0) -> int:
    """The local operations around the faces ``folds`` (turned over), each made only where it
    leaves fewer of the faces it changes turned over (module docstring); returns the number
    made.

    Parameters
    ----------
    S : RemeshState
        Changed in place: faces rewritten, vertices moved, collapsed vertices dropped (the
        others keep their order).
    folds : (k,) int
    chord : float, optional
        With it, a collapse may also remove a rim vertex that stands on a reflex corner of
        the input boundary along the rim (:meth:`_FoldPatch.removable`) where that leaves the
        input no farther than ``chord`` from the remesh (:meth:`_FoldPatch.rim_chord_ok`).
    floor : float
        The minimum angle (degrees) a two-step may not push the faces it changes below
        (:meth:`_FoldPatch.keeps_floor`).

    Returns
    -------
    int
    """
    if len(folds) == 0:
        return 0
    patch = _FoldPatch(S, folds, chord, floor)
    done = patch.unfold(OPERATIONS_PER_FOLD * len(folds))
    patch.write_back()
    S.tally("fold_operations", done)
    return done


class _FoldPatch(_Patch):
    """The patch of :mod:`.angles` around some folds, its operations judged by the faces they
    leave turned over (:func:`turned_over`) rather than by angles alone; no guards (``tol``
    None) but the rim collapses', ``chord`` (:meth:`rim_chord_ok`; None: no rim vertex
    removed), and the two-steps' ``floor`` (:meth:`keeps_floor`)."""

    def __init__(self, S: RemeshState, folds: np.ndarray, chord: float | None = None,
                 floor: float = 0.0):
        super().__init__(S, faces_within(S.F, folds, CHART_RINGS - 2, S.n), None)
        self.start = [int(t) for t in folds]
        self.chord = chord
        self.floor = floor
        self.wide = self.inner                 # the vertices a chart's region may hold
        self.inner = np.zeros(S.n, bool)       # those the other operations may change
        self.inner[S.F[faces_within(S.F, folds, 0, S.n)].ravel()] = True
        self.own = set(np.flatnonzero(touching(S.F, self.inner)).tolist())
        self.least_removed = 1                 # the folds an operation must remove (better)

    def n_folds(self, tris) -> int:
        """How many of the faces ``tris`` (lists of 3 vertices) are turned over."""
        return int(turned_over_rows(self.S, tris).sum())

    def better(self, old, new) -> float | None:
        """The score of replacing the faces ``old`` by ``new`` (``FOLD_WEIGHT`` × the folds
        removed + the smallest angle of ``new``) if ``new`` has at least ``least_removed``
        fewer folds (1; 0 for the first step of :meth:`two_step`) and no face degenerate on
        the surface (:func:`..remesh_quality.degenerate_faces`: a rim chord between the two
        copies of an input vertex the intake split at a bowtie has zero length, and no later
        step may remove a locked end of it), else None."""
        removed = self.n_folds(old) - self.n_folds(new)
        if removed < self.least_removed or len(degenerate_faces(self.S.X, np.asarray(new))):
            return None
        return FOLD_WEIGHT * removed + self.min_angle(new)

    def same_side(self, old, new) -> bool:
        """No test against the old faces' summed normal: it counts a fold's own turned normal
        (:meth:`better` judges the faces against the input)."""
        return True

    def chord_tol(self) -> float | None:
        """The bound of the rim chords, ``chord``."""
        return self.chord

    def rim_chord_ok(self, r, k, new) -> bool:
        """Whether the collapse of the rim vertex ``r`` into ``k`` leaves the input no farther
        from the remesh than ``chord`` either way: each input boundary vertex the new rim chord
        cuts off (:meth:`.angles._Patch.cut_off`) within ``chord`` of the patch's faces at its
        inner vertices as the collapse leaves them (a notch's end cut off often lies nearer the
        faces beside it than the chord), the centroids and edge middles of the faces it makes
        (``new``, lists of 3 vertices) within ``chord`` of the input (a chord across a wide
        notch spans empty space)."""
        cut = self.cut_off(r, k)
        if cut is None:
            return False
        P, X = cut[1], self.S.X
        shared = self.edge_faces(r, k)
        if len(P):
            inner = self.inner                 # a face's corners one by one: no index array
            T = np.asarray([[k if v == r else v for v in f] for t, f in self.faces.items()
                            if t not in shared and (inner[f[0]] or inner[f[1]] or inner[f[2]])],
                           np.int64)
            Q = np.repeat(P, len(T), axis=0)
            near = closest_points_on_triangles(Q, *(np.tile(X[T[:, c]], (len(P), 1))
                                                    for c in range(3)))
            if norms(Q - near).reshape(len(P), len(T)).min(axis=1).max() > self.chord:
                return False
        new = np.asarray(new, np.int64)
        M = np.vstack([X[new].mean(axis=1),
                       ((X[new] + X[np.roll(new, 1, axis=1)]) / 2).reshape(-1, 3)])
        return bool(self.S.of_input(input_distance)(M)[0].max() <= self.chord)

    def removable(self, r, shared) -> bool:
        """As :meth:`.angles._Patch.removable` inside; on the rim, a vertex (locked or not)
        along a rim edge that stands on a reflex corner of the input boundary (an input vertex
        whose faces span more than 180°), given ``chord``.

        At a notch's or a slit's end (a scan's ragged rim) the input's faces span up to
        360°, and the map straightens the boundary: the disk triangulation leaves the rim
        vertex there with two faces, one of which spans more than 180° on the surface —
        turned over, across the notch. Where the rim is ragged at the remesh's scale, the
        faces that would span the notch's end without it have three rim corners (not
        allowed), so no flip or move undoes it; the rim vertex's removal, the chord across
        the notch's mouth, does. Snapped corners (:mod:`.corners`, locked) stand there, and
        the rim refinement's vertices (:func:`.rim.refine_rim` splits at the input boundary
        vertex farthest from a chord, often a notch's end)."""
        S = self.S
        if not S.is_rim[r]:
            return super().removable(r, shared)
        if len(shared) != 1 or self.chord is None or S.bary[r].max() < 1.0 - ON_EDGE:
            return False
        return bool(S.angle_sums_in()[input_vertex_under(S, np.array([r]))[0]] > 180.0)

    def chart(self, t):
        """Triangulate anew the faces within ``k`` rings of the corners of face ``t`` (``k`` =
        1 … ``CHART_RINGS``, their corners all in ``wide``) as :func:`chart_triangulation`
        lays them out; of the regions where that removes folds, the one with the best score
        (``FOLD_WEIGHT`` × the folds removed + the smallest angle of its faces). Refused where
        a region holds an interior kept edge (``S.joined``) or its outline is not a simple
        loop, or the new faces are thinner than ``DISK_SHAPE_MIN`` on the domain, have three rim
        corners or an edge between two of its outline's vertices that a face outside the region
        already has."""
        S = self.S
        corners = set(self.faces[t])
        best = None
        for _ in range(CHART_RINGS):
            region = sorted({r for v in corners for r in self.vf[v]})
            old = np.asarray([self.faces[r] for r in region], np.int64)
            corners = set(old.ravel().tolist())
            if not self.wide[old].all():
                break
            new = self.chart_faces(region, old)
            if new is None:
                continue
            removed = self.n_folds(old) - self.n_folds(new)
            if removed > 0:
                score = FOLD_WEIGHT * removed + self.min_angle(new)
                if best is None or score > best[0]:
                    best = (score, region, new.tolist())
        if best is None:
            return None
        score, region, new = best

        def commit():
            S.tally("fold_charts", 1)
            return self.replace(region, new)
        return score, commit

    def chart_faces(self, region: list, old: np.ndarray):
        """The faces :func:`chart_triangulation` makes of the faces ``old`` (rows ``region``),
        or None where :meth:`chart` refuses them."""
        S = self.S
        local, T = np.unique(old, return_inverse=True)
        T = T.reshape(-1, 3)
        try:
            loops = topo.boundary_loops(T)
        except UserError:
            return None
        if len(loops) != 1 or (len(local) - len(loops[0])) * 2 + len(loops[0]) - 2 != len(T):
            return None
        outline = local[loops[0]]
        a, b = old.ravel(), np.roll(old, -1, axis=1).ravel()
        interior = np.isin(b * S.n + a, a * S.n + b)
        if S.is_joined(a[interior], b[interior]).any():
            return None
        inside = np.setdiff1d(local, outline)
        new = chart_triangulation(S, outline, inside)
        if new is None or S.is_rim[new].all(axis=1).any():
            return None
        if (disk_shape(S.uv, new) < DISK_SHAPE_MIN).any():
            return None
        inside_region = set(region)
        on_outline = set(outline.tolist())
        outline_edges = set(zip(outline.tolist(), np.roll(outline, -1).tolist()))
        for a, b in zip(new.ravel().tolist(), np.roll(new, -1, 1).ravel().tolist()):
            if a in on_outline and b in on_outline and (a, b) not in outline_edges and \
                    (b, a) not in outline_edges and \
                    any(b in self.faces[r] for r in self.vf[a] - inside_region):
                return None
        return new

    def write_back(self) -> None:
        """As :meth:`.angles._Patch.write_back`, the faces a chart did not change outside the
        rows of the other operations (``own``) left in their rows: the faces' order is that
        of the patch without the charts' reach."""
        S = self.S
        same = [t for t in self.rows.tolist() if t not in self.own and t in self.faces
                and self.faces[t] == S.F[t].tolist()]
        for t in same:
            del self.faces[t]
        self.rows = np.setdiff1d(self.rows, same)
        super().write_back()

    def move(self, v):
        """Move the free inner vertex ``v`` to the point of :func:`star_grid` (or an input
        vertex under its star) with the fewest faces of its star turned over, then the largest
        smallest angle, if that is fewer than now."""
        S = self.S
        if not self.inner[v] or S.is_rim[v] or S.locked[v]:
            return None
        ids = list(self.vf[v])
        star = np.asarray([[f[(f.index(v) + i) % 3] for i in range(3)]
                           for f in (self.faces[t] for t in ids)], np.int64)
        now = self.n_folds(star)
        if now == 0:
            return None
        best = unfolding_position(S, v, star)
        if best is None or best[1] >= now:
            return None
        where, n_after, angle = best

        def commit():
            S.uv[v], S.face[v], S.bary[v], S.X[v] = where
            return ids
        return FOLD_WEIGHT * (now - n_after) + angle, commit

    def best_at(self, t):
        """The best operation at face ``t`` (:meth:`.angles._Patch.options`): the
        ``(score, commit)`` with the highest score (the first of equals), or None where none
        removes a fold."""
        return max((op for op in (option() for option in self.options(t)) if op is not None),
                   key=lambda op: op[0], default=None)

    def rim_pairs(self, t) -> list:
        """The rim edges at the rim corners of face ``t``: ``(r, k)``, each rim corner ``r``
        with each of its neighbours ``k`` along the rim."""
        return [(r, k) for r in self.faces[t] if self.S.is_rim[r]
                for k in [w for w in self.ring(r) if len(self.edge_faces(r, w)) == 1]]

    def level_collapse(self, r, k):
        """:meth:`.angles._Patch.collapse` of ``r`` into ``k`` under its guards
        (:meth:`removable`, the link condition, the faces' shapes, :meth:`rim_chord_ok`) with
        ``least_removed`` 0: allowed where it leaves the folds of the faces it changes no more
        than before."""
        self.least_removed = 0
        try:
            return self.collapse(r, k)
        finally:
            self.least_removed = 1

    def snapshot(self) -> tuple:
        """The patch's faces, incidences, removals and next face id, and the positions of its
        inner vertices (:meth:`.angles._Patch.positions`), for :meth:`restore`."""
        return (dict(self.faces), {v: set(s) for v, s in self.vf.items()},
                self.removed.copy(), self.next_id, self.positions(np.flatnonzero(self.inner)))

    def restore(self, saved: tuple) -> None:
        """Put back the patch as :meth:`snapshot` saved it."""
        self.faces, vf, self.removed, self.next_id, positions = saved
        self.vf.clear()
        self.vf.update(vf)
        self.put_positions(positions)

    def keeps_floor(self, saved: tuple) -> bool:
        """Whether the faces changed since :meth:`snapshot` saved ``saved`` (their corners, or
        a corner's position) have no smallest angle below :attr:`floor`, or one of the faces
        they replaced had (each measured at its own positions)."""
        faces, at, X0 = saved[0], saved[4][0], saved[4][1]
        moved = set(at[(self.S.X[at] != X0).any(axis=1)].tolist())
        new = [f for t, f in self.faces.items() if faces.get(t) != f or moved.intersection(f)]
        if self.min_angle(new) >= self.floor:
            return True
        old = [f for t, f in faces.items() if self.faces.get(t) != f or moved.intersection(f)]
        X = self.S.X.copy()
        X[at] = X0
        return bool((face_min_angles(X, np.asarray(old, np.int64).reshape(-1, 3))
                     < self.floor).any())

    def two_step(self, t) -> list | None:
        """Where no single operation and no chart removes the fold ``t``: a rim collapse at it
        that keeps the fold count (:meth:`rim_pairs`, :meth:`level_collapse`), kept only where
        an operation at the faces it makes then removes a fold (:meth:`best_at`) and the two
        push none of the faces they change below the floor (:meth:`keeps_floor`), made with
        it; else put back (:meth:`snapshot`, :meth:`restore`). Returns the ids of the faces
        the two made, or None where no pair does.

        At a ragged rim's notch end beside a locked spike tip, the fold's rim corners are the
        locked tip and a vertex whose removal moves the fold to a face the second operation
        undoes: each alone leaves the fold count as it was. A pair that makes a face below the
        floor where none of those it replaced was leaves the fold instead: the minimum-angle
        pass would have to raise that face where the remesh folded, and its refinements,
        undone as a whole where they turn a face over, can turn that spot over again and so
        leave faces below the minimum elsewhere that they would have raised."""
        for r, k in self.rim_pairs(t):
            first = self.level_collapse(r, k)
            if first is None:
                continue
            saved = self.snapshot()
            made = first[1]()
            second = None
            for u in made:
                if u in self.faces and self.n_folds([self.faces[u]]):
                    op = self.best_at(u)
                    if op is not None and (second is None or op[0] > second[0]):
                        second = op
            if second is not None:
                made = made + list(second[1]())
                if self.keeps_floor(saved):
                    self.S.tally("fold_two_steps", 1)
                    return made
            self.restore(saved)
        return None

    def unfold(self, max_operations: int) -> int:
        """Fold after fold: the best operation at it (:meth:`best_at`), or its chart
        triangulation (:meth:`chart`) where that removes more folds than the best of them, the
        folds it makes taken up in turn; the folds neither removes set aside, and once no
        other fold is left, a rim collapse and an operation after it at each of them still
        turned over (:meth:`two_step`, two operations), the folds it makes taken up in turn as
        before; until none is left or none helps. Returns the number made."""
        queue = [t for t in self.start if t in self.faces]
        stuck = []
        done = 0
        while (queue or stuck) and done < max_operations:
            if not queue:
                t = stuck.pop()
                if t not in self.faces or not self.n_folds([self.faces[t]]):
                    continue
                made = self.two_step(t)
                if made is None:
                    continue
                done += 2
                queue.extend(f for f in made if f in self.faces and self.n_folds([self.faces[f]]))
                continue
            t = queue.pop()
            if t not in self.faces or not self.n_folds([self.faces[t]]):
                continue
            best = self.best_at(t)
            chart = self.chart(t)
            if chart is not None and (best is None or
                                      chart[0] // FOLD_WEIGHT > best[0] // FOLD_WEIGHT):
                best = chart
            if best is None:
                stuck.append(t)
                continue
            done += 1
            queue.extend(f for f in best[1]() if f in self.faces and self.n_folds([self.faces[f]]))
        return done


def faces_within(F: np.ndarray, faces: np.ndarray, rings: int, n: int) -> np.ndarray:
    """The faces (indices) of ``F`` (m×3, ``n`` vertices) with a corner within ``rings``
    rings of the corners of ``faces`` (k indices; 0 rings: the faces at their corners)."""
    near = np.zeros(n, bool)
    near[F[faces].ravel()] = True
    for _ in range(rings):
        near[F[touching(F, near)].ravel()] = True
    return np.flatnonzero(touching(F, near))


def chart_triangulation(S: RemeshState, outline: np.ndarray, inside: np.ndarray
                        ) -> np.ndarray | None:
    """The faces of the region of ``S`` bounded by the vertex loop ``outline`` (b, counter-
    clockwise on the domain) around the vertices ``inside`` (i), laid out as the surface lays
    them out: the vertices projected onto the plane across the sum of the input's normals
    under them, their Delaunay triangulation with the outline's edges flipped in
    (:func:`recover_edges`), the triangles whose centroid lies inside the projected outline;
    None where the projected outline is
    not a simple counter-clockwise polygon those triangles fill with every vertex used
    (b − 2 + 2i faces, their outline the same loop).

    Parameters
    ----------
    S : RemeshState
    outline : (b,) int
    inside : (i,) int

    Returns
    -------
    (b − 2 + 2i, 3) int or None
    """
    vs = np.concatenate([outline, inside])
    normal = S.normals_in()[S.face[vs]].sum(axis=0)
    e1 = cross(normal, np.eye(3)[np.argmin(np.abs(normal))])
    e2 = cross(normal, e1)
    Q = S.X[vs] @ np.column_stack([e1 / np.linalg.norm(e1), e2 / np.linalg.norm(e2)])
    b = len(outline)
    loop = np.column_stack([np.arange(b), np.roll(np.arange(b), -1)])
    fan = np.column_stack([np.zeros(b - 2, np.int64), np.arange(1, b - 1), np.arange(2, b)])
    if double_areas(Q, fan).sum() <= 0:
        return None
    T = Delaunay(Q).simplices.astype(np.int64)
    flip = double_areas(Q, T) < 0
    T[flip] = T[flip][:, [0, 2, 1]]
    T = recover_edges(Q, T, loop)
    if T is None:
        return None
    T = T[points_in_polygon(Q[T].mean(axis=1), Q[:b])]
    if len(T) != b - 2 + 2 * len(inside) or len(np.unique(T)) != len(vs):
        return None
    try:
        loops = topo.boundary_loops(T)
    except UserError:
        return None
    if len(loops) != 1 or len(loops[0]) != b:
        return None
    got = np.column_stack([loops[0], np.roll(loops[0], -1)])
    if set(map(tuple, got.tolist())) != set(map(tuple, loop.tolist())):
        return None
    return vs[T]


def recover_edges(Q: np.ndarray, T: np.ndarray, edges: np.ndarray) -> np.ndarray | None:
    """The triangulation ``T`` (m×3, counter-clockwise) of the points ``Q`` (n×2) with each
    of ``edges`` (k×2) made an edge of it: while one is missing, an edge that crosses it
    flipped where its two faces make a convex quadrilateral (Sloan's recovery of a
    constrained edge); None where no crossing edge can be flipped.

    Parameters
    ----------
    Q : (n, 2) float
    T : (m, 3) int
    edges : (k, 2) int

    Returns
    -------
    (m, 3) int or None
    """
    T = T.copy()
    h = np.column_stack(topo.half_edges(T))        # row 3f + c: T[f, c] → T[f, c + 1]
    key = {(x, y): i for i, (x, y) in enumerate(h.tolist())}
    for a, b in edges.tolist():
        for _ in range(len(T) + 1):
            if (a, b) in key or (b, a) in key:
                break
            if not _flip_across(Q, T, h, key, a, b):
                return None
        else:
            return None
    return T


def _flip_across(Q: np.ndarray, T: np.ndarray, h: np.ndarray, key: dict, a: int, b: int
                 ) -> bool:
    """Flip in place one edge of ``T`` (its half-edges ``h``, 3m×2, row ``3f + c`` the one
    from corner ``c`` of face ``f``, and ``key``, each half-edge's row) that crosses the
    segment ``a–b`` strictly and whose two faces make a convex quadrilateral, ``h`` and
    ``key`` updated with it; whether there was one."""
    def side(p, q, r):
        return np.sign((Q[q, 0] - Q[p, 0]) * (Q[r, 1] - Q[p, 1])
                       - (Q[q, 1] - Q[p, 1]) * (Q[r, 0] - Q[p, 0]))
    c, d = h[:, 0], h[:, 1]
    crossing = np.flatnonzero((side(a, b, c) * side(a, b, d) < 0) &
                              (side(c, d, a) * side(c, d, b) < 0))
    for i in crossing.tolist():
        j = key.get((int(d[i]), int(c[i])))
        if j is None:
            continue
        f, g = i // 3, j // 3
        p, q = T[f, (i % 3 + 2) % 3], T[g, (j % 3 + 2) % 3]
        new = np.array([[c[i], q, p], [q, d[i], p]])
        if (double_areas(Q, new) > 0).all():
            rows = np.r_[3 * f:3 * f + 3, 3 * g:3 * g + 3]
            for x, y in h[rows].tolist():
                del key[(x, y)]
            T[f], T[g] = new
            h[rows] = np.column_stack(topo.half_edges(T[[f, g]]))
            key.update(zip(map(tuple, h[rows].tolist()), rows.tolist()))
            return True
    return False


def points_in_polygon(P: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each point ``P`` (k×2) lies inside the closed ``polygon`` (b×2, its vertices in
    order), by the parity of its crossings with the polygon's edges along +x (k bool)."""
    A, B = polygon, np.roll(polygon, -1, axis=0)
    x, y = P[:, :1], P[:, 1:]
    spans = (A[:, 1] > y) != (B[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = A[:, 0] + (y - A[:, 1]) * (B[:, 0] - A[:, 0]) / (B[:, 1] - A[:, 1])
    return (spans & (x < at)).sum(axis=1) % 2 == 1


def unfolding_position(S: RemeshState, v: int, star: np.ndarray):
    """For vertex ``v`` of ``S`` and its ``star`` (d×3, ``v`` first): among the points of
    :func:`star_positions`, the one with the fewest faces of the star turned over, then the
    largest smallest 3D angle: ``((uv, face, bary, X), folds, angle)``, or None if there is
    none."""
    found = star_positions(S, v, star)
    if found is None:
        return None
    where, n_folds, angles = found
    angle = angles.min(axis=1)
    c = np.lexsort((-angle, n_folds))[0]
    return tuple(w[c] for w in where), int(n_folds[c]), float(angle[c])


def star_positions(S: RemeshState, v: int, star: np.ndarray):
    """The points of :func:`star_grid` and the input vertices of the input faces under the
    corners of the ``star`` (d×3, ``v`` first) of vertex ``v`` of ``S`` that keep the star
    counter-clockwise and not thinner than ``DISK_SHAPE_MIN`` on the domain and lie in the
    input map, as positions of ``v``; None if there is none.

    Returns
    -------
    where : tuple
        ``(uv, face, bary, X)``: (j, 2 or 3), (j,), (j, 3), (j, 3), each point's domain
        position, input face and barycentrics there, and its lift.
    folds : (j,) int
        The faces of the star turned over with ``v`` there (:func:`turned_over`).
    angles : (j, d) float
        The smallest 3D angle (degrees) of each face of the star with ``v`` there.
    """
    M = np.vstack([star_grid(S.uv, star), S.uv_in[np.unique(S.F_in[S.face[star]])]])
    M = M[star_shapes_ok(S.uv, M, star[:, 1:])]
    if len(M) == 0:
        return None
    mf, mb, inside = S.locator.relocate(M, np.full(len(M), S.face[v]), walk=CENTROID_WALK)
    M, mf, mb = M[inside], mf[inside], mb[inside]
    if len(M) == 0:
        return None
    P = lift(S.V_in, S.F_in, mf, mb)
    j, d = len(M), len(star)
    B, C = star[:, 1], star[:, 2]

    def corners(at_v, of):
        """The stars' corners: ``at_v`` (j rows) for ``v``, ``of[B]``, ``of[C]`` for the
        others (j·d×3 rows)."""
        reps = (j,) + (1,) * (of.ndim - 1)
        return np.stack([np.repeat(at_v, d, axis=0), np.tile(of[B], reps), np.tile(of[C], reps)],
                        axis=1)

    Pc = corners(P, S.X)
    n_folds = turned_over(S, Pc, corners(M, S.uv), corners(mf, S.face),
                          corners(mb, S.bary)).reshape(j, d).sum(axis=1)
    angles = triangle_min_angles(Pc[:, 0], Pc[:, 1], Pc[:, 2]).reshape(j, d)
    return (M, mf, mb, P), n_folds, angles
