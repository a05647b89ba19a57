"""Gauss–Newton (Levenberg–Marquardt) minimization of the spherical stretch energy with a
fold barrier.

Notation as in :mod:`.sphere`: ``S`` (n, 3) unit vectors, faces ``F`` outward, surface double
areas ``A_τ = 2|τ|``, ``p_τ = A_τ / Σ A``. Two image areas per face:

* the flat double area ``a_τ = |(s_j − s_i) × (s_k − s_i)| = 2|f(τ)|`` of eq. (15), whose
  stretch-energy ratio is the objective of the disk paper,
  ``R = E_S |M| / (Σ|f(τ)|)² = Σ_τ q_τ² / p_τ``, ``q_τ = a_τ / Σ a`` (so ``R − 1`` is the χ²
  divergence of ``q`` from ``p``: ≥ 0, = 0 iff equiareal);
* the orientation ``b_τ = det[s_i, s_j, s_k]`` (six times the volume of the tetrahedron on the
  origin), positive iff the spherical triangle is not folded. For a small triangle
  ``b ≈ a``; it falls to 0 where ``a`` need not — a long thin triangle whose vertices are near
  one great circle — which is how a map can approach a fold with no change in the stretch
  energy.

The objective is

    Φ_κ(S) = (R − 1) + κ KL(p ‖ b / Σ b),   KL(p ‖ r) = Σ_τ p_τ log(p_τ / r_τ),

with ``Φ = ∞`` when some ``b_τ ≤ 0``. The relative entropy is zero exactly where ``b ∝ p`` and
tends to infinity as a triangle approaches a fold, so it is a barrier that keeps every iterate
fold free without being a penalty on the equiareal maps themselves: for small triangles both
terms are minimized by the same maps. Its pull on crushed faces (``∂/∂b_τ = −p_τ / b_τ``)
also spreads crowded limbs, where the stretch energy's pull is bounded
(``∂R/∂a_τ ∝ a_τ/A_τ − E_S/Σa``) — up to a point: with faces crowded to many orders of
magnitude below their share, the weights ``p_τ/b_τ²`` make the system too ill-conditioned to
start, which is why :func:`.sphere.spherical_sem` runs its hemisphere free phase first, and
its area continuation (target areas moved in stages from the start's own image areas) when
the minimization stalls all the same.
``κ`` goes down a schedule (a barrier method; 2, 0.2, 0.02 by default). Where flat areas and
orientations differ (large or long thin image triangles), the last ``κ`` shifts the minimizer
of ``R`` by a little; a schedule may end at 0, where steps are still rejected if they fold a
face.

Each vertex moves in its tangent plane, ``s_i ↦ normalize(s_i + x_i e¹_i + y_i e²_i)``. With
``∇_i a_τ = n̂_τ × (s_k − s_j)`` and ``∇_i b_τ = s_j × (s_k − s_j)`` at corner ``i`` of
``τ = (i, j, k)`` (``n̂_τ`` the unit normal of the flat image triangle) projected on the
tangent bases, the Gauss–Newton matrix is the sum of one rank-one 6×6 term per face and area,

    H = Σ_τ 2 Σ A / (Σ a)² · ∇a_τ ∇a_τᵀ / A_τ + κ Σ_τ p_τ ∇b_τ ∇b_τᵀ / b_τ²

(the second derivatives of ``a`` and ``b`` and the rank-one terms of the normalizations left
out), the gradient ``g`` is exact, and a step solves the Levenberg–Marquardt system

    (H + μ L_f) δ = −g

with ``L_f`` the stretch Laplacian of the current map (eq. 12 weights, clamped positive) acting
on the 3D displacements ``δ_i = x_i e¹_i + y_i e²_i``: rotations of the whole map are a null
space of ``H``, and the Laplacian damping makes the system SPD and large-``μ`` steps smooth
(``μ → ∞`` is the Laplacian-preconditioned gradient of :func:`.sphere._gradient_phase`). The
curvature of the area constraints in ``H`` is what the hemisphere iteration and the
preconditioned gradient lack: they slow down on long limbs, whose image must move as a whole.
A step ``t δ`` is tried for ``t = 1, ½, …`` (with the vertex-wise damping of
:func:`.sphere_base.shrink_folding_steps` at faces it would fold) and kept if ``Φ`` falls; ``μ``
shrinks after full steps and grows after short or failed ones. The unknowns are interleaved
(``x_i, y_i`` adjacent); the pattern of ``H``'s upper triangle (2×2 blocks on the vertex
adjacency) and where each face's 21 products land in its ``data`` are computed once
(:func:`._kernels.face_pair_pattern`, as for the disk), so a step is one compiled pass over the
faces (:func:`._kernels.sphere_gauss_newton_terms`) and a refactorization of that triangle as
it is (the solvers' ``upper=True``) on a kept analysis (supernodal, nested dissection; the system Jacobi-scaled first, since the barrier
weights span many orders of magnitude).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from . import _kernels
from .laplacian import face_double_areas
from .solvers import CholmodSolver, NotPositiveDefinite, make_solver
from .sphere_base import energy_ratio, shrink_folding_steps, triple_products

#: the 21 pairs ``a ≤ b`` of a face's local unknowns (x_0, y_0, x_1, y_1, x_2, y_2)
_PAIRS = np.array([(a, b) for a in range(6) for b in range(a, 6)], dtype=np.int64)
_PAIR_INDEX = {(int(a), int(b)): q for q, (a, b) in enumerate(_PAIRS)}
#: corner c and the two corners (j, k) that follow it counter-clockwise
_CORNERS = ((0, 1, 2), (1, 2, 0), (2, 0, 1))


def _pair(a: int, b: int) -> int:
    return _PAIR_INDEX[(min(a, b), max(a, b))]


_PAIR_TABLE = np.array([[_pair(a, b) for b in range(6)] for a in range(6)], dtype=np.int64)


def tangent_basis(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent vectors ``(e¹, e²)`` at every unit vector of ``S`` (n, 3), with
    ``e¹ × e² = s``: ``e¹`` is ``s ×`` the coordinate axis least aligned with ``s``."""
    axis = np.argmin(np.abs(S), axis=1)
    a = np.zeros_like(S)
    a[np.arange(len(S)), axis] = 1.0
    e1 = np.cross(S, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(S, e1)
    return e1, e2


def orientations(S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``b_τ = det[s_i, s_j, s_k]`` per face (see :func:`.sphere_base.triple_products`)."""
    return triple_products(S, F)


def objective(A2: np.ndarray, S: np.ndarray, F: np.ndarray, kappa: float) -> float:
    """``Φ_κ = (R − 1) + κ KL(p ‖ b/Σb)``; ``inf`` if a face is folded (``b_τ ≤ 0``)."""
    b = orientations(S, F)
    if not np.all(b > 0):
        return np.inf
    a = face_double_areas(S, F)
    M, sa = A2.sum(), a.sum()
    value = float(np.sum(a * a / A2) * M / (sa * sa)) - 1.0
    if kappa:
        p = A2 / M
        value += kappa * float(np.sum(p * np.log(p * b.sum() / b)))
    return value


class SphereGaussNewton:
    """Levenberg–Marquardt steps on ``Φ_κ`` for a spherical map of the faces ``F`` whose
    surface double areas are ``A2``; every vertex free."""

    def __init__(self, F: np.ndarray, n: int, A2: np.ndarray, solver_kind: str = "auto"):
        self.F, self.n, self.A2 = F, n, A2
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self.A2 = np.ascontiguousarray(A2, dtype=np.float64)
        self.p = self.A2 / self.A2.sum()
        self.cols = np.empty((len(F), 6), dtype=np.int64)
        self.cols[:, 0::2], self.cols[:, 1::2] = 2 * F, 2 * F + 1
        N = 2 * n
        # H's upper triangle (CSR, sorted rows, each row's diagonal entry first) is what the
        # solvers factor (``upper=True``); ``slot`` says where each face's 21 products land
        indptr, indices, slot = _kernels.face_pair_pattern(self.cols, N)
        self.slot, self.n_upper = slot.ravel(), len(indices)
        self.H = sp.csr_matrix((np.empty(self.n_upper), indices, indptr), shape=(N, N))
        self.rows = np.repeat(np.arange(N), np.diff(indptr))
        self.diagonal = indptr[:-1].astype(np.int64)
        # supernodal Cholesky on nested dissection: on the 2×2-block pattern, denser than a
        # Laplacian's, the simplicial factor of ``refactored=True`` is slower
        self.solver = make_solver(solver_kind, refactored=False)
        if isinstance(self.solver, CholmodSolver):
            self.solver.ordering = "nesdis"
        self.factorizations = 0
        self._system = None

    def _assemble(self, local: np.ndarray) -> np.ndarray:
        """The upper triangle's values from every face's 21 local products (m, 21)."""
        return np.bincount(self.slot, weights=local.ravel(), minlength=self.n_upper)

    def linearize(self, S: np.ndarray, kappa: float) -> None:
        """Gradient, Gauss–Newton matrix and damping matrix of ``Φ_κ`` at ``S`` (fold free),
        kept for :meth:`direction`: one compiled pass over the faces
        (:func:`._kernels.sphere_gauss_newton_terms`; :meth:`_linearize_numpy` is its
        reference)."""
        S = np.ascontiguousarray(S, dtype=np.float64)
        e1, e2 = tangent_basis(S)
        H_upper, D_upper = np.zeros(self.n_upper), np.zeros(self.n_upper)
        g = np.zeros(2 * self.n)
        _kernels.sphere_gauss_newton_terms(S, self.F, e1, e2, self.A2, self.p, float(kappa),
                                           self.slot, _PAIR_TABLE, H_upper, D_upper, g)
        self._system = (H_upper, g, e1, e2, D_upper)

    def _linearize_numpy(self, S: np.ndarray, kappa: float) -> None:
        """:meth:`linearize` in numpy (the formulas of the module docstring)."""
        F = self.F
        P = [S[F[:, c]] for c in range(3)]
        e1, e2 = tangent_basis(S)
        E = [(e1[F[:, c]], e2[F[:, c]]) for c in range(3)]

        def local(grads):
            d = np.empty((len(F), 6))
            for c in range(3):
                d[:, 2 * c] = np.einsum("ij,ij->i", grads[c], E[c][0])
                d[:, 2 * c + 1] = np.einsum("ij,ij->i", grads[c], E[c][1])
            return d

        edge = [P[k] - P[j] for _, j, k in _CORNERS]                 # opposite corner c
        N = np.cross(P[1] - P[0], P[2] - P[0])
        a = np.linalg.norm(N, axis=1)
        nh = N / a[:, None]
        b = np.einsum("ij,ij->i", P[0], N)
        d_a = local([np.cross(nh, edge[c]) for c in range(3)])
        M, sa = self.A2.sum(), a.sum()
        scale = 2.0 * M / (sa * sa)
        energy = float(np.sum(a * a / self.A2))
        coef = scale * (a / self.A2 - energy / sa)                    # ∂R/∂a_τ
        g_local = d_a * coef[:, None]
        weight = scale / self.A2
        products = d_a[:, _PAIRS[:, 0]] * d_a[:, _PAIRS[:, 1]] * weight[:, None]
        if kappa:
            d_b = local([np.cross(P[j], edge[c]) for c, j, _ in _CORNERS])
            g_local += d_b * (kappa * (1.0 / b.sum() - self.p / b))[:, None]
            products += d_b[:, _PAIRS[:, 0]] * d_b[:, _PAIRS[:, 1]] * \
                (kappa * self.p / (b * b))[:, None]
        g = np.bincount(self.cols.ravel(), weights=g_local.ravel(), minlength=2 * self.n)
        # damping: ½ Σ_τ Σ_(j,k) w |δ_j − δ_k|², w = ½ (eq. 12 corner term, clamped > 0)
        cot = np.empty((len(F), 3))
        for c, j, k in _CORNERS:
            cot[:, c] = -np.einsum("ij,ij->i", edge[k], edge[j]) / self.A2
        w = 0.5 * np.maximum(cot, 1e-3 * np.abs(cot).mean())
        damp = np.zeros((len(F), len(_PAIRS)))
        for c, j, k in _CORNERS:
            for u in (j, k):
                damp[:, _pair(2 * u, 2 * u)] += w[:, c]
                damp[:, _pair(2 * u + 1, 2 * u + 1)] += w[:, c]
            for sj in range(2):
                for sk in range(2):
                    q = _pair(2 * j + sj, 2 * k + sk)
                    damp[:, q] -= w[:, c] * np.einsum("ij,ij->i", E[j][sj], E[k][sk])
        self._system = (self._assemble(products), g, e1, e2, self._assemble(damp))

    def direction(self, mu: float) -> np.ndarray:
        """The tangent step (n, 3 vectors) of ``(H + μ L_f) δ = −g`` at the linearized map.
        Raises :class:`.solvers.NotPositiveDefinite` if the factorization fails."""
        data, g, e1, e2, damp = self._system
        values = data + mu * damp
        # Jacobi scaling D^-1/2 (H + μL) D^-1/2: the barrier's weights p/b² of crushed faces
        # of a Tutte start span many orders of magnitude, beyond what the factorization's
        # pivots can take unscaled
        d = 1.0 / np.sqrt(values[self.diagonal])
        self.H.data = values * d[self.rows] * d[self.H.indices]
        self.H.data[self.diagonal] += 1e-9
        self.solver.factorize(self.H, upper=True)
        self.factorizations += 1
        x = -d * self.solver.solve(d * g)
        return x[0::2, None] * e1 + x[1::2, None] * e2

    def release(self) -> None:
        self.solver.release()


def minimize(F: np.ndarray, A2: np.ndarray, S: np.ndarray, kappas=(2.0, 0.2, 0.02),
             deadline: float = np.inf, max_iter: int = 500, tol: float = 1e-2,
             patience: int = 3, floor: float = 1e-4, solver: str = "auto", mu: float = 1e-3,
             min_step: float = 1.0 / 16, restarts: int = 2, history: list | None = None,
             clock_start: float | None = None, accept: float = 1e-3
             ) -> tuple[np.ndarray, str, int]:
    """Minimize ``Φ_κ`` from the fold-free map ``S`` down the barrier schedule ``kappas``.

    A stage ends after ``patience`` iterations in a row that lower ``Φ_κ`` by less than
    ``tol`` (relative), when no step lowers it (``μ`` beyond 1e8), or once ``R − 1 ≤ floor``
    (the energy at its bound to that precision); at the last stage's end, if it stalled above
    the floor, the schedule starts again from its first ``κ`` (at most ``restarts`` times, and
    only while a pass lowers ``R``), since a strong barrier moves the map off the nearly folded
    triangles at which the weak one stalls. The end is convergence if ``R − 1 ≤ accept``;
    a map that stalls further from the bound (a start crowded beyond what the steps can
    spread) ends "stalled", so that callers can tell.

    Parameters
    ----------
    F : (m, 3) int array, outward faces
    A2 : (m,) float array
        Surface double areas ``2|τ|``.
    S : (n, 3) float array
        The start: unit vectors, no folded face.
    deadline : float
        ``time.perf_counter()`` value after which no iteration starts (status "time_limit").
    mu, min_step : float
        Initial Levenberg–Marquardt damping; the shortest step ``t`` tried.
    accept : float
        Largest ``R − 1`` reported as "converged" when the minimization stops above ``floor``
        (``√accept`` bounds the face-based distortion, see :mod:`.sphere`).
    history : list, optional
        Receives one dict per iteration (``kappa``, ``objective``, ``energy_ratio``,
        ``folded_faces``, ``step``, ``damping``, ``seconds`` since ``clock_start``).

    Returns
    -------
    S : (n, 3) float array
        Fold free.
    status : {"converged", "stalled", "time_limit", "max_iter"}
    iterations : int
    """
    S = np.asarray(S, dtype=np.float64)
    gn = SphereGaussNewton(F, len(S), A2, solver)
    stage, kappa = 0, kappas[0]
    value = objective(A2, S, F, kappa)
    if not np.isfinite(value):
        raise ValueError("the start map has folded faces")
    quiet, status, it = 0, "max_iter", 0
    restart_ratio = np.inf
    t0 = time.perf_counter() if clock_start is None else clock_start
    try:
        while it < max_iter:
            if time.perf_counter() > deadline:
                status = "time_limit"
                break
            it += 1
            gn.linearize(S, kappa)
            found = None
            while mu < 1e8 and found is None:
                try:
                    D = gn.direction(mu)
                except NotPositiveDefinite:
                    mu *= 4
                    continue
                t = 1.0
                while t >= min_step:
                    C = shrink_folding_steps(S, S + D, F, t, 0)
                    c_value = objective(A2, C, F, kappa)
                    if c_value < value:
                        found = (C, c_value, t)
                        break
                    t /= 2
                if found is None:
                    mu *= 4
            decrease = 0.0
            if found is not None:
                C, c_value, t = found
                decrease = (value - c_value) / value
                S, value = C, c_value
                mu = max(mu / 3, 1e-10) if t == 1.0 else mu * 2
            ratio = energy_ratio(A2, S, F)
            if history is not None:
                history.append({"iteration": it, "phase": "newton", "kappa": kappa,
                                "objective": value, "energy_ratio": ratio, "folded_faces": 0,
                                "step": None if found is None else t, "damping": mu,
                                "seconds": time.perf_counter() - t0})
            quiet = quiet + 1 if decrease < tol else 0
            if found is None or quiet >= patience or ratio - 1.0 <= floor:
                if stage == len(kappas) - 1:
                    if ratio - 1.0 <= floor or restarts == 0 or \
                            ratio > restart_ratio * (1 - tol):
                        status = "converged" if ratio - 1.0 <= accept else "stalled"
                        break
                    # stalled above the floor: once more down the schedule (see above)
                    restarts, restart_ratio, stage = restarts - 1, ratio, -1
                stage, quiet = stage + 1, 0
                kappa = kappas[stage]
                value = objective(A2, S, F, kappa)
                mu = max(mu, 1e-3)
    finally:
        gn.release()
    return S, status, it
