"""Feature lines of the input: creases the remesh puts vertices on and keeps edges along.

Where the input surface folds sharply across an edge (a dihedral angle over ``FEATURE_DEG``), a
remesh whose edges cut across the crease between vertices on either side leaves the surface by
about the edge length times the fold, on both sides of every such crease: the RMS distance of a
coarse, creased input is decided there. The input edges sharper than the threshold, none at
the boundary and none at an input face whose map dilatation (:func:`..metrics.stretch_anisotropy`)
exceeds ``MAX_DILATATION`` (where the disk squeezes the surface that much, the flips that join
feature points and the remesh around its locked vertices fold it: gpp_bunny at 20k vertices,
30°, three faces turned over without this limit, none with it) (:func:`feature_edges`), form
**chains** (:func:`feature_chains`): runs through
vertices where exactly two of them meet and the line turns by at most ``TURN_DEG``; chains
shorter than ``MIN_LENGTH × L`` are dropped. Below the threshold a crease is taken where it
is a line of the shape rather than of the tessellation (:func:`smooth_creases`): a chain of
edges folded more than ``SMOOTH_CREASE_DEG`` that turns slowly, is closed or several ``L``
long, folds alike all along and has the surface smooth on both sides
(:func:`smooth_chain_mask`; a crease between a head and a neck) — with no limit on the map's
dilatation, but none of its edges above the threshold (those are the fold-back rule's, with
its limit). Each chain gets points (:func:`chain_points`):
its own vertices where its chords would leave it by more than ``BEND_TOL × L``
(:func:`chain_stops`), and evenly spaced points about ``L`` apart along its straight stretches.
The map is affine on every input face, so a point a fraction along an input edge has its disk
image the same fraction along the edge's image: a vertex there lifts (eq. 1) onto the crease.

:func:`place_features` snaps (or inserts) a locked remesh vertex onto each point
(:func:`.corners.snap_vertices`), the heaviest chains first (:func:`chain_weights`: length ×
dihedral², what cutting across them costs), a chain's ends before its other points, none
within ``FEATURE_GAP × L`` on the surface of one placed before (where creases run closer than
that, the lighter one gives way); then consecutive points of a chain that both got a vertex
are **joined** (:func:`consecutive_pairs`: a point without one cuts its chain): the edge
between them is made by flips on the disk where it is missing (:func:`join_edges`) and kept
(``RemeshState.joined``): the flips do not remove it, the splits do not divide it, and its
ends, locked, are neither moved nor collapsed. Faces flat on
the surface (three points on one straight crease) have their long edge flipped first. Where
the fold repair, the minimum-angle pass or the degenerate-face repair need a face with feature
corners, those vertices are freed (:func:`release_features`).
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from .. import topology as topo
from ..libm import arccos
from ..metrics import stretch_anisotropy
from ..rows import dots, norms
from .corners import snap_vertices
from .halfedge import DISK_SHAPE_MIN, disk_shape, edge_table, vertex_faces
from .state import RemeshState, at_points, face_normals
from .unfold import turned_over_rows

FEATURE_DEG = 30.0   # input edges whose faces' normals differ by more than this are creases
# the remesh command's default threshold: the folds that turn back (a lip's or a lid's fold, a
# sulcus, a mouth corner); without feature lines the follow step snaps vertices onto such a
# fold 0.2–0.4 L apart with no edge along it, the fold repair and the minimum-angle pass take
# them off again (the faces across the fold are needles), and no vertex can be put back
# without one: the fold's far side is left half an edge or more from the remesh
FOLD_BACK_DEG = 90.0
TURN_DEG = 60.0      # a chain ends where its line turns by more than this
MIN_LENGTH = 0.8     # chains shorter than this × L are dropped
FEATURE_GAP = 0.6    # feature vertices are at least this × L apart on the surface
MAX_STEP = 1.25      # consecutive feature points at most this × L apart along a chain, …
BEND_TOL = 0.05      # … their chord within this × L of the chain's vertices between them
MAX_DILATATION = 8.0  # no feature edge at an input face whose map dilatation exceeds this
# a crease folded less than the threshold is taken where it is a line of the shape, not of the
# tessellation (:func:`smooth_chain_mask`): a chain of edges folded more than SMOOTH_CREASE_DEG
# turning by at most SMOOTH_TURN_DEG at each vertex, closed or at least SMOOTH_MIN_LENGTH × L
# long, its largest fold at most SMOOTH_SPREAD × its smallest, and every other edge within two
# edges of it folded at most SMOOTH_SIDES × its smallest fold (the surface smooth beside it)
SMOOTH_CREASE_DEG = 40.0
SMOOTH_TURN_DEG = 15.0
SMOOTH_MIN_LENGTH = 3.0
SMOOTH_MIN_EDGES = 4      # … and of at least this many edges (on fewer, consistency says little)
SMOOTH_SPREAD = 1.25
SMOOTH_SIDES = 0.5
FLAT = 1e-3          # a face with 2·area ≤ this × its longest edge² is flat (three collinear
                     # feature points): its longest edge is flipped


def feature_edges(V: np.ndarray, F: np.ndarray, angle_deg: float = FEATURE_DEG,
                  faces: np.ndarray | None = None, folds: tuple | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The interior edges of ``(V, F)`` whose two faces' normals differ by more than
    ``angle_deg``, neither end on the boundary (and both faces among ``faces``, if given).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    angle_deg : float
    faces : (m,) bool, optional
    folds : tuple, optional
        :func:`edge_folds` of ``(V, F)``, when the caller has it.

    Returns
    -------
    E : (e, 2) int
        Vertex pairs.
    angle : (e,) float
        Their dihedral angles (radians).
    """
    h, twin, E, cos = edge_folds(V, F) if folds is None else folds
    keep = cos < math.cos(math.radians(angle_deg))
    if faces is not None:
        keep &= faces[h // 3] & faces[twin // 3]
    return E[keep], arccos(cos[keep])


def edge_folds(V: np.ndarray, F: np.ndarray) -> tuple:
    """The interior edges of ``(V, F)`` with neither end on the boundary and the cosines of
    their dihedral angles.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int

    Returns
    -------
    h, twin : (e,) int
        Each edge's half-edge ``a → b`` (:func:`.halfedge.edge_table`) and its twin.
    E : (e, 2) int
        The vertex pairs ``a, b``.
    cos : (e,) float
        The dot products of the two faces' unit normals, clipped to [−1, 1].
    """
    h, a, b, twin = edge_table(F)
    inner = twin >= 0
    h, a, b, twin = h[inner], a[inner], b[inner], twin[inner]
    N = face_normals(V, F)
    cos = np.clip(dots(N.take(h // 3, axis=0), N.take(twin // 3, axis=0)), -1.0, 1.0)
    on_b = topo.boundary_vertices_mask(F, len(V))
    off = ~on_b[a] & ~on_b[b]
    return h[off], twin[off], np.column_stack([a[off], b[off]]), cos[off]


def feature_chains(V: np.ndarray, E: np.ndarray, turn_deg: float = TURN_DEG) -> list:
    """The feature edges ``E`` cut into chains: maximal runs through vertices where exactly
    two of them meet at a turn of at most ``turn_deg`` (:func:`_passes_through`); a closed
    run starts and ends at one vertex.

    The chains come in the order of a walk from each vertex the runs do not pass through
    (vertices in the order they first appear in ``E``, their edges in ``E``'s order) along
    each edge not walked yet, then of the closed runs from the first end of their first edge
    in ``E``'s order (:func:`_walked_runs`): each edge, as a half-edge from one end, is
    followed by the other half-edge at its far end where a chain passes through that vertex,
    and the half-edges of a run are put in order by their distance from its first one
    (:func:`_steps_from_start`).

    Parameters
    ----------
    V : (n, 3) float
    E : (e, 2) int
    turn_deg : float

    Returns
    -------
    list of (k,) int
        Vertex sequences along each chain (k ≥ 2).
    """
    E = np.asarray(E).reshape(-1, 2)
    if len(E) == 0:
        return []
    tail = E.ravel().astype(np.int64)             # half h: edge h // 2 from its end h % 2
    halves = np.arange(len(tail))
    verts, first, at = np.unique(tail, return_index=True, return_inverse=True)
    appear = np.empty(len(verts), np.int64)       # vertex → order of first appearance
    appear[np.argsort(first)] = np.arange(len(verts))
    through, partner = _passes_through(V, tail, at, len(verts), turn_deg)
    nxt = np.where(through[at[halves ^ 1]], partner[halves ^ 1], -1)
    walked, start = _walked_runs(nxt, through[at], appear[at] * len(E) + halves // 2)
    prev = np.full(len(tail), -1)
    prev[nxt[nxt >= 0]] = halves[nxt >= 0]
    prev[start] = -1                              # a closed run cut at its first half
    steps, first_half = _steps_from_start(np.where(walked, prev, -1))
    kept = np.flatnonzero(walked)
    run_rank = np.empty(len(tail), np.int64)
    run_rank[start] = np.arange(len(start))
    order = kept[np.lexsort((steps[kept], run_rank[first_half[kept]]))]
    counts = np.bincount(run_rank[first_half[order]], minlength=len(start)) + 1
    flat = np.empty(counts.sum(), np.int64)
    offsets = np.r_[0, np.cumsum(counts)]
    flat[offsets[:-1]] = tail[start]
    inner = np.ones(len(flat), bool)
    inner[offsets[:-1]] = False
    flat[inner] = tail[order ^ 1]                 # each half's head, in order along its run
    return np.split(flat, offsets[1:-1])


def _passes_through(V: np.ndarray, tail: np.ndarray, at: np.ndarray, n_verts: int,
                    turn_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Which feature vertices a chain passes through, and the other half at each.

    Parameters
    ----------
    V : (n, 3) float
    tail : (2e,) int
        The vertex each half-edge leaves (half ``h``: edge ``h // 2`` from its end ``h % 2``).
    at : (2e,) int
        The feature vertex (``0 … n_verts − 1``) of each half's tail.
    n_verts : int
    turn_deg : float

    Returns
    -------
    through : (n_verts,) bool
        Exactly two feature edges meet there, first ``i`` then ``j`` in ``E``'s order, with
        ``d₁ · d₂ ≥ cos(turn_deg) |d₁| |d₂|`` for ``d₁ = v − (i's other end)``,
        ``d₂ = (j's other end) − v`` (:func:`blas_dots`, the dot products of ``d₁ @ d₂`` and
        ``np.linalg.norm``).
    partner : (2e,) int
        At a vertex with two feature edges, each half's other half there; −1 elsewhere.
    """
    by_vertex = np.argsort(at, kind="stable")     # halves by vertex, then by edge
    degree = np.bincount(at, minlength=n_verts)
    two = np.flatnonzero(degree == 2)
    first = np.r_[0, np.cumsum(degree)][two]
    h1, h2 = by_vertex[first], by_vertex[first + 1]
    v = tail[h1]
    d1, d2 = V[v] - V[tail[h1 ^ 1]], V[tail[h2 ^ 1]] - V[v]
    cos_turn = math.cos(math.radians(turn_deg))
    through = np.zeros(n_verts, bool)
    through[two] = blas_dots(d1, d2) >= (cos_turn * np.sqrt(blas_dots(d1, d1))
                                         * np.sqrt(blas_dots(d2, d2)))
    partner = np.full(len(tail), -1)
    partner[h1], partner[h2] = h2, h1
    return through, partner


def blas_dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a[i] @ b[i]`` per row (k×d, k×d → k) by NumPy's own dot product of two vectors (the
    BLAS one, which fuses multiply and add where the CPU can: not the same rounding as
    :func:`..rows.dots`), as a stack of (1×d)·(d×1) products."""
    return (a[:, None, :] @ b[:, :, None])[:, 0, 0]


def _walked_runs(nxt: np.ndarray, tail_through: np.ndarray, key: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The direction each run is walked in, and its first half-edge.

    Half-edges linked by ``nxt`` form runs, each edge in two, one per direction. An open run
    (it starts at a half whose tail the chains do not pass through) is walked from its end
    with the smaller ``key``; a closed one (every tail passed through) from its half with the
    smallest index, if that is an edge's first half (the other direction starts from the
    edge's second half).

    Parameters
    ----------
    nxt : (2e,) int
        The half that follows each one along its run (−1 at a run's end).
    tail_through : (2e,) bool
        Whether a chain passes through each half's tail.
    key : (2e,) int
        The walk's order of the open runs' first halves.

    Returns
    -------
    walked : (2e,) bool
        The halves of the runs walked.
    start : (c,) int
        Their first halves: the open runs by ``key``, then the closed ones by index.
    """
    h = np.flatnonzero(nxt >= 0)
    _, run = topo.graph_components(h, nxt[h], len(nxt))      # the runs, linked either way
    opens = np.flatnonzero(~tail_through)                     # each open run's first half
    first_of = np.full(run.max() + 1, -1)
    first_of[run[opens]] = opens
    other = first_of[run[opens ^ 1]]                          # the same run walked back
    opens = opens[key[opens] < key[other]]
    opens = opens[np.argsort(key[opens], kind="stable")]
    _, lowest = np.unique(run, return_index=True)             # each run's smallest half
    closed = np.sort(lowest[(first_of[run[lowest]] < 0) & (lowest % 2 == 0)])
    start = np.r_[opens, closed]
    walked = np.zeros(len(nxt), bool)
    walked[np.isin(run, run[start])] = True
    return walked, start


def _steps_from_start(prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each element of linked lists given by ``prev`` (n int, −1 at a list's start, no
    cycles): how many steps back its list's start is, and that start (pointer jumping)."""
    reach = np.where(prev >= 0, prev, np.arange(len(prev)))
    steps = (prev >= 0).astype(np.int64)
    while True:
        further = reach[reach]
        if np.array_equal(further, reach):
            return steps, reach
        steps = steps + steps[reach]
        reach = further


def chain_points(V: np.ndarray, uv: np.ndarray, chains: list, L: float,
                 min_length: float = MIN_LENGTH) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along each chain, about ``L`` apart, whose chords follow it: the chain's own
    vertices where it bends (:func:`chain_stops`), and on a stretch longer than ``MAX_STEP × L``
    between two of them, evenly spaced points at about ``L``. Chains shorter than
    ``min_length × L`` are left out.

    Parameters
    ----------
    V : (n, 3) float
    uv : (n, 2) float
        The disk map.
    chains : list of (k,) int
    L : float
    min_length : float

    Returns
    -------
    P_uv : (p, 2) float
        The points' disk images (the map is affine on an input edge: a point a fraction along
        it has its image the same fraction along the edge's image).
    chain : (p,) int
        The chain each belongs to, in order along it.
    rank : (p,) int
        0 for a chain's ends, 1 for its other vertices, 2 for points between them: the order
        in which they claim a remesh vertex.
    """
    P, which, rank = [], [], []
    long_enough = chain_sums(chain_steps(V, chains), [len(vs) - 1 for vs in chains])
    for c in np.flatnonzero(~(long_enough < min_length * L)).tolist():
        seg, t, r = chain_arcs(V, chains[c], L)
        P.append(along_chain(uv, chains[c], seg, t))
        which.append(np.full(len(t), c))
        rank.append(r)
    if not P:
        return np.zeros((0, uv.shape[1])), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.vstack(P), np.concatenate(which), np.concatenate(rank)


def chain_arcs(V: np.ndarray, vs: np.ndarray, L: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where :func:`chain_points` puts the points of one chain, as arc lengths along it.

    Parameters
    ----------
    V : (n, 3) float
    vs : (k,) int
        The chain's vertices in order (``vs[0] == vs[-1]`` for a closed chain).
    L : float

    Returns
    -------
    seg : (k - 1,) float
        The lengths of the chain's edges.
    t : (p,) float
        The points' arc lengths, increasing (a closed chain's start once).
    rank : (p,) int
        As :func:`chain_points` ranks them.
    """
    seg = norms(V[vs[1:]] - V[vs[:-1]])
    s = np.r_[0.0, np.cumsum(seg)]
    stops = chain_stops(V[vs], s, L)
    t, r = [], []
    for i, j in zip(stops[:-1], stops[1:]):
        k = max(1, int(round((s[j] - s[i]) / L))) if s[j] - s[i] > MAX_STEP * L else 1
        t.append(np.linspace(s[i], s[j], k + 1)[:-1])
        r.append(np.r_[1, np.full(k - 1, 2)])
    t.append(s[-1:])
    r.append([1])
    t, r = np.concatenate(t), np.concatenate(r)
    r[0] = r[-1] = 0
    if vs[0] == vs[-1]:
        t, r = t[:-1], r[:-1]                 # a closed chain: its start once
    return seg, t, r


def along_chain(uv: np.ndarray, vs: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The disk images (p×2) of the points at arc lengths ``t`` (p) along the chain ``vs``
    (k int) whose edges are ``seg`` (k − 1) long (:func:`chain_arcs`): the map is affine on
    an input edge, so a point a fraction along it has its image the same fraction along the
    edge's image."""
    s = np.r_[0.0, np.cumsum(seg)]
    e = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
    f = np.clip((t - s[e]) / np.maximum(seg[e], 1e-300), 0.0, 1.0)[:, None]
    return (1.0 - f) * uv[vs[e]] + f * uv[vs[e + 1]]


def chain_stops(Q: np.ndarray, s: np.ndarray, L: float) -> np.ndarray:
    """The chain vertices (indices into ``Q``, both ends included) kept as feature points:
    from each one, among the vertices along the chain within ``MAX_STEP × L`` of arc length
    whose chord passes within ``BEND_TOL × L`` of every vertex in between, the one whose arc
    length from it is nearest to ``L`` — to the rest of the chain's length over the nearest
    whole number of ``L`` — (the next vertex if none qualifies).

    Parameters
    ----------
    Q : (k, 3) float
        The chain's vertices.
    s : (k,) float
        Their arc lengths.
    L : float

    Returns
    -------
    (j,) int
    """
    from .rim import segment_distances

    stops, i, k = [0], 0, len(Q) - 1
    while i < k:
        best = i + 1
        step = (s[k] - s[i]) / max(1, round((s[k] - s[i]) / L))   # even steps to the end
        for j in range(i + 2, k + 1):
            if s[j] - s[i] > MAX_STEP * L:
                break
            mid = Q[i + 1:j]
            d = segment_distances(mid, np.repeat(Q[i:i + 1], len(mid), 0),
                                  np.repeat(Q[j:j + 1], len(mid), 0))
            if d.max() > BEND_TOL * L:
                break
            if abs(s[j] - s[i] - step) < abs(s[best] - s[i] - step):
                best = j
        stops.append(best)
        i = best
    return np.asarray(stops)


def chain_weights(V: np.ndarray, E: np.ndarray, angle: np.ndarray, chains: list
                  ) -> np.ndarray:
    """What each chain costs a remesh that cuts across it: the sum over its edges of length ×
    dihedral angle² (the squared distance of a chord across a crease grows with the angle's
    square), (c,) float; the heaviest chains claim remesh vertices first.

    Parameters
    ----------
    V : (n, 3) float
    E : (e, 2) int
        The feature edges, ``angle`` (e,) their dihedral angles.
    chains : list of (k,) int
        Runs of edges of ``E``.
    """
    E = np.asarray(E).reshape(-1, 2)
    weight = norms(V[E[:, 0]] - V[E[:, 1]]) * angle ** 2
    if not chains:
        return np.array([])
    return chain_sums(weight[chain_edge_rows(E, chains)], [len(vs) - 1 for vs in chains])


def chain_edge_rows(E: np.ndarray, chains: list) -> np.ndarray:
    """The row of ``E`` (e, 2) int of each of the chains' edges (:func:`chain_edges`), (s,) int:
    every chain edge, either way round, is a row of ``E``."""
    a, b = chain_edges(chains)
    n = int(max(E.max(), a.max(), b.max())) + 1
    keys = topo.pair_keys(E[:, 0], E[:, 1], n)
    by_key = np.argsort(keys, kind="stable")
    return by_key[np.searchsorted(keys[by_key], topo.pair_keys(a, b, n))]


def chain_edges(chains: list) -> tuple[np.ndarray, np.ndarray]:
    """The chains' edges ``a → b`` (s,) int each, chain after chain, each in order along it:
    ``vs[:-1]``, ``vs[1:]`` of every chain ``vs``."""
    if not chains:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    flat = np.concatenate(chains).astype(np.int64)
    step = np.ones(len(flat) - 1, bool)
    step[np.cumsum([len(vs) for vs in chains])[:-1] - 1] = False   # not across two chains
    return flat[:-1][step], flat[1:][step]


def chain_steps(V: np.ndarray, chains: list) -> np.ndarray:
    """The lengths of the chains' edges (:func:`chain_edges`) (s,) float:
    ``norms(V[vs[1:]] − V[vs[:-1]])`` of every chain ``vs`` (row by row, the same numbers)."""
    a, b = chain_edges(chains)
    return norms(V[b] - V[a])


def chain_sums(values: np.ndarray, counts) -> np.ndarray:
    """Per chain, the sum of its ``counts`` (c,) consecutive ``values`` (s,) taken in order
    from the left, ``((0 + x₀) + x₁) + …`` as Python's ``sum`` and ``np.cumsum`` add them
    (c,) float: one vector step per position along the chains, longest chains first."""
    counts = np.asarray(counts, np.int64)
    total = np.zeros(len(counts))
    if len(counts) == 0:
        return total
    longest_first = np.argsort(-counts, kind="stable")
    offsets = np.r_[0, np.cumsum(counts)][:-1][longest_first]
    remaining = counts[longest_first]
    acc = np.zeros(len(counts))
    for k in range(int(remaining.max(initial=0))):
        m = np.searchsorted(-remaining, -k, side="left")      # the chains longer than k
        acc[:m] += values[offsets[:m] + k]
    total[longest_first] = acc
    return total


def place_features(S: RemeshState, L: float, angle_deg: float = FEATURE_DEG,
                   fans: np.ndarray | None = None) -> np.ndarray:
    """Lock a remesh vertex on every point of the input's feature chains (:func:`chain_points`
    at spacing ``L``; :func:`.corners.snap_vertices`, ``FEATURE_GAP × L`` apart) and join
    consecutive ones (:func:`join_edges`); the joined pairs are added to ``S.joined``. The
    chains are those of the edges folded more than ``angle_deg`` at faces the map dilates at
    most ``MAX_DILATATION``, with the smooth creases below it (:func:`smooth_creases`), none
    at the ``fans`` filling the holes (whose loops :mod:`.holes` keeps already).

    Parameters
    ----------
    S : RemeshState
        Changed in place; counts under ``features_*`` in its log.
    L : float
        Target edge length, in the mesh's units.
    angle_deg : float
        The crease threshold (:func:`feature_edges`).
    fans : (M,) bool, optional
        The input faces that fill the holes: no edge of theirs is a feature edge.

    Returns
    -------
    (j, 2) int
        The pairs joined.
    """
    even = stretch_anisotropy(S.V_in, S.F_in, S.uv_in) <= MAX_DILATATION
    if fans is not None:
        even &= ~fans
    folds = edge_folds(S.V_in, S.F_in)
    E, angle = feature_edges(S.V_in, S.F_in, angle_deg, faces=even, folds=folds)
    if angle_deg > SMOOTH_CREASE_DEG:
        E_smooth, angle_smooth = smooth_creases(S.V_in, S.F_in, L, angle_deg, folds)
        if fans is not None:
            E_smooth, angle_smooth = off_fans(S.F_in, fans, E_smooth, angle_smooth)
        S.tally("feature_smooth_edges", len(E_smooth))
        E, angle = with_edges(E, angle, E_smooth, angle_smooth)
    chains = feature_chains(S.V_in, E, TURN_DEG)
    P, chain, rank = chain_points(S.V_in, S.uv_in, chains, L, MIN_LENGTH)
    S.tally("feature_points", len(P))
    if len(P) == 0:
        return np.zeros((0, 2), np.int64)
    weight = chain_weights(S.V_in, E, angle, chains)
    order = np.lexsort((rank, -weight[chain]))
    placed = snap_vertices(S, P[order], min_gap=FEATURE_GAP * L, counts="features")
    v = vertices_at(S.uv, P)
    pairs = consecutive_pairs(v, chain)
    S.tally("feature_pairs", len(pairs))
    pairs = join_edges(S, pairs)
    S.joined = np.vstack([S.joined, pairs])
    S.locked[np.setdiff1d(placed, pairs)] = False       # a point on no kept edge: a start
    S.tally("features_joined", len(pairs))
    return pairs


def off_fans(F: np.ndarray, fans: np.ndarray, E: np.ndarray, angle: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """The edges ``E`` (e, 2) int and their ``angle`` (e,) but those with both ends on faces
    of ``F`` (m×3) among the ``fans`` (m bool): a hole loop's edges and a fan's spokes."""
    on_fan = np.zeros(int(max(F.max(), E.max(initial=0))) + 1, bool)
    on_fan[F[fans].ravel()] = True
    keep = ~(on_fan[E[:, 0]] & on_fan[E[:, 1]])
    return E[keep], angle[keep]


def smooth_creases(V: np.ndarray, F: np.ndarray, L: float, max_deg: float = 180.0,
                   folds: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The edges of ``(V, F)`` folded more than ``SMOOTH_CREASE_DEG`` on chains turning by at
    most ``SMOOTH_TURN_DEG`` (:func:`feature_chains`) that run as a smooth crease of the shape
    (:func:`smooth_chain_mask`), none of their edges folded more than ``max_deg``.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    L : float
        Target edge length.
    max_deg : float
    folds : tuple, optional
        :func:`edge_folds` of ``(V, F)``, when the caller has it.

    Returns
    -------
    E : (e, 2) int
        Vertex pairs, chain after chain.
    angle : (e,) float
        Their dihedral angles (radians).
    """
    _, _, A, cos = edge_folds(V, F) if folds is None else folds
    fold = arccos(cos)
    crease = fold > math.radians(SMOOTH_CREASE_DEG)
    chains = feature_chains(V, A[crease], SMOOTH_TURN_DEG)
    if not chains:
        return A[:0], fold[:0]
    rows = chain_edge_rows(A, chains)
    steps = np.array([len(vs) - 1 for vs in chains])
    gentle = np.maximum.reduceat(fold[rows], np.r_[0, np.cumsum(steps)[:-1]])
    keep = smooth_chain_mask(V, A, fold, chains, L) & (gentle <= math.radians(max_deg))
    keep = np.repeat(keep, steps)
    return A[rows[keep]], fold[rows[keep]]


def smooth_chain_mask(V: np.ndarray, A: np.ndarray, fold: np.ndarray, chains: list, L: float
                      ) -> np.ndarray:
    """Which chains of creases run as a line of the shape, (c,) bool: closed or at least
    ``SMOOTH_MIN_LENGTH × L`` long, of at least ``SMOOTH_MIN_EDGES`` edges, their largest
    dihedral angle at most ``SMOOTH_SPREAD`` × their smallest, every other edge of ``A`` at
    their vertices, and every edge at their neighbours in ``A`` off the chain (the surface two
    edges deep on either side), folded by at most ``SMOOTH_SIDES`` × their smallest angle,
    and an open chain's ends on no other edge folded more than ``SMOOTH_CREASE_DEG``.

    Parameters
    ----------
    V : (n, 3) float
    A : (a, 2) int
        The interior edges with neither end on the boundary (:func:`edge_folds`), ``fold`` (a,)
        their dihedral angles (radians).
    chains : list of (k,) int
        Runs of edges of ``A`` (:func:`feature_chains`).
    L : float
    """
    rows = chain_edge_rows(A, chains)
    steps = np.array([len(vs) - 1 for vs in chains])
    starts = np.r_[0, np.cumsum(steps)[:-1]]
    length = np.add.reduceat(chain_steps(V, chains), starts)
    low = np.minimum.reduceat(fold[rows], starts)
    high = np.maximum.reduceat(fold[rows], starts)
    closed = np.array([vs[0] == vs[-1] for vs in chains])
    crease = A[fold > math.radians(SMOOTH_CREASE_DEG)]
    degree = np.bincount(crease.ravel(), minlength=len(V))
    ends_free = closed | ((degree[[vs[0] for vs in chains]] == 1)
                          & (degree[[vs[-1] for vs in chains]] == 1))
    keep = ((closed | (length >= SMOOTH_MIN_LENGTH * L)) & (steps >= SMOOTH_MIN_EDGES)
            & (high <= SMOOTH_SPREAD * low) & ends_free)
    if not keep.any():
        return keep
    beside = np.ones(len(A), bool)
    beside[rows] = False
    side = np.zeros(len(V))
    np.maximum.at(side, A[beside].ravel(), np.repeat(fold[beside], 2))
    every = np.zeros(len(V))
    np.maximum.at(every, A.ravel(), np.repeat(fold, 2))
    chain_of = np.full(len(V), -1)
    chain_of[np.concatenate(chains)] = np.repeat(np.arange(len(chains)), steps + 1)
    apart = (chain_of[A[:, 0]] != chain_of[A[:, 1]]) | (chain_of[A[:, 0]] < 0)
    near = side.copy()                              # … and every edge at their neighbours
    np.maximum.at(near, A[apart, 0], every[A[apart, 1]])    # off the chain
    np.maximum.at(near, A[apart, 1], every[A[apart, 0]])
    side_max = np.maximum.reduceat(near[np.concatenate(chains)], starts + np.arange(len(steps)))
    return keep & (side_max <= SMOOTH_SIDES * low)


def with_edges(E: np.ndarray, angle: np.ndarray, E_more: np.ndarray, angle_more: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``E`` (e, 2) int and ``angle`` (e,) float followed by the rows of ``E_more`` (f, 2) int
    and ``angle_more`` (f,) float whose edge (either way round) is not in ``E``."""
    if len(E_more) == 0:
        return E, angle
    n = int(max(E.max(initial=0), E_more.max())) + 1
    new = ~np.isin(topo.pair_keys(E_more[:, 0], E_more[:, 1], n),
                   topo.pair_keys(E[:, 0], E[:, 1], n))
    return np.vstack([E, E_more[new]]), np.r_[angle, angle_more[new]]


def consecutive_pairs(v: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """The vertices of consecutive feature points of one chain, where both got a vertex
    (``v ≥ 0``) and not the same one: the edges to join. A point left without a vertex (too
    close to one placed before) leaves its chain cut there: the chord between its neighbours
    could leave the crease where it bends, and the flips that make it would cut across the
    surface around it.

    Parameters
    ----------
    v : (p,) int
        The vertex at each point along the chains (:func:`vertices_at`), −1 for none.
    chain : (p,) int
        The chain of each point, in order along it.

    Returns
    -------
    (j, 2) int
    """
    pairs = np.column_stack([v[:-1], v[1:]])
    keep = (v[:-1] >= 0) & (v[1:] >= 0) & (chain[1:] == chain[:-1]) & (v[:-1] != v[1:])
    return pairs[keep]


def vertices_at(uv: np.ndarray, P: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """The vertex at each domain point ``P`` (p×2): the nearest row of ``uv`` within ``tol``,
    −1 where there is none."""
    from scipy.spatial import cKDTree

    d, j = cKDTree(uv).query(P)
    return np.where(d <= tol, j, -1)


def join_edges(S: RemeshState, pairs: np.ndarray, max_flips: int = 8, turned=None
               ) -> np.ndarray:
    """Make each pair ``a–b`` an edge of ``S`` by flipping, one at a time, an edge its disk
    segment crosses (:func:`_crossed_edges`; a flip only where its quad is strictly convex on
    the disk, both new faces keep a disk shape of at least ``DISK_SHAPE_MIN`` and neither
    turns over on the surface (:func:`_flip`, :func:`.unfold.turned_over` with ``ties``: the
    feature points lie on the input's creases, where the input face the map puts a point in
    is one of two turned against each other, and a flip across a fold narrower than the remesh
    makes a face over one side on the disk turned against the other in 3D); at most
    ``max_flips`` per pair, never of a pair joined before); first the long edge of every flat
    face is flipped (:func:`_flip_thin`). Returns the pairs that are edges at the end.

    Parameters
    ----------
    S : RemeshState
        Its faces changed in place.
    pairs : (k, 2) int
    max_flips : int
    turned : callable, optional
        Which new faces (k×3 vertex indices → k bool) turn over on the surface, instead of
        :func:`.unfold.turned_over_rows` with ``ties``.

    Returns
    -------
    (j, 2) int
    """
    if len(pairs) == 0:
        return pairs
    F = S.F.copy()
    VF = face_sets(F, S.n)
    done = set(map(tuple, np.sort(S.joined, axis=1).tolist())) if len(S.joined) else set()
    joined = []
    uv = S.uv
    turned = turned or partial(turned_over_rows, S, ties=True)
    changed = _flip_thin(F, VF, uv, S.X, turned, done)
    for a, b in pairs.tolist():
        for _ in range(max_flips + 1):
            if VF[a] & VF[b]:
                joined.append((a, b))
                done.add((min(a, b), max(a, b)))
                break
            hits = [h for h in _crossed_edges(F, VF, uv, a, b)
                    if (min(h[1:]), max(h[1:])) not in done]
            if not any(_flip(F, VF, uv, *h, turned=turned) is not None for h in hits):
                break
            changed = True
    if changed:
        S.F = F
    return np.asarray(joined, np.int64).reshape(-1, 2)


def face_sets(F: np.ndarray, n: int) -> dict:
    """Each vertex of ``F`` (m×3 over ``n`` vertices) → the set of its faces (indices), every
    set filled in increasing face order (:func:`.halfedge.vertex_faces`), the order a loop over
    the faces adds them in: the sets are laid out, and so iterate, as that loop's would. Only
    vertices at some face are keys (another raises ``KeyError``). A vertex's set is made when
    it is first asked for (:class:`_FaceSets`): the callers read the sets of a few vertices,
    and rewrite a vertex's set only after reading it."""
    VF = vertex_faces(F, n)
    return _FaceSets(VF.indptr, VF.indices)


class _FaceSets(dict):
    """The vertex → faces sets of :func:`face_sets`, each made from the incidence CSR
    ``(indptr, indices)`` (n + 1 and 3m int) when its vertex is first looked up, and kept (so
    changes to it stay). Only lookups by ``[]`` make sets: ``in``, ``keys`` and iteration see
    those made so far."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray):
        super().__init__()
        self.indptr, self.indices = indptr, indices

    def __missing__(self, v):
        """The set of ``v``'s faces, made and kept; ``KeyError`` if ``v`` is at no face."""
        if not 0 <= v < len(self.indptr) - 1 or not self.indptr[v] < self.indptr[v + 1]:
            raise KeyError(v)
        lo, hi = self.indptr[v], self.indptr[v + 1]
        faces = self[v] = set(self.indices[lo:hi].tolist())
        return faces


def _flip_thin(F, VF, uv, X, turned, done, passes: int = 3) -> bool:
    """Flip the longest edge of every face of ``F`` flat on the surface (twice its area at most
    ``FLAT × `` its longest edge squared) or thinner than ``DISK_SHAPE_MIN`` on the disk —
    feature points snapped onto one straight crease — where :func:`_flip` allows it and the
    edge is not in ``done``; whether any was flipped."""
    from ..laplacian import face_double_areas

    flipped = False
    for _ in range(passes):
        # the edge vectors opposite each corner
        E = X.take(F.take([2, 0, 1], axis=1), axis=0) - X.take(F.take([1, 2, 0], axis=1), axis=0)
        l2 = (E ** 2).sum(axis=2)
        thin = (disk_shape(uv, F) < DISK_SHAPE_MIN) | (face_double_areas(X, F)
                                                      <= FLAT * l2.max(axis=1))
        touched = set()                                     # faces rewritten this pass
        for t in np.flatnonzero(thin).tolist():
            f = F[t].tolist()
            c = int(np.argmax(l2[t]))
            p, q = f[(c + 1) % 3], f[(c + 2) % 3]
            if t in touched or (min(p, q), max(p, q)) in done:
                continue
            g = _flip(F, VF, uv, t, p, q, turned=turned)
            if g is not None:
                touched |= {t, g}
        flipped |= bool(touched)
        if not touched:
            break
    return flipped


def crossed_edges(S: RemeshState, a: int, b: int) -> list:
    """The edges of ``S`` the disk segment ``a → b`` crosses, from ``a``, as ``(t, p, q)``
    (:func:`_crossed_edges`)."""
    return _crossed_edges(S.F, face_sets(S.F, S.n), S.uv, a, b)


def _crossed_edges(F, VF, uv, a, b) -> list:
    """The edges of ``F`` the disk segment ``a → b`` crosses, from ``a``: ``(t, p, q)`` with
    ``t`` the face ``[x, p, q]`` (counter-clockwise) on ``a``'s side of edge ``p–q``; empty if
    the segment leaves ``a`` through no face (or runs through a vertex)."""
    A, B = uv[a], uv[b]
    d = B - A
    t = next((t for t in VF[a] if _between(F, uv, t, a, A, d)), None)
    if t is None:
        return []
    f = F[t].tolist()
    i = f.index(a)
    p, q = f[(i + 1) % 3], f[(i + 2) % 3]
    out = []
    for _ in range(len(F)):
        if _cross2(uv[q] - uv[p], B - uv[p]) >= 0:       # b not beyond p–q: no crossing
            return out
        out.append((t, p, q))
        g = next((g for g in VF[p] & VF[q] if g != t), None)
        if g is None:
            return out
        y = next(v for v in F[g].tolist() if v not in (p, q))
        if y == b:
            return out
        side = _cross2(d, uv[y] - A)
        if side == 0:
            return out
        t, p, q = (g, p, y) if side > 0 else (g, y, q)
    return out


def _between(F, uv, t, a, A, d) -> bool:
    """Whether the direction ``d`` from ``a`` (at ``A``) points into face ``t`` at corner
    ``a``."""
    f = F[t].tolist()
    i = f.index(a)
    p, q = f[(i + 1) % 3], f[(i + 2) % 3]
    return _cross2(d, uv[p] - A) <= 0 and _cross2(d, uv[q] - A) >= 0


def _cross2(u, v) -> float:
    """The 2D cross product ``u × v`` (positive when ``v`` turns left of ``u``)."""
    return float(u[0] * v[1] - u[1] * v[0])


def _flip(F, VF, uv, t, p, q, turned) -> int | None:
    """Flip the edge ``p–q`` of face ``t`` (``[x, p, q]`` counter-clockwise) if its quad is
    strictly convex and the new faces are not thinner than ``DISK_SHAPE_MIN`` on the disk and
    neither turns over on the surface (``turned``: the new faces, 2×3 vertex indices → 2 bool;
    :func:`join_edges` passes :func:`.unfold.turned_over_rows` judging a corner on an input
    edge or vertex against every input face there) (``F`` and the vertex → faces sets ``VF``
    updated); the face across, rewritten too, or None where no flip is made."""
    g = next((s for s in VF[p] & VF[q] if s != t), None)
    if g is None:
        return None
    f = F[t].tolist()
    x = f[(f.index(p) + 2) % 3]
    y = next(v for v in F[g].tolist() if v not in (p, q))
    new = np.array([[x, p, y], [x, y, q]])
    if not (disk_shape(uv, new) >= DISK_SHAPE_MIN).all():
        return None
    if turned(new).any():
        return None
    F[t], F[g] = new
    for v in (x, p, q, y):
        VF[v].discard(t)
        VF[v].discard(g)
    for s, row in ((t, new[0]), (g, new[1])):
        for v in row.tolist():
            VF[v].add(s)
    return g


def release_features(S: RemeshState, at: np.ndarray, corners: np.ndarray | None = None
                     ) -> np.ndarray:
    """Free the feature vertices ``at`` marks (n bool): the kept edges at them dropped from
    ``S.joined``, and they and the feature vertices left on no kept edge unlocked, except
    those at one of the points ``corners`` (k×3: the input's sharp corners, which stay
    locked) and those at ``S.fixed`` (a hole loop's, whose kept edges stay too). Returns the
    unlocked vertices (indices)."""
    if len(S.fixed):
        marked = np.flatnonzero(at)
        at = at.copy()
        at[marked[at_points(S.X[marked], S.fixed)]] = False
    on = np.zeros(S.n, bool)
    on[S.joined.ravel()] = True
    if not (at & on).any():
        return np.zeros(0, np.int64)
    S.joined = S.joined[~(at & on)[S.joined].any(axis=1)]
    still = np.zeros(S.n, bool)
    still[S.joined.ravel()] = True
    free = np.flatnonzero(on & ~still)
    if corners is not None:
        free = free[~at_points(S.X[free], corners)]
    S.locked[free] = False
    return free
