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


#: Above this many unknowns CHOLMOD's nested dissection ordering is used: its analysis costs
#: more (3.3 s against 0.6 s at 534k unknowns) but its factor has a third less fill, so each of
#: the many refactorizations SEM does is about 1.4× faster (measured: benchmarks/bench_sem.py).
NESDIS_ABOVE = 150_000


class CholmodSolver:
    """CHOLMOD LLᵀ with the analysis done once and numeric refactorizations after that."""

    name = "cholmod"

    def __init__(self, ordering: str | None = None):
        self._factor = None
        self._valid = False      # False after a failed refactorization (analysis kept)
        self.ordering = ordering

    def factorize(self, A: sp.spmatrix) -> None:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        A = _as_csc_symmetric(A)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # CHOLMOD warns (not raises) on some non-SPD input
            try:
                if self._factor is None:
                    ordering = self.ordering or ("nesdis" if A.shape[0] > NESDIS_ABOVE
                                                 else "default")
                    # supernodal = LLᵀ: a non-SPD matrix raises (simplicial LDLᵀ would accept
                    # negative pivots and silently solve an indefinite system)
                    self._factor = cholesky(A, mode="supernodal", ordering_method=ordering)
                else:
                    self._factor.cholesky_inplace(A)
            except (CholmodNotPositiveDefiniteError, Warning) as exc:
                self._valid = False
                raise NotPositiveDefinite(str(exc)) from exc
        self._valid = True

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._factor(B)

    def has_factor(self) -> bool:
        return self._factor is not None and self._valid

    def release(self) -> None:
        self._factor = None


class ScipySolver:
    """SuperLU with a COLAMD ordering applied symmetrically and no pivoting (SPD input).

    Measured here on disk Laplacians (factor + solve): COLAMD 0.32 s at 45k unknowns and 17 s
    at 534k; ``MMD_AT_PLUS_A`` took 9.5 s at 45k (its ordering step, not the factorization)."""

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


def make_solver(kind: str = "auto"):
    """A fresh solver of the requested kind; ``auto`` prefers CHOLMOD when installed."""
    if kind not in SOLVER_KINDS:
        raise UserError(f"unknown solver '{kind}'; use one of {', '.join(SOLVER_KINDS)}")
    if kind == "cholmod" and not cholmod_available():
        raise UserError("solver 'cholmod' requested but scikit-sparse is not installed; "
                        "pip install scikit-sparse (needs libsuitesparse-dev) or use solver: auto")
    if kind == "cholmod" or (kind == "auto" and cholmod_available()):
        return CholmodSolver()
    return ScipySolver()


#: Systems with at least this many unknowns may be solved by PCG on the previous factor.
PCG_ABOVE = 50_000
#: PCG iterations tried before refactoring instead (each costs one solve with the old factor;
#: at 534k unknowns a refactorization costs about ten solves).
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
