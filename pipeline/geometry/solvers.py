"""Sparse symmetric positive definite solves with the symbolic analysis reused.

Every SEM iteration solves ``L_II X = B`` (and the small ``L_BB`` system) with the same sparsity
pattern and new values (Remark 1 of the paper: both blocks are SPD when the weights are
positive). The fast path is CHOLMOD through scikit-sparse: the fill-reducing ordering and the
symbolic factorization are computed on the first call and every later call only refactors
numerically (``cholesky_inplace``). The fallback is SciPy's SuperLU in symmetric mode (it cannot
keep an analysis between calls). Both take real right-hand sides with two columns (the real and
imaginary parts of the complex map), never a complex one (see ``shared/docs/SOLVERS.md``).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import UserError

SOLVER_KINDS = ("auto", "cholmod", "scipy")


def cholmod_available() -> bool:
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


class NotPositiveDefinite(RuntimeError):
    """The matrix handed to the Cholesky solver is not SPD (negative weights dominate)."""


def _as_csc_symmetric(A: sp.spmatrix) -> sp.csc_matrix:
    """CSC form of a symmetric matrix without a conversion: the CSR arrays of ``A`` are the CSC
    arrays of ``Aᵀ = A``."""
    if sp.isspmatrix_csr(A):
        return sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
    return A.tocsc()


#: Below this many unknowns a refactored Laplacian gets CHOLMOD's simplicial LDLᵀ factor, above
#: it the supernodal LLᵀ one (both on nested dissection): timed on disk Laplacians of 5k–534k
#: unknowns with SEM's ~13 solves per refactorization, simplicial is faster below this size.
#: One-off and denser (biharmonic) systems keep supernodal LLᵀ: see :class:`CholmodSolver`.
SIMPLICIAL_BELOW = 60_000


class CholmodSolver:
    """CHOLMOD with the analysis done once and numeric refactorizations after that.

    ``refactored=True`` says the matrices are Laplacians refactored and solved many times (SEM):
    the ordering is then nested dissection, and below ``SIMPLICIAL_BELOW`` unknowns the factor is
    simplicial LDLᵀ. Otherwise (one-off solves, denser patterns such as the biharmonic, where the
    simplicial factor is slower) it is supernodal LLᵀ. Supernodal LLᵀ stops at a non-positive
    pivot by itself; LDLᵀ would go on through negative pivots and solve an indefinite system, so
    its pivots ``D`` are checked after every factorization (Sylvester's law of inertia: A is SPD
    iff all are positive)."""

    name = "cholmod"

    def __init__(self, ordering: str | None = None, refactored: bool = False):
        self._factor = None
        self._simplicial = False
        self._valid = False      # False after a failed refactorization (analysis kept)
        self.ordering = ordering
        self.refactored = refactored

    def factorize(self, A: sp.spmatrix) -> None:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        A = _as_csc_symmetric(A)
        self._valid = False
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # CHOLMOD warns (not raises) on some non-SPD input
            try:
                if self._factor is None:
                    n = A.shape[0]
                    self._simplicial = self.refactored and n < SIMPLICIAL_BELOW
                    # nested dissection: less fill than AMD on disk Laplacians, so each
                    # refactor and solve is cheaper; its costlier analysis runs once and is
                    # repaid within a few refactors, hence only for refactored systems
                    ordering = self.ordering or ("nesdis" if self.refactored else "default")
                    self._factor = cholesky(
                        A, mode="simplicial" if self._simplicial else "supernodal",
                        ordering_method=ordering)
                else:
                    self._factor.cholesky_inplace(A)
            except (CholmodNotPositiveDefiniteError, Warning) as exc:
                raise NotPositiveDefinite(str(exc)) from exc
        if self._simplicial and not np.all(self._factor.D() > 0):
            raise NotPositiveDefinite("matrix is not positive definite (LDLᵀ pivot ≤ 0)")
        self._valid = True

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._factor(B)

    def has_factor(self) -> bool:
        return self._factor is not None and self._valid

    def release(self) -> None:
        self._factor = None
        self._valid = False


class ScipySolver:
    """SuperLU with a COLAMD ordering applied symmetrically and no pivoting (SPD input).

    COLAMD rather than ``MMD_AT_PLUS_A``: on disk Laplacians the minimum-degree ordering step
    alone costs far more than a COLAMD factorization. No pivoting keeps the LDLᵀ pivots on
    ``U``'s diagonal, which is how a non-SPD matrix is detected."""

    name = "scipy"

    def __init__(self):
        self._lu = None

    def factorize(self, A: sp.spmatrix) -> None:
        try:
            self._lu = spla.splu(_as_csc_symmetric(A), permc_spec="COLAMD", diag_pivot_thresh=0.0,
                                 options=dict(SymmetricMode=True))
        except RuntimeError as exc:  # exactly singular
            raise NotPositiveDefinite(str(exc)) from exc
        # No pivoting + symmetric mode: U's diagonal holds the LDLᵀ pivots; SPD iff all > 0.
        if not np.all(self._lu.U.diagonal() > 0):
            self._lu = None
            raise NotPositiveDefinite("matrix is not positive definite (non-positive pivot)")

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.ascontiguousarray(B))

    def has_factor(self) -> bool:
        return self._lu is not None

    def release(self) -> None:
        self._lu = None


def make_solver(kind: str = "auto", refactored: bool = False):
    """A fresh solver of the requested kind; ``auto`` prefers CHOLMOD when installed.
    ``refactored``: Laplacians of one pattern refactored many times (see ``CholmodSolver``)."""
    if kind not in SOLVER_KINDS:
        raise UserError(f"unknown solver '{kind}'; use one of {', '.join(SOLVER_KINDS)}")
    if kind == "cholmod" and not cholmod_available():
        raise UserError("solver 'cholmod' requested but scikit-sparse is not installed; "
                        "pip install scikit-sparse (needs libsuitesparse-dev) or use solver: auto")
    if kind == "cholmod" or (kind == "auto" and cholmod_available()):
        return CholmodSolver(refactored=refactored)
    return ScipySolver()


#: Systems with at least this many unknowns may be solved by PCG on the previous factor.
PCG_ABOVE = 50_000
#: PCG iterations tried before refactoring instead: each costs one solve with the old factor,
#: and at the largest sizes a refactorization costs about ten solves.
PCG_MAX_ITER = 6
PCG_RTOL = 1e-12


def pcg(A: sp.spmatrix, B: np.ndarray, X0: np.ndarray, precondition, max_iter: int,
        rtol: float = PCG_RTOL):
    """Conjugate gradients on the columns of ``A X = B`` from ``X0`` with the preconditioner
    ``precondition(R)`` (a solve with an earlier factor of A's pattern). Returns ``(X,
    iterations)`` when every column's residual is below ``rtol·|b|``, else ``(None, iterations
    tried)`` — early, once the convergence rate seen so far predicts failure."""
    X = X0.copy()
    R = B - A @ X
    norm_b = np.maximum(np.linalg.norm(B, axis=0), np.finfo(float).tiny)
    if np.all(np.linalg.norm(R, axis=0) <= rtol * norm_b):
        return X, 0
    Z = precondition(R)
    P = Z.copy()
    rz = np.sum(R * Z, axis=0)
    r0 = np.linalg.norm(R, axis=0)
    for it in range(1, max_iter + 1):
        AP = A @ P
        alpha = rz / np.sum(P * AP, axis=0)
        X += P * alpha
        R -= AP * alpha
        r = np.linalg.norm(R, axis=0)
        if np.all(r <= rtol * norm_b):
            return X, it
        if it >= 2:
            # Give up early when the observed rate cannot reach rtol within max_iter:
            # a failed attempt then costs two solves, not max_iter, before the refactorization.
            rate = np.maximum(r / r0, 1e-300) ** (1.0 / it)
            with np.errstate(divide="ignore", invalid="ignore"):
                needed = np.log(rtol * norm_b / r) / np.log(rate)
            if np.any(rate >= 1.0) or np.nanmax(needed) > max_iter - it:
                return None, it
        Z = precondition(R)
        rz_new = np.sum(R * Z, axis=0)
        P = Z + P * (rz_new / rz)
        rz = rz_new
    return None, max_iter


def solve_complex(solver, A: sp.spmatrix, b: np.ndarray, x0: np.ndarray | None = None
                  ) -> np.ndarray:
    """Solve ``A x = b`` for a complex ``b`` (stacked as two real columns), reusing the solver's
    analysis.

    For large systems with a starting guess ``x0`` (the previous iterate) and a factor of an
    earlier matrix of the same pattern, preconditioned CG with that factor is tried first
    (warm start; ``PCG_MAX_ITER`` iterations to a relative residual of ``PCG_RTOL``); only if it
    does not converge is ``A`` refactored. ``solver.stats`` counts both outcomes.
    """
    B = np.column_stack([b.real, b.imag])
    stats = solver.__dict__.setdefault("stats", {"factorizations": 0, "pcg_solves": 0,
                                                 "pcg_iterations": 0})
    if x0 is not None and A.shape[0] >= PCG_ABOVE and solver.has_factor():
        X, its = pcg(A, B, np.column_stack([x0.real, x0.imag]), solver.solve, PCG_MAX_ITER)
        if X is not None:
            stats["pcg_solves"] += 1
            stats["pcg_iterations"] += its
            return X[:, 0] + 1j * X[:, 1]
    solver.factorize(A)
    stats["factorizations"] += 1
    X = solver.solve(B)
    return X[:, 0] + 1j * X[:, 1]
