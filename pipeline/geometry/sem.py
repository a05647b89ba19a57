"""Stretch Energy Minimization (Algorithm 1 of Yueh, Lin, Wu, Yau 2019), and its converged form.

One SEM step from a map ``f`` (complex, one value per vertex), line for line:

    L  ← L(f)                                  stretch Laplacian, eq. (12)–(14)
    f_B ← solve L_BB f_B = −L_BI f_I            eq. (19)   [Remark 2: f_I → 1/conj(f_I)]
    f_B ← f_B − mean(f_B)                       eq. (20)   centralize
    f_B ← f_B / |f_B|                           eq. (21)   back onto the unit circle
    f_I ← solve L_II f_I = −L_IB f_B            eq. (22)

Modes:

* ``paper`` — Algorithm 1: ``max_iter`` (10) SEM steps from the harmonic map, each kept while
  ``E_S`` falls (Remark 3), through folded intermediate maps as in the paper. Where Algorithm 1
  would stop early or end on a folded map, it goes back to the last map kept and continues with
  damped steps that add no flipped face — the SEM step ``f + α (f_SEM − f)`` (boundary back on
  the circle), else a preconditioned gradient step — and stops early only when no such step
  lowers ``E_S`` (:func:`_paper_iterations`).
* ``converged`` — iterate until the energy stops decreasing. The plain SEM fixed-point iteration
  is fast at first but is not a descent method: on real meshes its energy turns back up and it
  passes through folded maps (negative stretch weights, Remark 4). So:

  A. plain SEM steps, keeping the best *flip-free* iterate by the normalized energy
     ``E_S / (|f(M)|²/|M|)``; this phase ends once ``patience`` steps bring no new best. If
     the plain steps fold where they would gain (every one of them, or those after the best:
     many obtuse triangles, as in a decimated scan), paper mode's damped steps go on from the
     best (:func:`_damped_start`). If the map is then still crowded
     (:func:`crowded`: a face's share of the image below 10⁻³ of its share of the surface), phase
     B first runs towards intermediate areas (:func:`_area_continuation`);
  B. from that iterate, a monotone descent: each step first tries a Levenberg–Marquardt
     (Gauss–Newton) step on ``E_S`` written as a sum of squared image areas, on the interior,
     later with the boundary angles too, its direction shaped by an orientation barrier after
     a step that ran faces into folds (:mod:`.gauss_newton`; ``descent="gauss_newton"``, the
     default), then the SEM step and the preconditioned gradient step
     ``f_I ← f_I − P⁻¹ (L(f) f)_I``. ``L(f) f`` is half the gradient of ``E_S`` (an identity of
     the paper's Appendix, checked by finite differences in the tests) and ``P`` is ``L_II``
     with non-positive weights clamped, so ``P`` is SPD and the step is a descent direction.
     A step is accepted only if it lowers the energy and flips no face: damped by halving,
     and vertices of faces that would flip keep their previous position.
     Phase B ends when the relative decrease stays below ``tol`` for ``patience`` steps in a
     row (``gn_tol``, ``gn_patience`` with Gauss–Newton), or at ``max_iter`` steps in all; with
     Gauss–Newton also once the stretch ``σ = |f(τ)|/|τ|`` is uniform to ``gn_cv`` (1 %: the
     excess ``E_S/bound − 1`` is σ's squared area-weighted coefficient of variation) and the
     excess is at most ``gn_drop`` (3 %) of its value where the descent started, which is
     where its linear tail would refine a map already that equiareal for tens of steps.
     ``descent="gradient"`` is the schedule without Gauss–Newton: many cheap steps on a kept
     preconditioner factor instead of one factorization per step.

Both modes minimize eq. (15) with every face's area raised to at least 10⁻³ of the mean
(:func:`target_double_areas`: the near-zero slivers of decimated scans), and record its energy
and distortions against the surface's own areas. The returned map is the best flip-free map
found (an area continuation's stages are recorded as phase ``continuation``, their energy
against the surface's areas, which may rise there; the map it ends on is kept only if it is
better than its start), so it has no flipped face whenever the harmonic start has none
(guaranteed by :mod:`.harmonic`). ``SEMResult.flipped_faces`` reports
what remains, and callers treat a non-zero count as failure; ``SEMResult.stop_reason`` says why
the iteration ended and ``SEMResult.steps`` how many steps of each kind were taken (both go into
the ``parameterization`` section of ``metrics.json``).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Literal, Optional

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from .gauss_newton import BARRIER, GaussNewton
from .harmonic import clamp_positive, harmonic_map
from .laplacian import (face_double_areas, laplacian_blocks, laplacian_pattern,
                        stretch_weight_map)
from .metrics import area_distortions, signed_double_areas, vertex_area_fractions
from .topology import vertex_faces
from ._kernels import hold_rounds, stretch_weights
from .solvers import NotPositiveDefinite, make_solver, solve_complex

#: Algorithm 1's steps of ``mode: auto`` on the disk, the remesh's map. The first SEM steps
#: remove most of the harmonic start's area distortion; the later ones remove the rest by
#: stretching faces (the anisotropy of long thin parts grows with every step: c3d_alligator's
#: tips, igl_camel_b's limbs), and the remesh, whose isotropic rounds even out the density on
#: the surface anyway, works on the disk and is hurt by that stretch more than helped by the
#: last percent of evenness (``benchmarks/bench_remesh.py --compare --maps paper paper2``).
REMESH_DISK_STEPS = 2

#: The sphere map of ``mode: auto``, the remesh's: ``REMESH_SPHERE_FREE_STEPS`` iterations of
#: the free phase from the Tutte start (:func:`.sphere.spherical_sem`'s ``free_iter``), then
#: ``REMESH_SPHERE_STEPS`` guarded alternating-hemisphere iterations (paper mode), every
#: spherical triangle positively oriented. The first two free iterations spread the start's
#: crowded limbs; the later ones, and the Gauss–Newton steps of converged mode, remove the last
#: percent of the area distortion, which the remesh's isotropic rounds even out on the surface
#: anyway (``benchmarks/bench_remesh.py --compare --closed --maps converged auto``).
REMESH_SPHERE_FREE_STEPS = 3
REMESH_SPHERE_STEPS = 2


class SEMOptions(BaseModel):
    """SEM's settings; also the ``parameterize`` section of a run config (validated once, here).

    ``max_iter`` defaults to 10 steps in paper mode (Algorithm 1) and 1000 in converged mode.
    ``mode: auto`` is the quick map for remeshing: on the disk paper mode with
    ``REMESH_DISK_STEPS`` steps, on the sphere paper mode with ``REMESH_SPHERE_STEPS``
    hemisphere iterations after ``REMESH_SPHERE_FREE_STEPS`` free ones, unless ``max_iter``
    (and ``free_iter``) say otherwise; :meth:`for_domain` resolves it.
    """

    model_config = ConfigDict(extra="forbid")

    mode: Literal["paper", "converged", "auto"] = "converged"
    # auto: the sphere for a closed genus-0 mesh, the disk otherwise (stages.parameterize)
    domain: Literal["auto", "disk", "sphere"] = "auto"
    max_iter: Optional[int] = Field(None, ge=0)
    tol: float = Field(1e-7, gt=0.0)   # converged: relative energy decrease counted as none
    patience: int = Field(20, ge=1)    # converged: steps without progress that end a phase
    inversion: bool = False            # Remark 2
    stop_when_energy_rises: bool = True   # paper: Remark 3; False runs exactly max_iter steps
    solver: Literal["auto", "pardiso", "cholmod", "scipy"] = "auto"
    min_step: float = Field(1.0 / 64, gt=0.0, le=1.0)   # smallest damping factor tried
    max_step: float = Field(8.0, ge=1.0)   # converged: largest extrapolation of a full step
    refactor_every: int = Field(8, ge=1)   # converged: preconditioner factor reused this often
    # converged: phase B's first step (see _converged_iterations)
    descent: Literal["gradient", "gauss_newton"] = "gauss_newton"
    # converged with gauss_newton: its own stopping rule in place of tol and patience
    gn_tol: float = Field(3e-6, gt=0.0)
    gn_patience: int = Field(3, ge=1)
    # converged with gauss_newton: also ends once the stretch σ = |f(τ)|/|τ| is uniform to
    # gn_cv (its area-weighted coefficient of variation, √(E_S/bound − 1)) and the excess
    # E_S/bound − 1 is at most gn_drop × its value where phase B started (gn_drop 0: off)
    gn_cv: float = Field(0.01, gt=0.0)
    gn_drop: float = Field(0.03, ge=0.0, le=1.0)
    # sphere: iterations of the free phase before the hemisphere or Gauss–Newton steps
    # (spherical_sem's free_iter; None: its default)
    free_iter: Optional[int] = Field(None, ge=0)

    def for_domain(self, domain: str) -> "SEMOptions":
        """These options with ``mode: auto`` resolved for ``domain`` ("disk" or "sphere")."""
        if self.mode != "auto":
            return self
        if domain == "sphere":
            steps = REMESH_SPHERE_STEPS if self.max_iter is None else self.max_iter
            free = REMESH_SPHERE_FREE_STEPS if self.free_iter is None else self.free_iter
            return self.model_copy(update={"mode": "paper", "max_iter": steps,
                                           "free_iter": free})
        steps = REMESH_DISK_STEPS if self.max_iter is None else self.max_iter
        return self.model_copy(update={"mode": "paper", "max_iter": steps})

    def iterations(self) -> int:
        if self.max_iter is not None:
            return self.max_iter
        return 1000 if self.mode == "converged" else 10


@dataclass
class SEMResult:
    """The result of :func:`stretch_energy_minimization`: the map ``uv`` (n, 2), why and
    after how many iterations it ended, its flipped faces, the harmonic start's facts, the
    accepted maps' ``history``, the times, the solver and its statistics, the accepted steps
    by kind and the surface's doubled face areas (m,)."""

    uv: np.ndarray                       # n×2
    status: str                          # converged | max_iter | energy_rose | stalled
    iterations: int
    flipped_faces: int
    harmonic: dict
    history: list = field(default_factory=list)    # one dict per accepted map (0 = harmonic)
    timings: dict = field(default_factory=dict)    # seconds per phase
    solver: str = ""
    solver_stats: dict = field(default_factory=dict)   # factorizations / PCG solves per system
    stop_reason: str = ""                # why the iteration ended, in words
    steps: dict = field(default_factory=dict)   # accepted steps by kind (see step_counts)
    surface_double_area: np.ndarray | None = None  # 2|τ| of every face of the surface (m,)


def step_counts(history: list) -> dict:
    """Accepted steps by kind: ``sem`` (the full SEM step, or longer), ``sem_damped`` (α < 1),
    ``gradient`` (preconditioned gradient steps), ``gauss_newton`` (:mod:`.gauss_newton`), from
    the history entries after the start."""
    counts = {"sem": 0, "sem_damped": 0, "gradient": 0, "gauss_newton": 0}
    for h in history[1:]:
        kind = h["phase"]
        if kind == "sem" and h["step"] < 1.0:
            kind = "sem_damped"
        counts[kind] = counts.get(kind, 0) + 1
    return counts


def _as_uv(f: np.ndarray) -> np.ndarray:
    """The complex map as an n×2 real array (a view, no copy)."""
    return np.ascontiguousarray(f, dtype=np.complex128).view(np.float64).reshape(-1, 2)


class _Problem:
    """Everything fixed during the iterations: areas, Laplacian pattern, solvers."""

    def __init__(self, V, F, boundary, solver_kind):
        self.V, self.F = V, F
        self.surface_A2 = face_double_areas(V, F)            # 2|τ|
        self.A2 = target_double_areas(self.surface_A2)       # what the map's areas aim at
        self.floored = bool(np.any(self.A2 != self.surface_A2))
        self.area_M = self.A2.sum() / 2
        # vertex–face incidence (faces in increasing order in each row), as floats for the
        # per-vertex area sums of eq. (28) and as the faces around held vertices
        self.incidence = vertex_faces(F, len(V)).astype(np.float64)
        self.surface_fractions = vertex_area_fractions(F, len(V), self.surface_A2,
                                                       self.incidence)
        self.pattern = laplacian_pattern(F, len(V), boundary)
        self.I, self.B = self.pattern.interior, self.pattern.boundary
        self.weight_map = stretch_weight_map(self.pattern, self.A2)
        # Separate factors: L_II(f) and its clamped form have the same pattern but their own
        # values; L_BB is the small boundary system.
        self.solver_I = make_solver(solver_kind, refactored=True)
        self.solver_P = make_solver(solver_kind, refactored=True)
        self.solver_B = make_solver(solver_kind, refactored=True)
        self.gn_stats = None     # Gauss–Newton factorizations (and refinements), once run

    def evaluate(self, f, a2=None):
        """``(E_S, E_S/(|f(M)|²/|M|), flipped faces, 2·signed image areas)`` of ``f`` (eq. 15);
        ``a2`` if the image areas are already known."""
        if a2 is None:
            a2 = signed_double_areas(_as_uv(f), self.F)
        return (*_energy_and_ratio(a2, self.A2, self.area_M), int(np.count_nonzero(a2 <= 0)),
                a2)

    def surface_energy(self, value) -> tuple[float, float]:
        """``(E_S, E_S/(|f(M)|²/|M|))`` of eq. (15) with the surface's own areas, from an
        :meth:`evaluate` result (the same numbers unless a face's area was raised by
        :func:`target_double_areas`)."""
        if not self.floored:
            return value[0], value[1]
        return _energy_and_ratio(value[3], self.surface_A2, self.surface_A2.sum() / 2)

    def distortions(self, a2):
        """``(D(f) eq. 28, face-based area distortion)`` from the image areas of a map,
        against the surface's own areas."""
        return area_distortions(self.F, len(self.V), self.surface_A2, a2,
                                self.surface_fractions, self.incidence)

    def weights(self, f):
        """Stretch Laplacian edge weights ``w_ij(f)``, eq. (12), from the squared edge lengths:
        ``W ℓ²(f)`` (:func:`stretch_weight_map`) in one compiled call."""
        W, E = self.weight_map, len(self.pattern.edges)
        w = np.empty(E)
        stretch_weights(W.data, W.indices, W.indptr, self.pattern.edges,
                        np.ascontiguousarray(f, dtype=np.complex128), np.empty(E), w)
        return w

    def with_areas(self, double_area: np.ndarray) -> "_Problem":
        """This problem aiming at other double areas ``2|τ|`` (an area continuation stage):
        the same pattern and solvers, the energy and weights against them. Its steps are
        recorded through this problem (:func:`_area_continuation`), so distortions stay the
        surface's."""
        stage = copy.copy(self)
        stage.A2, stage.area_M = double_area, double_area.sum() / 2
        stage.weight_map = stretch_weight_map(self.pattern, double_area)
        return stage

    def release(self):
        for s in (self.solver_I, self.solver_P, self.solver_B):
            s.release()


def _energy_and_ratio(a2: np.ndarray, double_area: np.ndarray, area_M: float
                      ) -> tuple[float, float]:
    """``(E_S, E_S/(|f(M)|²/|M|))`` of eq. (15) from the signed double image areas ``a2``
    (m,), the double face areas ``double_area`` (m,) they are measured against and their
    surface area ``area_M``."""
    E = float(0.5 * np.sum(a2 * a2 / double_area))
    image_area = np.abs(a2).sum() / 2
    if not image_area > 0:                  # every face collapsed: no ratio to the bound
        return E, np.inf
    return E, E * area_M / image_area ** 2


#: A face whose area is below this share of the mean face area counts as having that area in
#: the energy the map minimizes (:func:`target_double_areas`).
AREA_FLOOR = 1e-3


def target_double_areas(double_area: np.ndarray) -> np.ndarray:
    """The double areas ``2|τ|`` that eq. (15)'s energy and the stretch factors use: the
    surface's, each raised to at least ``AREA_FLOOR`` × their mean.

    A sliver of nearly zero area (10⁻¹¹ of the mean in a quadric-decimated scan, where whole
    strips of them sit) asks for an image triangle as flat as itself: every step that moves
    its corners folds it, the line search holds them, and the descent around it crawls. Raised
    to a thousandth of the mean, the targets of such faces change the total by at most 10⁻³ of
    a face per sliver, and faces at least that large keep their own areas.

    Parameters
    ----------
    double_area : (m,) float
        The surface's double face areas.

    Returns
    -------
    (m,) float
    """
    return np.maximum(double_area, AREA_FLOOR * double_area.mean())


def sem_step(problem: _Problem, f: np.ndarray, w: np.ndarray, inversion: bool = False
             ) -> np.ndarray:
    """One SEM update, eq. (19)–(22), from ``f`` with its stretch weights ``w``.

    Remark 1 needs ``L_BB`` and ``L_II`` positive definite; negative weights (obtuse image
    triangles) can break that. Then the step is taken with those weights clamped positive, a
    Tutte-type system that is always SPD — in place of Remark 4's edge flips, which would change
    the mesh's connectivity."""
    try:
        return _sem_update(problem, f, laplacian_blocks(problem.pattern, w), inversion)
    except NotPositiveDefinite:
        return _sem_update(problem, f, laplacian_blocks(problem.pattern, clamp_positive(w)),
                           inversion)


def _sem_update(problem: _Problem, f: np.ndarray, blocks, inversion: bool) -> np.ndarray:
    L_II, L_IB, L_BB = blocks
    I, B = problem.I, problem.B
    fI = f[I]
    if inversion:                                                     # Remark 2
        fI = fI / np.abs(fI) ** 2
    fB = solve_complex(problem.solver_B, L_BB, -(L_IB.T @ fI))        # eq. (19)
    fB = fB - fB.mean()                                               # eq. (20)
    fB = _onto_circle(fB, f[B])                                       # eq. (21)
    g = np.empty_like(f)
    g[B] = fB
    g[I] = solve_complex(problem.solver_I, L_II, -(L_IB @ fB), x0=f[I])  # eq. (22)
    return g


def _onto_circle(z: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Eq. (21): each boundary value ``z`` (k,) divided by its modulus; a value of modulus 0
    (eq. (19)'s right-hand side vanishes there, as for a mesh whose only interior vertex maps
    to the centre) has no direction and keeps its ``previous`` place (k,)."""
    r = np.abs(z)
    placed = r > 0
    if placed.all():
        return z / r
    return np.where(placed, z / np.where(placed, r, 1.0), previous)


def gradient_step(problem: _Problem, f: np.ndarray, w: np.ndarray, blocks,
                  refactor: bool = True) -> np.ndarray:
    """Preconditioned gradient step on the interior: ``f_I − P⁻¹ (L(f) f)_I``, where
    ``(L(f) f)_I = ½ ∇_I E_S`` and ``P`` is ``L_II`` with positive (clamped) weights.

    With ``refactor=False`` the preconditioner factored at an earlier map is reused: any SPD
    ``P`` gives a descent direction, and one solve costs far less than a refactorization."""
    L_II, L_IB, _ = blocks
    I, B = problem.I, problem.B
    grad = L_II @ f[I] + L_IB @ f[B]
    if refactor:
        if hasattr(problem.solver_P, "ordering"):
            # L_II's pattern: its order, as analysed (a step or two per factorization: the
            # solves, sequential with a given order, cost less than a second nested dissection)
            problem.solver_P.ordering = getattr(problem.solver_I, "permutation", None)
        problem.solver_P.factorize(laplacian_blocks(problem.pattern, clamp_positive(w))[0])
    X = problem.solver_P.solve(np.column_stack([grad.real, grad.imag]))
    g = f.copy()
    g[I] = f[I] - (X[:, 0] + 1j * X[:, 1])
    return g


def damped(f: np.ndarray, g: np.ndarray, alpha: float, boundary: np.ndarray) -> np.ndarray:
    """``f + α (g − f)`` with the boundary projected back onto the unit circle (a boundary
    vertex the step takes to the centre keeps its place in ``f``)."""
    h = f + alpha * (g - f)
    h[boundary] = _onto_circle(h[boundary], f[boundary])
    return h


def hold_flipping_vertices(problem: "_Problem", f: np.ndarray, g: np.ndarray, allowed: int,
                           rounds: int | None = None):
    """Keep the previous position of every vertex of a face that ``g`` flips, until ``g`` flips
    no more faces than ``allowed`` (or ``rounds`` passes; by default as many as it takes, which
    ends at the latest when every vertex of a flipped face is held: such a face is as it was in
    ``f``); returns ``(g, evaluation)``.

    Round 1 holds the vertices of every flipped face; each later round holds the not yet held
    vertices of the faces that the last round re-measured and found flipped (a face still flipped
    that was not re-measured had all its vertices held already). Only the faces around newly
    held vertices have their image areas (eq. 15's ``|f(τ)|``) recomputed. The rounds run
    in compiled code (:mod:`._kernels`): each round touches only a few faces, so in numpy the
    per-call overhead would dominate, and a failed damping try runs all the rounds."""
    a2 = signed_double_areas(_as_uv(g), problem.F)
    count = int(np.count_nonzero(a2 <= 0))
    if count > allowed:
        g = g.copy()
        VF = problem.incidence
        hold_rounds(problem.F, VF.indptr, VF.indices, f, g, a2, count, allowed,
                    len(f) if rounds is None else rounds)
    return g, problem.evaluate(g, a2)


def line_search(problem: _Problem, f, g, current, better, min_step, hold: bool,
                max_step: float = 1.0, start: float = 1.0, rounds: int | None = None):
    """Largest ``α = start, start/2, … ≥ min_step`` whose damped map flips no new face and
    satisfies ``better(evaluation)``; if α = 1 passes, ``α = 2, 4 … ≤ max_step`` while the
    energy keeps falling. ``rounds``: of the flip holding (:func:`hold_flipping_vertices`).
    Returns ``(map, evaluation, α)`` or ``None``."""
    alpha = start
    while alpha >= min_step:
        cand = g if alpha == 1.0 else damped(f, g, alpha, problem.B)
        if hold:
            cand, value = hold_flipping_vertices(problem, f, cand, current[2], rounds)
        else:
            value = problem.evaluate(cand)
        if value[2] <= current[2] and better(value):
            break
        alpha /= 2
    else:
        return None
    if alpha == 1.0 and max_step > 1.0:
        # The full step is accepted: extrapolate along it while that keeps lowering the energy
        # (energy evaluations cost far less than the factorization that produced the step).
        while alpha < max_step:
            ext = damped(f, g, 2 * alpha, problem.B)
            ext_value = problem.evaluate(ext)
            if ext_value[2] > current[2] or not ext_value[1] < value[1]:
                break
            cand, value, alpha = ext, ext_value, 2 * alpha
    return cand, value, alpha


def stretch_energy_minimization(V: np.ndarray, F: np.ndarray, boundary: np.ndarray,
                                options: SEMOptions | None = None, progress=None) -> SEMResult:
    """Equiareal disk map of a disk mesh (one boundary loop, given in order) by SEM.

    ``boundary`` must be ordered with the surface on its left (as
    :func:`pipeline.geometry.topology.boundary_loops` returns it) so that the image of a
    consistently oriented mesh is counter-clockwise. ``progress`` is called with each history
    entry if given.
    """
    opt = options or SEMOptions()
    V = np.asarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    timings = {}
    t0 = time.perf_counter()
    problem = _Problem(V, F, boundary, opt.solver)
    timings["setup"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    h = harmonic_map(V, F, problem.pattern, problem.solver_I, problem.surface_A2)
    timings["harmonic"] = time.perf_counter() - t0

    history: list = []
    t_start = time.perf_counter()

    def record(it, f, value, alpha, phase):
        D, face_D = problem.distortions(value[3])
        energy, ratio = problem.surface_energy(value)
        entry = {"iteration": it, "phase": phase, "stretch_energy": energy,
                 "energy_ratio": ratio,
                 "total_area_distortion_eq28": D,
                 "face_area_distortion": face_D,
                 "flipped_faces": value[2], "step": alpha,
                 "seconds": time.perf_counter() - t_start}
        history.append(entry)
        if progress:
            progress(entry)

    f = h.f
    value = problem.evaluate(f)
    record(0, f, value, 0.0, "harmonic")
    opt = opt.for_domain("disk")
    if opt.mode == "paper":
        f, value, it, status, reason = _paper_iterations(problem, f, value, opt, record)
    else:
        f, value, it, status, reason = _converged_iterations(problem, f, value, opt, record)
    timings["sem"] = time.perf_counter() - t_start
    solver_stats = {name: getattr(sv, "stats", {}) for name, sv in
                    (("interior", problem.solver_I), ("preconditioner", problem.solver_P),
                     ("boundary", problem.solver_B))}
    if problem.gn_stats is not None:
        solver_stats["gauss_newton"] = problem.gn_stats
    problem.release()
    return SEMResult(uv=_as_uv(f).copy(), status=status, iterations=it, flipped_faces=value[2],
                     harmonic={"weights": h.weights, "negative_weights": h.negative_weights,
                               "flipped_faces": h.flipped_faces},
                     history=history, timings=timings, solver=problem.solver_I.name,
                     solver_stats=solver_stats, stop_reason=reason, steps=step_counts(history),
                     surface_double_area=problem.surface_A2)


#: Paper mode: a relative decrease of ``E_S`` below this counts as none (rounding, not progress).
PAPER_RTOL = 1e-13
#: Paper mode's damped steps hold flipping vertices for at most this many rounds first.
PAPER_HOLD_ROUNDS = 8


def _paper_iterations(problem, f, value, opt, record, rounds=PAPER_HOLD_ROUNDS):
    """Algorithm 1 for at most ``max_iter`` steps, with damped steps where it would stop early.

    Each iteration takes the SEM step, eq. (19)–(22), from the current Algorithm-1 iterate and
    keeps it if ``E_S`` falls (Remark 3). Like the paper's algorithm it may pass through folded
    maps (negative stretch weights, Remark 4; the step is then solved with clamped weights,
    :func:`sem_step`): such iterates are held back and enter the history only once a later
    iterate has no more flipped faces than the last map kept. Where Algorithm 1 would end —
    ``E_S`` rises, or ``max_iter`` is reached on a folded iterate — the iteration goes back to the
    last map kept and goes on from there with damped steps that never add a flipped face:

    1. the SEM step damped, ``f + α (f_SEM − f)`` with the boundary back on the circle (α halved
       from twice the last accepted α down to ``min_step``, vertices of faces that would flip
       held in place), the largest α that lowers ``E_S`` — phase ``sem``, step α;
    2. else the preconditioned gradient step on the interior (:func:`gradient_step`, a descent
       direction for ``E_S``), damped the same way — phase ``gradient``.

    After a folded excursion that failed, only damped steps are taken. A step that unflips faces
    of a folded start counts as progress even if ``E_S`` rises. The iteration ends early only
    when no damped step lowers ``E_S``: status ``energy_rose`` if the SEM step itself adds no
    flipped face (a stationary map: Remark 3's stop), else ``stalled``. With
    ``stop_when_energy_rises=False`` every SEM step is kept whatever ``E_S`` does, and a damped
    step only has to add no flipped face: exactly ``max_iter`` iterations, ending on a map with
    no more flipped faces than the start. ``rounds``: of the flip holding in the damped steps
    (if both damped searches fail, the damped SEM step is tried once more with no limit;
    None: no limit from the start). Returns ``(f, evaluation, iterations, status, reason)``."""
    max_iter = opt.iterations()
    it, start = 0, 1.0
    g_f, g_v = f, value            # the Algorithm-1 iterate (may be folded)
    excursion = []                 # folded iterates since the last map kept: (it, map, value)
    undamped = True                # False once a folded excursion has failed

    def commit(i, h, v, alpha, kind):
        nonlocal f, value
        f, value = h, v
        record(i, h, v, alpha, kind)

    while it < max_iter or excursion:
        if it >= max_iter:                     # ended on a folded iterate: back, then damped
            it, excursion, undamped = excursion[0][0] - 1, [], False
            continue
        if undamped:
            g = sem_step(problem, g_f, problem.weights(g_f), opt.inversion)
            v = problem.evaluate(g)
            if not opt.stop_when_energy_rises or v[0] < g_v[0] * (1.0 - PAPER_RTOL):
                it += 1
                g_f, g_v = g, v
                if v[2] <= value[2]:
                    for entry in excursion:
                        commit(*entry, 1.0, "sem")
                    excursion = []
                    commit(it, g, v, 1.0, "sem")
                else:
                    excursion.append((it, g, v))
                continue
            if excursion:                      # E_S rose after folded iterates: go back
                it, excursion, undamped = excursion[0][0] - 1, [], False
        # a damped step from the last map kept
        current = value

        def better(v):
            if not opt.stop_when_energy_rises:
                return True                   # the largest α that adds no flipped face
            return v[2] < current[2] or (v[2] == current[2]
                                         and v[0] < current[0] * (1.0 - PAPER_RTOL))

        w = problem.weights(f)
        g_sem = sem_step(problem, f, w, opt.inversion)
        step, kind = line_search(problem, f, g_sem, current, better, opt.min_step, hold=True,
                                 start=start, rounds=rounds), "sem"
        if step is None:
            try:
                g = gradient_step(problem, f, w, laplacian_blocks(problem.pattern, w))
                step, kind = line_search(problem, f, g, current, better, opt.min_step,
                                         hold=True, rounds=rounds), "gradient"
            except NotPositiveDefinite:
                step = None
        if step is None and rounds is not None:
            # a crowded map (the harmonic start of a decimated scan) can need longer holding
            # cascades than ``rounds``: the damped SEM step once more with as many as it
            # takes, before the iteration is called stalled
            step, kind = line_search(problem, f, g_sem, current, better, opt.min_step,
                                     hold=True), "sem"
        if step is None:
            if hold_flipping_vertices(problem, f, g_sem, current[2])[1][2] <= current[2]:
                reason = (f"iteration {it + 1}: the SEM step raises E_S (Remark 3) and no "
                          f"damped SEM or gradient step down to α = {opt.min_step:g} lowers it")
                return f, value, it, "energy_rose", reason
            reason = (f"iteration {it + 1}: every damped SEM and gradient step down to α = "
                      f"{opt.min_step:g} flips faces or raises E_S")
            return f, value, it, "stalled", reason
        it += 1
        g, v, alpha = step
        if kind == "sem":
            start = min(1.0, 2.0 * alpha)
        commit(it, g, v, alpha, kind)
        g_f, g_v = f, value
    return f, value, it, "max_iter", f"reached max_iter = {max_iter}"


#: Phase A's end: a flip-free SEM step that removes less than this fraction of the excess energy
#: ratio ``E_S/bound − 1`` of the best map counts as no progress, and phase A ends after
#: ``patience`` such steps (gradient descent) or the first one (Gauss–Newton, whose steps gain
#: more than a slowing SEM step from there). A folded SEM iterate that still removes
#: ``PHASE_A_UNFOLD_GAIN`` of the previous iterate's excess is waited for (plain SEM often
#: unfolds within a few steps): Gauss–Newton started on a map far from equiareal crawls with
#: heavily damped steps.
PHASE_A_GAIN = {"gradient": 0.01, "gauss_newton": 0.05}
PHASE_A_UNFOLD_GAIN = 0.01
#: Levenberg–Marquardt damping: the first μ as a multiple of its floor (:func:`damping_floor`),
#: its factor after a full or a damped step, and how often μ is raised tenfold before phase B
#: falls back to the SEM and gradient steps.
GN_MU_START, GN_MU_DOWN, GN_MU_UP, GN_RETRIES = 10.0, 1.0 / 3.0, 2.0, 2
#: μ's floor on small meshes: below it the step's components along the near-null directions of
#: the Gauss–Newton matrix (motions that keep every image area) are set by rounding, and the maps
#: of different solvers drift apart step by step.
GN_MU_MIN = 1e-4


def damping_floor(unknowns: int) -> float:
    """The least Levenberg–Marquardt damping μ for a Gauss–Newton system of ``unknowns`` unknowns:
    ``min(GN_MU_MIN, 1 / unknowns)``.

    The damped step ``(H + μ diag H) δ = −g`` keeps the share ``λ / (λ + μ)`` of its component
    along an eigenvector of ``H`` whose eigenvalue is ``λ`` (relative to the diagonal). ``H =
    Jᵀ W J`` is a second-order difference operator on the mesh (``J`` differentiates the image
    areas), so the eigenvalues of its smooth modes, the large-scale motions that carry area
    across the disk, fall like ``1 / unknowns``: a smooth radial perturbation of an equiareal
    polar disk map has ``λ ≈ 40 / unknowns`` at 40k and at 159k unknowns (from the excess energy
    one step leaves: 0.82 % and 6.6 % at μ = 10⁻⁴, 0.13 % at both with this floor). A fixed floor
    of ``GN_MU_MIN`` keeps about a quarter of such a step at a million unknowns, where the
    descent then needs many more steps; ``1 / unknowns`` keeps nearly all of it and still damps
    the near-null modes."""
    return min(GN_MU_MIN, 1.0 / unknowns)


#: Phase A's fallback where plain SEM steps fold: at most this many damped SEM steps.
DAMPED_START = 10
#: Area continuation (:func:`_area_continuation`): run when the map phase B starts from has a
#: face whose share of the image area is below ``CROWDED`` × its share of the surface, in
#: ``CONTINUATION_STAGES`` stages of at most ``STAGE_ITER`` steps before the last.
CROWDED = 1e-3
CONTINUATION_STAGES = 8
STAGE_ITER = 60


def crowded(double_area: np.ndarray, image_double_area: np.ndarray) -> bool:
    """Whether some face's normalized area ratio ``(|f(τ)|/|f(M)|) / (|τ|/|M|)`` is below
    ``CROWDED``: a map crowded there by orders of magnitude (a Tutte or harmonic start of a
    mesh with long limbs, which SEM's plain steps could not spread without folding)."""
    q = (np.abs(image_double_area) / double_area) * (double_area.sum()
                                                     / np.abs(image_double_area).sum())
    return bool(q.min() < CROWDED)


def continuation_areas(start_double_area: np.ndarray, double_area: np.ndarray, t: float
                       ) -> np.ndarray:
    """Double areas ``A_t = a^(1 − t) A^t`` on the geometric path from the start map's normalized
    image areas ``a`` (t = 0, where that map is equiareal) to the surface's ``A`` (t = 1), scaled
    to the surface's total."""
    a = np.maximum(np.abs(start_double_area), np.finfo(float).tiny)
    log_a, log_A = np.log(a / a.sum()), np.log(double_area / double_area.sum())
    return np.exp((1.0 - t) * log_a + t * log_A) * double_area.sum()


def _area_continuation(problem, newton, f, value, opt, record, it, max_iter):
    """Phase B towards intermediate surface areas before the true ones: stage ``k = 1 …
    CONTINUATION_STAGES − 1`` descends (:func:`_descent`, at most ``STAGE_ITER`` steps) towards
    :func:`continuation_areas` at ``t = k / CONTINUATION_STAGES`` from the last stage's map.

    A map crowded to many orders of magnitude below the surface's areas (:func:`crowded`) is a
    start from which the fold-free descent on the true areas crawls: every Gauss–Newton step that
    spreads the crowded faces is cut short by the faces it would flip, for hundreds of steps
    (decimated scans of hands and heads). Each stage moves the targets by a bounded factor from
    areas at which its start is already nearly equiareal, so it starts near its own minimizer.
    Its steps are recorded as phase ``continuation`` with the energy against the surface's
    areas. Returns ``(f, evaluation, iterations)``; the caller finishes on the target areas."""
    start = value[3]

    def staged(i, g, v, alpha, kind):
        record(i, g, problem.evaluate(g, v[3]), alpha, "continuation")

    for k in range(1, CONTINUATION_STAGES):
        target = continuation_areas(start, problem.A2, k / CONTINUATION_STAGES)
        stage = problem.with_areas(target)
        newton.set_areas(target)
        f, _, it, _, _ = _descent(stage, newton, f, stage.evaluate(f, value[3]), opt, staged,
                                  it, min(max_iter, it + STAGE_ITER))
        value = problem.evaluate(f)
    newton.set_areas(problem.A2)
    return f, value, it


def _converged_iterations(problem, f, value, opt, record):
    """Phase A (plain SEM, best flip-free iterate) then phase B (monotone descent).

    Phase B's first try is, with ``descent="gauss_newton"``, the Levenberg–Marquardt step of
    :mod:`.gauss_newton` (μ lowered after a full step, raised after a damped one, raised tenfold
    and retried when no damped step lowers the energy); with ``descent="gradient"``, the
    preconditioned gradient step on the last preconditioner factor. Then the SEM and gradient
    steps, first whichever of them worked last. Gauss–Newton first moves the interior only (the
    boundary rows held, ``GaussNewton.hold_boundary``; this does most of the work); when its
    steps go quiet (``gn_tol``, ``gn_patience``) or fail, it goes on with the boundary angles as
    unknowns too (where the boundary limits the energy, the interior alone ends well above the
    long gradient schedule's map; moving the boundary from the start crawls on meshes with
    faces that have three boundary vertices). When that goes quiet, the next step is a SEM or
    gradient step, and Gauss–Newton resumes only if that step makes progress; otherwise the
    iteration ends."""
    max_iter = opt.iterations()
    gain = PHASE_A_GAIN[opt.descent]
    patience_a = opt.patience if opt.descent == "gradient" else 1
    best = (f, value) if value[2] == 0 else None
    it, since_best, g, prev = 0, 0, f, value
    while it < max_iter and since_best < patience_a:               # phase A
        g = sem_step(problem, g, problem.weights(g), opt.inversion)
        it += 1
        v = problem.evaluate(g)
        # A gain of less than `gain` of the excess energy E_S/bound − 1 counts as no progress:
        # phase B's descent is faster from there.
        fast = lambda old, r=gain: (old[1] - v[1]) >= r * (old[1] - 1.0)  # noqa: E731
        if v[2] == 0 and (best is None or v[1] < best[1][1]):
            best, since_best = (g, v), (0 if best is None or fast(best[1]) else since_best + 1)
            record(it, g, v, 1.0, "sem")
        elif not (v[2] > 0 and fast(prev, PHASE_A_UNFOLD_GAIN)):
            since_best += 1             # (a folded iterate that still improves fast is waited
        prev = v                        #  for: plain SEM often unfolds within a few steps)
    accepted = best is not None and best[0] is not f
    if best is not None:
        f, value = best
    if it < max_iter and (not accepted or (prev[2] > 0 and prev[1] < value[1])):
        # plain SEM steps fold where they would gain: Algorithm 1's damped steps take over
        f, value, it = _damped_start(problem, f, value, opt, record, it, max_iter)
    # the interior Laplacian's elimination order (PARDISO's, from the steps so far) orders the
    # Gauss–Newton system too, so that its analysis needs no nested dissection of its own (on
    # one thread: see GaussNewton)
    newton = GaussNewton(problem.F, len(problem.V), problem.I, problem.A2, opt.solver,
                         problem.B, getattr(problem.solver_I, "permutation", None)
                         ) if opt.descent == "gauss_newton" and it < max_iter else None
    try:
        if newton is None or not crowded(problem.A2, value[3]):
            return _descent(problem, newton, f, value, opt, record, it, max_iter)
        start = f, value
        f, value, it = _area_continuation(problem, newton, f, value, opt, record, it, max_iter)
        f, value, it, status, reason = _descent(problem, newton, f, value, opt, record, it,
                                                max_iter)
        if start[1][1] < value[1]:          # the continuation's map is kept only if better
            return (*start, it, status, reason + "; the area continuation ended above its "
                    "start, which is returned")
        return f, value, it, status, reason
    finally:
        if newton is not None:
            problem.gn_stats = newton.stats()
            newton.release()


def _damped_start(problem, f, value, opt, record, it, max_iter):
    """Paper mode's iterations (:func:`_paper_iterations`, at most ``DAMPED_START`` steps, kept
    only while they lower ``E_S``) from phase A's best ``f``, recorded after the ``it`` steps
    taken so far. Where the plain SEM steps fold where they would gain (meshes with many obtuse
    triangles: a decimated scan), phase A keeps a crowded map (the harmonic start, or the first
    step), from which the fold-free descent crawls; the damped SEM steps spread it first.
    Returns ``(f, evaluation, iterations)``."""
    steps = min(DAMPED_START, max_iter - it)

    def shifted(i, g, v, alpha, kind):
        if i > 0:
            record(it + i, g, v, alpha, kind)

    paper = opt.model_copy(update={"mode": "paper", "max_iter": steps,
                                   "stop_when_energy_rises": True})
    f, value, taken, _, _ = _paper_iterations(problem, f, value, paper, shifted, rounds=None)
    return f, value, it + max(taken, 1)


def _folds_more(problem: _Problem, g: np.ndarray, flipped: int) -> bool:
    """Whether the map ``g`` has more flipped faces than ``flipped``."""
    return int(np.count_nonzero(signed_double_areas(_as_uv(g), problem.F) <= 0)) > flipped


def _descent(problem, newton, f, value, opt, record, it, max_iter):
    """Phase B from ``f`` (see :func:`_converged_iterations`) up to ``max_iter`` steps in all;
    ``newton`` is the Gauss–Newton stepper or None. Returns ``(f, evaluation, iterations, status,
    reason)``."""
    status, quiet = "max_iter", 0
    reason = f"reached max_iter = {max_iter}"
    order = ["gradient", "sem"]
    age = None                      # iterations since the preconditioner was factored
    if newton is not None:
        newton.hold_boundary = True  # interior first (one analysis serves both stages)

    def turn_boundary():
        """Interior-only Gauss–Newton went quiet: go on with the boundary angles as unknowns."""
        nonlocal mu
        newton.hold_boundary = False
        mu = GN_MU_START * floor
    tol, patience = (opt.gn_tol, opt.gn_patience) if newton is not None else \
        (opt.tol, opt.patience)
    floor = damping_floor(2 * len(problem.I))    # μ's floor for the interior unknowns
    mu = GN_MU_START * floor
    boundary_turn = False           # Gauss–Newton went quiet: a SEM/gradient step's turn
    # the accuracy at which Gauss–Newton's descent counts as converged (see SEMOptions.gn_cv)
    accurate = min(opt.gn_cv ** 2, opt.gn_drop * (value[1] - 1.0))
    while it < max_iter:
        w = blocks = None               # stretch weights: only for a SEM or gradient try
        step = None
        tries = [(k, False) for k in order]
        if age is not None and age < opt.refactor_every:
            tries.insert(0, ("gradient", True))  # first: the stale preconditioner
        if newton is not None and not boundary_turn:
            tries[:0] = [("gauss_newton", False)] * (GN_RETRIES + 1)
        for kind, stale in tries:
            if kind != "gauss_newton" and w is None:
                w = problem.weights(f)
                blocks = laplacian_blocks(problem.pattern, w)
            try:
                if kind == "gauss_newton":
                    g = newton.step(f, value[3], mu)
                    # the orientation barrier shapes the next step after one that runs faces
                    # into folds (which the line search then holds back)
                    newton.barrier = BARRIER if _folds_more(problem, g, value[2]) else 0.0
                elif kind == "gradient":
                    g = gradient_step(problem, f, w, blocks, refactor=not stale)
                    age = age + 1 if stale else 0
                else:
                    g = sem_step(problem, f, w, opt.inversion)
            except NotPositiveDefinite:
                if kind == "gauss_newton":
                    mu *= 10.0
                continue
            step = line_search(problem, f, g, value, lambda v: v[1] < value[1],
                               opt.min_step, hold=True,
                               max_step=1.0 if kind == "gauss_newton" else opt.max_step)
            if kind == "gauss_newton":
                if step is not None:
                    mu = max(mu * (GN_MU_DOWN if step[2] == 1.0 else GN_MU_UP), floor)
                    break
                mu *= 10.0
                continue
            if step is not None and not (stale and step[2] < 1.0):
                break
            step = None                 # a damped stale step: refactor and try again
        if step is None and newton is not None and newton.hold_boundary:
            turn_boundary()
            continue
        if step is None:
            status = "stalled" if quiet < patience else "converged"
            reason = (f"no Gauss–Newton, SEM or gradient step down to α = {opt.min_step:g} "
                      "lowers the energy ratio without flipping a face")
            break
        it += 1
        if kind in order and kind != order[0]:
            order.reverse()             # try first what worked last
        g, new, alpha = step
        quiet = quiet + 1 if (value[1] - new[1]) < tol * value[1] else 0
        f, value = g, new
        record(it, f, value, alpha, kind)
        if newton is not None and value[1] - 1.0 <= accurate:
            status = "converged"
            reason = (f"the stretch is uniform to {opt.gn_cv:g} (coefficient of variation) and "
                      f"the excess energy ratio fell to {opt.gn_drop:g} of where the descent "
                      "started")
            break
        if boundary_turn and quiet == 0:
            boundary_turn = False       # the boundary moved: Gauss–Newton again
        elif quiet >= patience and kind == "gauss_newton" and newton.hold_boundary:
            turn_boundary()             # interior-only went quiet: the boundary moves too
            quiet = 0
        elif quiet >= patience and kind == "gauss_newton":
            boundary_turn = True        # Gauss–Newton went quiet: a SEM step's turn
        elif quiet >= patience:
            status = "converged"
            reason = (f"the energy ratio fell by less than {tol:g} (relative) in "
                      f"{patience} steps in a row")
            break
    return f, value, it, status, reason
