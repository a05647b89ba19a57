# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Compiled inner loop of SEM's flip holding (see ``sem.hold_flipping_vertices``).

Built when the package is installed (``pip install -e .`` runs Cython and the C compiler). A
loop here replaces rounds of small numpy calls whose fixed overhead (~0.1 ms each at 10k faces)
exceeded their arithmetic; the arithmetic is the same, operation for operation, so results are
bit for bit those of the numpy formulas (the module is compiled with ``-ffp-contract=off``).
"""

import numpy as np


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
    cdef double complex e1, e2
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
            e1 = g[F[t, 1]] - g[F[t, 0]]
            e2 = g[F[t, 2]] - g[F[t, 0]]
            area = e1.real * e2.imag - e1.imag * e2.real
            count += (area <= 0) - (a2[t] <= 0)
            a2[t] = area
    return count
