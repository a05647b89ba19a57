"""How far a straight remesh edge leaves the input surface (its *sag*).

A vertex of the remesh lies on the surface, but the straight segment between two of them
need not: where the equiareal map squeezes a region (a finger's side, a fold, a closed mouth)
into a thin sliver of the disk, an edge across the sliver bridges over the surface. The sag
drives the refinement (:mod:`.refine`), the flips of folded quads (:mod:`.flips`) and the
guards of the collapses (:mod:`.collapse`). Distances are in the mesh's units.
"""

from __future__ import annotations

import math

import numpy as np

from .._kernels import points_along, sag_along_block, walked_sags
from ..locate import TOL, PointLocator, lift
from ..rows import dots
from .state import RemeshState

SAG_BLOCK = 262144    # sample points per point-location query
SAG_WALK = 64         # walk steps from the face under an edge's nearer end to a point on it
CHAIN_MIN = 64        # edges from which the samples along them are located one t at a time


def surface_middles(S: RemeshState, a: np.ndarray, b: np.ndarray, ts=(0.5,)
                    ) -> tuple[np.ndarray, np.ndarray]:
    """For each edge ``a–b``, the ``t`` of ``ts`` whose lifted domain point
    ``(1 − t)·uv[a] + t·uv[b]`` (eq. 1) is nearest to the middle of the edge in 3D: its
    distances to the two ends differ least. Where the map stretches the surface unevenly
    along an edge, the domain midpoint can lift next to one end.

    Parameters
    ----------
    S : RemeshState
    a, b : (k,) int
    ts : (s,) float
        Candidate points along the edges, in ``(0, 1)``.

    Returns
    -------
    t : (k,) float
    balance : (k,) float
        The lifted point's distance to the nearer end over the edge's length (½ at the exact
        middle of a straight edge, 0 at an end).
    """
    ts = np.asarray(ts, dtype=np.float64)
    k, s = len(a), len(ts)
    T = np.repeat(ts, k)[:, None]
    ea, eb = np.tile(a, s), np.tile(b, s)
    P, _ = lift_samples(S, ea, eb, T)
    da = np.linalg.norm(P - S.X.take(ea, axis=0), axis=1).reshape(s, k)
    db = np.linalg.norm(P - S.X.take(eb, axis=0), axis=1).reshape(s, k)
    j = np.argmin(np.abs(da - db), axis=0)
    r = np.arange(k)
    length = np.maximum(np.linalg.norm(S.X.take(a, axis=0) - S.X.take(b, axis=0), axis=1), 1e-300)
    return ts[j], np.minimum(da[j, r], db[j, r]) / length


def lift_samples(S: RemeshState, ea: np.ndarray, eb: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The lifts (eq. 1; k×3) of the domain points ``(1 − T)·uv[ea] + T·uv[eb]`` (``T`` k×1),
    each located from the face under the nearer end; also the faces they are in."""
    M, hint = points_along(np.ascontiguousarray(S.uv, dtype=np.float64),
                           np.ascontiguousarray(S.face, dtype=np.int64),
                           np.ascontiguousarray(ea, dtype=np.int64),
                           np.ascontiguousarray(eb, dtype=np.int64),
                           np.ascontiguousarray(T, dtype=np.float64).reshape(-1))
    mf, mb, _ = S.locator.relocate(M, hint, walk=SAG_WALK)
    return lift(S.V_in, S.F_in, mf, mb), mf


def lift_along(S: RemeshState, a: np.ndarray, b: np.ndarray, ts: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The lifts (eq. 1) of the domain points ``(1 − t)·uv[a] + t·uv[b]`` of every edge
    ``a–b`` at every ``t`` of ``ts``, sample-major (row ``j·k + i``: edge ``i`` at ``ts[j]``),
    as :func:`lift_samples` gives them, and the faces they are in.

    With at least ``CHAIN_MIN`` edges on an input with more faces than the remesh (an edge
    then spans several input faces), the points are located one ``t`` at a time, each from
    the face found for the previous ``t`` of the same edge on the way from its nearer end
    (the ``t ≤ 1/2`` in increasing order from ``face[a]``, the others in decreasing order
    from ``face[b]``): every walk crosses only the stretch between two samples. A point
    inside a face gets the same face and barycentrics whatever face its walk starts from.
    Where the remesh is the finer, most samples lie in the face under an end and one query
    costs less.

    Parameters
    ----------
    S : RemeshState
    a, b : (k,) int
    ts : (s,) float
        In ``[0, 1]``.

    Returns
    -------
    P : (s·k, 3) float
    face : (s·k,) int
    """
    k, s = len(a), len(ts)
    ea, eb = np.tile(a, s), np.tile(b, s)
    T = np.repeat(ts, k)
    if k < CHAIN_MIN or s == 1 or len(S.F_in) <= len(S.F):
        return lift_samples(S, ea, eb, T[:, None])
    M, hint = points_along(np.ascontiguousarray(S.uv, dtype=np.float64),
                           np.ascontiguousarray(S.face, dtype=np.int64), ea, eb, T)
    mf = np.empty(s * k, np.int64)
    mb = np.empty((s * k, 3))
    for order in sample_chains(ts):
        start = None
        for j in order:
            rows = slice(j * k, (j + 1) * k)
            mf[rows], mb[rows], _ = S.locator.relocate(
                M[rows], hint[rows] if start is None else mf[start], walk=SAG_WALK)
            start = rows
    return lift(S.V_in, S.F_in, mf, mb), mf


def sample_chains(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The indices of ``ts`` (s) in the order :func:`lift_along` locates them: those with
    ``t ≤ 1/2`` by increasing ``t`` (from an edge's first end), the others by decreasing
    ``t`` (from its second end)."""
    ts = np.asarray(ts)
    order = np.argsort(ts, kind="stable")
    low = ts[order] <= 0.5
    return order[low], order[~low][::-1]


def may_sag(S: RemeshState, a: np.ndarray, b: np.ndarray, threshold: float) -> np.ndarray:
    """Which edges ``a–b`` (k) may be farther than ``threshold`` from the surface (k bool): a
    cheap filter before :func:`edge_sag_along` — an edge whose ends lie on input faces within
    10° of parallel, with the edge within ``threshold / 2`` of both tangent planes, is over a
    flat patch (sag 0) unless a feature narrower than the edge sits in between."""
    N_in = S.normals_in()
    na, nb = N_in.take(S.face.take(a), axis=0), N_in.take(S.face.take(b), axis=0)
    e = S.X.take(b, axis=0) - S.X.take(a, axis=0)         # (take: faster than fancy rows)
    return ((dots(na, nb) < math.cos(math.radians(10.0)))
            | (np.abs(dots(e, na)) > 0.5 * threshold)
            | (np.abs(dots(e, nb)) > 0.5 * threshold))


def edge_sag(S: RemeshState, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """How far the straight 3D edge ``a–b`` is from the surface at its middle
    (:func:`edge_sag_along` at ``t = 1/2``)."""
    return edge_sag_along(S, a, b, (0.5,))[0]


def edge_sag_along(S: RemeshState, a: np.ndarray, b: np.ndarray, ts=(0.5,),
                   end_normals: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The largest distance of the straight 3D edge ``a–b`` from the surface over the points
    ``t`` in ``ts``, and the ``t`` where it is reached.

    At ``t``, ``d`` = the offset between the edge's 3D point ``(1 − t)·X[a] + t·X[b]`` and the
    lift (eq. 1) of the disk point ``(1 − t)·uv[a] + t·uv[b]``. Its tangential part is only the
    map's non-linearity (on a plane ``d`` is tangential however far it is), so the sag is the
    largest component of ``d`` along the input surface's normals at that point and at the two
    ends: bridging over a finger shows along the normal in between, skipping a fold (a closed
    mouth) along those at the ends. Where the map squeezes a gap (between fingers, a sulcus)
    into a strip much thinner than the edge on the disk, only a point inside the strip sees
    it, which the midpoint seldom is; hence several ``t``.

    Fewer than ``CHAIN_MIN`` edges (the guards of the local operations) go through one
    compiled pass (:func:`.._kernels.walked_sags`) when every sample's walk from the face
    under the nearer end finds it; otherwise, and for more edges, the samples are located in
    blocks (:func:`lift_along`). Both give the same values, bit for bit.

    Parameters
    ----------
    S : RemeshState
    a, b : (k,) int
        The edges' ends.
    ts : (s,) float
        Points along the edges, in ``[0, 1]``.
    end_normals : pair of (k, 3) float, optional
        The input normals under ``a`` and ``b`` when the caller has them already.

    Returns
    -------
    sag : (k,) float
        The largest distance, in the mesh's units.
    t : (k,) float
        The first ``t`` of ``ts`` where it is reached.
    """
    a = np.ascontiguousarray(a, dtype=np.int64)
    b = np.ascontiguousarray(b, dtype=np.int64)
    N_in = S.normals_in()
    X = np.ascontiguousarray(S.X, dtype=np.float64)
    ts = np.ascontiguousarray(ts, dtype=np.float64)
    k, s = len(a), len(ts)
    best = np.empty(k)
    t_best = np.empty(k)
    if k < CHAIN_MIN and end_normals is None and isinstance(S.locator, PointLocator) and \
            walked_sags(S.locator.walk_table(), np.ascontiguousarray(S.uv, dtype=np.float64),
                        np.ascontiguousarray(S.face, dtype=np.int64), a, b, ts, SAG_WALK, TOL,
                        np.ascontiguousarray(S.V_in, dtype=np.float64),
                        np.ascontiguousarray(S.F_in, dtype=np.int64), N_in, X, best, t_best):
        return best, t_best                # a few edges, every sample found by its walk
    n_a, n_b = (np.ascontiguousarray(n, dtype=np.float64) for n in
                (end_normals if end_normals is not None
                 else [N_in.take(S.face.take(v), axis=0) for v in (a, b)]))   # N_in[face[v]]
    step = max(SAG_BLOCK // max(s, 1), 1)
    for lo in range(0, k, step):
        # all samples of a block of edges in one query (sample-major), each located from the
        # face under the nearer end; the offsets and their largest normal components compiled
        e = slice(lo, min(lo + step, k))
        P, mf = lift_along(S, a[e], b[e], ts)
        sag_along_block(np.ascontiguousarray(P), np.ascontiguousarray(mf, dtype=np.int64),
                        N_in, X, a, b, ts, n_a, n_b, lo, best, t_best)
    return best, t_best
