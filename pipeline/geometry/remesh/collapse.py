"""Edge collapses: the collapse step of isotropic remeshing (Botsch & Kobbelt 2004), 3D lengths.

Used to give the vertex count back after refinement (the shortest edges are collapsed) and to
remove slivers. A collapse ``r → k`` removes one endpoint ``r`` and keeps the other where it
is. It is made only if

* ``r`` is not a locked corner, and not a rim vertex unless the edge is a boundary edge (an
  interior edge between two rim vertices is never collapsed);
* the link condition holds (the ends share exactly two neighbours, one on the boundary);
* no face flips on the disk or turns over in 3D, no face gets three boundary corners and no
  edge gets longer than ``L_max``, and no new face is thinner on the disk than
  ``DISK_SHAPE_MIN`` (:func:`.halfedge.disk_shape`; compiled with the link condition:
  :func:`.._kernels.collapses_valid`);
* given ``max_gap``: the removed vertex, a point of the surface, stays within ``max_gap`` of
  the faces that replace its ring (so that collapses do not undo the refinement of folds);
* given ``max_sag``: no new edge is farther than that from the surface (:func:`.sag.edge_sag`;
  so that collapses do not re-create the bridges refinement removed).

Collapses run in rounds; each takes a maximal set of independent ones (pairwise disjoint
closed 1-rings of the removed vertices), greedy from the shortest edge.
"""

from __future__ import annotations

import numpy as np

from .. import topology as topo
from .._kernels import (close_rings_of, collapses_valid, faces_kept_by_collapses,
                        half_edge_lengths, pairs_in_rows, renumbered_faces, ring_minima,
                        short_edge_ends, short_edges)
from ..remesh_quality import closest_points_on_triangles
from ..rows import norms
from .halfedge import DISK_SHAPE_MIN, CSR, adjacency, faces_at, group, vertex_faces
from .sag import edge_sag
from .state import RemeshState

COLLAPSE_POOL = 4     # with a budget, the shortest 4 × remaining + 5000 edges are checked
COLLAPSE_POOL_MIN = 5000
MIS_TAIL = 0.02       # a round's passes stop when one takes < 2 % of the first's collapses


def collapse_short_edges(S: RemeshState, L_min: float, L_max: float, max_rounds: int = 8,
                         budget: int | None = None, max_gap: float | None = None,
                         max_sag: float | None = None, at: np.ndarray | None = None) -> int:
    """Collapse edges shorter than ``L_min`` (3D), shortest first, when no edge longer than
    ``L_max`` appears, the removed vertex stays within ``max_gap`` (if given) of the new faces
    around it, no new edge has a sag (:func:`edge_sag`) above ``max_sag`` (if given), and the
    result stays valid (see the module docstring); at most ``budget`` collapses. In rounds:
    each takes a maximal set of independent collapses, greedy from the shortest
    (:func:`_independent_collapses`). With a budget the candidates are a pool of the shortest
    ``COLLAPSE_POOL × budget + COLLAPSE_POOL_MIN`` edges, chosen again when it is used up. A
    round reads only the faces at the candidates' ends, leaving out the edges an earlier round
    refused while no collapse has touched their rings (:class:`RefusedEdges`); after the
    first it looks for them only where candidates were, at the vertices kept and at the ends
    of the edges no longer refused.

    Parameters
    ----------
    S : RemeshState
        Changed in place; the removed vertices are dropped at the end, the others keep their
        order.
    L_min, L_max : float
        3D lengths, in the mesh's units (``L_min`` may be inf: any edge, within ``budget``).
    max_rounds : int
    budget : int, optional
    max_gap, max_sag : float, optional
        The guards' tolerances, in the mesh's units.
    at : (n,) bool, optional
        Only edges with both ends marked (the short edges of skinny faces).

    Returns
    -------
    int
        The number of collapses.
    """
    done = 0
    look = None                     # after a round: where open short edges can be (n bool)
    thr = L_min
    alive = np.ones(S.n, bool)      # vertices not removed yet
    X = np.ascontiguousarray(S.X)   # fixed until the rounds end (removed vertices stay)
    refused = RefusedEdges(S.n)
    for _ in range(max_rounds):
        F, n = np.ascontiguousarray(S.F, dtype=np.int64), S.n
        Fs = F
        if budget is not None and look is None:
            # the pool: the shortest COLLAPSE_POOL × remaining + COLLAPSE_POOL_MIN edges (each
            # interior edge is two half-edges); validity is checked per candidate
            hl = half_edge_lengths(F, X)
            pool = 2 * (COLLAPSE_POOL * (budget - done) + COLLAPSE_POOL_MIN)
            thr = min(L_min, float(np.partition(hl, pool)[pool])) if pool < len(hl) else L_min
        if np.isfinite(thr):
            # only the faces at the ends of the short edges not refused already: a collapse
            # reads nothing but the rings of its two ends, whose faces (and so their edges'
            # twins) are all among these
            count, at_short = short_edge_ends(
                F, np.ones(n, np.uint8) if look is None else look.view(np.uint8), X, thr,
                np.ascontiguousarray(S.is_rim).view(np.uint8), *refused.rows())
            if count == 0:
                # (refused edges are short edges of this pool: with some, it is not used up)
                if thr < L_min and look is not None and not len(refused):
                    look = None                  # the pool is used up: a new one
                    continue
                break
            Fs = faces_at(F, at_short)
        if at is not None:
            # only edges between marked vertices are candidates: every face at a marked vertex
            # of Fs stays, in order, so the candidates, the twins of their ends' edges and
            # their ends' rows of the adjacency and incidence are those of the whole Fs
            Fs = faces_at(Fs, at)
        twin_all = topo.interior_edge_twins(Fs)
        h, a, b, twin, ln = short_edges(Fs, twin_all, X, thr)
        keep = ~refused.has(a, b)
        if at is not None:
            keep &= at[a] & at[b]
        h, a, b, twin, ln = (x[keep] for x in (h, a, b, twin, ln))
        if len(h) == 0:
            break
        on_b = twin < 0
        ra, rb = S.is_rim[a], S.is_rim[b]
        ok = ~(ra & rb & ~on_b)                   # an interior edge between rim vertices: no
        # remove r, keep k: never remove a rim vertex unless the edge is on the boundary, and
        # never a locked vertex
        keep_a = (ra & ~rb) | S.locked[a]
        r = np.where(keep_a, b, a)
        k = np.where(keep_a, a, b)
        ok &= ~S.locked[r] & ~(S.is_rim[r] & ~on_b)   # (a locked k can make r a rim vertex)
        refused.add(a[~ok], b[~ok])
        r, k, a, b, ln, on_b, h, twin = (x[ok] for x in (r, k, a, b, ln, on_b, h, twin))
        if len(r) == 0:
            break
        A = adjacency(Fs, n, twin_all)
        VF = vertex_faces(Fs, n)
        r, k = r.astype(np.int64), k.astype(np.int64)
        ok = collapses_valid(A.indptr, A.indices, VF.indptr, VF.indices, Fs, r, k,
                             on_b.view(np.uint8), np.ascontiguousarray(S.uv, dtype=np.float64),
                             X, np.ascontiguousarray(S.is_rim).view(np.uint8), float(L_max),
                             DISK_SHAPE_MIN)
        refused.add(a[~ok], b[~ok])
        win = _independent_collapses(S, r, k, ln, ok, A, VF, Fs, max_gap, max_sag,
                                     None if budget is None else budget - done)
        if len(win) == 0:
            break
        remap = np.arange(n)
        remap[r[win]] = k[win]
        # the removed vertices stay in the arrays, unreferenced, until the rounds end: one
        # compaction instead of one a round (the same numbering: deletions keep the order)
        S.set_faces(renumbered_faces(F, remap))
        alive[r[win]] = False
        again = refused.forget_at(r[win], A)
        if np.isfinite(thr):
            # the open short edges left are among those seen this round, at a kept vertex or
            # refused ones no longer refused
            at_short[k[win]] = True
            at_short[again] = True
            look = at_short
        done += len(win)
        if budget is not None and done >= budget:
            break
    if not alive.all():
        S.keep_vertices(alive)
    S.tally("collapses", done)
    return done


class RefusedEdges:
    """Edges ``a–b`` whose collapse a round of :func:`collapse_short_edges` refused (the
    checks before the guards: rim and lock rules, link condition, face tests), kept until the
    ring of an end changes. Within one call ``X``, ``uv``, the rim and the locks are fixed, so
    these checks read only the faces at the two ends: while no collapse touches those, the
    verdict stands, and the rounds skip the edge (and the faces around it) instead of checking
    it again.

    Parameters
    ----------
    n : int
        The number of vertices.
    """

    def __init__(self, n: int):
        self.n = n
        self.pairs = np.zeros((0, 2), np.int64)
        self.csr = None                         # rows(), made on demand

    def add(self, a: np.ndarray, b: np.ndarray) -> None:
        """Record the edges ``a–b`` (k int each) as refused."""
        if len(a):
            self.pairs = np.concatenate([self.pairs, np.stack([a, b], axis=1)])
            self.csr = None

    def __len__(self) -> int:
        return len(self.pairs)

    def forget_at(self, removed: np.ndarray, A: CSR) -> np.ndarray:
        """Drop the edges with an end in the closed ring (adjacency ``A``) of a removed vertex
        (the collapses of ``removed`` rewrote the faces there); returns the ends of the
        dropped edges (k×2)."""
        changed = np.zeros(self.n, bool)
        changed[removed] = True
        changed[topo.csr_rows(A.indptr, A.indices, removed)[1]] = True
        drop = changed[self.pairs[:, 0]] | changed[self.pairs[:, 1]]
        dropped, self.pairs = self.pairs[drop], self.pairs[~drop]
        self.csr = None
        return dropped

    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Both directions of the refused edges grouped by their tail: CSR ``(indptr,
        indices)``, row ``a`` the vertices ``b`` of the refused edges ``a–b``."""
        if self.csr is None:
            a, b = self.pairs[:, 0], self.pairs[:, 1]
            self.csr = group(np.concatenate([a, b]), np.concatenate([b, a]), self.n)
        return self.csr.indptr, self.csr.indices

    def has(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which edges ``a–b`` (k int each) are refused ones (k bool)."""
        if len(self.pairs) == 0:
            return np.zeros(len(a), bool)
        return pairs_in_rows(*self.rows(), np.ascontiguousarray(a, np.int64),
                             np.ascontiguousarray(b, np.int64))


def _independent_collapses(S: RemeshState, r, k, ln, ok, A: CSR, VF: CSR, F, max_gap, max_sag,
                           budget: int | None) -> np.ndarray:
    """A maximal set of collapses ``r → k`` among the ``ok`` candidates whose removed vertices
    have pairwise disjoint closed 1-rings (``A``: adjacency), greedy from the shortest ``ln``:
    in passes, every candidate that is the shortest at all vertices of its closed ring among
    those not yet decided is checked against the guards (``max_gap``: the removed vertex within
    that of its new faces, from the faces ``F`` and their incidence ``VF``; ``max_sag``: no
    new edge ``k–x`` farther than that from the surface) and taken if it passes; the
    candidates touching a taken ring drop out (compiled: :func:`.._kernels.ring_minima`,
    :func:`.._kernels.close_rings_of`). Disjoint closed rings make the collapses independent:
    one changes only the faces at its ``r``, whose corners are all in ``r``'s closed ring, and
    no other collapse reads them. The guards (the costly part) run only on the pass winners.
    Passes stop when one takes
    under ``MIS_TAIL`` of the first's. With a ``budget`` (at most that many, shortest first)
    the passes after the first consider only the shortest ``budget`` candidates, so that the
    budget goes to the shortest edges and not to longer ones taken while shorter ones wait for
    the next round."""
    sel = np.flatnonzero(ok)
    if len(sel) == 0:
        return sel
    n, c = S.n, len(sel)
    rank = np.empty(c, np.int64)
    rank[np.argsort(ln[sel], kind="stable")] = np.arange(c)
    pr, pv = topo.csr_rows(A.indptr, A.indices, r[sel])
    pr = np.concatenate([pr, np.arange(c)])                # candidate → its closed ring
    pv = np.concatenate([pv, r[sel]])
    prank = rank[pr]
    open_ = np.ones(c, np.uint8)                           # not yet taken, refused or blocked
    taken = np.zeros(n, np.uint8)                          # vertices of taken closed rings
    best = np.full(n, c, np.int64)                         # ring_minima's scratch
    won = []
    n_won = 0
    while open_.any() and (budget is None or n_won < budget):
        w = ring_minima(pr, pv, prank, open_, best)        # shortest in its whole ring
        w = w[_collapse_guards(S, r, k, sel[w], A, VF, F, max_gap, max_sag)]
        if budget is not None:
            w = w[np.argsort(rank[w], kind="stable")][:budget - n_won]
        close_rings_of(pr, pv, w, taken, open_)
        won.append(w)
        n_won += len(w)
        if budget is not None and len(won) == 1:
            # later passes only among the shortest ``budget``: they must not spend the budget
            # on longer edges while shorter ones wait for a ring to free up (next round)
            open_ &= rank < budget
        if len(w) < MIS_TAIL * len(won[0]):
            break                    # the tail: what is left waits for the next round
    return sel[np.concatenate(won)] if won else sel[:0]


def _collapse_guards(S: RemeshState, r, k, cand, A: CSR, VF: CSR, F, max_gap, max_sag
                     ) -> np.ndarray:
    """Which collapses ``r[cand] → k[cand]`` (``cand`` increasing) pass the guards of
    :func:`collapse_short_edges` (a bool mask over ``cand``): the removed vertex, a point of
    the surface, within ``max_gap`` of the faces that replace its ring (its faces in ``F``
    (incidence ``VF``) without ``k``, rewritten with ``k``); no new edge ``k–x`` (``x`` in
    ``r``'s ring, adjacency ``A``) farther than ``max_sag`` from the surface
    (:func:`edge_sag`)."""
    good = np.ones(len(cand), bool)
    if len(cand) and max_gap is not None:
        rc = r[cand]
        fr, _, Tr = faces_kept_by_collapses(VF.indptr, VF.indices, F, rc, k[cand])
        X = S.X
        Pr = X.take(rc[fr], axis=0)
        gap = norms(Pr - closest_points_on_triangles(Pr, *(X.take(Tr[:, c], axis=0)
                                                           for c in range(3))))
        near = np.full(len(cand), np.inf)
        np.minimum.at(near, fr, gap)
        good &= near <= max_gap
    if len(cand) and max_sag is not None:
        idx = np.flatnonzero(good)
        wr, x = topo.csr_rows(A.indptr, A.indices, r[cand[idx]])
        kk = k[cand[idx]][wr]
        new_edge = x != kk
        far = edge_sag(S, kk[new_edge], x[new_edge]) > max_sag
        good[idx[np.bincount(wr[new_edge][far], minlength=len(idx)) > 0]] = False
    return good
