"""Sparse symmetric positive definite solves with the symbolic analysis reused.

Every SEM iteration solves ``L_II X = B`` (and the small ``L_BB`` system) with the same sparsity
pattern and new values (Remark 1 of the paper: both blocks are SPD when the weights are
positive). Three solvers, each analysing a pattern once where it can:

* ``pardiso`` — MKL PARDISO (the ``mkl`` wheel that ``pypardiso``, a default dependency on
  x86-64 Linux and Windows, brings; its library is found in the wheel's folder, else through
  pypardiso's loader) called directly: SPD type (mtype 2) on the upper triangle, analysis
  (phase 11) once per pattern, numeric refactorization (phase 22) and solve (phase 33) after
  that, no iterative refinement; or, for large Gauss–Newton systems, a single-precision factor
  whose solves are refined in double precision to a given residual (``single=True``). On more
  than one thread (systems from ``PARALLEL_ABOVE`` unknowns) it runs in MKL's conditional
  numerical reproducibility mode (``iparm[33]``) with the sequential METIS ordering
  (``iparm[1] = 2``; the parallel one rules the mode out), so that a map is the same bit for
  bit from run to run, as it is on one thread (without the mode the last bits of the factor and
  the solves follow the threads' scheduling). pypardiso's own ``spsolve`` is not used: it
  re-analyses whenever the values change and treats the matrix as unsymmetric.
* ``cholmod`` — CHOLMOD through scikit-sparse (the optional ``fast`` extra; needs SuiteSparse
  headers to build): ordering and symbolic factorization on the first call, ``cholesky_inplace``
  after that.
* ``scipy`` — SuperLU in symmetric mode, the fallback everywhere (it cannot keep an analysis).

``auto`` takes PARDISO where it is installed, then CHOLMOD, then SciPy. PARDISO's refactor +
solve is the fastest at 100k and 1M faces in ``benchmarks/bench_sem.py`` (the README's
performance table), and both modes refactor at every step (a SEM step, a Gauss–Newton step),
so its maps are the quickest. Loading MKL (its library, and its kernels on the first call)
costs a few hundredths of a second per process. All take real right-hand sides with two
columns (the real and imaginary parts of the complex map), never a complex one (see
``shared/docs/SOLVERS.md``). ``factorize(A, upper=True)`` takes the upper triangle alone (CSR,
sorted rows, every diagonal entry stored), as the Gauss–Newton assembly writes it: PARDISO
factors it as given, CHOLMOD reads it as the lower triangle of the CSC form (the same arrays),
SciPy mirrors it first.
"""

from __future__ import annotations

import ctypes
import threading
import warnings
import weakref

import numpy as np
import scipy.sparse as sp

from ..errors import UserError

SOLVER_KINDS = ("auto", "pardiso", "cholmod", "scipy")


def cholmod_available() -> bool:
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


_MKL_LOCK = threading.Lock()
_MKL_PARDISO = None      # the ctypes function, once loaded; False when it cannot be loaded

#: where the ``mkl`` wheel puts MKL's single dynamic library, relative to an installation
#: prefix (``sys.prefix`` or the user base): Linux, then Windows
_MKL_RT_GLOBS = ("lib/libmkl_rt.so*", "Library/bin/mkl_rt*.dll")


def _mkl_rt_paths() -> list[str]:
    """Candidate paths of MKL's ``mkl_rt`` library, cheapest look-ups first: the
    ``PYPARDISO_MKL_RT`` variable, then the ``mkl`` wheel's own folder under ``sys.prefix``
    and the user base (a few ``stat`` calls; pypardiso's import and its loader search the
    whole installation tree recursively, which costs most of a second)."""
    import glob
    import os
    import site
    import sys

    given = os.environ.get("PYPARDISO_MKL_RT")
    if given:
        return [given]
    found = []
    for prefix in dict.fromkeys(p for p in (sys.prefix, site.USER_BASE) if p):
        for pattern in _MKL_RT_GLOBS:
            found += sorted(glob.glob(os.path.join(prefix, pattern)), key=len)
    return found


def _load_mkl_rt():
    """MKL's ``mkl_rt`` as a ``ctypes.CDLL``: from :func:`_mkl_rt_paths`, else through
    pypardiso's own library search; ``None`` when neither finds it."""
    for path in _mkl_rt_paths():
        try:
            return ctypes.CDLL(path)
        except OSError:
            continue
    try:
        import pypardiso
        return pypardiso.PyPardisoSolver().libmkl
    except (ImportError, OSError, AttributeError):
        return None


def _mkl_pardiso():
    """MKL's ``pardiso`` entry point from the ``mkl`` wheel (the wheel's folder first, then
    pypardiso's loader), or ``None`` when MKL is not installed."""
    global _MKL_PARDISO
    with _MKL_LOCK:
        if _MKL_PARDISO is None:
            lib = _load_mkl_rt()
            try:
                fn = lib.pardiso
                set_threads = lib.MKL_Set_Num_Threads_Local
                max_threads = lib.MKL_Get_Max_Threads
            except AttributeError:          # no library, or not MKL's
                _MKL_PARDISO = False
            else:
                set_threads.argtypes = [ctypes.c_int]
                set_threads.restype = ctypes.c_int
                fn.set_threads = set_threads
                max_threads.argtypes = []
                max_threads.restype = ctypes.c_int
                fn.max_threads = max_threads
                i32 = ctypes.POINTER(ctypes.c_int32)
                fn.argtypes = [ctypes.POINTER(ctypes.c_int64), i32, i32, i32, i32, i32,
                               ctypes.c_void_p, i32, i32, i32, i32, i32, i32,
                               ctypes.c_void_p, ctypes.c_void_p, i32]
                fn.restype = None
                _MKL_PARDISO = fn
    return _MKL_PARDISO or None


def mkl_max_threads() -> int:
    """The threads MKL would use by itself (``MKL_Get_Max_Threads``): the cores this process may
    run on, or ``MKL_NUM_THREADS``/``OMP_NUM_THREADS`` when set; 1 without MKL."""
    fn = _mkl_pardiso()
    return max(1, int(fn.max_threads())) if fn is not None else 1


#: PARDISO factors systems with at least this many unknowns on :func:`mkl_max_threads`
#: threads, smaller ones on one. On this project's 2-core machine two threads made a
#: Gauss–Newton refactor + solve 1.5–1.6× faster on a quiet machine from 35k to 2.1M unknowns,
#: but 1.7–3.5× slower when a second process did the same (MKL's threads wait for each other
#: spinning); below this size a step takes a few hundredths of a second either way.
PARALLEL_ABOVE = 50_000


def reproducible_threading(threads: int) -> tuple[int, int]:
    """PARDISO's ordering (``iparm[1]``) and conditional numerical reproducibility
    (``iparm[33]``) settings for a factor computed on ``threads`` threads.

    On more than one thread a factor, and so every solve with it, differs in its last bits from
    run to run unless MKL's conditional numerical reproducibility mode is on (``iparm[33]``:
    the thread count); MKL's parallel nested dissection (``iparm[1] = 3``) rules that mode out,
    so the sequential METIS ordering (``iparm[1] = 2``) is taken with it. One thread needs
    neither: its results are the same from run to run as they are.

    Parameters
    ----------
    threads : int
        The threads MKL runs the analysis, factorization and solves on (≥ 1).

    Returns
    -------
    (ordering, cnr) : (int, int)
        ``iparm[1]`` and ``iparm[33]``.
    """
    return 2, (threads if threads > 1 else 0)


def pardiso_available() -> bool:
    return _mkl_pardiso() is not None


class NotPositiveDefinite(RuntimeError):
    """The matrix handed to the Cholesky solver is not SPD (negative weights dominate)."""


def symmetric_product(A: sp.csr_matrix, X: np.ndarray, full: bool) -> np.ndarray:
    """``A @ X`` for a symmetric matrix given whole (``full``) or as its upper triangle (CSR,
    every diagonal entry stored), in double precision.

    Parameters
    ----------
    A : (n, n) scipy.sparse.csr_matrix
    X : (n, k) float64
    full : bool
    """
    if full:
        return A @ X
    return A @ X + A.T @ X - A.diagonal()[:, None] * X


def _same_pattern(key, A: sp.spmatrix) -> bool:
    """Whether ``A`` (CSR or CSC) has the pattern ``key = (indptr, indices)`` of an analysed
    matrix: the very index arrays (SEM's blocks share them) or equal ones."""
    return key is not None and (key[1] is A.indices or (
        np.array_equal(key[0], A.indptr) and np.array_equal(key[1], A.indices)))


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
    pcg_max_iter = 6       # see PCG_MAX_ITER

    def __init__(self, ordering: str | None = None, refactored: bool = False):
        self._factor = None
        self._key = None         # (indptr, indices) of the analysed pattern
        self._simplicial = False
        self._valid = False      # False after a failed refactorization (analysis kept)
        self.ordering = ordering
        self.refactored = refactored

    def factorize(self, A: sp.spmatrix, upper: bool = False) -> None:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        # CHOLMOD reads the lower triangle only: an upper triangle's CSR arrays are the CSC
        # arrays of the lower one
        A = _as_csc_symmetric(A)
        self._valid = False
        if not _same_pattern(self._key, A):
            self._factor = None            # a new pattern needs its own analysis
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # CHOLMOD warns (not raises) on some non-SPD input
            try:
                if self._factor is None:
                    self._key = (A.indptr, A.indices)
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


def _pardiso_release(pt: np.ndarray, iparm: np.ndarray) -> None:
    """PARDISO phase −1: free every internal array of the handle ``pt`` (a no-op if unused)."""
    if not pt.any():
        return
    fn = _mkl_pardiso()
    one, err = ctypes.c_int32(1), ctypes.c_int32(0)
    i32 = ctypes.POINTER(ctypes.c_int32)
    dummy = np.zeros(1, dtype=np.int32)
    fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one), ctypes.byref(one),
       ctypes.byref(ctypes.c_int32(2)), ctypes.byref(ctypes.c_int32(-1)), ctypes.byref(one),
       None, dummy.ctypes.data_as(i32), dummy.ctypes.data_as(i32), None, ctypes.byref(one),
       iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)), None, None,
       ctypes.byref(err))
    pt[:] = 0


class PardisoSolver:
    """MKL PARDISO for SPD matrices (mtype 2) with the analysis kept per sparsity pattern.

    The first ``factorize`` of a pattern stores its upper triangle's CSR index arrays (zero-based,
    ``iparm[34]``) and where each of their entries sits in the full matrix's ``data`` (with
    ``upper=True`` the matrix given is that triangle, taken as it is), and runs the analysis
    (phase 11, METIS nested dissection, whose elimination order it keeps in ``permutation``;
    or the order given in ``ordering``, which saves METIS's time where the caller knows a good
    one, see :func:`.gauss_newton.block_ordering`; but with a given order MKL solves on one
    thread: at 2M unknowns 0.175 s a solve instead of 0.096 s on two, so it pays only for
    systems solved a few times per analysis, or on one thread, :meth:`threads_for`). Every
    call then gathers the upper triangle's values and refactors numerically (phase 22);
    ``solve`` is phase 33 with iterative refinement off (``iparm[7] = 0``: the Cholesky factor
    of an SPD Laplacian is exact to rounding). A non-positive pivot makes phase 22 fail (error
    −4), reported as ``NotPositiveDefinite``; a missing diagonal entry (``A_ii = 0``) is caught
    before the call.

    With ``single=True`` the factor is computed and applied in single precision (``iparm[27] =
    1``: at 2M unknowns a Gauss–Newton refactorization takes 0.74–0.82 s instead of 1.14–1.18 s
    and a solve 0.058 s instead of 0.10 s), and ``solve`` refines the solution in double
    precision against the matrix's own values (residual ``b − A x`` in double, a single-precision
    correction) until its relative residual is at most ``rtol``; after ``REFINE_STEPS``
    corrections short of that (a badly conditioned matrix) it factors the matrix in double
    precision once and solves with that (``refinement_stats["double_fallbacks"]``). This serves systems
    whose solution only has to be good to ``rtol`` (an inexact Newton step: see
    :class:`.gauss_newton.GaussNewton`).

    MKL runs on ``threads`` threads during these calls (``MKL_Set_Num_Threads_Local``, restored
    after each call). By default that is one thread below ``PARALLEL_ABOVE`` unknowns and MKL's
    own maximum above it (:func:`mkl_max_threads`: the usable cores, or fewer where
    ``MKL_NUM_THREADS``/``OMP_NUM_THREADS`` say so, as the experiment runner's pool workers
    do). On more than one thread every call runs in MKL's conditional numerical
    reproducibility mode with the sequential METIS ordering (:func:`reproducible_threading`),
    so that the factor and every solve are the same bit for bit from run to run (without it
    their last bits follow the threads' scheduling); the factor differs
    from the one-thread factor by rounding only (about 1e-9 of a Gauss–Newton step on
    choi_hand).
    """

    name = "pardiso"
    #: no PCG on an old factor: a PARDISO solve costs about half a refactorization + solve,
    #: so two PCG iterations already cost more than refactoring
    pcg_max_iter = 0

    #: at most this many refinement steps in single precision (see ``single``)
    REFINE_STEPS = 2

    def __init__(self, refactored: bool = False, threads: int | None = None,
                 single: bool = False, rtol: float = 1e-3):
        self.threads = threads    # None: chosen per pattern by its size (PARALLEL_ABOVE)
        #: factor in single precision and refine solves to ``rtol`` (relative residual);
        #: set before the first ``factorize``
        self.single, self.rtol = single, rtol
        self.refinement_stats = {"refinements": 0, "double_fallbacks": 0}
        self._double = None        # the double-precision fallback solver (single=True)
        self._matrix = None        # the factored matrix (single=True: the residuals)
        self._threads = 1
        self._fn = _mkl_pardiso()
        if self._fn is None:
            raise UserError("solver 'pardiso' requested but pypardiso/MKL is not installed")
        self.pt = np.zeros(64, dtype=np.int64)     # PARDISO's opaque handle
        self.iparm = np.zeros(64, dtype=np.int32)
        ip = self.iparm
        ip[0] = 1      # iparm given here, not defaults
        ip[1] = 2      # METIS nested dissection ordering
        ip[7] = 0      # no iterative refinement
        ip[9] = 13     # pivot perturbation 1e-13 (unused for SPD)
        ip[34] = 1     # zero-based ia/ja
        self._key = None          # (indptr, indices) of the analysed full pattern
        self._upper = None        # positions of the upper triangle in the full data array
        #                           (None: the analysed matrix was the upper triangle itself)
        self._ia = self._ja = None
        self._valid = False
        self.refactored = refactored
        #: a fill-reducing order to analyse the next pattern with instead of METIS's (a
        #: new-order list: row ``ordering[k]`` of the matrix is the ``k``-th eliminated)
        self.ordering = None
        #: the analysed pattern's elimination order (METIS's, or ``ordering``), same form
        self.permutation = None
        self._perm = None
        self.factor_entries = 0     # entries of the analysed pattern's Cholesky factor
        self._finalizer = weakref.finalize(self, _pardiso_release, self.pt, self.iparm)

    def _call(self, phase: int, data: np.ndarray | None, B: np.ndarray | None = None):
        i32 = ctypes.POINTER(ctypes.c_int32)
        n = len(self._ia) - 1
        nrhs = 1 if B is None else B.shape[1]
        X = None if B is None else np.zeros((n, nrhs), order="F", dtype=self._dtype())
        err = ctypes.c_int32(0)
        one = ctypes.c_int32(1)
        previous = self._fn.set_threads(self._threads)
        try:
            self._fn(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one),
                     ctypes.byref(one), ctypes.byref(ctypes.c_int32(2)),
                     ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(n)),
                     None if data is None else data.ctypes.data,
                     self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32),
                     None if self._perm is None else self._perm.ctypes.data_as(i32),
                     ctypes.byref(ctypes.c_int32(nrhs)), self.iparm.ctypes.data_as(i32),
                     ctypes.byref(ctypes.c_int32(0)), None if B is None else B.ctypes.data,
                     None if X is None else X.ctypes.data, ctypes.byref(err))
        finally:
            self._fn.set_threads(previous)
        return err.value, X

    def _dtype(self):
        return np.float32 if self.iparm[27] == 1 else np.float64

    def _analyse(self, A: sp.csr_matrix, upper: bool) -> None:
        _pardiso_release(self.pt, self.iparm)
        self.iparm[27] = 1 if self.single else 0     # the precision is fixed at the analysis
        n = A.shape[0]
        if upper:
            ia, ja = A.indptr.astype(np.int32), A.indices.astype(np.int32)
            entries = None
        else:
            rows = np.repeat(np.arange(n), np.diff(A.indptr))
            entries = np.flatnonzero(A.indices >= rows)      # CSR rows sorted: diagonal first
            ja = A.indices[entries].astype(np.int32)
            ia = np.zeros(n + 1, dtype=np.int32)
            np.cumsum(np.bincount(rows[entries], minlength=n), out=ia[1:])
        self._ia, self._ja, self._upper = ia, ja, entries
        self._has_diagonal = bool(np.all(np.diff(ia) > 0) and np.all(ja[ia[:-1]] == np.arange(n)))
        self._key = (A.indptr, A.indices)
        self._threads = self.threads_for(n)
        self.iparm[1], self.iparm[33] = reproducible_threading(self._threads)
        given = self.ordering is not None and len(self.ordering) == n
        # iparm[4]: 1 analyses with the order in perm, 2 returns METIS's order in it
        self.iparm[4] = 1 if given else 2
        self._perm = (np.array(self.ordering, dtype=np.int32) if given
                      else np.zeros(n, dtype=np.int32))
        self.permutation = None
        self.iparm[17] = -1         # report the factor's entries (``factor_entries``)
        if self._has_diagonal:
            err, _ = self._call(11, self._upper_values(A))
            if err:
                raise RuntimeError(f"PARDISO analysis failed with error {err}")
            self.permutation = self._perm
            self.factor_entries = int(self.iparm[17])

    def threads_for(self, n: int) -> int:
        """The threads MKL runs on for a system of ``n`` unknowns: ``threads`` if given, else
        one below ``PARALLEL_ABOVE`` and :func:`mkl_max_threads` from there."""
        return self.threads or (1 if n < PARALLEL_ABOVE else mkl_max_threads())

    def _upper_values(self, A: sp.csr_matrix) -> np.ndarray:
        """The values of the analysed upper triangle, from ``A``'s ``data``, in the factor's
        precision."""
        return np.ascontiguousarray(A.data if self._upper is None else A.data[self._upper],
                                    dtype=self._dtype())

    def factorize(self, A: sp.spmatrix, upper: bool = False) -> None:
        A = A.tocsr() if not sp.isspmatrix_csr(A) else A
        if not A.has_sorted_indices:
            A = A.sorted_indices()
        A = A.astype(np.float64, copy=False)
        self._valid = False
        if not _same_pattern(self._key, A) or (self._upper is None) != upper:
            self._analyse(A, upper)
        if not self._has_diagonal:
            raise NotPositiveDefinite("matrix is not positive definite (a zero diagonal entry)")
        self._data = self._upper_values(A)
        self._matrix = A if self.single else None      # for the refinement's residuals
        err, _ = self._call(22, self._data)
        if err == -4:
            raise NotPositiveDefinite("matrix is not positive definite (PARDISO pivot ≤ 0)")
        if err:
            raise RuntimeError(f"PARDISO factorization failed with error {err}")
        self._valid = True

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = np.asarray(B, dtype=np.float64)
        one = B.ndim == 1
        B = B.reshape(len(B), -1)
        X = self._solve_factor(B)
        if self.iparm[27] == 1:
            X = self._refined(B, X)
        return X[:, 0] if one else X

    def _solve_factor(self, B: np.ndarray) -> np.ndarray:
        """Phase 33 with the factor as it is (in its precision), as float64."""
        err, X = self._call(33, self._data, np.asfortranarray(B, dtype=self._dtype()))
        if err:
            raise RuntimeError(f"PARDISO solve failed with error {err}")
        return np.ascontiguousarray(X, dtype=np.float64)

    def _refined(self, B: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``X`` (a single-precision solve) refined in double precision to ``rtol``, or the
        double-precision factor's solution where ``REFINE_STEPS`` corrections do not get
        there."""
        A = self._matrix
        bound = self.rtol * np.linalg.norm(B, axis=0)
        for k in range(self.REFINE_STEPS + 1):
            R = B - symmetric_product(A, X, self._upper is not None)
            if np.all(np.linalg.norm(R, axis=0) <= bound):
                return X
            if k < self.REFINE_STEPS:
                X += self._solve_factor(R)
                self.refinement_stats["refinements"] += 1
        self.refinement_stats["double_fallbacks"] += 1
        if self._double is None:
            self._double = PardisoSolver(threads=self.threads)
            self._double.ordering = self.permutation
        self._double.factorize(A, upper=self._upper is None)
        return self._double.solve(B)

    def has_factor(self) -> bool:
        return self._valid

    def release(self) -> None:
        _pardiso_release(self.pt, self.iparm)
        self._key = None
        self._valid = False
        self._matrix = None
        if self._double is not None:
            self._double.release()


class ScipySolver:
    """SuperLU with a COLAMD ordering applied symmetrically and no pivoting (SPD input).

    COLAMD rather than ``MMD_AT_PLUS_A``: on disk Laplacians the minimum-degree ordering step
    alone costs far more than a COLAMD factorization. No pivoting keeps the LDLᵀ pivots on
    ``U``'s diagonal, which is how a non-SPD matrix is detected."""

    name = "scipy"
    pcg_max_iter = 6

    def __init__(self):
        self._lu = None

    def factorize(self, A: sp.spmatrix, upper: bool = False) -> None:
        from scipy.sparse.linalg import splu      # (SciPy's solvers: only this fallback's)

        if upper:
            A = (A + sp.triu(A, 1).T).tocsr()
        try:
            self._lu = splu(_as_csc_symmetric(A), permc_spec="COLAMD", diag_pivot_thresh=0.0,
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
    """A fresh solver of the requested kind; ``auto`` prefers PARDISO, then CHOLMOD, when
    installed. ``refactored``: Laplacians of one pattern refactored many times (see
    ``CholmodSolver``)."""
    if kind not in SOLVER_KINDS:
        raise UserError(f"unknown solver '{kind}'; use one of {', '.join(SOLVER_KINDS)}")
    if kind == "pardiso" and not pardiso_available():
        raise UserError("solver 'pardiso' requested but pypardiso (MKL) is not installed; "
                        "pip install pypardiso (x86-64) or use solver: auto")
    if kind == "cholmod" and not cholmod_available():
        raise UserError("solver 'cholmod' requested but scikit-sparse is not installed; "
                        "pip install scikit-sparse (needs libsuitesparse-dev) or use solver: auto")
    if kind == "pardiso" or (kind == "auto" and pardiso_available()):
        return PardisoSolver(refactored=refactored)
    if kind == "cholmod" or (kind == "auto" and cholmod_available()):
        return CholmodSolver(refactored=refactored)
    return ScipySolver()


#: Systems with at least this many unknowns may be solved by PCG on the previous factor.
PCG_ABOVE = 50_000
#: PCG iterations tried before refactoring instead (CHOLMOD, SuperLU): each costs one solve
#: with the old factor, and at the largest sizes a refactorization costs about ten solves. A
#: solver's ``pcg_max_iter`` says its own budget (0: never).
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
    (warm start; the solver's ``pcg_max_iter`` iterations to a relative residual of
    ``PCG_RTOL``); only if it does not converge is ``A`` refactored. ``solver.stats`` counts
    both outcomes.
    """
    B = np.column_stack([b.real, b.imag])
    stats = solver.__dict__.setdefault("stats", {"factorizations": 0, "pcg_solves": 0,
                                                 "pcg_iterations": 0})
    budget = getattr(solver, "pcg_max_iter", PCG_MAX_ITER)
    if x0 is not None and budget and A.shape[0] >= PCG_ABOVE and solver.has_factor():
        X, its = pcg(A, B, np.column_stack([x0.real, x0.imag]), solver.solve, budget)
        if X is not None:
            stats["pcg_solves"] += 1
            stats["pcg_iterations"] += its
            return X[:, 0] + 1j * X[:, 1]
    solver.factorize(A)
    stats["factorizations"] += 1
    X = solver.solve(B)
    return X[:, 0] + 1j * X[:, 1]
