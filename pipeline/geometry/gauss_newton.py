"""Gauss–Newton (Levenberg–Marquardt) steps on the stretch energy over the interior vertices.

The stretch energy (eq. 15) is a sum of squares, ``E_S(f) = Σ_τ |f(τ)|² / |τ| = ½ Σ_τ r_τ²``
with residuals ``r_τ = a_τ(f) / √(A_τ)``, where ``a_τ = 2|f(τ)|`` is the signed double area of
the image face, quadratic in the image points, and ``A_τ = 2|τ|``. With the boundary held,
minimizing ``E_S`` over the interior points equalizes ``a_τ / A_τ`` (Cauchy–Schwarz, eq. 15's
bound), i.e. makes the map equiareal. With ``J = ∂a/∂f_I`` (one row per face, the derivatives
``∂a_τ/∂u_i = v_j − v_k``, ``∂a_τ/∂v_i = u_k − u_j`` for a face ``[i, j, k]``), the gradient is
``g = Jᵀ W a`` and the Gauss–Newton matrix ``H = Jᵀ W J`` with ``W = diag(1/A_τ)``; the step is

    (H + μ diag H) δ = −g,      f_I ← f_I + δ

(Levenberg–Marquardt damping ``μ``; ``H + μ diag H`` is SPD for ``μ > 0``). With ``barrier``
set (the caller does after a step that ran faces into folds), the sums are those of ``E_S``
plus an orientation barrier ``−β c² Σ A log a`` (:func:`barrier_terms`), which keeps the step
from running nearly flat image faces into folds.

With ``boundary`` given, the boundary points move too, along the unit circle: each is
``f_b = e^{iθ_b}`` with its angle as the unknown (``∂a_τ/∂θ_b = −v_b ∂a_τ/∂u_b + u_b ∂a_τ/∂v_b``),
and after the step ``f_b ← f_b e^{iδθ_b}`` stays on the circle, as eq. (21) keeps it. The image
area ``|f(M)|`` then changes with the step, and ``E_S`` alone would be lowered by shrinking it;
so the residuals become ``r_τ = (a_τ − c A_τ) / √A_τ`` with ``c = Σ a / Σ A`` held at the current
map: the Gauss–Newton form of matching every image area to ``|τ| |f(M)| / |M|``, whose
minimizer is the equality case of eq. (15)'s Cauchy–Schwarz bound. For the interior alone this
is the same step (``Σ_τ a_τ`` does not depend on interior points). ``hold_boundary`` takes
interior-only steps on the same system (the boundary rows decoupled by a huge diagonal), so
that turning the boundary loose later needs no new analysis. It uses the
curvature of the area constraints that the Laplacian preconditioner of the gradient step in
:mod:`.sem` lacks, which is why it needs few steps where preconditioned gradient steps need
hundreds. The unknowns are ``[u_I; v_I]``; the pattern of ``H``'s upper triangle (the 2×2-block
vertex adjacency) and where every face's 21 products land in its ``data`` are computed once, so
each step assembles that triangle and ``g`` in one compiled pass over the faces
(:func:`._kernels.disk_gauss_newton_terms`) and refactors it as it is (the solvers'
``upper=True``) on a kept analysis.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ._kernels import disk_gauss_newton_terms, face_pair_pattern
from .solvers import make_solver

#: ``hold_boundary``: the boundary angles' diagonal is scaled by this, so their coupling to the
#: interior step is ~1/HOLD of it (the step is the interior-only one to rounding) while the
#: system keeps its pattern and PARDISO/CHOLMOD their analysis for when the boundary moves
HOLD = 1e12
#: weight β of the orientation barrier that shapes a step (:func:`barrier_terms`; the caller
#: sets ``GaussNewton.barrier``), and the excess energy ratio at or below which it is left out
BARRIER = 0.1
BARRIER_EXCESS = 1e-3


def barrier_terms(a2: np.ndarray, residual: np.ndarray, double_area: np.ndarray, beta: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and weights that make the Gauss–Newton sums those of the per-face objective
    ``ψ(a) = r(a)² / (2A) − β c² A log a`` (``r`` the area residual, ``c = Σa / ΣA``).

    The assembly adds ``d w r`` to the gradient and ``d dᵀ w`` to the matrix for a face's area
    derivatives ``d``; with ``w = ψ''(a) = 1/A + β c² A / a²`` and ``r' = ψ'(a) / ψ''(a)``,
    ``ψ'(a) = r/A − β c² A / a``, it gives Gauss–Newton on ``ψ``. The barrier's curvature
    ``β c² A / a²`` exceeds the area term's ``1/A`` only on faces whose normalized ratio
    ``a / (cA)`` is below ``√β``, and grows without bound as such a face tends to zero area, so
    the step moves the corners of nearly flat image faces less and pushes their area up
    (Newton on ``−log a`` at most doubles ``a``) instead of running them into the fold that the
    flip holding would stop at. Steps are still accepted on ``E_S`` alone
    (:func:`pipeline.geometry.sem.line_search`): the barrier shapes the direction only. It is
    left out (β = 0) once the excess energy ratio ``R − 1`` is at most ``BARRIER_EXCESS``, so
    that close to the minimizer the steps are Gauss–Newton's on ``E_S`` and converge to it.

    Parameters
    ----------
    a2 : (m,) float
        Signed double image areas (all positive on a fold-free map).
    residual : (m,) float
        The area residuals ``r`` (``a``, or ``a − cA`` with the boundary moving).
    double_area : (m,) float
        The target double areas ``A``.
    beta : float
        The barrier weight ``β``.

    Returns
    -------
    (residual, weight) : two (m,) float arrays
        ``r' = ψ'/ψ''`` and ``w = ψ''``.
    """
    c = a2.sum() / double_area.sum()
    a = np.maximum(a2, np.finfo(float).tiny)
    excess = float(np.sum(a2 * a2 / double_area)) / (c * c * double_area.sum()) - 1.0
    beta = beta if excess > BARRIER_EXCESS else 0.0
    push = beta * c * c * double_area / a
    weight = 1.0 / double_area + push / a
    return (residual / double_area - push) / weight, weight


def block_ordering(interior_order: np.ndarray, cols: np.ndarray, nI: int, N: int) -> np.ndarray:
    """A fill-reducing elimination order of the Gauss–Newton system from one of the interior
    Laplacian ``L_II`` (the SEM solver's, already computed), instead of a new nested dissection
    of the system's twice larger graph.

    The system's graph is the interior vertex graph with every vertex split into its two
    unknowns ``u_i`` (column ``i``) and ``v_i`` (``nI + i``), plus the boundary angles
    (columns ``2 nI …``): each vertex's pair takes its place in ``interior_order``, and each
    boundary angle comes right after the last of the interior vertices it shares a face with
    (a boundary angle joins the separator of its latest neighbour; eliminated after all of
    them, it adds no fill between branches; eliminated first, the angles along the rim chain
    into each other's fill). The factor has as many entries as with PARDISO's own nested
    dissection of the system (within 0.3 % on choi_hand and at 1M faces), and the analysis
    skips the ordering (at 1M faces, 2.4 s of one thread). :class:`GaussNewton` gives it to
    PARDISO on one thread only (a given order makes its solves sequential, see
    :class:`.solvers.PardisoSolver`).

    Parameters
    ----------
    interior_order : (nI,) int
        A new-order list of ``L_II``'s unknowns: ``interior_order[k]`` is eliminated ``k``-th.
    cols : (m, 6) int
        Every face's unknowns as :class:`GaussNewton` numbers them (the first three: each
        corner's ``u`` column, or its boundary angle's).
    nI, N : int
        Interior vertices and unknowns in all.

    Returns
    -------
    (N,) int32
        The same form for the system's unknowns.
    """
    position = np.empty(nI, dtype=np.int64)
    position[interior_order] = np.arange(nI)
    key = np.empty(N)
    key[:nI] = 2 * position
    key[nI:2 * nI] = 2 * position + 1
    if N > 2 * nI:
        c = cols[:, :3]
        interior = (c >= 0) & (c < nI)
        latest = np.where(interior, key[np.where(interior, c, 0)] + 1, -1.0).max(axis=1)
        angle = c >= 2 * nI
        after = np.full(N - 2 * nI, -1.0)
        np.maximum.at(after, c[angle] - 2 * nI, np.broadcast_to(latest[:, None], c.shape)[angle])
        key[2 * nI:] = after + 0.5
    return np.argsort(key, kind="stable").astype(np.int32)


#: Gauss–Newton systems of at least this many unknowns are factored in single precision where
#: the solver can (PARDISO: ``PardisoSolver(single=True)``) and each step solved to a relative
#: residual of ``STEP_RTOL`` by refinement in double precision: an inexact Newton step (the
#: Levenberg–Marquardt damping and the line search decide the step anyway). Measured with
#: PARDISO on two threads: at 1.07M faces (2.1M unknowns) a refactorization 1.14 → 0.8 s,
#: the same 21 steps to as good a map, converged mode 39.7 → 35 s (30.5 s without the
#: reproducible mode's slower solves, see :class:`.solvers.PardisoSolver`); at 363k faces
#: the same time in about as many steps (23 → 24); at 100k faces (choi_hand,
#: choi_human_brain) within ±0.1 s either way, hence the threshold. Smaller systems, and the
#: other solvers, factor in double precision: their maps equal other solvers' to rounding.
SINGLE_ABOVE = 200_000
#: the relative residual ``‖g − H δ‖ / ‖g‖`` a single-precision Gauss–Newton step is solved to
#: (1e-3 took 30 steps instead of 23 at 363k faces; 1e-5 costs a second refinement at 2.1M)
STEP_RTOL = 1e-4


class GaussNewton:
    """Levenberg–Marquardt steps on ``E_S`` for the interior of a disk map, boundary held."""

    def __init__(self, F: np.ndarray, n: int, interior: np.ndarray, double_area: np.ndarray,
                 solver_kind: str, boundary: np.ndarray | None = None,
                 interior_order: np.ndarray | None = None):
        nI = len(interior)
        nB = 0 if boundary is None else len(boundary)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self.interior, self.nI, self.boundary = interior, nI, boundary
        self.double_area = double_area
        self.inv_area = 1.0 / double_area
        col = np.full(n, -1, dtype=np.int64)
        col[interior] = np.arange(nI)
        c = col[F]
        v_cols = np.where(c >= 0, c + nI, -1)
        if nB:
            # a boundary corner: its angle θ_b in the u slot, nothing in the v slot
            bcol = np.full(n, -1, dtype=np.int64)
            bcol[boundary] = 2 * nI + np.arange(nB)
            self.on_boundary = bcol[F] >= 0                                       # m×3
            c = np.where(self.on_boundary, bcol[F], c)
        else:
            self.on_boundary = None
        self.cols = np.ascontiguousarray(np.concatenate([c, v_cols], axis=1))   # m×6
        N = 2 * nI + nB
        indptr, indices, self.face_slots = face_pair_pattern(self.cols, N)
        self.n_upper = len(indices)
        # H's upper triangle is what the solvers factor (``upper=True``); rows sorted, so each
        # row's diagonal entry comes first
        self.H_upper = sp.csr_matrix((np.empty(self.n_upper), indices, indptr), shape=(N, N))
        self.diagonal = indptr[:-1].astype(np.int64)
        self.corner_flags = np.ascontiguousarray(
            np.zeros(F.shape, dtype=np.uint8) if self.on_boundary is None
            else self.on_boundary.astype(np.uint8))
        self.solver = make_solver(solver_kind, refactored=True)
        if hasattr(self.solver, "single") and N >= SINGLE_ABOVE:
            self.solver.single, self.solver.rtol = True, STEP_RTOL
        if interior_order is not None and len(interior_order) == nI \
                and hasattr(self.solver, "ordering") and self.solver.threads_for(N) == 1:
            # (on more threads PARDISO's own METIS ordering keeps the ~20 solves parallel)
            self.solver.ordering = block_ordering(interior_order, self.cols, nI, N)
        self.factorizations = 0
        self.hold_boundary = False
        self.barrier = 0.0            # β of barrier_terms (0: Gauss–Newton on E_S alone)

    def step(self, f: np.ndarray, a2: np.ndarray, mu: float) -> np.ndarray:
        """The damped Gauss–Newton map from ``f`` (complex, one value per vertex) whose signed
        double image areas are ``a2``: interior moved by ``δ``, boundary unchanged or (with
        ``boundary``) turned along the circle. Raises :class:`.solvers.NotPositiveDefinite` if
        the factorization fails."""
        moving = self.on_boundary is not None and not self.hold_boundary
        residual = a2
        if moving:
            residual = a2 - (a2.sum() / self.double_area.sum()) * self.double_area
        weight = self.inv_area
        if self.barrier > 0:
            residual, weight = barrier_terms(a2, residual, self.double_area, self.barrier)
        N = self.H_upper.shape[0]
        g = np.empty(N)
        H = self.H_upper
        disk_gauss_newton_terms(self.F, np.ascontiguousarray(f, dtype=np.complex128),
                                np.ascontiguousarray(residual, dtype=np.float64), weight,
                                self.cols, self.corner_flags, self.face_slots, H.data, g)
        H.data[self.diagonal] *= 1.0 + mu
        if self.on_boundary is not None and not moving:
            g[2 * self.nI:] = 0.0
            H.data[self.diagonal[2 * self.nI:]] *= HOLD
        self.solver.factorize(H, upper=True)
        self.factorizations += 1
        x = self.solver.solve(g)
        out = f.copy()
        nI = self.nI
        out[self.interior] = f[self.interior] - (x[:nI] + 1j * x[nI:2 * nI])
        if moving:
            out[self.boundary] = f[self.boundary] * np.exp(-1j * x[2 * nI:])
        return out

    def stats(self) -> dict:
        """Factorizations so far, and with a single-precision factor its refinement steps and
        double-precision fallbacks (:class:`.solvers.PardisoSolver`)."""
        out = {"factorizations": self.factorizations}
        if getattr(self.solver, "single", False):
            out.update(self.solver.refinement_stats)
        return out

    def set_areas(self, double_area: np.ndarray) -> None:
        """Aim the steps at other double areas ``A_τ`` (an area continuation's stage)."""
        self.double_area = double_area
        self.inv_area = 1.0 / double_area

    def release(self) -> None:
        self.solver.release()
