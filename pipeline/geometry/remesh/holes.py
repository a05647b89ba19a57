"""The input's holes kept open: constrain the filled disk, remesh it, cut the holes out.

The intake closes every hole but the outer boundary with a fan to a new centre vertex
(:func:`..repair.repair_mesh`), so that the mesh is a disk and has a disk map. The remesh keeps
them as constraints of that one disk (:func:`place_holes`, before the corners, feature lines
and landmarks): each hole loop gets locked remesh vertices about ``L`` apart along it, on the
points of :func:`.features.chain_arcs` on the loop as a closed chain, every one of them, and
where the disk chord between two of them crosses a loop or another chord (a slit, such as a
closed mouth), on the loop's own vertices between them too (:func:`untangled`); consecutive
ones are joined by an edge that no flip, split or collapse removes and whose ends never move
(``RemeshState.joined``, ``RemeshState.fixed``). Where the flips cannot make such an edge, the
one edge in the way is split where the loop crosses it, or else the loop's point halfway
between the two is put in and both halves joined (:func:`join_loop`). After the improvement
pass every remesh face lies wholly inside or outside each loop, and the faces inside a hole —
their disk centroid in the image of a fan face — are cut away with the vertices no other face
uses (:func:`cut_holes`).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from .. import topology as topo
from .corners import insert_vertices, snap_vertices
from .features import along_chain, chain_arcs, crossed_edges, join_edges, vertices_at
from .state import RemeshFailed, RemeshState
from .unfold import turned_over_rows

MIN_LOOP_POINTS = 3      # a hole keeps at least this many vertices (a triangle)
MAX_INSERT_PASSES = 8    # rounds of insertions of a hole loop's points left without a vertex
MAX_HALVINGS = 4         # a pair still unjoined after this many halvings: RemeshFailed


def place_holes(S: RemeshState, loops: list, fans: np.ndarray, L: float) -> np.ndarray:
    """Lock a remesh vertex on every point of each hole loop (:func:`loop_arcs`) and join
    consecutive ones round the loop (:func:`join_loop`); the pairs are added to ``S.joined``
    and the vertices' positions to ``S.fixed``.

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
    arcs = [loop_arcs(S.V_in, loop, L) for loop in loops]
    arcs = untangled(S.uv_in, arcs)
    P = [along_chain(S.uv_in, vs, seg, t) for vs, seg, t in arcs]
    if P:
        locked_on(S, np.vstack(P), "hole_points")
    pairs = [np.zeros((0, 2), np.int64)]
    for (vs, seg, t), Q in zip(arcs, P):
        pairs.append(join_loop(S, vs, seg, vertices_at(S.uv, Q), t,
                               partial(turned_outside, S, fans)))
    S.fixed = S.X[np.unique(np.vstack(pairs))].copy()
    S.tally("hole_edges", sum(map(len, pairs)))
    return S.fixed


def loop_arcs(V: np.ndarray, loop: np.ndarray, L: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A hole loop as a closed chain and its points' arc lengths (:func:`.features.chain_arcs`
    at spacing ``L``), at least ``MIN_LOOP_POINTS`` of them (evenly spaced on a loop too short
    for more).

    Parameters
    ----------
    V : (n, 3) float
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
    seg, t, _ = chain_arcs(V, vs, L)
    if len(t) < MIN_LOOP_POINTS:
        t = np.linspace(0.0, float(np.r_[0.0, np.cumsum(seg)][-1]), MIN_LOOP_POINTS + 1)[:-1]
    return vs, seg, t


def untangled(uv: np.ndarray, arcs: list) -> list:
    """The loops' points ``arcs`` (``(vs, seg, t)`` per loop, :func:`loop_arcs`) with,
    wherever the disk chord between two consecutive points of a loop crosses an edge of a
    loop or another chord on the disk, the loop's vertices between them added, until no chord
    crosses: a chord that cuts across a loop (a slit, such as a closed mouth, narrower than
    the chord's bend, or a noisy one whose two lips wiggle across each other's chords) could
    never be an edge beside the crossing one, whereas a chord along one loop edge crosses no
    other (the map is bijective). Returns the loops in the same form."""
    A = np.vstack([uv[vs[:-1]] for vs, _, _ in arcs])
    B = np.vstack([uv[vs[1:]] for vs, _, _ in arcs])
    for _ in range(max(len(vs) for vs, _, _ in arcs)):
        P = [along_chain(uv, vs, seg, t) for vs, seg, t in arcs]
        ends = np.vstack([np.roll(Q, -1, axis=0) for Q in P])
        P = np.vstack(P)
        crossing = crossings(P, ends, A, B).any(axis=1) | crossings(P, ends, P, ends).any(axis=1)
        if not crossing.any():
            break
        arcs = [(vs, seg, _with_vertices_between(seg, t, flags))
                for (vs, seg, t), flags in zip(arcs, np.split(
                    crossing, np.cumsum([len(t) for _, _, t in arcs])[:-1]))]
    return arcs


def _with_vertices_between(seg: np.ndarray, t: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """The arc lengths ``t`` (p) round a closed loop of edges ``seg`` with the loop's vertices
    added between each flagged point (``flags``, p bool) and the next."""
    if not flags.any():
        return t
    s = np.r_[0.0, np.cumsum(seg)]
    ends = np.r_[t[1:], s[-1]]
    more = [s[(s > t[i]) & (s < ends[i])] for i in np.flatnonzero(flags)]
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
    inside = fans[S.locator.locate(S.uv[T].mean(axis=1))[0]]
    return turned_over_rows(S, T, ties=True) & ~inside


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


def locked_on(S: RemeshState, Q: np.ndarray, counts: str) -> np.ndarray:
    """A locked vertex of ``S`` on each disk point ``Q`` (p×2): snapped or inserted
    (:func:`.corners.snap_vertices`), then inserted again where a point got none (the
    insertions go in rounds, one point per face each, and a slit's loop, crossing its own
    chords, can put many points in one face), up to ``MAX_INSERT_PASSES`` times, then
    :class:`.state.RemeshFailed`. Returns the vertices (p int); ``<counts>_*`` in the log."""
    snap_vertices(S, Q, counts=counts)
    for _ in range(MAX_INSERT_PASSES):
        v = vertices_at(S.uv, Q)
        if (v >= 0).all():
            return v
        insert_vertices(S, Q[v < 0], counts=counts)
    _failed(f"{int((vertices_at(S.uv, Q) < 0).sum())} points of a hole loop got no vertex")


def _failed(what: str):
    """Raise :class:`.state.RemeshFailed` for a hole loop the remesh cannot keep."""
    raise RemeshFailed(f"remesh: {what}; the holes cannot be kept (--cover-holes covers "
                       f"them); nothing is written")


def faces_in_holes(S: RemeshState, fans: np.ndarray) -> np.ndarray:
    """Which faces of ``S`` (m bool) lie in a hole: their disk centroid in the image of an
    input face among ``fans`` (M bool)."""
    centroids = S.uv[S.F].mean(axis=1)
    face, _ = S.locator.locate(centroids)
    return fans[face]


def cut_holes(S: RemeshState, fans: np.ndarray) -> int:
    """Remove the faces of ``S`` in the holes (:func:`faces_in_holes`) and the vertices no
    other face uses (:meth:`.state.RemeshState.keep_vertices`: the rest keep their order,
    ``F`` and ``joined`` are renumbered). Returns the number of faces removed."""
    inside = faces_in_holes(S, fans)
    S.set_faces(S.F[~inside])
    used = np.zeros(S.n, bool)
    used[S.F.ravel()] = True
    S.keep_vertices(used)
    S.tally("hole_faces_cut", int(inside.sum()))
    return int(inside.sum())


def check_loops(S: RemeshState) -> None:
    """Check that every hole edge placed (``hole_edges`` in the log) is still a kept edge
    between two vertices at ``S.fixed`` and an edge of ``S`` (before the cut); raise
    :class:`.state.RemeshFailed` if one is missing (an operation of the improvement removed
    it, or moved or removed one of its ends)."""
    if len(S.fixed) == 0:
        return
    pairs = S.joined[S.is_fixed(S.joined[:, 0], S.joined[:, 1])]
    a, b = topo.half_edges(S.F)
    have = set(zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist()))
    missing = [p for p in np.sort(pairs, axis=1).tolist() if tuple(p) not in have]
    missing += [None] * (S.log.get("hole_edges", 0) - len(pairs))
    if missing:
        _failed(f"{len(missing)} edges of the hole loops were lost in the improvement")
