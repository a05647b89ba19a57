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
                    self._factor = cholesky(A, ordering_method=ordering)
                else:
                    self._factor.cholesky_inplace(A)
            except (CholmodNotPositiveDefiniteError, Warning) as exc:
                raise NotPositiveDefinite(str(exc)) from exc

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._factor(B)

    def release(self) -> None:
        self._factor = None


class ScipySolver:
    """SuperLU with a symmetric minimum-degree ordering and no pivoting (SPD input)."""

    name = "scipy"

    def __init__(self):
        self._lu = None

    def factorize(self, A: sp.spmatrix) -> None:
        try:
            self._lu = spla.splu(_as_csc_symmetric(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                 options=dict(SymmetricMode=True))
        except RuntimeError as exc:  # exactly singular
            raise NotPositiveDefinite(str(exc)) from exc

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.ascontiguousarray(B))

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


def solve_complex(solver, A: sp.spmatrix, b: np.ndarray) -> np.ndarray:
    """Factorize ``A`` (reusing the solver's analysis) and solve for a complex right-hand side,
    stacked as two real columns."""
    solver.factorize(A)
    X = solver.solve(np.column_stack([b.real, b.imag]))
    return X[:, 0] + 1j * X[:, 1]
