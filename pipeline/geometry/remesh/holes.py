"""The input's holes kept open: constrain the filled disk, remesh it, cut the holes out.

The intake closes every hole but the outer boundary with a fan to a new centre vertex
(:func:`..repair.repair_mesh`), so that the mesh is a disk and has a disk map. The remesh keeps
them as constraints of that one disk (:func:`place_holes`, before the corners, feature lines
and landmarks): each hole loop gets locked remesh vertices about ``L`` apart along it
(:func:`loop_arcs`): on a smooth loop the points of :func:`.features.chain_arcs`, which follow
it within its bend tolerance; on a ragged one (a scan's opening, :func:`is_ragged`) loop
vertices about ``L`` apart in space, whose chords cut across its teeth, with the loop vertex
farthest from a chord added where the loop runs beyond it by more than ``NOTCH_TOL × L`` on
the surface's side or ``TOOTH_TOL × L`` on the hole's (:func:`followed_stops`: the faces
along a chord would otherwise cover a notch of the hole with the fan's surface, or the cut
take a tooth of the surface away), but not at the tip of a tooth whose triangle with its
neighbours would have an angle below ``TOOTH_MIN_DEG`` (:func:`without_thin_teeth`: that
face stays, and the tooth goes with the hole). Where the disk chord
between two consecutive points crosses another chord, another loop or another stretch of its
own loop (a slit, such as a closed mouth), the loop vertex nearest the middle between them is
added, until none does (:func:`untangled`). Consecutive ones are joined by an edge that no
flip, split or collapse removes and whose ends never move (``RemeshState.joined``,
``RemeshState.fixed``). Where the flips cannot make such an edge, the one edge in the way is
split where the loop crosses it, or else the loop's point halfway between the two is put in
and both halves joined (:func:`join_loop`). After the improvement pass the edges of each
whole loop (:func:`intact_loops`) split the remesh into regions, and those mostly in a hole —
their faces' disk centroids in the image of its fan — are cut away with the vertices no other
face uses (:func:`cut_holes`): a tooth beyond a chord goes with the side of the chord it lies
on. A loop that could not be placed or kept whole leaves its hole covered by the fan's
surface (listed in the log's ``holes_covered``, a warning of the report), not a failure.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from .. import topology as topo
from ..locate import lift
from ..metrics import min_corner_angles, signed_double_areas
from ..repair import used_vertices_only
from ..rows import norms
from .corners import insert_vertices, snap_vertices
from .features import along_chain, chain_arcs, crossed_edges, join_edges, vertices_at
from .state import RemeshFailed, RemeshState, at_points
from .unfold import turned_over_rows

MIN_LOOP_POINTS = 3      # a hole keeps at least this many vertices (a triangle)
MAX_INSERT_PASSES = 8    # rounds of insertions of a hole loop's points left without a vertex
MAX_HALVINGS = 4         # a pair still unjoined after this many halvings: RemeshFailed
RAGGED_DEPTH = 0.25      # a loop whose median vertex sits this × its median edge off the
                         # chord of its neighbours is ragged (a scan's ~0.55, a model's < 0.1)
NOTCH_TOL = 0.2          # × L: a chord of a ragged loop covers its hole no deeper than this
TOOTH_TOL = 0.3          # × L: and cuts off a tooth of the surface no deeper than this
TOOTH_MIN_DEG = 20.0     # a followed tooth whose triangle with its neighbours is thinner is
                         # dropped
LOOP_GAP = 0.3           # × L (at least the loop's median edge): save where a point would
                         # come nearer its neighbours than this


def place_holes(S: RemeshState, loops: list, fans: np.ndarray, L: float) -> np.ndarray:
    """Lock a remesh vertex on every point of each hole loop (:func:`loop_arcs`,
    :func:`untangled`) and join consecutive ones round the loop (:func:`join_loop`); the
    pairs are added to ``S.joined``, the vertices' positions to ``S.fixed`` and each loop's
    edges, as the positions of their ends, to ``S.hole_chains`` (None for a loop that could
    not be placed: its hole is covered, :func:`cut_holes`).

    Parameters
    ----------
    S : RemeshState
        Changed in place; counts under ``hole_*`` in its log.
    loops : list of (k,) int
        The holes' loops, input vertex indices in order round each.
    fans : (M,) bool
        The input faces that fill the holes.
    L : float
        Target edge length, in the mesh's units.

    Returns
    -------
    (h, 3) float
        The positions of the hole vertices.
    """
    S.fans = fans
    arcs = untangled(S.uv_in, [loop_arcs(S.V_in, S.uv_in, loop, L) for loop in loops])
    turned = partial(turned_outside, S, fans)
    pairs = [placed_loop(S, vs, seg, t, turned) for vs, seg, t in arcs]
    kept = [p for p in pairs if p is not None]
    S.hole_chains = [None if p is None else S.X[p] for p in pairs]
    S.fixed = S.X[np.unique(np.vstack([np.zeros((0, 2), np.int64), *kept]))].copy()
    S.tally("hole_edges", sum(map(len, kept)))
    return S.fixed


def placed_loop(S: RemeshState, vs: np.ndarray, seg: np.ndarray, t: np.ndarray, turned
                ) -> np.ndarray | None:
    """The pairs (j×2 int) joining the locked vertices put on the points at arc lengths ``t``
    of the closed loop ``vs`` (:func:`locked_on`, :func:`join_loop`); None where that fails
    (:class:`.state.RemeshFailed`), counted as ``hole_loops_not_placed``."""
    try:
        v = locked_on(S, along_chain(S.uv_in, vs, seg, t), "hole_points")
        return join_loop(S, vs, seg, v, t, turned)
    except RemeshFailed:
        S.tally("hole_loops_not_placed", 1)
        return None


def loop_arcs(V: np.ndarray, uv: np.ndarray, loop: np.ndarray, L: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A hole loop as a closed chain and its points' arc lengths: on a ragged loop
    (:func:`is_ragged`), loop vertices about ``L`` apart in space (:func:`spaced_stops`),
    so that the chords between them cut across its teeth, and those where the loop runs
    farther beyond a chord (:func:`followed_stops`, none nearer a neighbour than
    ``LOOP_GAP × L`` or the loop's median edge: a remesh about as fine as the loop would
    follow each of its teeth); on another, the points of
    :func:`.features.chain_arcs` (the loop followed within its bend tolerance); at least
    ``MIN_LOOP_POINTS`` of them (evenly spaced by arc length on a loop too short for more).

    Parameters
    ----------
    V : (n, 3) float
    uv : (n, 2) float
        The disk map.
    loop : (k,) int
    L : float

    Returns
    -------
    vs : (k + 1,) int
        The loop closed (its first vertex again at the end).
    seg : (k,) float
        Its edges' lengths.
    t : (p,) float
        The points' arc lengths from ``vs[0]``, increasing, below the loop's length.
    """
    vs = np.r_[loop, loop[:1]].astype(np.int64)
    if is_ragged(V[loop]):
        seg = norms(V[vs[1:]] - V[vs[:-1]])
        stops = followed_stops(V[vs], uv[vs], spaced_stops(V[vs], L), NOTCH_TOL * L,
                               TOOTH_TOL * L, max(LOOP_GAP * L, float(np.median(seg))))
        t = np.r_[0.0, np.cumsum(seg)][stops]
    else:
        seg, t, _ = chain_arcs(V, vs, L)
    if len(t) < MIN_LOOP_POINTS:
        t = np.linspace(0.0, seg.sum(), MIN_LOOP_POINTS + 1)[:-1]
    return vs, seg, t


def is_ragged(Q: np.ndarray) -> bool:
    """Whether the closed loop through ``Q`` (k×3) is ragged: its vertices' median distance
    from the chord between their two neighbours is over ``RAGGED_DEPTH`` × its median edge
    length (teeth about an edge deep, as an opening of a scan has, rather than a smooth
    curve's sag)."""
    before, after = np.roll(Q, 1, axis=0), np.roll(Q, -1, axis=0)
    chord = after - before
    depth = norms(np.cross(chord, Q - before)) / np.maximum(norms(chord), 1e-300)
    return bool(np.median(depth) > RAGGED_DEPTH * np.median(norms(after - Q)))


def spaced_stops(Q: np.ndarray, L: float) -> np.ndarray:
    """Vertices of the closed chain ``Q`` (k×3, ``Q[0] == Q[-1]``) about ``L`` apart in
    space: from ``0``, each next one the first vertex at least ``L`` from the last, or the one
    before it where that is nearer to ``L``; the last one dropped where it is within ``L / 2``
    of the start. Returns their indices (p int, from 0, below ``k − 1``)."""
    stops, i, k = [0], 0, len(Q) - 1
    while True:
        d = norms(Q[i + 1:k + 1] - Q[i])
        far = np.flatnonzero(d >= L)
        if len(far) == 0:
            break
        j = int(far[0])
        if j > 0 and L - d[j - 1] < d[j] - L:
            j -= 1
        i = i + 1 + j
        if i >= k:
            break
        stops.append(i)
    if len(stops) > 1 and norms(Q[stops[-1:]] - Q[:1])[0] < L / 2:
        stops.pop()
    return np.array(stops, np.int64)


def followed_stops(Q: np.ndarray, P: np.ndarray, stops: np.ndarray, notch_tol: float,
                   tooth_tol: float, gap: float) -> np.ndarray:
    """The ``stops`` of a ragged hole loop with, between two consecutive ones, the loop vertex
    farthest in space from their chord beyond its tolerance added (:func:`_beyond_chord`),
    again between the new pairs, until none is: ``notch_tol`` on the chord's outer side (a
    notch of the hole into the surface, which the chord's faces would cover: the surface
    there is the fan's filling, not the input's), ``tooth_tol`` on its hole's side (a tooth
    of the surface, which the cut would take away with the hole); a vertex within ``gap`` of
    either end of the chord is not added (a needle); then the added tips of thin teeth are
    dropped (:func:`without_thin_teeth`).

    Parameters
    ----------
    Q : (k, 3) float
        The loop closed (``Q[0] == Q[-1]``).
    P : (k, 2) float
        Its disk images, the hole inside them.
    stops : (p,) int
        Indices into ``Q``, increasing, below ``k − 1``.
    notch_tol, tooth_tol, gap : float

    Returns
    -------
    (p', ) int
        The stops with those added, increasing.
    """
    inner = np.sign(np.sum(P[:-1, 0] * P[1:, 1] - P[1:, 0] * P[:-1, 1]))
    stops = [int(x) for x in stops]
    todo, out = list(zip(stops, stops[1:] + [len(Q) - 1])), set(stops)
    while todo:
        a, b = todo.pop()
        j = _beyond_chord(Q, P, a, b, inner, (notch_tol, tooth_tol), gap)
        if j is not None:
            out.add(j)
            todo += [(a, j), (j, b)]
    return without_thin_teeth(Q, P, sorted(out), set(stops), inner)


def without_thin_teeth(Q: np.ndarray, P: np.ndarray, stops: list, spaced: set,
                       inner: float) -> np.ndarray:
    """The ``stops`` (increasing indices into the closed loop ``Q``, k×3; disk images ``P``,
    k×2, the loop's inside turning as ``inner``) without those not in ``spaced`` that are
    the tip of a tooth between their neighbours (on the hole's side of their chord) whose
    triangle with them has an angle below ``TOOTH_MIN_DEG`` (:func:`_thin_tooth`), dropped
    one at a time until none is: that triangle is the face the remesh keeps there (its
    chord, the one edge not kept, flips only to a vertex across it, whose face then has
    the tooth's short edge facing it), and no triangulation of the surface raises its
    angles; without the tip the tooth goes with the hole. Returns them as (p,) int."""
    stops = list(stops)
    while True:
        thin = next((k for k in range(len(stops)) if stops[k] not in spaced
                     and _thin_tooth(Q, P, *_around(stops, len(Q), k), inner)), None)
        if thin is None:
            return np.array(stops, np.int64)
        del stops[thin]


def _around(stops: list, closed: int, k: int) -> tuple[int, int, int]:
    """``stops[k]`` and the stops before and after it round a closed loop of ``closed``
    points (its last the first again): ``(before, stops[k], after)``, ``after`` being
    ``closed − 1`` after the last stop and ``before`` the last stop before the first."""
    return stops[k - 1], stops[k], stops[k + 1] if k + 1 < len(stops) else closed - 1


def _thin_tooth(Q: np.ndarray, P: np.ndarray, a: int, j: int, b: int, inner: float) -> bool:
    """Whether loop vertex ``j`` (of ``Q``, k×3; disk images ``P``, k×2) lies on the hole's
    side of the chord ``a``–``b`` (as in :func:`_beyond_chord`) and the triangle ``a, j, b``
    has an angle below ``TOOTH_MIN_DEG``."""
    smallest = min_corner_angles(Q, np.array([[a, j, b]]))[0]
    return bool(_side_of_chord(P, a, b, j, inner) > 0 and np.degrees(smallest) < TOOTH_MIN_DEG)


def _side_of_chord(P: np.ndarray, a: int, b: int, i, inner: float):
    """Which side of the disk chord ``P[a]``–``P[b]`` (``P``: k×2) the points ``P[i]`` (an
    index or j indices) lie on: positive on the loop's inside (it turns as ``inner``, the
    sign of its area), negative outside; a float or (j,) float."""
    d = P[b] - P[a]
    return inner * (d[0] * (P[i, 1] - P[a, 1]) - d[1] * (P[i, 0] - P[a, 0]))


def _beyond_chord(Q: np.ndarray, P: np.ndarray, a: int, b: int, inner: float,
                  tols: tuple, gap: float) -> int | None:
    """The vertex of ``Q`` (k×3; disk images ``P``, k×2) strictly between ``a`` and ``b``
    farthest in space from the chord ``Q[a]``–``Q[b]`` among those farther than
    ``tols[0]`` on its outer side or ``tols[1]`` on its inner side (the disk's side of the
    chord that the loop's inside, turning as ``inner``, the sign of its area, lies on) and
    at least ``gap`` from both ends; None where there is none."""
    from .rim import segment_distances

    i = np.arange(a + 1, b)
    if len(i) == 0:
        return None
    side = _side_of_chord(P, a, b, i, inner)
    dist = segment_distances(Q[i], np.repeat(Q[a:a + 1], len(i), 0),
                             np.repeat(Q[b:b + 1], len(i), 0))
    ok = ((dist > np.where(side > 0, tols[1], tols[0])) & (norms(Q[i] - Q[a]) >= gap)
          & (norms(Q[i] - Q[b]) >= gap))
    return int(i[ok][np.argmax(dist[ok])]) if ok.any() else None


def untangled(uv: np.ndarray, arcs: list) -> list:
    """The loops' points ``arcs`` (``(vs, seg, t)`` per loop, :func:`loop_arcs`) with,
    wherever the disk chord between two consecutive points of a loop crosses another chord or
    an edge of a loop other than the loop's own edges between the two points, the loop vertex
    between them nearest to their middle by arc length added, until no chord crosses. A chord
    may cut across the teeth of its own stretch of loop (the cut takes what lies beyond it,
    :func:`cut_holes`), but one that cuts across another stretch (a slit, such as a closed
    mouth, narrower than the chord's bend) or another loop could never be an edge beside the
    crossing one, whereas a chord along one loop edge crosses nothing (the map is
    bijective). Returns the loops in the same form."""
    A = np.vstack([uv[vs[:-1]] for vs, _, _ in arcs])
    B = np.vstack([uv[vs[1:]] for vs, _, _ in arcs])
    for _ in range(max(len(vs) for vs, _, _ in arcs)):
        P = [along_chain(uv, vs, seg, t) for vs, seg, t in arcs]
        ends = np.vstack([np.roll(Q, -1, axis=0) for Q in P])
        P = np.vstack(P)
        crossing = ((crossings(P, ends, A, B) & ~own_stretch(arcs)).any(axis=1)
                    | crossings(P, ends, P, ends).any(axis=1))
        if not crossing.any():
            break
        arcs = [(vs, seg, _with_middle_vertex(seg, t, flags))
                for (vs, seg, t), flags in zip(arcs, np.split(
                    crossing, np.cumsum([len(t) for _, _, t in arcs])[:-1]))]
    return arcs


def own_stretch(arcs: list) -> np.ndarray:
    """Which loop edges (all loops' in order) lie on the stretch of their loop between each
    chord's two points (all loops' chords in order): (p, e) bool, for the loops ``arcs``
    (``(vs, seg, t)`` each)."""
    blocks = []
    for vs, seg, t in arcs:
        s = np.r_[0.0, np.cumsum(seg)]
        ends = np.r_[t[1:], s[-1]]
        blocks.append((s[None, 1:] > t[:, None]) & (s[None, :-1] < ends[:, None]))
    out = np.zeros((sum(len(b) for b in blocks), sum(b.shape[1] for b in blocks)), bool)
    r = c = 0
    for b in blocks:
        out[r:r + b.shape[0], c:c + b.shape[1]] = b
        r, c = r + b.shape[0], c + b.shape[1]
    return out


def _with_middle_vertex(seg: np.ndarray, t: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """The arc lengths ``t`` (p) round a closed loop of edges ``seg`` with, between each
    flagged point (``flags``, p bool) and the next, the loop vertex nearest to their middle
    added (none where no vertex lies between them)."""
    if not flags.any():
        return t
    s = np.r_[0.0, np.cumsum(seg)]
    ends = np.r_[t[1:], s[-1]]
    more = []
    for i in np.flatnonzero(flags):
        between = s[(s > t[i]) & (s < ends[i])]
        if len(between):
            more.append(between[[np.argmin(np.abs(between - (t[i] + ends[i]) / 2))]])
    return np.unique(np.concatenate([t, *more]))


def crossings(P: np.ndarray, Q: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Which segments ``P–Q`` (p×2 each) properly cross which segments ``A–B`` (e×2 each):
    each one's ends strictly on either side of the other's line; (p, e) bool."""
    def side(o, d, x):
        return np.sign(d[..., 0] * (x[..., 1] - o[..., 1]) - d[..., 1] * (x[..., 0] - o[..., 0]))

    P, Q, A, B = P[:, None], Q[:, None], A[None], B[None]
    return ((side(P, Q - P, A) * side(P, Q - P, B) < 0)
            & (side(A, B - A, P) * side(A, B - A, Q) < 0))


def turned_outside(S: RemeshState, fans: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Which faces ``T`` (k×3 vertex indices of ``S``) turn over on the surface
    (:func:`.unfold.turned_over_rows` with ``ties``) outside the holes: a face whose disk
    centroid is in the image of one of the ``fans`` (M bool) is cut away at the end, and
    across a slit (a closed mouth) the flips that join a loop make such faces spanning it."""
    T = np.asarray(T, np.int64).reshape(-1, 3)
    inside = fans[input_face_under(S.locator, S.uv, T)]
    return turned_over_rows(S, T, ties=True) & ~inside


def input_face_under(locator, uv: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The input face (k int) under each face ``T`` (k×3 indices of the disk points ``uv``):
    the one whose image holds the face's disk centroid (``locator``: the input map's
    :class:`..locate.PointLocator`); the test by which a face lies in a hole's fan."""
    return locator.locate(uv[T].mean(axis=1))[0]


def join_loop(S: RemeshState, vs: np.ndarray, seg: np.ndarray, v: np.ndarray,
              t: np.ndarray, turned) -> np.ndarray:
    """Join the vertices ``v`` (p int) at the arc lengths ``t`` (p) along the closed loop
    ``vs`` (edges ``seg`` long) round it, the last to the first (:func:`.features.join_edges`,
    judging the faces turned over by ``turned``: :func:`turned_outside`, then, for the pairs
    left, not at all: counted as ``hole_joins_unjudged``), the pairs added to ``S.joined``;
    where a pair cannot be joined (counted as ``hole_joins_failed``), the one remesh edge its
    segment crosses is split where the loop crosses it (:func:`_split_across`), or else a
    locked vertex is put on the loop's point halfway between its ends (:func:`locked_on`) and
    both halves are joined, up to ``MAX_HALVINGS`` times, then :class:`.state.RemeshFailed`.

    Returns
    -------
    (j, 2) int
        The pairs joined.
    """
    total = float(np.r_[0.0, np.cumsum(seg)][-1])
    todo = [(int(a), int(b), float(ta), float(tb))
            for a, b, ta, tb in zip(v, np.roll(v, -1), t, np.r_[t[1:], total])]
    before = len(S.joined)
    for _ in range(MAX_HALVINGS + 1):
        todo = _joined(S, todo, turned)
        if todo:
            judged = len(todo)
            todo = _joined(S, todo, _nothing_turned)
            S.tally("hole_joins_unjudged", judged - len(todo))
        if not todo:
            return S.joined[before:]
        S.tally("hole_joins_failed", len(todo))
        todo = [half for pair in todo for half in _split_across(S, vs, seg, pair)]
        todo = _halved(S, vs, seg, todo)
    _failed(f"{len(todo)} edges of a hole loop could not be made by flips")


def _joined(S: RemeshState, todo: list, turned) -> list:
    """Join the pairs ``todo`` (``(a, b, t_a, t_b)``) by flips (:func:`.features.join_edges`
    with ``turned``), those joined added to ``S.joined`` (kept by the joins that follow);
    returns the pairs left."""
    got = join_edges(S, np.array([p[:2] for p in todo], np.int64).reshape(-1, 2),
                     turned=turned)
    S.joined = np.vstack([S.joined, got])
    done = {(min(a, b), max(a, b)) for a, b in got.tolist()}
    return [p for p in todo if (min(p[:2]), max(p[:2])) not in done]


def _nothing_turned(T: np.ndarray) -> np.ndarray:
    """No face turned over (k bool for the faces ``T``, k×3): the flips of a hole loop's last
    joins judged on the disk alone (the fold repair takes the folds they leave)."""
    return np.zeros(len(T), bool)


def _split_across(S: RemeshState, vs: np.ndarray, seg: np.ndarray, pair: tuple) -> list:
    """The pair ``(a, b, t_a, t_b)`` joined by splitting the one edge its disk segment crosses
    (:func:`.features.crossed_edges`) where the loop crosses it (:func:`_loop_crossing`), the
    new vertex locked: then ``a`` and ``b`` are corners of the two faces at it, and both
    halves are edges, added to ``S.joined`` (an empty list is returned); the pair itself
    (in a list) where its segment crosses several edges or the loop does not cross that one."""
    from .refine import split_edges

    a, b, ta, tb = pair
    hits = crossed_edges(S, a, b)
    if len(hits) != 1 or S.is_joined(np.array(hits[0][1:2]), np.array(hits[0][2:3]))[0]:
        return [pair]
    t, p, q = hits[0]
    at = _loop_crossing(S, vs, seg, ta, tb, p, q)
    if at is None:
        return [pair]
    c = S.F[t].tolist().index(p)
    h = 3 * t + c
    split_edges(S, np.array([h]), S.twins()[[h]], np.array([at]))
    w = S.n - 1
    S.locked[w] = True
    S.joined = np.vstack([S.joined, [[a, w], [w, b]]])
    S.tally("hole_edges_split", 1)
    return []


def _loop_crossing(S: RemeshState, vs: np.ndarray, seg: np.ndarray, ta: float, tb: float,
                   p: int, q: int) -> float | None:
    """Where the loop ``vs`` between the arc lengths ``ta`` and ``tb`` first crosses the
    remesh edge ``p–q`` on the disk, as the fraction along ``p → q`` (strictly between 0 and
    1); None where it does not."""
    s = np.r_[0.0, np.cumsum(seg)]
    arcs = np.r_[ta, s[(s > ta) & (s < tb)], tb]
    Q = along_chain(S.uv_in, vs, seg, arcs)
    A, B = S.uv[p], S.uv[q]
    d, e = B - A, Q[1:] - Q[:-1]
    den = e[:, 0] * d[1] - e[:, 1] * d[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = ((A[0] - Q[:-1, 0]) * d[1] - (A[1] - Q[:-1, 1]) * d[0]) / den    # along the loop
        v = ((A[0] - Q[:-1, 0]) * e[:, 1] - (A[1] - Q[:-1, 1]) * e[:, 0]) / den   # along p → q
    hit = np.flatnonzero((den != 0) & (u >= 0) & (u <= 1) & (v > 1e-6) & (v < 1 - 1e-6))
    return None if len(hit) == 0 else float(v[hit[0]])


def _halved(S: RemeshState, vs: np.ndarray, seg: np.ndarray, todo: list) -> list:
    """The pairs ``todo`` (``(a, b, t_a, t_b)``) each split in two at a locked vertex on the
    loop's point halfway between them by arc length."""
    if not todo:
        return []
    mid = np.array([(ta + tb) / 2 for _, _, ta, tb in todo])
    m = locked_on(S, along_chain(S.uv_in, vs, seg, mid), "hole_midpoints")
    return [half for (a, b, ta, tb), w, tm in zip(todo, m.tolist(), mid.tolist())
            for half in ((a, w, ta, tm), (w, b, tm, tb))]


def away_from_holes(S: RemeshState, P: np.ndarray, gap: float) -> np.ndarray:
    """The disk points ``P`` (p×2) whose surface points lie ``gap`` or farther from every
    placed hole loop's edges (``S.hole_chains``): a vertex locked nearer would make a sliver
    of the face between it and the loop's kept edge, which no operation could mend."""
    from .rim import segment_distances

    chains = [c for c in S.hole_chains or [] if c is not None]
    if not chains or len(P) == 0:
        return P
    C = np.vstack(chains)
    f, b = S.locator.locate(P)
    X = lift(S.V_in, S.F_in, f, b)
    near = np.array([segment_distances(np.repeat(x[None], len(C), 0), C[:, 0], C[:, 1]).min()
                     < gap for x in X], bool)
    S.tally("corners_near_holes", int(near.sum()))
    return P[~near]


def locked_on(S: RemeshState, Q: np.ndarray, counts: str) -> np.ndarray:
    """A locked vertex of ``S`` on each disk point ``Q`` (p×2): snapped or inserted
    (:func:`.corners.snap_vertices`), then inserted again where a point got none (the
    insertions go in rounds, one point per face each, and a slit's loop, crossing its own
    chords, can put many points in one face), up to ``MAX_INSERT_PASSES`` times, then
    :class:`.state.RemeshFailed`. Returns the vertices (p int); ``<counts>_*`` in the log."""
    snap_vertices(S, Q, counts=counts)
    v = vertices_at(S.uv, Q)
    for _ in range(MAX_INSERT_PASSES):
        if (v >= 0).all():
            return v
        insert_vertices(S, Q[v < 0], counts=counts)
        v = vertices_at(S.uv, Q)
    if (v >= 0).all():
        return v
    _failed(f"{int((v < 0).sum())} points of a hole loop got no vertex")


def _failed(what: str):
    """Raise :class:`.state.RemeshFailed` for a hole loop the remesh cannot keep."""
    raise RemeshFailed(f"remesh: {what}; the holes cannot be kept (--cover-holes covers "
                       f"them); nothing is written")


def loop_of_fans(F: np.ndarray, fans: np.ndarray, loops: list) -> np.ndarray:
    """The hole (index into ``loops``) whose fan each input face of ``F`` (M×3) is in, −1
    for a face not among the ``fans`` (M bool): (M,) int."""
    of_vertex = np.full(int(F.max()) + 1, -1, np.int64)
    for i, loop in enumerate(loops):
        of_vertex[loop] = i
    out = of_vertex[F].max(axis=1)
    out[~fans] = -1
    return out


def intact_loops(S: RemeshState) -> np.ndarray:
    """Which hole loops (``S.hole_chains``) are whole: placed, and each of their edges still
    an edge of ``S`` between two vertices at their placed positions; (h,) bool."""
    a, b = topo.half_edges(S.F)
    have = set(zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist()))
    out = np.zeros(len(S.hole_chains), bool)
    for k, ends in enumerate(chain_vertices(S, S.hole_chains)):
        out[k] = ends is not None and all(e[0] >= 0 and tuple(e) in have for e in ends.tolist())
    return out


def chain_vertices(S: RemeshState, chains: list) -> list:
    """Each hole loop's kept edges (``chains``: (j, 2, 3) end positions, or None) as the
    vertices of ``S`` at their ends, each row sorted ((j, 2) int; −1 where no vertex is at a
    ``S.fixed`` point there), None for None."""
    where = {S.X[i].tobytes(): i for i in np.flatnonzero(at_points(S.X, S.fixed)).tolist()}
    return [None if chain is None else
            np.sort(np.array([[where.get(p.tobytes(), -1) for p in edge] for edge in chain],
                             np.int64).reshape(-1, 2), axis=1)
            for chain in chains]


def all_loops_whole(S: RemeshState) -> bool:
    """Whether ``S`` has holes and every loop of them is placed and whole
    (:func:`intact_loops`): all its holes would be cut, none covered."""
    return S.fans is not None and bool(intact_loops(S).all())


def in_fans(S: RemeshState, faces: np.ndarray) -> np.ndarray:
    """Which of the ``faces`` (k indices) of ``S`` lie in a hole by the cut's test of a face
    alone (:func:`faces_in_holes` without the regions' votes): its disk centroid in the image
    of an input face of the holes' fans (``S.fans``); (k,) bool."""
    return S.fans[input_face_under(S.locator, S.uv, S.F[faces])]


def faces_in_holes(S: RemeshState, holes: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Which faces of ``S`` (m bool) lie in a hole that is ``kept`` (h bool): the faces
    between the edges of the kept loops split into regions, and a region is in hole ``i``
    where most of its disk area has its centroid in the image of an input face of that hole's
    fan (``holes``, M int, :func:`loop_of_fans`). A tooth of a ragged loop beyond the chord
    across it thus goes with the side of the chord it lies on."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(S.F)
    kept_chains = [c for c, k in zip(S.hole_chains, kept) if k]
    walls = {tuple(e) for ends in chain_vertices(S, kept_chains) for e in ends.tolist()}
    a, b = topo.half_edges(S.F)
    twin = S.twins()
    h = np.flatnonzero(twin >= 0)
    wall = np.array([(min(x, y), max(x, y)) in walls
                     for x, y in zip(a[h].tolist(), b[h].tolist())], bool)
    h = h[~wall]
    graph = coo_matrix((np.ones(len(h)), (h // 3, twin[h] // 3)), shape=(m, m))
    _, region = connected_components(graph, directed=False)
    label = holes[input_face_under(S.locator, S.uv, S.F)]
    label = np.where((label >= 0) & kept[np.maximum(label, 0)], label, -1)
    area = np.abs(signed_double_areas(S.uv, S.F))
    k = len(kept) + 1
    votes = np.bincount(region * k + label + 1, area, (region.max() + 1) * k).reshape(-1, k)
    return votes.argmax(axis=1)[region] > 0


def cut_holes(S: RemeshState, holes: np.ndarray) -> np.ndarray:
    """Remove the faces of ``S`` in the holes whose loops are whole (:func:`intact_loops`,
    :func:`faces_in_holes`) and the vertices no other face uses
    (:meth:`.state.RemeshState.keep_vertices`: the rest keep their order, ``F`` and
    ``joined`` are renumbered); a hole whose loop is not whole is covered, its loop's input
    vertex count listed in the log's ``holes_covered`` (its index in ``holes_covered_index``).
    Returns which holes are kept (h bool).

    Parameters
    ----------
    S : RemeshState
    holes : (M,) int
        The hole whose fan each input face is in, −1 for none (:func:`loop_of_fans`).
    """
    kept = intact_loops(S)
    inside = faces_in_holes(S, holes, kept)
    S.set_faces(S.F[~inside])
    used = np.zeros(S.n, bool)
    used[S.F.ravel()] = True
    S.keep_vertices(used)
    S.tally("hole_faces_cut", int(inside.sum()))
    sizes = np.bincount(holes[holes >= 0], minlength=len(kept))
    S.log["holes_covered"] = [int(n) for n in sizes[~kept]]
    S.log["holes_covered_index"] = np.flatnonzero(~kept).tolist()
    return kept


def lift_with_holes_cut(X: np.ndarray, F: np.ndarray, uv: np.ndarray, locator,
                        holes: np.ndarray, covered) -> tuple[np.ndarray, np.ndarray]:
    """The plain lift ``(X, F)`` (n×3, m×3; disk points ``uv``, n×2) without its faces whose
    disk centroid lies in a hole not ``covered`` (indices): in the image of an input face of
    that hole's fan (``holes``, M int, :func:`loop_of_fans`; ``locator`` over the input's
    map), and without the vertices no other face uses. It has no vertices on the loops, so
    its hole rims run along its own edges."""
    label = holes[input_face_under(locator, uv, F)]
    cut = (label >= 0) & ~np.isin(label, np.asarray(covered, np.int64))
    X, F, _ = used_vertices_only(X, F[~cut])
    return X, F
