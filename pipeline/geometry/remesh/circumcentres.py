"""Delaunay refinement of the faces the local operations leave below the minimum angle.

What :func:`.angles.raise_min_angles` cannot raise is mostly a face beside a short edge whose
opposite corner is about ``L`` away: a rim edge between two kept boundary corners, or an edge
between a rim corner and an interior vertex the operations could not move (its guards refuse).
No flip, move or collapse fixes such a face: the short edge stays, so the far corner must come
closer — a graded refinement. :func:`refine_at_circumcentres` makes it as Delaunay refinement
does (Chew, Ruppert), with Üngör's off-centres: a vertex goes on the perpendicular bisector of
each such face's shortest edge, where it sees that edge at ``OFF_CENTRE_DEG`` (or at the
circumcentre if that is nearer), so the new face on the short edge has that angle at its apex
and the steps grade the remesh from the short edge outwards. The point is computed in the
face's plane, carried to the domain point whose lift is nearest to it
(:func:`domain_points_for`), located in the remesh and lifted by eq. (1); the flips connect
it. Where it lies beyond the rim or encroaches a rim edge (inside the ball on its diameter)
that edge is split instead, its vertex on the image polygon; next to an edge of its face, that
edge is split there; next to a vertex, or where its lift is far from it (the surface bends
away from the face's plane), nothing is done.

With ``caps`` a cap — a face with an angle of ``CAP_DEG`` or more, whose short edges meet at
that corner — has its long edge split where the altitude from the wide corner meets it
instead (:func:`cap_split`): the wide angle halves, and the local operations the caller runs
after the round (:func:`.angles.raise_min_angles`) move the new vertex, which the guards
around the cap's own corners (a crumpled input, a corner on a ridge) keep from moving.

:func:`corner_split_round` splits instead the interior edges at each such face's smallest
corner (the caller's alternative where neither refinement is kept): next to a rim sampled
closer than the remesh's spacing, an interior vertex can have rim vertices all round, and the
fan it balances over the short rim edges needs one more vertex, not another position.

A round takes one insertion per face, worst face first, those in distinct parts of the remesh
(no two touching one face), then the caller's ``flip`` around them (flips, and in
:meth:`.improve._Operations.grade` the local operations); a round that leaves more faces turned
over than at the start is made again without the faces with a corner on a fold before or after
it (:func:`fold_free_round`: the fold repair's to mend; an insertion there turns faces over
where the map's stretch turns, and the round, judged on the fold count, would be lost with all
its other insertions; the later rounds of the same refinement pass over the faces at those
folds from their first attempt on). The rounds go on while there are faces
to refine, at most ``ROUNDS`` (a round may make things worse on the way to better ones; after
one that leaves more than ``RUNAWAY`` × the best round's count + 1, or, given ``patience``,
after that many in a row that beat no earlier state, none; nor after one that changes nothing
measurable: as many faces to refine with the same smallest angle, vertices and faces turned
over as before it, most often its insertions all collapsed again by the caller's operations
where a ragged rim's teeth leave faces no vertex mends, which the next round would insert
again); the remesh ends as the best state:
the fewest faces below the minimum that no input corner forces
(:func:`.angles.forced_by_corners`), then the largest smallest angle among them, with no more
faces turned over than at the start (the start itself if no round beat it).
"""

from __future__ import annotations

import math

import numpy as np

from ..locate import lift
from ..metrics import min_corner_angles_below
from ..rows import norms
from .angles import corner_angles_deg, forced_corners
from .corners import locate_near
from .domain import project
from .halfedge import DISK_SHAPE_MIN, disk_shape
from .refine import split_edges, split_faces, split_keeps_shape
from .state import RemeshState, at_points

ROUNDS = 6            # at most this many rounds of insertions, none after one that leaves
RUNAWAY = 2           # more than this × (the best round's count of faces to refine + 1)
EDGE_BARY = 0.1       # a target this close (barycentric) to an edge of its face splits the edge,
                      # to a corner is not inserted
OFF_CENTRE_DEG = 35.0  # the new vertex's angle over the bad face's shortest edge
FLAT = 1e-12          # 16 area² at most this × (longest edge)⁴: the corners on one line
NEWTON_STEPS = 4      # steps carrying a 3D target to the domain point that lifts to it,
HALVINGS = 4          # each halved up to this many times until the lift comes nearer
CAP_DEG = 120.0       # a face with an angle this wide or wider is a cap: its long edge is split
LOCATE_WALK = 64      # walk steps locating a target from a known input face
DRIFT = 1.0           # a target whose lift is farther from it in 3D than this × its distance
                      # to the face's corners (the surface bends away) is not inserted
_STATE = ("X", "F", "uv", "is_rim", "face", "bary", "locked", "joined")


def circumcentre_weights(P0: np.ndarray, P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    """The barycentric coordinates (k×3, summing to 1) of the circumcentre of each triangle
    ``P0, P1, P2`` (k×3 each) in its plane; an obtuse triangle's is negative at its obtuse
    corner (the circumcentre lies beyond the opposite edge)."""
    a2 = ((P1 - P2) ** 2).sum(axis=1)
    b2 = ((P2 - P0) ** 2).sum(axis=1)
    c2 = ((P0 - P1) ** 2).sum(axis=1)
    w = np.column_stack([a2 * (b2 + c2 - a2), b2 * (c2 + a2 - b2), c2 * (a2 + b2 - c2)])
    return w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)


def off_centre_weights(P0: np.ndarray, P1: np.ndarray, P2: np.ndarray, angle_deg: float
                       ) -> np.ndarray:
    """The barycentric coordinates of each triangle's off-centre (Üngör): the point on the
    perpendicular bisector of its shortest edge, towards the circumcentre, that makes with that
    edge an isosceles triangle whose apex angle is ``angle_deg`` — or the circumcentre itself
    when that is nearer to the edge. A triangle whose corners are (nearly) on one line
    (``16 area²`` at most ``FLAT × (longest edge)⁴``: its circumcentre's weights overflow or
    lose every digit) gets the middle of its shortest edge.

    Parameters
    ----------
    P0, P1, P2 : (k, 3) float
        The corners.
    angle_deg : float
        The apex angle, below 60°.

    Returns
    -------
    (k, 3) float
    """
    W = circumcentre_weights(P0, P1, P2)
    P = np.stack([P0, P1, P2], axis=1)
    ln = np.linalg.norm(P[:, [1, 2, 0]] - P, axis=2)     # edge j: corner j → corner j+1
    j = np.argmin(ln, axis=1)
    k = np.arange(len(P))
    M = np.zeros_like(W)
    M[k, j] = M[k, (j + 1) % 3] = 0.5                    # the middle of the shortest edge
    C = np.einsum("ij,ijk->ik", W, P)
    Mx = np.einsum("ij,ijk->ik", M, P)
    far = ln[k, j] / (2.0 * math.tan(math.radians(angle_deg) / 2.0))
    lam = np.minimum(1.0, far / np.maximum(norms(C - Mx), 1e-300))
    out = M + lam[:, None] * (W - M)
    a2, b2, c2 = (ln ** 2).T
    area16 = 2.0 * (a2 * b2 + b2 * c2 + c2 * a2) - (a2 ** 2 + b2 ** 2 + c2 ** 2)
    flat = ~(area16 > FLAT * ln.max(axis=1) ** 4) | ~np.isfinite(out).all(axis=1)
    out[flat] = M[flat]
    return out


def domain_points_for(S: RemeshState, c: np.ndarray, C: np.ndarray,
                      steps: int = NEWTON_STEPS, near: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Domain points whose lifts come near the 3D points ``C``: from the first guesses ``c``,
    ``steps`` steps ``c += J⁺ (C − lift(c))`` with the pull-back ``J⁺`` of the input face
    under ``c`` (:meth:`.state.RemeshState.pullback`), each point put back on the domain
    (:func:`.domain.project`: on the sphere, normalised): where the map's stretch changes
    within a remesh face, the face's own affine map carries a point of its plane far from
    where it lifts. A step that does not bring the lift nearer is halved, up to ``HALVINGS``
    times, then not made. Each point's input face and barycentrics are kept from where it
    was located last (:func:`_miss`), and a step's point is located by a walk from that face.

    Parameters
    ----------
    S : RemeshState
    c : (k, 2) or (k, 3) float
        Disk points, or points of the sphere's ambient space.
    C : (k, 3) float
    steps : int
    near : (k,) int, optional
        Input faces near the first guesses (e.g. under a corner of the remesh face each one
        was computed in), where their location walks from.

    Returns
    -------
    c : (k, 2) or (k, 3) float
        On the domain.
    face, bary : (k,) int, (k, 3) float
        Where they are in the input map.
    """
    c = project(np.array(c, dtype=np.float64))
    J = S.pullback()
    miss, mf, mb = _miss(S, c, C, near)
    for _ in range(steps):
        step = np.einsum("ijk,ik->ij", J[mf], C - lift(S.V_in, S.F_in, mf, mb))
        for _ in range(HALVINGS):
            trial = project(c + step)
            nxt, tf, tb = _miss(S, trial, C, mf, project=False)
            better = nxt < miss
            c[better] = trial[better]
            miss[better], mf[better], mb[better] = nxt[better], tf[better], tb[better]
            step[better] = 0.0
            step *= 0.5
    return c, mf, mb


def _miss(S: RemeshState, c: np.ndarray, C: np.ndarray, near: np.ndarray | None = None,
          project: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far (k) the lifts of the domain points ``c`` (k×2 or k×3) are from the 3D points
    ``C`` (k×3), infinite for a point outside the input map; and where the points are in the
    input map (input faces k and barycentrics k×3, :meth:`.locate.PointLocator.locate`, or
    given input faces ``near`` (k) walked from, up to ``LOCATE_WALK`` steps:
    :meth:`.locate.PointLocator.relocate`). Without ``project`` (``near`` given), a point
    outside the input map gets face −1 and zero barycentrics instead of its closest rim
    point's, for a caller that keeps only nearer points."""
    if near is None:
        mf, mb, inside = S.locator.locate_with_inside(c)
    else:
        mf, mb, inside = S.locator.relocate(c, near, walk=LOCATE_WALK, project=project)
    miss = np.full(len(mf), np.inf)
    miss[inside] = norms(lift(S.V_in, S.F_in, mf[inside], mb[inside]) - C[inside])
    return miss, mf, mb


def encroached(C: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Whether each point ``C`` lies strictly inside the ball on the segment ``A–B`` as its
    diameter (k×3 each; k bool)."""
    return norms(C - 0.5 * (A + B)) < 0.5 * norms(B - A)


def unforced_shortfall(S: RemeshState, min_angle_deg: float) -> tuple[int, float]:
    """The faces below ``min_angle_deg`` that no input corner forces: how many, and their
    smallest angle (degrees; 180 when there are none)."""
    return shortfall_of(unforced_below(S, min_angle_deg)[1])


def shortfall_of(worst: np.ndarray) -> tuple[int, float]:
    """:func:`unforced_shortfall` of the faces whose smallest angles are ``worst`` (k,
    degrees, e.g. :func:`unforced_below`'s): how many, and the smallest (180 when none)."""
    return len(worst), float(worst.min(initial=180.0))


def unforced_below(S: RemeshState, min_angle_deg: float, only: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The faces (k indices) below ``min_angle_deg`` that no input corner forces
    (:func:`.angles.forced_by_corners`) and their smallest angles (k, degrees), worst
    first; given ``only`` (j×3 points), those of them whose corners are all at these points
    (:func:`.state.at_points`)."""
    among = None if only is None else np.flatnonzero(at_points(S.X, only)[S.F].all(axis=1))
    return unforced_among(S, min_angle_deg, among)


def unforced_among(S: RemeshState, min_angle_deg: float, among: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`unforced_below` of the faces ``among`` (j increasing indices; all by default):
    the angles of those faces alone, row by row, so the answer is the whole remesh's with
    the other faces left out, in the same order.

    Returns
    -------
    faces : (k,) int
    worst : (k,) float
        Degrees, increasing.
    """
    if among is None:
        bad, smallest = min_corner_angles_below(S.X, S.F, np.radians(min_angle_deg))
    else:
        bad, smallest = min_corner_angles_below(S.X, S.F[among], np.radians(min_angle_deg))
        bad = among[bad]
    smallest = np.degrees(smallest)
    below = smallest < min_angle_deg
    bad, smallest = bad[below], smallest[below]
    unforced = ~forced_corners(S, min_angle_deg, bad).any(axis=1)
    bad, worst = bad[unforced], smallest[unforced]
    order = np.argsort(worst, kind="stable")
    return bad[order], worst[order]


def refine_at_circumcentres(S: RemeshState, min_angle_deg: float, flip, folds,
                            rounds: int = ROUNDS, caps: bool = False,
                            patience: int | None = None, only: np.ndarray | None = None,
                            shortfall: tuple[int, float] | None = None) -> int:
    """Delaunay refinement at off-centres of the faces below ``min_angle_deg`` no input corner
    forces (module docstring); returns the number of vertices inserted (tallied as
    ``circumcentre_insertions``).

    Parameters
    ----------
    S : RemeshState
        Changed in place (vertices appended, faces rewritten); on the disk or the sphere.
    min_angle_deg : float
    flip : callable ``flip(F_before)``
        Flips around the faces changed since ``F_before`` (m×3), and any other operations
        the caller makes after a round.
    folds : callable ``folds() -> (j,) int``
        The faces of ``S`` turned over against the input.
    rounds : int
    caps : bool
        Split the long edge of a cap instead (:func:`cap_split`).
    patience : int, optional
        Stop after this many rounds in a row that beat no earlier state (for a ``flip`` that
        settles each round's vertices, so that a round no better than those before is no
        step on the way to a better one); default: no limit but ``rounds``.
    only : (j, 3) float, optional
        Insert only for the faces whose corners are all at these points (the rounds are
        judged on the whole remesh all the same).
    shortfall : (int, float), optional
        :func:`unforced_shortfall` of ``S`` as it is, when the caller knows it (not measured
        again).

    Returns
    -------
    int
    """
    done = 0
    n_folds = len(folds())
    if shortfall is None:
        shortfall = unforced_shortfall(S, min_angle_deg)
    best = (shortfall, saved_state(S), 0)
    stale = 0                              # rounds in a row that beat no earlier state
    start = (best[0], S.n, n_folds)        # what a round started from, as measured
    avoid = np.zeros((0, 3))               # where an earlier round's insertions made folds
    for _ in range(rounds):
        if best[0][0] == 0 or (patience is not None and stale >= patience):
            break
        k, near_folds = fold_free_round(S, min_angle_deg, caps, flip, folds, n_folds, avoid,
                                        only)
        if k == 0:
            break
        avoid = np.vstack([avoid, near_folds])
        done += k
        after = unforced_shortfall(S, min_angle_deg)
        n_turned = len(folds())
        if shortfall_order(after) < shortfall_order(best[0]) and n_turned <= n_folds:
            best, stale = (after, saved_state(S), done), 0
            start = (after, S.n, n_turned)
            continue
        stale += 1
        if after[0] > RUNAWAY * best[0][0] + RUNAWAY:
            break                          # the rounds make more faces than they mend
        if (after, S.n, n_turned) == start:
            break                          # the round changed nothing measurable
        start = (after, S.n, n_turned)
    restore_state(S, best[1])
    S.tally("circumcentre_insertions", best[2])
    return best[2]


def fold_free_round(S: RemeshState, min_angle_deg: float, caps: bool, flip, folds,
                    n_folds: int, avoid: np.ndarray | None = None,
                    only: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """A round of insertions (:func:`insert_round`, none for the faces with a corner at the
    points ``avoid``, k×3, if given, and given ``only``, j×3 points, only for the faces with
    their corners all at them) and the caller's ``flip(F_before)``; where that leaves
    more than ``n_folds`` faces turned over (``folds()``, indices), the round made again from
    the start without the faces with a corner on a fold before or after it (their vertices
    found by position, :func:`.state.at_points`): the fold repair's to mend, and one
    fold-making insertion would lose the round its other insertions. Returns how many
    vertices the round kept inserted and the corners of the folds it was made again without
    (j×3 points; none if it was not)."""
    F0, start = S.F.copy(), saved_state(S)
    skip = None if avoid is None or len(avoid) == 0 else at_points(S.X, avoid)
    none = np.zeros((0, 3))
    k = insert_round(S, min_angle_deg, caps, skip=skip, only=only)
    if k == 0:
        return 0, none
    flip(F0)
    turned = folds()
    if len(turned) <= n_folds:
        return k, none
    P = S.X[S.F[turned].ravel()]
    restore_state(S, start)
    redo = at_points(S.X, P)
    redo[S.F[folds()].ravel()] = True
    at_folds = S.X[redo]                # before the round: its flips may collapse vertices
    k = insert_round(S, min_angle_deg, caps, skip=redo if skip is None else redo | skip,
                     only=only)
    if k:
        flip(F0)
    return k, at_folds if k else none


def shortfall_order(shortfall: tuple[int, float]) -> tuple[int, float]:
    """The order of :func:`unforced_shortfall`'s results: fewer faces first, then the larger
    smallest angle."""
    return shortfall[0], -shortfall[1]


def saved_state(S: RemeshState) -> dict:
    """Copies of the arrays of ``S`` the operations change (:func:`restore_state`), with the
    half-edge twins of ``F`` under ``"twins"`` where they are known
    (:meth:`.state.RemeshState.cached_twins`: no operation changes them in place, and
    computing them again costs a sort of every half-edge)."""
    saved = {k: getattr(S, k).copy() for k in _STATE}
    twins = S.cached_twins()
    if twins is not None:
        saved["twins"] = twins
    return saved


def restore_state(S: RemeshState, saved: dict) -> None:
    """Put ``S`` back as :func:`saved_state` saved it (its twins with it, where saved)."""
    for key in _STATE:
        setattr(S, key, saved[key])
    S.set_faces(saved["F"], saved.get("twins"))


def insert_round(S: RemeshState, min_angle_deg: float, caps: bool = False,
                 skip: np.ndarray | None = None, only: np.ndarray | None = None) -> int:
    """One round of :func:`refine_at_circumcentres`: a vertex at the off-centre of each
    face below ``min_angle_deg`` no input corner forces (or on the rim edge it lies beyond or
    encroaches; given ``only``, j×3 points, of those with their corners all at them), worst
    face first, none in a face another one of the round touches nor for a face with a corner
    among the vertices ``skip`` (n bool); returns how many."""
    bad, _ = unforced_below(S, min_angle_deg, only)
    if skip is not None:
        bad = bad[~skip[S.F[bad]].any(axis=1)]
    if len(bad) == 0:
        return 0
    T = S.F[bad]
    X = S.X.take(T, axis=0)
    W = off_centre_weights(X[:, 0], X[:, 1], X[:, 2], OFF_CENTRE_DEG)
    C3 = np.einsum("ij,ijk->ik", W, X)
    R = norms(C3 - X[:, 0])
    c, mf, mb = domain_points_for(S, np.einsum("ij,ijk->ik", W, S.uv.take(T, axis=0)), C3,
                                  near=S.face[T[:, 0]])
    drift = norms(lift(S.V_in, S.F_in, mf, mb) - C3)
    f, bary, inside = locate_near(S, c)
    twin = S.twins()
    used = np.zeros(len(S.F), bool)
    edges, faces, points = [], [], []
    for i in range(len(bad)):
        if used[bad[i]]:                  # a face of the round touches it: skipped whatever
            continue                      # its action
        act = _action(S, bad[i], f[i], bary[i], bool(inside[i]), c[i], C3[i], R[i], drift[i],
                      twin, caps)
        if act is None:
            continue
        kind, h, t = act
        touched = [h // 3] + ([twin[h] // 3] if twin[h] >= 0 else []) if kind == "edge" \
            else [f[i]]
        ring = [bad[i]] + touched
        if used[ring].any():
            continue
        used[ring] = True
        if kind == "edge":
            edges.append((h, twin[h], t))
        else:
            faces.append(f[i])
            points.append(c[i])
    if edges:
        h, tw, t = zip(*edges)
        split_edges(S, np.array(h, np.int64), np.array(tw, np.int64),
                    np.array([0.5 if x is None else x for x in t]))
    if faces:
        split_faces(S, np.array(faces, np.int64), np.array(points))
    return len(edges) + len(faces)


def _action(S: RemeshState, bad: int, f: int, bary: np.ndarray, inside: bool, c: np.ndarray,
            C3: np.ndarray, R: float, drift: float, twin: np.ndarray, caps: bool = False):
    """What a round does for the bad face ``bad`` whose off-centre (domain ``c``, 3D ``C3``,
    ``R`` from the face's first corner, ``drift`` from the lift of ``c``) was located in face
    ``f`` at ``bary`` (``inside`` the remesh or not): with ``caps``, a split of a cap's long
    edge (:func:`cap_split`); a split of the rim edge it lies beyond or encroaches
    (``("edge", h, t)`` with ``t`` along the half-edge ``h``, None for the middle), a split
    of the edge it lies next to, a split of ``f`` at it (``("face", f, None)``), or None when
    none is allowed."""
    F = S.F
    cap = cap_split(S, bad) if caps else None
    if cap is not None:
        return _edge_split(S, cap[0], twin, cap[1])
    for g in (bad, f):                    # an encroached rim edge of the bad face or of f
        for j in range(3):
            h = 3 * g + j
            a, b = F[g, j], F[g, (j + 1) % 3]
            if twin[h] < 0 and encroached(C3[None], S.X[[a]], S.X[[b]])[0]:
                return _edge_split(S, h, twin, None)
    j = int(np.argmin(bary))
    h = 3 * f + (j + 1) % 3                # the edge opposite the corner of least weight
    t = float(bary[(j + 2) % 3])
    if _is_shortest_edge(S, bad, h) or bary.max() > 1.0 - EDGE_BARY:
        return None                        # the edge the off-centre stands on stays; a target
                                           # next to a vertex has one
    if not inside:
        return _edge_split(S, h, twin, t) if twin[h] < 0 else None
    if drift > DRIFT * R:
        return None
    if bary[j] < EDGE_BARY:
        return _edge_split(S, h, twin, t)
    tri = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]])
    U = np.vstack([S.uv[F[f]], c])
    if (disk_shape(U, tri) < DISK_SHAPE_MIN).any():
        return None
    return "face", f, None


def corner_split_round(S: RemeshState, min_angle_deg: float, only: np.ndarray | None = None
                       ) -> int:
    """A vertex in the middle (on the disk) of each interior edge at the smallest corner of a
    face below ``min_angle_deg`` that no input corner forces (:func:`unforced_below`; given
    ``only``, j×3 points, of those with their corners all at them), worst face first, none
    in a face another split of the round touches, no kept edge (``S.joined``), none between
    two rim vertices and none that makes a face thinner on the disk than ``DISK_SHAPE_MIN``
    (:func:`.refine.split_keeps_shape`); returns how many.

    Where the rim is sampled closer than the remesh's spacing (the teeth of a ragged rim), an
    interior vertex next to it can have rim vertices all round: the one vertex balances the
    angles of a fan over several short rim edges, and no move or flip of it raises the
    smallest; the split gives the small corner one more face, which the local operations
    after it (the caller's) shape."""
    bad, _ = unforced_below(S, min_angle_deg, only)
    if len(bad) == 0:
        return 0
    twin = S.twins()
    A = corner_angles_deg(S.X, S.F[bad])
    used = np.zeros(len(S.F), bool)
    picked = []
    for g, v in zip(bad, S.F[bad, np.argmin(A, axis=1)]):
        for j in range(3):
            h, a, b = 3 * g + j, S.F[g, j], S.F[g, (j + 1) % 3]
            if v not in (a, b) or twin[h] < 0 or S.is_rim[[a, b]].all() or \
                    used[[g, twin[h] // 3]].any():
                continue
            if S.is_joined(np.array([a]), np.array([b]))[0] or \
                    not split_keeps_shape(S, np.array([h]), twin[[h]])[0]:
                continue
            used[[g, twin[h] // 3]] = True
            picked.append(h)
    if not picked:
        return 0
    h = np.array(picked, np.int64)
    return split_edges(S, h, twin[h])


def cap_split(S: RemeshState, g: int) -> tuple[int, float] | None:
    """For a cap — a face ``g`` whose largest angle is at least ``CAP_DEG``, its small angles
    at the ends of the edge across from it — the half-edge of that edge and where along it
    the altitude from the wide corner meets it (``(h, t)``, ``t`` kept within
    ``[EDGE_BARY, 1 − EDGE_BARY]``); None for any other face. No off-centre mends a cap: its
    short edges are beside the wide corner, and the point across the long edge sees them
    from farther still."""
    A = corner_angles_deg(S.X, S.F[[g]])[0]
    k = int(np.argmax(A))
    if A[k] < CAP_DEG:
        return None
    a, b, w = S.F[g, (k + 1) % 3], S.F[g, (k + 2) % 3], S.F[g, k]
    e = S.X[b] - S.X[a]
    t = float(np.dot(S.X[w] - S.X[a], e) / max(float(np.dot(e, e)), 1e-300))
    return 3 * g + (k + 1) % 3, min(max(t, EDGE_BARY), 1.0 - EDGE_BARY)


def _is_shortest_edge(S: RemeshState, g: int, h: int) -> bool:
    """Whether the half-edge ``h`` or its twin is the shortest edge (3D) of face ``g``."""
    P = S.X[S.F[g]]
    j = int(np.argmin(np.linalg.norm(P[[1, 2, 0]] - P, axis=1)))
    ends = {int(S.F[g, j]), int(S.F[g, (j + 1) % 3])}
    return ends == {int(S.F[h // 3, h % 3]), int(S.F[h // 3, (h % 3 + 1) % 3])}


def _edge_split(S: RemeshState, h: int, twin: np.ndarray, t: float | None):
    """``("edge", h, t)`` if the split of half-edge ``h`` at ``t`` (None: the middle) is
    allowed — not a kept edge, no face with three rim corners, no face thinner than
    ``DISK_SHAPE_MIN`` on the disk — else None."""
    F = S.F
    f, j = h // 3, h % 3
    a, b, p = F[f, j], F[f, (j + 1) % 3], F[f, (j + 2) % 3]
    if S.is_joined(np.array([a]), np.array([b]))[0]:
        return None
    if twin[h] < 0 and S.is_rim[p]:
        return None
    tt = None if t is None else np.array([t])
    if not split_keeps_shape(S, np.array([h]), twin[[h]], tt)[0]:
        return None
    return "edge", h, t
