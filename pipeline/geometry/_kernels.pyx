# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Compiled inner loops of SEM's iteration: image areas, Laplacian block values, flip holding.

Built when the package is installed (``pip install -e .`` runs Cython and the C compiler). A
loop here replaces numpy calls whose fixed overhead and temporaries cost more than their
arithmetic at 10k faces, where an SEM iteration's solver floor is ~3 ms. The arithmetic is that
of the numpy formulas they replace, operation for operation and in the same order (the module
is compiled with ``-ffp-contract=off``: no fused multiply-adds), so results are bit for bit the
same.
"""

import numpy as np

ctypedef fused index_t:
    int
    long


def signed_double_areas(const index_t[:, ::1] F, const double complex[::1] z, double[::1] out):
    """``out[t]`` = twice the signed area of image face ``t`` (corners ``z[F[t]]``):
    ``Im(conj(z1 − z0) (z2 − z0))``, positive for counter-clockwise faces."""
    cdef Py_ssize_t t
    for t in range(F.shape[0]):
        out[t] = _double_area(z[F[t, 0]], z[F[t, 1]], z[F[t, 2]])


cdef inline double _double_area(double complex z0, double complex z1, double complex z2
                                ) noexcept nogil:
    cdef double complex e1 = z1 - z0, e2 = z2 - z0
    return e1.real * e2.imag - e1.imag * e2.real


def laplacian_values(const double[::1] w, const long[:, ::1] edges, const long[::1] II_src,
                     const long[::1] IB_src, const long[::1] BB_src, double[::1] diag,
                     double[::1] II, double[::1] IB, double[::1] BB):
    """The stored values of ``L_II``, ``L_IB``, ``L_BB`` for edge weights ``w`` (eq. 14):
    ``L_ij = −w_ij`` and ``L_ii = Σ_j w_ij``. A block's ``*_src[k]`` indexes ``[−w, diag]``.
    The diagonal sums every vertex's edges in increasing edge order, as the incidence product
    it replaces does."""
    cdef Py_ssize_t e, E = w.shape[0]
    diag[:] = 0.0
    for e in range(E):
        diag[edges[e, 0]] += w[e]
        diag[edges[e, 1]] += w[e]
    _gather(w, diag, II_src, II)
    _gather(w, diag, IB_src, IB)
    _gather(w, diag, BB_src, BB)


cdef void _gather(const double[::1] w, const double[::1] diag, const long[::1] src,
                  double[::1] out) noexcept:
    cdef Py_ssize_t k, s, E = w.shape[0]
    for k in range(src.shape[0]):
        s = src[k]
        out[k] = -w[s] if s < E else diag[s - E]


def hold_rounds(const long[:, ::1] F, const int[::1] vf_ptr, const int[::1] vf_idx,
                const double complex[::1] f, double complex[::1] g, double[::1] a2,
                long count, long allowed, int rounds):
    """Hold vertices of flipped faces at ``f`` in ``g`` (in place), round by round, until at most
    ``allowed`` faces of ``g`` are flipped (``a2 <= 0``) or ``rounds`` rounds have run.

    ``a2`` holds twice the signed image area of every face of ``g`` (eq. 15's ``|f(τ)|``, signed)
    and is updated in place; ``vf_ptr``/``vf_idx`` is the vertex–face incidence in CSR form.
    Round 1 holds every vertex of every flipped face; a later round holds the not yet held
    vertices of the faces re-measured in the round before that are still flipped (a face not
    re-measured had all its vertices held already). Returns the new flipped-face count."""
    cdef Py_ssize_t n = f.shape[0], m = F.shape[0]
    cdef Py_ssize_t r, k, c, p, t, v, n_held, n_faces, n_touched = 0
    cdef double area
    is_held_arr = np.zeros(n, dtype=np.uint8)
    seen_arr = np.full(m, -1, dtype=np.int64)
    held_arr = np.empty(n, dtype=np.int64)
    touched_arr = np.empty(m, dtype=np.int64)
    cdef unsigned char[::1] is_held = is_held_arr
    cdef long[::1] seen = seen_arr
    cdef long[::1] held = held_arr
    cdef long[::1] touched = touched_arr
    for r in range(rounds):
        if count <= allowed:
            break
        n_held = 0
        n_faces = m if r == 0 else n_touched
        for k in range(n_faces):
            t = k if r == 0 else touched[k]
            if a2[t] <= 0:
                for c in range(3):
                    v = F[t, c]
                    if not is_held[v]:
                        is_held[v] = 1
                        held[n_held] = v
                        n_held += 1
        if n_held == 0:
            break
        n_touched = 0
        for k in range(n_held):
            v = held[k]
            g[v] = f[v]
            for p in range(vf_ptr[v], vf_ptr[v + 1]):
                t = vf_idx[p]
                if seen[t] != r:
                    seen[t] = r
                    touched[n_touched] = t
                    n_touched += 1
        for k in range(n_touched):
            t = touched[k]
            area = _double_area(g[F[t, 0]], g[F[t, 1]], g[F[t, 2]])
            count += (area <= 0) - (a2[t] <= 0)
            a2[t] = area
    return count
