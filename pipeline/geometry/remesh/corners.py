"""Sharp corners of the input keep a vertex of the remesh.

Where the boundary turns sharply, or the surface comes to a point (cone tips, spikes), a
uniform remesh would cut the corner off. Such input vertices are found by their angle sums,
judged at the remesh's scale where the input is finer than the remesh, so that a scan's
noise and its ragged border are not taken for corners (:func:`boundary_corners`,
:func:`interior_corners`, :func:`_corners_at_scale`, :func:`ragged_boundary`); boundary ones
get a rim sample moved onto them before triangulation (:func:`.sampling.snap_rim`), interior
ones get the nearest remesh vertex moved exactly onto them (:func:`snap_vertices`), or a new
vertex (:func:`insert_vertices`) when none can move there, also when the map has put the tip
beyond the remesh's rim, between a rim chord and the image polygon. Either way the vertex is
locked: never moved or removed afterwards.
"""

from __future__ import annotations

import numpy as np

from .. import topology as topo
from ..locate import lift
from ..metrics import corner_angles
from ..rows import norms
from .domain import locator, on_sphere
from .halfedge import (DISK_SHAPE_MIN, disk_shape, edge_lengths, independent_by_faces, touching,
                       vertex_faces)
from .refine import split_edges, split_faces
from .state import RemeshState

NEAR_VERTICES = 24     # a target is located among the faces at its 24 nearest remesh vertices
NEAR_DIRECT = 32       # up to this many query points, nearest rows from all distances (no tree)
CORNER_REACH = 1.0     # × L: the scale at which an interior corner is judged
RIM_REACH = 0.5        # × L: the same for a boundary corner
NOTCH_REACH = 2.0      # × L: a notch closed at its mouth within this much of the rim
NOISE_NEIGHBOURS = 64  # the nearest input vertices that give the noise level around a vertex
MIN_NEIGHBOURS = 16    # fewer of them within the reach: the vertex-by-vertex rule
NOISE_SHARE = 0.25     # a noise level above this × corner_angle_deg: a noisy input
STANDS_OUT = 6.0       # a corner stands out from the noise level by this factor


def boundary_corners(V: np.ndarray, F: np.ndarray, boundary: np.ndarray, angle_deg: float,
                     length: float = 0.0, turning: np.ndarray | None = None) -> np.ndarray:
    """Boundary vertices where the boundary turns sharply at the scale ``length`` of a remesh:
    the angles of the faces at the vertex sum to less than ``180° − angle_deg`` or more than
    ``180° + angle_deg`` (a flat boundary has 180°), the vertex is a corner within
    ``RIM_REACH × length`` (:func:`_corners_at_scale`) and, where the input is finer than
    the remesh (:func:`_dense` within ``length``), the boundary still turns there when
    followed at the scale ``length`` (:func:`_turns_along_loop`: a scan's spurs, teeth and
    notches do not).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    boundary : (b,) int
        The boundary loop.
    angle_deg : float
        The tolerance; 0 or None: no corners.
    length : float
        The remesh's target edge length (mesh units); 0: each vertex on its own.
    turning : (n,) float, optional
        :func:`vertex_turning` of ``(V, F)`` when already computed.

    Returns
    -------
    (k,) int
        Vertex indices, sharpest first.
    """
    if angle_deg is None or angle_deg <= 0:
        return np.zeros(0, np.int64)
    value = vertex_turning(V, F) if turning is None else turning
    at = _sharpest_first(np.abs(value[boundary]), angle_deg)
    sharp = boundary[at]
    nearest = _nearest(V, sharp, length)              # one query serves both scales
    keep = _corners_at_scale(V, value, sharp, RIM_REACH * length, angle_deg, nearest)
    dense = _dense(nearest, sharp, length)
    keep[dense] &= _turns_along_loop(V[boundary], value[boundary], at[dense],
                                     length, angle_deg)
    keep &= ~closed_notches(V[boundary], NOTCH_REACH * length)[at]
    return sharp[keep]


def closed_notches(P: np.ndarray, reach: float) -> np.ndarray:
    """Which points of a boundary loop (b bool; ``P`` b×3, in loop order) stand exactly where
    another one does, with less than ``reach`` of the loop between them either way round, and
    the loop touches itself there alone (their neighbours along the loop stand apart): the
    two sides of a notch closed at its mouth (a split bowtie vertex, where a ragged rim touched
    itself), no deeper than half of ``reach``. Not corners: two rim vertices there would be
    one point, joined by a rim edge of length 0; the rim crosses the notch's mouth instead.
    (The two sides of a cut seam coincide along it, neighbours with neighbours.)"""
    out = np.zeros(len(P), bool)
    order = np.lexsort(P.T[::-1])
    same = np.flatnonzero(np.all(P[order[1:]] == P[order[:-1]], axis=1))
    if len(same) == 0:
        return out
    s = loop_arc_lengths(P)
    total = s[-1]
    i, j = order[same], order[same + 1]              # neighbours in the sort, at one point
    b = len(P)
    seam = (np.all(P[(i + 1) % b] == P[(j - 1) % b], axis=1)
            | np.all(P[(i - 1) % b] == P[(j + 1) % b], axis=1))
    apart = np.abs(s[i] - s[j])
    close = ~seam & (np.minimum(apart, total - apart) < reach)
    out[i[close]] = True
    out[j[close]] = True
    return out


def loop_arc_lengths(P: np.ndarray) -> np.ndarray:
    """The arc length along the closed loop ``P`` (b×3, in order) from its first point to each
    point, and last once round back to the first (b + 1,)."""
    return np.r_[0.0, np.cumsum(norms(np.roll(P, -1, axis=0) - P))]


def _nearest(V: np.ndarray, at: np.ndarray, reach: float):
    """``(distances, indices, order)``: the ``K = NOISE_NEIGHBOURS + 1`` vertices of ``V``
    nearest to each of ``V[at]`` (k×K each; itself among them; all of ``V`` when fewer),
    asked in the mesh's order (nearby points in turn): row ``i`` answers ``at[order[i]]``;
    or None where nothing is judged at a scale: ``reach`` 0, no vertex asked, or at most
    ``MIN_NEIGHBOURS`` vertices in all."""
    if reach <= 0 or len(at) == 0 or len(V) <= MIN_NEIGHBOURS:
        return None
    from scipy.spatial import cKDTree

    order = np.argsort(at, kind="stable")
    dist, near = cKDTree(V).query(V[at[order]], k=min(NOISE_NEIGHBOURS + 1, len(V)))
    return dist, near, order


def _unsorted(rows: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Per-row values ``rows`` (k,) of :func:`_nearest`'s rows put back in the order of the
    vertices asked: entry ``order[i]`` is ``rows[i]``."""
    out = np.empty_like(rows)
    out[order] = rows
    return out


def _dense(nearest, at: np.ndarray, reach: float) -> np.ndarray:
    """Which vertices ``at`` (k,) have at least ``MIN_NEIGHBOURS`` other vertices strictly
    closer than ``reach`` among their :func:`_nearest` ``nearest`` (None: none) (k bool):
    where the input is finer than that scale."""
    if nearest is None:
        return np.zeros(len(at), bool)
    dist, near, order = nearest
    rows = ((near != at[order][:, None]) & (dist < reach)).sum(axis=1) >= MIN_NEIGHBOURS
    return _unsorted(rows, order)


def _turns_along_loop(P: np.ndarray, turning: np.ndarray, at: np.ndarray, reach: float,
                      angle_deg: float) -> np.ndarray:
    """Which loop vertices ``at`` (k,) still turn sharply when the boundary is followed at the
    scale ``reach`` (k bool): the turnings of the loop vertices within ``reach`` of each along
    the loop (arc length, both ways, itself included), summed with the weights
    :func:`_smooth` of that arc length, come to more than ``angle_deg`` in its own turning's
    sign. A spur, a tooth or a notch narrower than ``reach`` turns the loop out and back in:
    its turnings cancel; a corner's do not. A vertex whose loop edges are both longer than
    ``reach`` is judged on its own (it is sharp).

    Parameters
    ----------
    P : (b, 3) float
        The boundary loop's vertices, in order.
    turning : (b,) float
        Their turnings (degrees, :func:`vertex_turning`).
    at : (k,) int
        Positions in the loop.
    reach : float
        Mesh units; 0: every vertex on its own.
    angle_deg : float
    """
    b = len(P)
    if reach <= 0 or len(at) == 0 or b < 3:
        return np.ones(len(at), bool)
    s = loop_arc_lengths(P)
    length = s[-1]
    s3 = np.r_[s[:-1] - length, s[:-1], s[:-1] + length]           # the loop three times round
    reach = min(reach, 0.5 * length)
    lo = np.searchsorted(s3, s[at] - reach, side="left")
    hi = np.searchsorted(s3, s[at] + reach, side="right")
    j = lo[:, None] + np.arange(int((hi - lo).max()))
    inside = j < hi[:, None]
    j = np.minimum(j, len(s3) - 1)
    w = np.where(inside, _smooth(np.abs(s3[j] - s[at][:, None]), reach), 0.0)
    held = (w * turning[j % b]).sum(axis=1) * np.sign(turning[at])
    return held > angle_deg


def ragged_boundary(V: np.ndarray, F: np.ndarray, boundary: np.ndarray, angle_deg: float,
                    corners: np.ndarray, turning: np.ndarray | None = None) -> np.ndarray:
    """Which boundary vertices (b bool, in the loop's order) are ragged: sharp at the input's
    own scale (the boundary turns there by more than ``angle_deg``, 0 or None: none is
    ragged) but not among ``corners`` (k int), the corners at the remesh's scale
    (:func:`boundary_corners`, whose other parameters these are, ``turning`` among them) — a
    scan's spurs, teeth and
    notches, a few input edges across, which the rim crosses instead of following
    (:func:`.rim.refine_rim`)."""
    if angle_deg is None or angle_deg <= 0:
        return np.zeros(len(boundary), bool)
    value = vertex_turning(V, F) if turning is None else turning
    return (np.abs(value[boundary]) > angle_deg) & ~np.isin(boundary, corners)


def interior_corners(V: np.ndarray, F: np.ndarray, angle_deg: float, length: float = 0.0,
                     turning: np.ndarray | None = None) -> np.ndarray:
    """Interior vertices that are sharp points of the surface at the scale ``length`` of a
    remesh: the angles of their faces sum to less than ``360° − angle_deg`` (a cone tip) or
    more than ``360° + angle_deg`` (a saddle spike), and the vertex is a corner within
    ``CORNER_REACH × length`` (:func:`_corners_at_scale`, with ``fine`` where the input's
    mean edge is shorter than ``length``). Parameters and result as in
    :func:`boundary_corners`, without ``boundary``."""
    if angle_deg is None or angle_deg <= 0:
        return np.zeros(0, np.int64)
    value = vertex_turning(V, F) if turning is None else turning
    dev = np.abs(value)
    dev[topo.boundary_vertices_mask(F, len(V))] = 0.0
    sharp = _sharpest_first(dev, angle_deg)
    fine = bool(edge_lengths(V, *topo.half_edges(F)).mean() < length)
    return sharp[_corners_at_scale(V, value, sharp, CORNER_REACH * length, angle_deg,
                                   fine=fine)]


def vertex_turning(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Per vertex (n), in degrees: the angle defect ``360° − (sum of the angles of its
    faces)`` of an interior vertex, the turning ``180° − (sum)`` of a boundary vertex (0
    where a degenerate face leaves it undefined)."""
    total = np.degrees(np.bincount(F.ravel(), corner_angles(V, F).ravel(), len(V)))
    flat = np.where(topo.boundary_vertices_mask(F, len(V)), 180.0, 360.0)
    return np.nan_to_num(flat - total, nan=0.0)


def _sharpest_first(dev: np.ndarray, angle_deg: float) -> np.ndarray:
    """The indices where ``dev`` exceeds ``angle_deg``, largest first."""
    sharp = np.flatnonzero(dev > angle_deg)
    return sharp[np.argsort(-dev[sharp])]


def _corners_at_scale(V: np.ndarray, value: np.ndarray, sharp: np.ndarray, reach: float,
                      angle_deg: float, nearest=None, fine: bool = False) -> np.ndarray:
    """Which of the sharp vertices (k bool) are corners at the scale ``reach``.

    Around each sharp vertex, its ``NOISE_NEIGHBOURS`` nearest input vertices in 3D (itself
    excluded) give the noise level: the median distance of their ``value`` from its mean.
    A sharp vertex with fewer than ``MIN_NEIGHBOURS`` of them within ``reach`` is a corner,
    as vertex by vertex: the input is about as coarse as the remesh there; but where the input
    is ``fine`` (finer than the remesh as a whole) and the vertex noisy (below), it is judged
    as a noisy one over its ``MIN_NEIGHBOURS`` nearest instead: a scan sampled about as
    densely as the remesh, whose noise spikes a vertex-by-vertex rule would all keep. Otherwise
    it is a corner where it stands out:

    - noise level at most ``NOISE_SHARE × angle_deg`` (a clean input, finer than the
      remesh): ``|value|`` above ``STANDS_OUT`` times the noise level;
    - noise level above that (a noisy scan, whose per-vertex defects of both signs are as
      large as ``angle_deg``): its *held* value, the ``value`` of those neighbours and its
      own summed with the weights :func:`_smooth` of their distance within
      ``min(reach, distance to the farthest of them)``, taken with its own sign, above both
      ``angle_deg`` and ``STANDS_OUT`` times the noise level, and the largest held value
      among the noisy sharp vertices of its sign within ``reach`` (:func:`_peaks`; ``reach``
      and the weights' scale widened to the ``MIN_NEIGHBOURS``-th nearest for the sparse
      vertices of a ``fine`` input). Noise
      spikes are paid back by the vertices around them and hold little; a cone tip, or a
      tight fold of the surface, holds its defect.

    The opposite sign never competes, so a sharp vertex next to an opposite one (a cone tip
    by a saddle) is judged on its own. Every query has at most ``NOISE_NEIGHBOURS``
    answers: the cost is ``k × NOISE_NEIGHBOURS`` whatever ``reach``.

    Parameters
    ----------
    V : (n, 3) float
    value : (n,) float
        Angle defect or turning per vertex (degrees, :func:`vertex_turning`).
    sharp : (k,) int
        The sharp vertices, sharpest first.
    reach : float
        Mesh units; 0: each vertex on its own (all are corners).
    angle_deg : float
        The sharpness tolerance that chose ``sharp``.
    nearest : tuple, optional
        :func:`_nearest` of ``sharp`` when already queried (made here otherwise).
    fine : bool
        The input is finer than the remesh (judge its sparse noisy vertices too).
    """
    keep = np.ones(len(sharp), bool)
    if reach <= 0:
        return keep
    if nearest is None:
        nearest = _nearest(V, sharp, reach)
    if nearest is None:
        return keep
    dist, near, order = nearest                   # rows: per vertex, row by row
    other = near != sharp[order][:, None]
    around = np.where(other, value[near], np.nan)
    noise = _unsorted(_nan_median_rows(np.abs(around - np.nanmean(around, axis=1)[:, None])),
                      order)
    dense = _unsorted((other & (dist <= reach)).sum(axis=1) >= MIN_NEIGHBOURS, order)
    noisy = (dense | fine) & (noise > NOISE_SHARE * angle_deg)
    keep[dense] = (np.abs(value[sharp]) > STANDS_OUT * noise)[dense]
    if noisy.any():
        scale = np.maximum(reach, dist[:, MIN_NEIGHBOURS]) if fine else np.full(len(dist), reach)
        r = np.minimum(scale, dist[:, -1])[:, None]
        held = _unsorted((_smooth(dist, r) * value[near]).sum(axis=1), order)
        held = held * np.sign(value[sharp])
        at = sharp[noisy]
        held = held[noisy]
        strong = held > np.maximum(angle_deg, STANDS_OUT * noise[noisy])
        scale = _unsorted(scale, order)[noisy]
        keep[noisy] = strong & _peaks(V[at], value[at], held, scale, strong)
    return keep


def _nan_median_rows(x: np.ndarray) -> np.ndarray:
    """``np.nanmedian(x, axis=1)`` of a (k×K) array with at least one number in every row
    (k,): the mean of the row's two middle numbers (its middle one when it has an odd count),
    ``(low + high) / 2`` as NumPy's masked median takes it; NaNs sort last."""
    count = (~np.isnan(x)).sum(axis=1)
    high = count // 2
    low = np.where(count % 2 == 1, high, high - 1)
    ranked = np.sort(x, axis=1)
    rows = np.arange(len(x))
    return (ranked[rows, low] + ranked[rows, high]) / 2.0


def _smooth(dist: np.ndarray, reach) -> np.ndarray:
    """The weights ``(1 − (dist/reach)²)²``: 1 at distance 0, 0 from ``reach`` on."""
    return (1.0 - np.minimum(dist / reach, 1.0) ** 2) ** 2


def _peaks(P: np.ndarray, sign: np.ndarray, score: np.ndarray, reach: float,
           asked: np.ndarray | None = None) -> np.ndarray:
    """Which points (k bool) have no point of the same ``sign`` within ``reach`` (a number,
    or one per point) with a larger ``score`` (on a tie, a lower index), among their
    ``NOISE_NEIGHBOURS`` nearest of that sign; only the points ``asked`` (k bool; all when
    None) are judged, the others come back True (every point of a sign still competes)."""
    from scipy.spatial import cKDTree

    peak = np.ones(len(P), bool)
    for side in (sign > 0, sign < 0):
        idx = np.flatnonzero(side)
        ask = idx if asked is None else idx[asked[idx]]
        if len(idx) < 2 or len(ask) == 0:
            continue
        within = np.broadcast_to(reach, len(P))[ask]
        dist, near = cKDTree(P[idx]).query(P[ask], k=min(NOISE_NEIGHBOURS + 1, len(idx)),
                                           distance_upper_bound=within.max())
        found = dist < within[:, None]
        j = idx[np.where(found, near, 0)]
        theirs, mine = score[j], score[ask][:, None]
        later = (theirs == mine) & (j < ask[:, None])
        beats = found & (j != ask[:, None]) & ((theirs > mine) | later)
        peak[ask] = ~beats.any(axis=1)
    return peak


def _apart_on_surface(S: RemeshState, targets_uv: np.ndarray, min_gap: float,
                      counts: str = "corners") -> np.ndarray:
    """The targets (in order) whose lifts are at least ``min_gap`` from every locked vertex
    and from every target kept before them (KD-trees: a noisy scan has thousands of sharp
    vertices, and comparing every pair of them took a minute); the others are counted as
    ``<counts>_too_close``."""
    if min_gap <= 0 or len(targets_uv) == 0:
        return targets_uv
    from scipy.spatial import cKDTree

    f, b, _ = S.locator.locate_with_inside(targets_uv)
    P = lift(S.V_in, S.F_in, f, b)
    keep = np.ones(len(P), bool)
    if S.locked.any():
        keep = cKDTree(S.X[S.locked]).query(P)[0] >= min_gap
    idx = np.flatnonzero(keep)
    idx = idx[_kept_apart(P[idx], min_gap)]
    S.tally(f"{counts}_too_close", len(P) - len(idx))
    return targets_uv[idx]


def _kept_apart(P: np.ndarray, gap: float) -> np.ndarray:
    """Greedily in order, which points (k bool) are kept: each one at least ``gap`` from every
    point kept before it (a KD-tree's pairs closer than ``gap``, then one pass)."""
    kept = np.ones(len(P), bool)
    if len(P) < 2 or gap <= 0:
        return kept
    from scipy.spatial import cKDTree

    pairs = cKDTree(P).query_pairs(np.nextafter(gap, 0.0), output_type="ndarray")
    later, earlier = pairs.max(axis=1), pairs.min(axis=1)
    order = np.argsort(later, kind="stable")
    later, earlier = later[order], earlier[order]
    bounds = np.searchsorted(later, np.arange(len(P) + 1))
    for i in range(len(P)):
        kept[i] = not kept[earlier[bounds[i]:bounds[i + 1]]].any()
    return kept


def nearest_rows(P: np.ndarray, T: np.ndarray, k: int) -> np.ndarray:
    """The indices (j×k) of the ``k`` rows of ``P`` (n×d, k ≤ n) nearest to each point of
    ``T`` (j×d), nearest first: ``cKDTree(P).query(T, k=k)[1]``. For at most ``NEAR_DIRECT``
    points in the plane, from the squared distances to every row, ``(Δx)² + (Δy)²`` as the
    tree sums them (building a tree costs several milliseconds at 10⁴ rows, for a few
    points), where the ``k + 1`` nearest are at distinct distances, which makes the answer
    the only one; otherwise (a tie, which the tree settles its own way) by the tree."""
    P = np.asarray(P, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64).reshape(-1, P.shape[1])
    if len(T) <= NEAR_DIRECT and P.shape[1] == 2:
        out = np.empty((len(T), k), np.int64)
        m = min(k + 1, len(P))
        for i, (x, y) in enumerate(T.tolist()):
            d2 = (P[:, 0] - x) ** 2 + (P[:, 1] - y) ** 2
            first = np.argpartition(d2, m - 1)[:m]
            first = first[np.argsort(d2[first], kind="stable")]
            if not (np.diff(d2[first]) > 0).all():
                break
            out[i] = first[:k]
        else:
            return out
    from scipy.spatial import cKDTree

    return np.asarray(cKDTree(P).query(T, k=k)[1], dtype=np.int64).reshape(len(T), k)


def snap_vertices(S: RemeshState, targets_uv: np.ndarray, min_gap: float = 0.0,
                  counts: str = "corners") -> np.ndarray:
    """Move an interior vertex exactly onto each target (the disk image of a sharp input
    vertex) and lock it: for each target in the given order (sharpest first), the nearest of
    its 4 nearest free vertices on the disk whose faces stay counter-clockwise there, none
    thinner than ``DISK_SHAPE_MIN`` (:func:`.halfedge.disk_shape`); a target
    none of them can take gets a new vertex (:func:`insert_vertices`) unless one of them is
    within ``min_gap`` of it on the surface (a new edge that short would be a sliver). A target
    within ``min_gap`` on the surface of a sharper one or of a vertex locked already is
    dropped: two locked vertices that close keep a sliver edge no collapse may remove, and
    the needles on it (sharp input vertices close together, as at a mouth's corners).

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    targets_uv : (k, 2) float
        Disk images of the sharp input vertices, sharpest first.
    min_gap : float
        In the mesh's units.
    counts : str
        The log's keys: ``<counts>_snapped``, ``<counts>_inserted`` and ``<counts>_too_close``
        (:mod:`.fidelity` snaps onto input vertices under ``followed``).

    Returns
    -------
    (j,) int
        The snapped and inserted vertices.
    """
    T = np.asarray(targets_uv, dtype=np.float64).reshape(-1, S.uv.shape[1])
    T = _apart_on_surface(S, T, min_gap, counts)
    free = np.flatnonzero(~S.is_rim & ~S.locked)
    if len(T) == 0 or len(free) == 0:
        return np.zeros(0, np.int64)
    J = free[nearest_rows(S.uv[free], T, min(4, len(free)))]
    VF = vertex_faces(S.F, S.n)
    taken = np.zeros(S.n, bool)
    snapped, missed = [], []
    for t, cands in zip(T, J):
        for v in cands.tolist():
            if taken[v]:
                continue
            faces = VF.indices[VF.indptr[v]:VF.indptr[v + 1]]
            old = S.uv[v].copy()
            S.uv[v] = t
            Ff = S.F[faces]
            if np.all(disk_shape(S.uv, Ff) >= DISK_SHAPE_MIN):
                taken[v] = True
                snapped.append(v)
                break
            S.uv[v] = old
        else:
            missed.append((t, cands))
    v = np.asarray(snapped, np.int64)
    if len(v):
        f, b, _ = S.locator.locate_with_inside(S.uv[v])
        S.face[v], S.bary[v] = f, b
        S.X[v] = lift(S.V_in, S.F_in, f, b)
        S.locked[v] = True
    S.tally(f"{counts}_snapped", len(v))
    if missed:
        T = np.array([t for t, _ in missed])
        cands = np.array([c for _, c in missed])
        f, b, _ = S.locator.locate_with_inside(T)
        gap = np.linalg.norm(S.X[cands] - lift(S.V_in, S.F_in, f, b)[:, None, :], axis=2)
        gap = gap.min(axis=1)
        v = np.concatenate([v, insert_vertices(S, T[gap >= min_gap], counts=counts)])
    return v


def locate_near(S: RemeshState, T: np.ndarray, k: int = NEAR_VERTICES
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Locate the domain points ``T`` (j×2) in the remesh's own triangulation
    ``(S.uv, S.F)``: face, barycentrics and whether inside, as
    :meth:`..locate.PointLocator.locate_with_inside` gives them. On the disk the locator is
    built over the faces at the ``k`` vertices nearest to each point only (a locator over
    the whole remesh costs a quarter of a second at 10⁵ vertices, for a few points); a point
    outside them comes back outside, on their border. On the sphere, over every face."""
    if on_sphere(S.uv) or len(T) == 0:
        return locator(S.uv, S.F).locate_with_inside(T)
    near = np.zeros(S.n, bool)
    near[nearest_rows(S.uv, T, min(k, S.n)).ravel()] = True
    sub = np.flatnonzero(touching(S.F, near))
    f, bary, inside = locator(S.uv, S.F[sub]).locate_with_inside(T)
    return sub[f], bary, inside


def insert_vertices(S: RemeshState, targets_uv: np.ndarray, max_rounds: int = 6,
                    counts: str = "corners") -> np.ndarray:
    """Insert a locked vertex exactly at each disk target (the image of a sharp input vertex
    that no existing vertex could be snapped to), in rounds of targets in distinct faces of
    the remesh: a target inside a face splits it 1 → 3, one on an edge splits the edge there.
    A target beyond the remesh's rim — between a rim chord and the image polygon, where a
    spike squeezed against the boundary ends up — first splits that rim edge at the polygon
    point nearest to it, which brings the target inside. Returns the inserted vertices,
    counted as ``<counts>_inserted``."""
    T = np.asarray(targets_uv, dtype=np.float64).reshape(-1, S.uv.shape[1])
    done = []
    for _ in range(max_rounds):
        if len(T) == 0:
            break
        f, bary, inside = locate_near(S, T)
        c = np.argmin(bary, axis=1)                        # the corner opposite the nearest edge
        h = 3 * f + (c + 1) % 3                            # half-edge F[f, c+1] → F[f, c+2]
        twin = S.twins()[h]
        on_edge = inside & (bary.min(axis=1) < 1e-9)       # on edge h: split it exactly there
        f2 = np.where((~inside | on_edge) & (twin >= 0), twin // 3, f)
        first = independent_by_faces(len(S.F), f, f2, np.arange(len(T)))
        again = np.ones(len(T), bool)
        h, twin, t = h[first], twin[first], bary[first, (c[first] + 2) % 3]
        # beyond the rim (projected onto a rim edge): split that edge, the target comes next round
        out = ~inside[first] & (twin < 0)
        on_edge = on_edge[first]
        strict = inside[first] & ~on_edge
        n0 = S.n
        split_edges(S, h[out | on_edge], twin[out | on_edge], t[out | on_edge])
        w_edge = n0 + np.flatnonzero(on_edge[out | on_edge])
        S.locked[w_edge] = True
        done.append(w_edge)
        if strict.any():
            done.append(split_faces(S, f[first[strict]], T[first[strict]], locked=True))
        again[first[on_edge | strict]] = False
        T = T[again]
    v = np.concatenate(done) if done else np.zeros(0, np.int64)
    S.tally(f"{counts}_inserted", len(v))
    return v
