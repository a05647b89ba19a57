"""Cotangent and stretch Laplacians on a fixed sparsity pattern.

Both Laplacians of the paper share one pattern, that of the mesh's edges:

* cotangent Laplacian (eq. 5–6): ``w_ij = ½ Σ (v_i − v_k)·(v_j − v_k) / (2|τ|)`` over the faces
  ``τ = [v_i, v_j, v_k]`` that contain the edge, i.e. ``½ (cot α_ij + cot α_ji)``;
* stretch Laplacian (eq. 12–14): the same expression with the image points ``f(v)`` in the
  numerator and the *surface* area ``|τ|`` in the denominator, i.e. ``½ Σ cot α_ij(f) / σ(τ)``
  with the stretch factor ``σ(τ) = |τ| / |f(τ)|`` (eq. 10);

and ``L_ij = −w_ij``, ``L_ii = Σ_k w_ik``. So the pattern — the CSR index arrays of the blocks
``L_II``, ``L_IB``, ``L_BB`` and where every edge weight and every diagonal entry lands in their
``data`` arrays — is computed once (:func:`laplacian_pattern`); an iteration only computes the
edge weights (for SEM one sparse product, :func:`stretch_weight_map`) and writes the diagonal
and the block values in one compiled pass (:func:`laplacian_blocks`). No COO→CSR conversion, no
sorting and no sparse fancy indexing happens inside the SEM loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from . import _kernels


@dataclass(frozen=True)
class LaplacianPattern:
    """Sparsity pattern of a mesh Laplacian split into interior (I) and boundary (B) blocks.

    ``corner_edge[t, c]`` is the edge opposite corner ``c`` of face ``t``; ``edges`` are the unique
    undirected edges. For each block, ``*_src`` indexes the vector ``[−w (E entries), d (n entries)]``
    (negated edge weights followed by the diagonal) to fill that block's CSR ``data``.
    """

    n: int
    edges: np.ndarray          # E×2, i < j
    corner_edge: np.ndarray    # m×3
    interior: np.ndarray       # nI, sorted vertex indices
    boundary: np.ndarray       # nB, the boundary loop in order
    II: sp.csr_matrix          # structure only; data overwritten by laplacian_blocks
    IB: sp.csr_matrix
    BB: sp.csr_matrix
    II_src: np.ndarray
    IB_src: np.ndarray
    BB_src: np.ndarray


def unique_edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges (E×2, i < j, sorted) and, for every face corner, the opposite
    edge (m×3). Corner c of face t is opposite the edge (F[t, c+1], F[t, c+2]). A compiled
    counting sort by the smaller vertex, linear in m (``np.unique`` of the 3m edge keys would sort
    them); the result equals that ``np.unique``'s."""
    F = np.ascontiguousarray(F, dtype=np.int64)
    n = int(F.max()) + 1 if F.size else 0
    return _kernels.unique_edges(F.reshape(-1, 3), n)


def _block(edges: np.ndarray, rows_of: np.ndarray, cols_of: np.ndarray, n_rows: int,
           n_cols: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """CSR structure (int32 indices, sorted rows, zero ``data``) of one block of ``L`` —
    both directions of every edge and the diagonal, at the rows ``rows_of`` and columns
    ``cols_of`` of the vertices in it (−1 outside) — and for each stored entry the index of
    its value in ``[−w (E entries), d (n entries)]`` (:func:`._kernels.laplacian_block`, one
    counting pass; built once per mesh)."""
    indptr, indices, ids = _kernels.laplacian_block(edges, rows_of, cols_of, n_rows)
    M = sp.csr_matrix((np.zeros(len(ids)), indices, indptr), shape=(n_rows, n_cols))
    M.has_sorted_indices = True
    return M, ids


def laplacian_pattern(F: np.ndarray, n: int, boundary: np.ndarray) -> LaplacianPattern:
    """Precompute the block structure of ``L`` for the interior/boundary split given by the
    ordered boundary loop (Algorithm 1 solves with ``L_II``, ``L_BB`` and multiplies by ``L_IB``)."""
    edges, corner_edge = unique_edges(F)
    boundary = np.asarray(boundary, dtype=np.int64)
    is_b = np.zeros(n, dtype=bool)
    is_b[boundary] = True
    interior = np.flatnonzero(~is_b)
    pos_I = np.full(n, -1, dtype=np.int64)
    pos_I[interior] = np.arange(len(interior))
    pos_B = np.full(n, -1, dtype=np.int64)
    pos_B[boundary] = np.arange(len(boundary))

    II, II_src = _block(edges, pos_I, pos_I, len(interior), len(interior))
    IB, IB_src = _block(edges, pos_I, pos_B, len(interior), len(boundary))
    BB, BB_src = _block(edges, pos_B, pos_B, len(boundary), len(boundary))
    return LaplacianPattern(n, edges, corner_edge, interior, boundary,
                            II, IB, BB, II_src, IB_src, BB_src)


def face_double_areas(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Twice the unsigned area of every face, ``2|τ|``, for 2D or 3D points (the corners'
    rows gathered by ``take``, faster than the fancy index)."""
    P0 = P.take(F[:, 0], axis=0)
    e1 = P.take(F[:, 1], axis=0) - P0
    e2 = P.take(F[:, 2], axis=0) - P0
    if P.shape[1] == 2:
        return np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    cx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    cy = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    cz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return np.sqrt(cx * cx + cy * cy + cz * cz)


def corner_dot_over_area(P: np.ndarray, F: np.ndarray, double_area: np.ndarray) -> np.ndarray:
    """``(p_j − p_i)·(p_k − p_i) / (2|τ|)`` at every corner i of every face (m×3).

    With ``P = V`` and ``2|τ|`` the face's own doubled area this is ``cot`` of the corner angle
    (eq. 5); with ``P = f`` (the disk map) and the *surface* area it is the stretch weight term of
    eq. (12), ``cot α(f) / σ(τ)``. With the edge vectors ``d_c = p_{c+1} − p_c`` of each face, the
    dot product at corner c is ``−d_c · d_{c−1}``, accumulated coordinate by coordinate from 0:
    one compiled pass over the faces (:func:`._kernels.corner_dots_over_area`), no cross
    products.

    Parameters
    ----------
    P : (n, d) float array
    F : (m, 3) int array
    double_area : (m,) float array

    Returns
    -------
    (m, 3) float array
    """
    return _kernels.corner_dots_over_area(np.ascontiguousarray(P, dtype=np.float64),
                                          np.ascontiguousarray(F, dtype=np.int64),
                                          np.ascontiguousarray(double_area, dtype=np.float64))


def edge_weights(pattern: LaplacianPattern, corner_values: np.ndarray) -> np.ndarray:
    """``w_ij = ½ Σ`` of the corner values opposite edge ij (eq. 6 / eq. 12), one bincount."""
    return 0.5 * np.bincount(pattern.corner_edge.ravel(), weights=corner_values.ravel(),
                             minlength=len(pattern.edges))


def stretch_weight_map(pattern: LaplacianPattern, double_area: np.ndarray) -> sp.csr_matrix:
    """The E×E matrix ``W`` with ``w(f) = W ℓ²(f)``: the stretch weights of eq. (12) are a fixed
    linear map of the image's squared edge lengths ``ℓ²_e = |f_i − f_j|²``.

    At the corner of face τ opposite edge e, with the corner's two edges a and b, the law of
    cosines gives ``(f_j − f_i)·(f_k − f_i) = (ℓ²_a + ℓ²_b − ℓ²_e) / 2``, and the term of eq. (12)
    is that over ``2|τ|`` (the surface area, fixed during SEM); ``w_e`` is half the sum over the
    faces on e. So one sparse product (at most 5 nonzeros a row: the edges of the two faces on e)
    replaces the per-corner dot products and their scatter in every SEM iteration. Built by a
    compiled pass that writes the CSR arrays directly (rows sorted, the two ``−s`` of an inner
    edge's own column summed: exactly what a COO → CSR conversion would give, without its
    sort)."""
    E = len(pattern.edges)
    data, indices, indptr = _kernels.stretch_weight_map(
        pattern.corner_edge, np.ascontiguousarray(double_area, dtype=np.float64), E)
    return sp.csr_matrix((data, indices, indptr), shape=(E, E))


def squared_edge_lengths(pattern: LaplacianPattern, f: np.ndarray) -> np.ndarray:
    """``|f_i − f_j|²`` for every edge ij of the pattern, for a complex map f."""
    d = f[pattern.edges[:, 0]] - f[pattern.edges[:, 1]]
    return d.real * d.real + d.imag * d.imag


def laplacian_blocks(pattern: LaplacianPattern, w: np.ndarray
                     ) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """``(L_II, L_IB, L_BB)`` for edge weights ``w``: values written into the fixed pattern
    (eq. 14: ``L_ij = −w_ij``, ``L_ii = Σ_j w_ij``) by one compiled pass."""
    data = [np.empty(M.nnz) for M in (pattern.II, pattern.IB, pattern.BB)]
    _kernels.laplacian_values(np.ascontiguousarray(w, dtype=np.float64), pattern.edges,
                              pattern.II_src, pattern.IB_src, pattern.BB_src,
                              np.empty(pattern.n), *data)
    return tuple(sp.csr_matrix((values, M.indices, M.indptr), shape=M.shape, copy=False)
                 for M, values in zip((pattern.II, pattern.IB, pattern.BB), data))


def laplacian_matrix(F: np.ndarray, n: int, w_edges: np.ndarray, edges: np.ndarray) -> sp.csr_matrix:
    """The full n×n Laplacian for given edge weights (for tests and small problems only)."""
    i, j = edges[:, 0], edges[:, 1]
    W = sp.coo_matrix((np.concatenate([w_edges, w_edges]), (np.concatenate([i, j]),
                                                             np.concatenate([j, i]))), shape=(n, n))
    W = W.tocsr()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()
