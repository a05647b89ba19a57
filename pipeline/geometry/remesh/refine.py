"""Refinement: edge splits where the remesh is too coarse or leaves the surface.

* :func:`split_long_edges` — the split step of isotropic remeshing (Botsch & Kobbelt 2004) with
  3D lengths, longest first; with a budget it gives back vertices the collapses removed. At
  the domain midpoint, or with ``S.surface_middles`` at the point of ``t = 1/8 … 7/8`` whose
  lift is nearest to the middle of the edge in 3D (:func:`.sag.surface_middles`): where the
  map stretches the surface unevenly along an edge, the domain midpoint can lift next to an end
  and leave a needle; an edge none of whose points lifts at least ``MIN_BALANCE`` × its length
  from both ends is then left unsplit, and so is a sagging edge whose worst point lifts that
  near an end (:func:`split_balance`; split there, then again near the new vertex, the sag
  refinement packs vertices into one input face).
* :func:`refine_by_sag` — where the map squeezes a region into a thin sliver of the disk (the
  sides of fingers, deep folds, a closed mouth), uniform samples are too sparse across it and
  lifted edges bridge over the surface. An edge whose straight line is farther than a
  threshold from the surface at any of ``SAG_SAMPLES`` points ``t = 1/8 … 7/8``
  (:func:`.sag.edge_sag_along`) is split on the disk at the worst of them, so that the new
  vertex lies on the surface inside the sliver. Several points, not the midpoint alone: a gap
  squeezed into a strip much thinner than the edge on the disk is seldom under the midpoint.

Both split on the disk and lift the new vertex by eq. (1). A split boundary edge gets its
vertex on the image polygon. Both leave an edge unsplit when a new face would be thinner on the
disk than ``DISK_SHAPE_MIN`` (:func:`split_keeps_shape`). They run in rounds of independent
splits (no two in one face); after the first round only the edges at new vertices and the
candidates that waited for a free face are looked at again. :func:`split_edges` keeps the
state's half-edge twins up to date instead of recomputing them.
"""

from __future__ import annotations

import numpy as np

from ..locate import Segments
from ..rows import norms, row_min
from .domain import project
from .halfedge import (DISK_SHAPE_MIN, disk_shape, edge_lengths, edge_table, independent_edges,
                       touching)
from .sag import SAG_WALK, edge_sag_along, lift_samples, may_sag, surface_middles
from .state import RemeshState

SAG_SAMPLES = 7       # the sag is measured at t = 1/8 … 7/8 along an edge
SAG_TS = np.arange(1, SAG_SAMPLES + 1) / (SAG_SAMPLES + 1)   # those t (and where a surface
                                                            # middle may be)
MIN_BALANCE = 0.25    # with surface middles, an edge whose every split point lifts nearer than
                      # this × its length to an end is not split (it would leave a needle)


def split_edges(S: RemeshState, h: np.ndarray, twin: np.ndarray,
                t: np.ndarray | None = None, points: np.ndarray | None = None) -> int:
    """Split edges on the disk: face ``[a, b, p]`` becomes ``[a, w, p]`` and ``[w, b, p]``,
    and so does the face across, with the new vertex ``w`` lifted by eq. (1).

    Parameters
    ----------
    S : RemeshState
        Changed in place; its cached twins are kept up to date.
    h : (k,) int
        Half-edges ``a → b`` of independent edges (no two in one face).
    twin : (k,) int
        Their twins, −1 on the boundary (``w`` then goes on the image polygon).
    t : (k,) float, optional
        Split at ``(1 − t)·uv[a] + t·uv[b]``; default the disk midpoint.
    points : (k, 2) float, optional
        Or the domain points of the new vertices themselves (a boundary edge's on the image
        polygon, :func:`.rim.refine_rim`).

    Returns
    -------
    int
        The number of splits, ``k``; the new vertices are the last ``k``.
    """
    k = len(h)
    if k == 0:
        return 0
    F = S.F
    f, c = h // 3, h % 3
    a, b, p = F[f, c], F[f, (c + 1) % 3], F[f, (c + 2) % 3]
    on_b = twin < 0
    M = _split_points(S, a, b, on_b, t) if points is None else points
    near_a = np.ones(k, bool) if t is None else t <= 0.5
    mf, mb, _ = S.locator.relocate(M, np.where(near_a, S.face[a], S.face[b]), walk=SAG_WALK)
    w = S.append_vertices(M, mf, mb, on_b)
    tw_old = S.cached_twins()
    m = len(F)
    F = F.copy()
    new = [np.column_stack([w, b, p])]
    F[f] = np.column_stack([a, w, p])
    inner = np.flatnonzero(~on_b)
    g, d = twin[inner] // 3, twin[inner] % 3
    if len(inner):
        q = F[g, (d + 2) % 3]
        F[g] = np.column_stack([b[inner], w[inner], q])
        new.append(np.column_stack([w[inner], a[inner], q]))
    S.set_faces(np.vstack([F] + new),
                None if tw_old is None else _split_twins(tw_old, m, f, c, inner, g, d))
    return k


def _split_points(S: RemeshState, a: np.ndarray, b: np.ndarray, on_b: np.ndarray,
                  t: np.ndarray | None) -> np.ndarray:
    """The domain points where :func:`split_edges` puts the new vertices of edges ``a–b``: at
    ``t`` along the edge (default the midpoint; on the sphere then normalised,
    :func:`.domain.project`), on the image polygon for a boundary edge."""
    A, B = S.uv.take(a, axis=0), S.uv.take(b, axis=0)
    M = project(0.5 * (A + B) if t is None else (1.0 - t)[:, None] * A + t[:, None] * B)
    if on_b.any():                               # a boundary edge's vertex goes on the polygon
        _, _, M[on_b] = S.of_input(polygon_segments).closest(M[on_b])
    return M


def polygon_segments(S: RemeshState) -> Segments:
    """The edges of the image polygon ``S.polygon`` as :class:`.locate.Segments` (for
    :meth:`.state.RemeshState.of_input`: their search tree built once)."""
    return Segments(S.polygon, np.roll(S.polygon, -1, 0))


def split_balance(S: RemeshState, a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The lift (eq. 1) of the split point ``t`` of each edge ``a–b``: its distance to the
    nearer end over the edge's length (k float; ½ at the middle of a straight edge)."""
    P, _ = lift_samples(S, a, b, t[:, None])
    near = np.minimum(norms(P - S.X[a]), norms(P - S.X[b]))
    return near / np.maximum(norms(S.X[a] - S.X[b]), 1e-300)


def split_keeps_shape(S: RemeshState, h: np.ndarray, twin: np.ndarray,
                      t: np.ndarray | None = None, points: np.ndarray | None = None
                      ) -> np.ndarray:
    """Which splits of :func:`split_edges` (same arguments; a bool mask) make only faces with a
    disk shape (:func:`.halfedge.disk_shape`) of at least ``DISK_SHAPE_MIN``. Halving the
    short disk edge of a face the map squeezes thin halves its shape; without this test,
    repeated splits drive it to rounding level, where the next split lands on a corner. A
    kept edge (``S.joined``, a feature line's) is never split: its new vertex would leave the
    line."""
    if len(h) == 0:
        return np.zeros(0, bool)
    F = S.F
    f, c = h // 3, h % 3
    a, b, p = F[f, c], F[f, (c + 1) % 3], F[f, (c + 2) % 3]
    on_b = twin < 0
    M = _split_points(S, a, b, on_b, t) if points is None else points
    g, d = np.maximum(twin, 0) // 3, np.maximum(twin, 0) % 3
    q = np.where(on_b, p, F[g, (d + 2) % 3])
    w = S.n + np.arange(len(h))
    uv = np.vstack([S.uv, M])
    new = np.column_stack([a, w, p, w, b, p, b, w, q, w, a, q]).reshape(-1, 3)
    shape = disk_shape(uv, new).reshape(-1, 4)
    shape[on_b, 2:] = np.inf                     # a boundary edge has no face across
    return (row_min(shape) >= DISK_SHAPE_MIN) & ~S.is_joined(a, b)


def _split_twins(tw_old: np.ndarray, m: int, f, c, inner, g, d) -> np.ndarray:
    """The half-edge twins after :func:`split_edges` (from those before, ``tw_old``; ``m``
    faces before): face ``f`` (edge ``a → b`` at corner ``c``) became ``[a, w, p]`` plus the new
    face ``f2 = [w, b, p]``; for an inner edge, its twin's face ``g`` (corner ``d``) became
    ``[b, w, q]`` plus ``g2 = [w, a, q]``. The four outer half-edges (``p→a``, ``b→p``,
    ``q→b``, ``a→q``) keep their twins, which may themselves have moved."""
    k, j = len(f), len(inner)
    f2 = m + np.arange(k)
    g2 = m + k + np.arange(j)
    tw = np.concatenate([tw_old, np.full(3 * (k + j), -1, np.int64)])
    # outer half-edges: old slot → new slot
    old = np.concatenate([3 * f + (c + 2) % 3, 3 * f + (c + 1) % 3,
                          3 * g + (d + 2) % 3, 3 * g + (d + 1) % 3])
    new = np.concatenate([3 * f + 2, 3 * f2 + 1, 3 * g + 2, 3 * g2 + 1])
    ext = tw_old[old]
    # the inner half-edges of the new fans
    fi, f2i = f[inner], f2[inner]
    pairs = [(3 * f + 1, 3 * f2 + 2),                    # w→p ↔ p→w
             (3 * fi, 3 * g2),                           # a→w ↔ w→a
             (3 * g, 3 * f2i),                           # b→w ↔ w→b
             (3 * g + 1, 3 * g2 + 2)]                    # w→q ↔ q→w
    outer_f = np.ones(k, bool)
    outer_f[inner] = False
    tw[3 * f[outer_f]] = -1                              # a→w on the rim
    tw[3 * f2[outer_f]] = -1                             # w→b on the rim
    for x, y in pairs:
        tw[x] = y
        tw[y] = x
    _pair_moved(tw, old, new, ext)
    return tw


def _pair_moved(tw: np.ndarray, old: np.ndarray, new: np.ndarray, ext: np.ndarray) -> None:
    """Give the half-edges moved from slots ``old`` to ``new`` (k distinct each) their twins
    ``ext`` (k, their twins before, −1 for none) at those twins' own new slots, and those
    twins the moved half-edges, in ``tw`` (in place; a twin moved too is looked up among
    ``old``, by a search of the k slots instead of a map of every slot)."""
    has = ext >= 0
    there = ext[has]
    order = np.argsort(old)
    pos = np.minimum(np.searchsorted(old[order], there), len(old) - 1)
    there = np.where(old[order][pos] == there, new[order][pos], there)   # the twin's slot now
    tw[new] = -1
    tw[new[has]] = there
    tw[there] = new[has]


def split_faces(S: RemeshState, faces: np.ndarray, M: np.ndarray, locked: bool = False
                ) -> np.ndarray:
    """Split each of the given (distinct) faces 1 → 3 at the disk point ``M`` strictly inside
    it; returns the new vertices."""
    mf, mb, _ = S.locator.locate_with_inside(M)
    w = S.append_vertices(M, mf, mb, np.zeros(len(M), bool), locked)
    a, b, c = S.F[faces, 0], S.F[faces, 1], S.F[faces, 2]
    tw_old = S.cached_twins()
    F = S.F.copy()
    F[faces] = np.column_stack([a, b, w])
    S.set_faces(np.vstack([F, np.column_stack([b, c, w]), np.column_stack([c, a, w])]),
                None if tw_old is None else _face_split_twins(tw_old, len(F), faces))
    return w


def _face_split_twins(tw_old: np.ndarray, m: int, faces: np.ndarray) -> np.ndarray:
    """The half-edge twins after :func:`split_faces` (from those before, ``tw_old``; ``m``
    faces before): face ``t = [a, b, c]`` (the ``i``-th of the ``k`` ``faces``) became
    ``[a, b, w]`` plus ``t1 = [b, c, w]`` (face ``m + i``) and ``t2 = [c, a, w]`` (face
    ``m + k + i``). Its outer half-edges ``b→c`` and ``c→a`` moved to the first slots of
    ``t1`` and ``t2`` and keep their twins, which may themselves have moved; ``a→b`` stays."""
    k = len(faces)
    t1 = m + np.arange(k)
    t2 = m + k + np.arange(k)
    tw = np.concatenate([tw_old, np.full(6 * k, -1, np.int64)])
    old = np.concatenate([3 * faces + 1, 3 * faces + 2])        # b→c, c→a
    new = np.concatenate([3 * t1, 3 * t2])
    ext = tw_old[old]
    for x, y in [(3 * faces + 1, 3 * t1 + 2),                   # b→w ↔ w→b
                 (3 * faces + 2, 3 * t2 + 1),                   # w→a ↔ a→w
                 (3 * t1 + 1, 3 * t2 + 2)]:                     # c→w ↔ w→c
        tw[x] = y
        tw[y] = x
    _pair_moved(tw, old, new, ext)
    return tw


def _edges_at(S: RemeshState, active: np.ndarray | None):
    """Every edge with an ``active`` end (n bool; all edges when None) once, as
    :func:`.halfedge.edge_table` gives them, in the half-edge numbering of ``S.F``."""
    if active is None:
        return edge_table(S.F, twin=S.twins())
    # both faces of an edge with an active end contain that end: the edge table of the faces
    # at active vertices has those edges' twins right
    sub = np.flatnonzero(touching(S.F, active))
    hs, a, b, ts = edge_table(S.F[sub])
    keep = active[a] | active[b]
    hs, a, b, ts = hs[keep], a[keep], b[keep], ts[keep]
    h = 3 * sub[hs // 3] + hs % 3
    return h, a, b, np.where(ts >= 0, 3 * sub[ts // 3] + ts % 3, -1)


def _after_splits(S: RemeshState, n0: int, a: np.ndarray, b: np.ndarray,
                  waiting: np.ndarray) -> np.ndarray:
    """Where a round of splits leaves edges to look at again (n bool): every new edge ends at
    a new vertex (index ≥ ``n0``), and the candidates ``waiting`` (edges ``a–b``) that were
    not split this round are still there."""
    active = np.zeros(S.n, bool)
    active[n0:] = True
    active[a[waiting]] = True
    active[b[waiting]] = True
    return active


def split_long_edges(S: RemeshState, L_max: float, max_rounds: int = 6,
                     budget: int | None = None, accept=None) -> int:
    """Split edges longer than ``L_max``, longest first, in independent rounds (after the
    first, only the edges at new vertices and the candidates that waited).

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    L_max : float
        3D length, in the mesh's units (0: any edge, to add ``budget`` vertices).
    max_rounds : int
    budget : int, optional
        At most this many splits.
    accept : callable ``accept(h, t) -> (k,) bool``, optional
        Which splits of the half-edges ``h`` at ``t`` along them (:func:`split_edges`) may be
        made (:func:`.angles.keeps_min_angle`: none that makes a skinny face).

    Returns
    -------
    int
        The number of splits.
    """
    done = 0
    active = None
    for _ in range(max_rounds):
        h, a, b, twin = _edges_at(S, active)
        ln = edge_lengths(S.X, a, b)
        cand = np.flatnonzero(ln > L_max)
        if budget is not None and len(cand) > 4 * (budget - done) + 1000:
            # only the longest few can be among the longest independent ones
            k = 4 * (budget - done) + 1000
            cand = cand[np.argpartition(-ln[cand], k)[:k]]
        t = np.full(len(S.F) * 3, 0.5)                   # per half-edge; used when middles
        if S.surface_middles and len(cand):
            t[h[cand]], balance = surface_middles(S, a[cand], b[cand], SAG_TS)
            cand = cand[balance >= MIN_BALANCE]          # no split point away from both ends
        cand = cand[split_keeps_shape(S, h[cand], twin[cand],
                                      t[h[cand]] if S.surface_middles else None)]
        if accept is not None and len(cand):
            cand = cand[accept(h[cand], t[h[cand]])]
        if len(cand) == 0:
            break
        sel = cand[independent_edges(len(S.F), h[cand], twin[cand], -ln[cand])]
        if budget is not None:
            sel = sel[np.argsort(-ln[sel], kind="stable")][:budget - done]
        if len(sel) == 0:
            break
        n0 = S.n
        done += split_edges(S, h[sel], twin[sel], t[h[sel]] if S.surface_middles else None)
        if budget is not None and done >= budget:
            break
        active = _after_splits(S, n0, a, b, np.setdiff1d(cand, sel))
    S.tally("splits", done)
    return done


def refine_by_sag(S: RemeshState, threshold: float, budget: int, max_rounds: int = 8,
                  active: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """Split edges whose straight line is farther than ``threshold`` from the surface at any
    of ``SAG_SAMPLES`` points along it, worst first, at the worst point, in independent
    rounds, at most ``budget`` splits.

    Where the equiareal map squeezes a region into a thin sliver of the disk (the sides of
    fingers, deep folds), uniform disk samples are too sparse across it and the lifted
    triangles bridge over the surface; an edge split at its worst disk point puts a vertex on
    the surface inside the sliver. After the first round only the edges at new vertices (and the
    candidates that waited for a free face) are measured again; ``active`` (n bool) limits the
    first round the same way.

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    threshold : float
        Sag tolerance, in the mesh's units.
    budget : int
        At most this many splits.
    max_rounds : int
    active : (n,) bool, optional

    Returns
    -------
    splits : int
    pending : (n',) bool
        The vertices whose edges were still to be measured when the rounds ran out.
    """
    done = 0
    pending = None
    for _ in range(max_rounds):
        if done >= budget:
            break
        h, a, b, twin = _edges_at(S, active)
        if len(h) == 0:
            break
        probe = may_sag(S, a, b, threshold)     # only the others are probed along their length
        h, a, b, twin = h[probe], a[probe], b[probe], twin[probe]
        N_in = S.normals_in()
        sag, t_split = edge_sag_along(S, a, b, SAG_TS,
                                      end_normals=(N_in.take(S.face[a], axis=0),
                                                   N_in.take(S.face[b], axis=0)))
        cand = np.flatnonzero(sag > threshold)
        if S.surface_middles and len(cand):
            cand = cand[split_balance(S, a[cand], b[cand], t_split[cand]) >= MIN_BALANCE]
        cand = cand[split_keeps_shape(S, h[cand], twin[cand], t_split[cand])]
        if len(cand) == 0:
            break
        sel = cand[independent_edges(len(S.F), h[cand], twin[cand], -sag[cand])]
        sel = sel[np.argsort(-sag[sel], kind="stable")][:budget - done]
        if len(sel) == 0:
            break
        n0 = S.n
        done += split_edges(S, h[sel], twin[sel], t_split[sel])
        active = _after_splits(S, n0, a, b, np.setdiff1d(cand, sel))
    else:
        pending = active                         # the rounds ran out
    S.tally("sag_splits", done)
    return done, np.zeros(S.n, bool) if pending is None else pending
