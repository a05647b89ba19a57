"""Sparse SPD solvers of SEM, ``pipeline/geometry/solvers.py``: SciPy and CHOLMOD agree on an SPD
Laplacian block, refactor on a kept pattern, and raise ``NotPositiveDefinite`` on matrices that are
not SPD (Remark 1: the blocks are SPD only for positive weights).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.sparse as sp

from pipeline.errors import UserError
from pipeline.geometry.laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                                         laplacian_blocks, laplacian_pattern)
from pipeline.geometry.solvers import (NotPositiveDefinite, cholmod_available, make_solver,
                                       solve_complex)

IN_CI = os.environ.get("CI") == "true"


@pytest.fixture(scope="module")
def spd_block(ddisk):
    P, F, b = ddisk
    pattern = laplacian_pattern(F, len(P), b)
    w = edge_weights(pattern, corner_dot_over_area(P, F, face_double_areas(P, F)))
    L_II = laplacian_blocks(pattern, w)[0]
    assert np.linalg.eigvalsh(L_II.toarray()).min() > 0
    return L_II


def _kinds():
    if cholmod_available():
        return ["scipy", "cholmod"]
    if IN_CI:
        pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
    return ["scipy"]


def test_solvers_agree_on_spd_block(spd_block):
    A = spd_block
    rng = np.random.default_rng(10)
    b = rng.normal(size=A.shape[0]) + 1j * rng.normal(size=A.shape[0])
    ref = np.linalg.solve(A.toarray(), b)
    sols = {}
    for kind in _kinds():
        s = make_solver(kind)
        sols[kind] = solve_complex(s, A, b)
        np.testing.assert_allclose(sols[kind], ref, rtol=1e-10, atol=0)
        # refactorization with new values on the same pattern (reused analysis)
        A2 = A + sp.diags(rng.uniform(0.1, 1.0, A.shape[0]))
        np.testing.assert_allclose(solve_complex(s, A2, b), np.linalg.solve(A2.toarray(), b),
                                   rtol=1e-10)
    if "cholmod" in sols:
        np.testing.assert_allclose(sols["cholmod"], sols["scipy"], rtol=1e-10, atol=0)
    if not cholmod_available():
        pytest.skip("CHOLMOD part skipped: scikit-sparse not installed")


def test_make_solver_rejects_unknown_kind():
    with pytest.raises(UserError):
        make_solver("bogus")
    assert make_solver("scipy").name == "scipy"
    assert make_solver("auto").name == ("cholmod" if cholmod_available() else "scipy")


def _grid_laplacian(m):
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    return (sp.kron(T, sp.identity(m)) + sp.kron(sp.identity(m), T)).tocsr()


@pytest.mark.parametrize("refactored", [False, True])
@pytest.mark.parametrize("case", ["negative_definite", "indefinite", "negative_definite_large"])
@pytest.mark.parametrize("kind", ["scipy", "cholmod"])
def test_non_spd_matrix_raises_not_positive_definite(kind, case, refactored, spd_block):
    """Remark 1: the blocks are SPD only for positive weights; the solvers must say when they are
    not (sem.py catches NotPositiveDefinite). CHOLMOD is supernodal LLᵀ by default and
    simplicial LDLᵀ for refactored systems below SIMPLICIAL_BELOW unknowns (all three cases
    here), where only the pivot check can tell. "large" = 10⁴ unknowns."""
    if kind == "cholmod" and not cholmod_available():
        if IN_CI:
            pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
        pytest.skip("scikit-sparse not installed")
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
def test_cholmod_refactor_to_indefinite_raises_and_drops_the_factor(refactored, spd_block):
    """SEM refactors one pattern with new values: an indefinite matrix after an SPD one must
    raise (not solve with negative LDLᵀ pivots) and leave no usable factor; the next SPD matrix
    is factored again on the kept analysis and solved exactly."""
    if not cholmod_available():
        if IN_CI:
            pytest.fail("scikit-sparse (CHOLMOD) not installed in CI")
        pytest.skip("scikit-sparse not installed")
    A = spd_block
    lam = np.linalg.eigvalsh(A.toarray())
    solver = make_solver("cholmod", refactored=refactored)
    solver.factorize(A)
    assert solver.has_factor()
    with pytest.raises(NotPositiveDefinite):
        solver.factorize((A - np.median(lam) * sp.identity(A.shape[0])).tocsr())
    assert not solver.has_factor()
    A2 = (A + sp.identity(A.shape[0])).tocsr()
    solver.factorize(A2)
    X = np.random.default_rng(1).standard_normal((A.shape[0], 2))
    np.testing.assert_allclose(solver.solve(A2 @ X), X, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kind", ["scipy", "cholmod"])
def test_singular_matrix_raises_not_positive_definite(kind):
    if kind == "cholmod" and not cholmod_available():
        pytest.skip("scikit-sparse not installed")
    M = sp.csr_matrix(np.diag([2.0, 1.0, 3.0, 0.0]))
    with pytest.raises(NotPositiveDefinite):
        make_solver(kind).factorize(M)
