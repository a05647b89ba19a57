"""Triangle-quality improvement of a lifted remesh (beyond the paper's §8), done on the disk.

An equiareal map keeps areas but distorts angles; where a shape has long protrusions or deep
folds (fingers, ears, sulci) the map squeezes them into thin slivers of the disk. Uniform disk
samples therefore have the right *density* on the surface but not the right *shape*: lifted
triangles are skewed, and across a sliver they bridge over the surface. The pass below
isotropically remeshes towards the target edge length ``L`` (3D, the mesh's units) with the
operations of Botsch & Kobbelt (2004) — split, collapse, flip, tangential smoothing — plus
splits where an edge leaves the surface, all made on the disk: a vertex is always a disk
position lifted by eq. (1), so it stays exactly on the input surface, and every face stays
counter-clockwise on the disk, so the output stays a parameterized disk.

The schedule (:func:`improve_remesh`):

1. snap (or insert) a locked vertex onto each sharp input corner (:mod:`.corners`);
2. flips, then ``relax_iterations`` × (tangential smoothing, flips);
3. refinement: split edges farther than ``refine_sag × L`` from the surface; split once the
   edges still longer than ``LONG_EDGE × L`` (they lie along the map's stretch, on the surface,
   where the sag test cannot see them); flips; the sag splits again around what changed and
   what the rounds left (they can run out where a steep wall is squeezed against the rim),
   flips;
4. count correction: collapse the shortest edges (slivers shorter than ``SLIVER × L`` and as
   many more as the refinement added) under the gap and sag guards at ``refine_sag × L``, so
   that they do not undo the refinement; without the sag guard if it leaves the count above
   the target; split the longest edges if below;
5. one more smoothing step and flips;
6. up to ``SLIVER_PASSES`` collapses of the slivers the last steps left, under the same
   guards, the count given back by splits, each followed by flips.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..rows import norms
from .collapse import collapse_short_edges
from .corners import snap_vertices
from .flips import flip_edges
from .halfedge import edge_table
from .refine import refine_by_sag, split_long_edges
from .relax import tangential_smoothing
from .sag import edge_sag
from .state import RemeshState

SLIVER = 0.2          # edges shorter than this × L are collapsed; no corner inserted closer
SLIVER_PASSES = 3     # at most this many last sliver collapses (each with its splits, flips),
SLIVER_AGAIN = 5e-4   # the next only after one that collapsed at least this × the vertex count
LONG_EDGE = 3.0       # after the sag refinement, split edges longer than this × L once


def improve_remesh(S: RemeshState, L: float, *, relax_iterations: int = 2, flips: bool = True,
                   max_dihedral_deg: float = 20.0, relax_step: float = 0.5,
                   refine_sag: float = 0.2, refine_budget: float = 0.3,
                   target_vertices: int | None = None,
                   corners_uv: np.ndarray | None = None) -> RemeshState:
    """Improve the remesh ``S`` in place (see the module docstring for the schedule).

    Parameters
    ----------
    S : RemeshState
    L : float
        Target edge length on the surface, in the mesh's units.
    relax_iterations : int
        Tangential smoothing steps before refinement (each followed by flips); with 0, none
        after count correction either.
    flips : bool
        Delaunay flips on the lifted surface.
    max_dihedral_deg : float
        Quads folded less than this flip freely; more folded ones only towards an edge closer
        to the surface.
    relax_step : float
        The fraction of the way to the 1-ring centroid a smoothing step moves.
    refine_sag : float
        Split edges farther than ``refine_sag × L`` from the surface (0: no refinement); also
        the tolerance of the collapses' guards.
    refine_budget : float
        At most this fraction of the vertex count in sag splits (and in long-edge splits).
    target_vertices : int, optional
        The count to restore after refinement; default: the count after refinement.
    corners_uv : (k, 2) float, optional
        Disk images of sharp interior input vertices, sharpest first.

    Returns
    -------
    RemeshState
        ``S``, with counts and seconds per step in ``S.log``.
    """
    ops = _Operations(S, L, flips, max_dihedral_deg, relax_step, refine_sag)
    lap = Stopwatch(S.log, "seconds")
    if corners_uv is not None and len(corners_uv):
        snap_vertices(S, corners_uv, min_gap=SLIVER * L)
    ops.flip()
    lap("flips")
    for _ in range(relax_iterations):
        ops.relax()
        lap("relax")
        ops.flip()
        lap("flips")
    if refine_sag > 0:
        ops.refine(budget=int(refine_budget * S.n))
        lap("refine")
    target = S.n if target_vertices is None else int(target_vertices)
    ops.restore_count(target)
    lap("count")
    if relax_iterations > 0:
        ops.relax()
        lap("relax")
        ops.flip()
        lap("flips")
    ops.remove_slivers(target)
    lap("count")
    return S


@dataclass
class _Operations:
    """The steps of :func:`improve_remesh` on ``S``, with its parameters."""

    S: RemeshState
    L: float
    flips: bool
    max_dihedral_deg: float
    relax_step: float
    refine_sag: float

    @property
    def tol(self) -> float | None:
        """The collapse guards' tolerance (mesh units), None without refinement."""
        return self.refine_sag * self.L if self.refine_sag > 0 else None

    def flip(self, since: np.ndarray | None = None) -> None:
        """Flips everywhere, or — given the faces before a run of splits — only from the
        faces those splits changed or added."""
        if not self.flips:
            return
        S = self.S
        active = None if since is None else _corners_changed_since(S, since)
        twin = S.twins().copy()
        F, k, _ = flip_edges(S.X, S.F, S.uv, self.max_dihedral_deg, sag=partial(edge_sag, S),
                             boundary=S.is_rim, active=active, twin=twin)
        S.set_faces(F, twin)
        S.tally("flips", k)

    def relax(self) -> None:
        """One tangential smoothing step of every vertex not on the rim and not locked."""
        S = self.S
        S.uv, S.face, S.bary, S.X, moved = tangential_smoothing(
            S.V_in, S.F_in, S.uv_in, S.locator, S.uv, S.F, S.face, S.bary,
            ~S.is_rim & ~S.locked, 1, self.relax_step, X=S.X, pullback=S.pullback())
        S.tally("relaxed_vertex_moves", sum(moved))

    def refine(self, budget: int) -> None:
        """Sag splits, one long-edge split, flips, sag splits again around what changed and
        what the first rounds left, flips; at most ``budget`` sag splits in all."""
        S, L = self.S, self.L
        F_pre = S.F.copy()
        done, pending = refine_by_sag(S, self.refine_sag * L, budget)
        F0 = S.F.copy()
        split_long_edges(S, LONG_EDGE * L, budget=budget)
        self.flip(since=F_pre)
        active = _corners_changed_since(S, F0)
        active[:len(pending)] |= pending
        F1 = S.F.copy()
        refine_by_sag(S, self.refine_sag * L, budget - done, active=active)
        self.flip(since=F1)

    def restore_count(self, target: int) -> None:
        """Collapse the slivers and as many of the shortest edges as the count exceeds
        ``target``, under the guards (without the sag guard if it refuses too many); split the
        longest edges if the count is below ``target``."""
        S, L, tol = self.S, self.L, self.tol
        h, a, b, _ = edge_table(S.F, twin=S.twins())
        n_short = int(np.count_nonzero(norms(S.X[a] - S.X[b]) < SLIVER * L))
        excess = max(S.n - target, 0) + n_short
        if excess > 0:
            collapse_short_edges(S, np.inf, 2.0 * L, budget=excess, max_gap=tol, max_sag=tol)
            if tol is not None and S.n > target:
                collapse_short_edges(S, np.inf, 2.0 * L, budget=S.n - target, max_gap=tol)
        if S.n < target:
            split_long_edges(S, 0.0, budget=target - S.n)

    def remove_slivers(self, target: int) -> None:
        """Collapse the edges shorter than ``SLIVER × L`` under the guards, the count given back
        by splits, then flips; again while a pass collapses many (the flips let the guards pass
        collapses next to it that they refused before)."""
        S, L, tol = self.S, self.L, self.tol
        for _ in range(SLIVER_PASSES):
            collapsed = collapse_short_edges(S, SLIVER * L, 2.0 * L, max_gap=tol, max_sag=tol)
            if not collapsed:
                break
            if S.n < target:
                split_long_edges(S, 0.0, budget=target - S.n)
            self.flip()
            if collapsed < SLIVER_AGAIN * S.n:
                break


class Stopwatch:
    """``lap(key)`` adds the seconds since the last lap to ``log[key]``, or with ``within`` to
    ``log[within][key]``."""

    def __init__(self, log: dict, within: str | None = None):
        self.log, self.within = log, within
        self.tick = time.perf_counter()

    def __call__(self, key: str) -> None:
        now = time.perf_counter()
        seconds = self.log if self.within is None else self.log.setdefault(self.within, {})
        seconds[key] = seconds.get(key, 0.0) + now - self.tick
        self.tick = now


def _corners_changed_since(S: RemeshState, F_before: np.ndarray) -> np.ndarray:
    """The corners (n bool) of the faces rewritten or added since ``F_before`` (m₀×3) by
    splits and flips (both rewrite faces in place and only append new ones)."""
    changed = np.r_[np.flatnonzero((S.F[:len(F_before)] != F_before).any(axis=1)),
                    np.arange(len(F_before), len(S.F))]
    corners = np.zeros(S.n, bool)
    corners[S.F[changed].ravel()] = True
    return corners
