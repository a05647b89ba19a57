"""Sparse SPD solvers of SEM, ``pipeline/geometry/solvers.py``: SciPy, MKL PARDISO and CHOLMOD
agree on an SPD Laplacian block, refactor on a kept pattern, and raise ``NotPositiveDefinite`` on
matrices that are not SPD (Remark 1: the blocks are SPD only for positive weights).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.sparse as sp

from pipeline.errors import UserError
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_blocks, laplacian_pattern)
from pipeline.geometry import solvers
from pipeline.geometry.solvers import (NotPositiveDefinite, cholmod_available, make_solver,
                                       pardiso_available, solve_complex)

IN_CI = os.environ.get("CI") == "true"
AVAILABLE = {"scipy": lambda: True, "pardiso": pardiso_available, "cholmod": cholmod_available}


def _need(kind):
    """Skip a test of an optional solver that is not installed; on CI both are (pypardiso is a
    default dependency on x86-64, scikit-sparse the ``fast`` extra .ci/run installs)."""
    if not AVAILABLE[kind]():
        if IN_CI:
            pytest.fail(f"solver {kind} is not installed on CI")
        pytest.skip(f"solver {kind} is not installed")


@pytest.fixture(scope="module")
def spd_block(ddisk):
    P, F, b = ddisk
    pattern = laplacian_pattern(F, len(P), b)
    w = edge_weights(pattern, corner_dot_over_area(P, F, face_double_areas(P, F)))
    L_II = laplacian_blocks(pattern, w)[0]
    assert np.linalg.eigvalsh(L_II.toarray()).min() > 0
    return L_II


@pytest.mark.parametrize("refactored", [False, True])
@pytest.mark.parametrize("kind", ["scipy", "pardiso", "cholmod"])
def test_solvers_agree_on_spd_block(kind, refactored, spd_block):
    _need(kind)
    A = spd_block
    rng = np.random.default_rng(10)
    b = rng.normal(size=A.shape[0]) + 1j * rng.normal(size=A.shape[0])
    s = make_solver(kind, refactored=refactored)
    np.testing.assert_allclose(solve_complex(s, A, b), np.linalg.solve(A.toarray(), b),
                               rtol=1e-10, atol=0)
    # refactorizations with new values on the same pattern (the analysis reused), twice
    for _ in range(2):
        A2 = A + sp.diags(rng.uniform(0.1, 1.0, A.shape[0]))
        np.testing.assert_allclose(solve_complex(s, A2, b), np.linalg.solve(A2.toarray(), b),
                                   rtol=1e-10)
    # a new pattern is analysed anew, not solved with the old analysis
    n = A.shape[0]      # (SPD: the new entries shift eigenvalues by at most 0.2, the diagonal by 1)
    A3 = (A + 0.1 * (sp.eye(n, k=3) + sp.eye(n, k=-3)) + sp.eye(n)).tocsr()
    np.testing.assert_allclose(solve_complex(s, A3, b), np.linalg.solve(A3.toarray(), b),
                               rtol=1e-10)
    s.release()


@pytest.mark.parametrize("kind", ["scipy", "pardiso", "cholmod"])
def test_upper_triangle_alone_factors_the_symmetric_matrix(kind, spd_block):
    """``factorize(U, upper=True)`` with U the upper triangle (CSR, sorted rows) solves with the
    whole symmetric matrix, and switching between the two forms of one pattern re-analyses."""
    _need(kind)
    A = spd_block.tocsr()
    U = sp.triu(A).tocsr()
    U.sort_indices()
    rng = np.random.default_rng(11)
    b = rng.normal(size=A.shape[0])
    exact = np.linalg.solve(A.toarray(), b)
    s = make_solver(kind, refactored=True)
    for M, upper in [(U, True), (A, False), (U, True)]:
        s.factorize(M, upper=upper)
        np.testing.assert_allclose(s.solve(b), exact, rtol=1e-10, atol=1e-12)
    U.data = U.data * 2.0            # new values on the upper pattern: a refactorization
    s.factorize(U, upper=True)
    np.testing.assert_allclose(s.solve(b), exact / 2.0, rtol=1e-10, atol=1e-12)
    s.release()


def _grid_laplacian(k: int) -> sp.csr_matrix:
    """The 5-point Laplacian of a k×k grid with zero values around it (SPD, k² unknowns)."""
    T = sp.diags([-np.ones(k - 1), 2 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    return (sp.kron(T, sp.eye(k)) + sp.kron(sp.eye(k), T)).tocsr()


def test_pardiso_threads_follow_the_system_size():
    """Systems from ``PARALLEL_ABOVE`` unknowns are factored on MKL's own thread count, smaller
    ones on one thread; the factors agree to rounding, and ``threads=`` overrides the choice."""
    _need("pardiso")
    big = _grid_laplacian(int(np.ceil(np.sqrt(solvers.PARALLEL_ABOVE))))
    small = _grid_laplacian(40)
    b = np.random.default_rng(3).normal(size=(big.shape[0], 2))
    chosen = {}
    for A in (small, big):
        s = make_solver("pardiso", refactored=True)
        s.factorize(A)
        chosen[A.shape[0]] = s._threads
        s.release()
    assert chosen == {small.shape[0]: 1, big.shape[0]: solvers.mkl_max_threads()}
    X = {}
    for threads in (1, 2):
        s = solvers.PardisoSolver(refactored=True, threads=threads)
        s.factorize(big)
        assert s._threads == threads
        X[threads] = s.solve(b)
        s.release()
    np.testing.assert_allclose(X[2], X[1], rtol=1e-10, atol=1e-12 * np.abs(X[1]).max())
    np.testing.assert_allclose(big @ X[1], b, atol=1e-9)


def test_pardiso_keeps_its_ordering_and_analyses_with_a_given_one():
    """PARDISO's elimination order of a pattern is kept (a permutation of the unknowns); a
    solver given it analyses with it (the same factor size, the same solution), and a given
    order is really used: the natural order of a grid Laplacian (a band) fills its factor with
    more than twice the entries of the nested dissection's."""
    _need("pardiso")
    A = _grid_laplacian(60)
    b = np.random.default_rng(4).normal(size=(A.shape[0], 2))
    first = make_solver("pardiso", refactored=True)
    first.factorize(A)
    order = first.permutation
    assert np.array_equal(np.sort(order), np.arange(A.shape[0]))
    again = make_solver("pardiso", refactored=True)
    again.ordering = order
    again.factorize(A)
    assert np.array_equal(again.permutation, order)
    assert again.factor_entries == first.factor_entries
    np.testing.assert_allclose(again.solve(b), first.solve(b), rtol=1e-12)
    band = make_solver("pardiso", refactored=True)
    band.ordering = np.arange(A.shape[0])
    band.factorize(A)
    assert band.factor_entries > 2 * first.factor_entries
    np.testing.assert_allclose(A @ band.solve(b), b, atol=1e-9)
    for s in (first, again, band):
        s.release()


@pytest.mark.parametrize("upper", [False, True])
def test_pardiso_single_precision_factor_is_refined_to_rtol(upper):
    """``single=True`` factors in single precision (``iparm[27]``) and refines each solve in
    double precision until ``‖b − A x‖ ≤ rtol ‖b‖``: a single-precision solve alone misses
    1e-10, one refinement per column is counted, and no double-precision fallback is needed."""
    _need("pardiso")
    A = _grid_laplacian(60) * 1e3 + sp.eye(3600) * 1e-2        # κ ≈ 1.5e3
    M = sp.triu(A).tocsr() if upper else A
    b = np.random.default_rng(5).normal(size=(A.shape[0], 2))
    s = solvers.PardisoSolver(single=True, rtol=1e-10)
    s.factorize(M, upper=upper)
    assert s.iparm[27] == 1 and s._data.dtype == np.float32
    rough = s._solve_factor(b)
    assert np.linalg.norm(b - A @ rough) > 1e-10 * np.linalg.norm(b)
    X = s.solve(b)
    assert np.all(np.linalg.norm(b - A @ X, axis=0) <= 1e-10 * np.linalg.norm(b, axis=0))
    assert s.refinement_stats["refinements"] >= 1
    assert s.refinement_stats["double_fallbacks"] == 0
    assert s.iparm[33] <= 0     # (MKL writes −1: off) one thread, reproducible as it is
    x = s.solve(b[:, 0])
    assert x.shape == (A.shape[0],) and x.dtype == np.float64
    s.release()


def test_pardiso_on_threads_asks_for_reproducible_results():
    """On more than one thread both precisions run in MKL's conditional numerical
    reproducibility mode (``iparm[33]`` = the thread count) with the sequential METIS ordering
    (``iparm[1] = 2``; the parallel one rules the mode out); one thread leaves the mode off
    (MKL then writes −1 there)."""
    _need("pardiso")
    A = _grid_laplacian(30)
    for single, threads, cnr in [(True, 2, 2), (True, 1, 0), (False, 2, 2), (False, 1, 0)]:
        s = solvers.PardisoSolver(single=single, threads=threads)
        s.factorize(A)
        assert (s.iparm[33] == cnr) if cnr else (s.iparm[33] <= 0), (single, threads)
        assert s.iparm[1] == 2
        np.testing.assert_allclose(A @ s.solve(np.ones(900)), np.ones(900), atol=1e-3)
        s.release()


def _weighted_triangle_grid_laplacian(k: int, seed: int) -> sp.csr_matrix:
    """A Laplacian of a k×k grid split into triangles (each square's diagonal an edge) with
    random edge weights in [0.5, 2], plus 1e-3 on the diagonal (SPD, k² unknowns)."""
    index = np.arange(k * k).reshape(k, k)
    rows = np.concatenate([index[:, :-1].ravel(), index[:-1, :].ravel(),
                           index[:-1, :-1].ravel()])
    cols = np.concatenate([index[:, 1:].ravel(), index[1:, :].ravel(), index[1:, 1:].ravel()])
    weights = np.random.default_rng(seed).uniform(0.5, 2.0, len(rows))
    W = sp.coo_matrix((weights, (rows, cols)), shape=(k * k, k * k))
    W = (W + W.T).tocsr()
    A = (sp.diags(np.asarray(W.sum(axis=1)).ravel() + 1e-3) - W).tocsr()
    A.sort_indices()
    return A


def test_pardiso_solves_on_threads_are_the_same_bit_for_bit():
    """Two-thread factorizations and solves of one system give the same solution bit for bit
    every time (without the reproducibility mode, solves of a single right-hand side of this
    system differ in their last bits from call to call)."""
    _need("pardiso")
    A = _weighted_triangle_grid_laplacian(230, seed=1)
    b = np.random.default_rng(7).standard_normal(A.shape[0])
    solutions = []
    for _ in range(3):
        s = solvers.PardisoSolver(refactored=True, threads=2)
        for _ in range(2):
            s.factorize(A)
            solutions += [s.solve(b) for _ in range(4)]
        s.release()
    np.testing.assert_allclose(A @ solutions[0], b, atol=1e-8)
    assert all(np.array_equal(x, solutions[0]) for x in solutions[1:])


def test_pardiso_single_precision_falls_back_to_double_where_refinement_stalls():
    """A residual the refinement cannot reach (below double rounding) makes the solver factor
    the matrix in double precision once and return that solution."""
    _need("pardiso")
    A = _grid_laplacian(40)
    b = np.random.default_rng(6).normal(size=(A.shape[0], 2))
    s = solvers.PardisoSolver(single=True, rtol=1e-30)
    s.factorize(A)
    X = s.solve(b)
    assert s.refinement_stats == {"refinements": solvers.PardisoSolver.REFINE_STEPS,
                                  "double_fallbacks": 1}
    assert s._double.iparm[27] == 0
    np.testing.assert_allclose(X, np.linalg.solve(A.toarray(), b), rtol=1e-10)
    s.release()


def test_symmetric_product_of_the_upper_triangle_equals_the_full_product():
    A = _grid_laplacian(12) + sp.diags(np.arange(144.0))
    X = np.random.default_rng(7).normal(size=(144, 3))
    np.testing.assert_allclose(solvers.symmetric_product(sp.triu(A).tocsr(), X, full=False),
                               A @ X, rtol=1e-14, atol=1e-12)


def test_mkl_thread_count_follows_mkl_num_threads():
    """The experiment runner's pool workers set ``MKL_NUM_THREADS=1``: PARDISO then stays on
    one thread at every size."""
    _need("pardiso")
    import subprocess
    import sys
    code = "from pipeline.geometry.solvers import mkl_max_threads; print(mkl_max_threads())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "MKL_NUM_THREADS": "1"}, check=True)
    assert out.stdout.strip() == "1"


def test_mkl_library_named_in_pypardiso_mkl_rt_is_the_only_candidate(monkeypatch):
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/opt/intel/libmkl_rt.so.2")
    assert solvers._mkl_rt_paths() == ["/opt/intel/libmkl_rt.so.2"]


def test_mkl_library_is_found_in_the_wheel_folder(monkeypatch):
    """The ``mkl`` wheel pypardiso brings puts ``libmkl_rt`` in the installation's own library
    folder, where the loader looks first (no search of the whole tree)."""
    _need("pardiso")
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    paths = solvers._mkl_rt_paths()
    assert paths and "mkl_rt" in os.path.basename(paths[0])
    assert hasattr(solvers._load_mkl_rt(), "pardiso")


def test_mkl_loader_falls_back_to_pypardiso_when_no_candidate_loads(monkeypatch):
    _need("pardiso")
    monkeypatch.setattr(solvers, "_mkl_rt_paths", lambda: ["/nonexistent/libmkl_rt.so"])
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    assert hasattr(solvers._load_mkl_rt(), "pardiso")


def test_make_solver_rejects_unknown_kind():
    with pytest.raises(UserError):
        make_solver("bogus")
    assert make_solver("scipy").name == "scipy"
    auto = "pardiso" if pardiso_available() else "cholmod" if cholmod_available() else "scipy"
    assert make_solver("auto").name == auto


@pytest.mark.parametrize("refactored", [False, True])
@pytest.mark.parametrize("case", ["negative_definite", "indefinite", "negative_definite_large"])
@pytest.mark.parametrize("kind", ["scipy", "pardiso", "cholmod"])
def test_non_spd_matrix_raises_not_positive_definite(kind, case, refactored, spd_block):
    """Remark 1: the blocks are SPD only for positive weights; the solvers must say when they are
    not (sem.py catches NotPositiveDefinite). CHOLMOD is supernodal LLᵀ by default and
    simplicial LDLᵀ for refactored systems below SIMPLICIAL_BELOW unknowns (all three cases
    here), where only the pivot check can tell; PARDISO's SPD factorization stops at a
    non-positive pivot. "large" = 10⁴ unknowns."""
    _need(kind)
    A = spd_block
    if case == "negative_definite":
        M = -A
    elif case == "negative_definite_large":
        M = -_grid_laplacian(100)
    else:  # shift so that about half the spectrum is negative
        lam = np.linalg.eigvalsh(A.toarray())
        M = (A - np.median(lam) * sp.identity(A.shape[0])).tocsr()
    with pytest.raises(NotPositiveDefinite):
        make_solver(kind, refactored=refactored).factorize(M)


@pytest.mark.parametrize("refactored", [False, True])
@pytest.mark.parametrize("kind", ["pardiso", "cholmod"])
def test_refactor_to_indefinite_raises_and_drops_the_factor(kind, refactored, spd_block):
    """SEM refactors one pattern with new values: an indefinite matrix after an SPD one must
    raise (not solve with negative LDLᵀ pivots) and leave no usable factor; the next SPD matrix
    is factored again on the kept analysis and solved exactly."""
    _need(kind)
    A = spd_block
    lam = np.linalg.eigvalsh(A.toarray())
    solver = make_solver(kind, refactored=refactored)
    solver.factorize(A)
    assert solver.has_factor()
    with pytest.raises(NotPositiveDefinite):
        solver.factorize((A - np.median(lam) * sp.identity(A.shape[0])).tocsr())
    assert not solver.has_factor()
    A2 = (A + sp.identity(A.shape[0])).tocsr()
    solver.factorize(A2)
    X = np.random.default_rng(1).standard_normal((A.shape[0], 2))
    np.testing.assert_allclose(solver.solve(A2 @ X), X, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("stored_zero", [False, True])
@pytest.mark.parametrize("kind", ["scipy", "pardiso", "cholmod"])
def test_singular_matrix_raises_not_positive_definite(kind, stored_zero):
    """A zero diagonal entry, stored or not (PARDISO needs every diagonal entry stored)."""
    _need(kind)
    M = sp.csr_matrix(np.diag([2.0, 1.0, 3.0, 0.0]))
    if stored_zero:
        M = sp.csr_matrix((np.array([2.0, 1.0, 3.0, 0.0]), np.arange(4), np.arange(5)))
    with pytest.raises(NotPositiveDefinite):
        make_solver(kind).factorize(M)
