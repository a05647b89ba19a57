# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Compiled inner loops: SEM's iteration and setup, point location, and remeshing's rounds.

Built when the package is installed (``pip install -e .`` runs Cython and the C compiler). A
loop here replaces numpy calls whose fixed overhead and temporaries (first-touch page faults are
expensive on the project's machines) cost more than their arithmetic: SEM on small meshes,
where an iteration's solves take only milliseconds, and remeshing's dozens of rounds over the
whole mesh.
Each does the arithmetic of the numpy formula it replaces, operation for operation and in the
same order — 3-vector dot products and lengths in the order numpy's einsum sums them on these
machines (x, z, then y) — and the module is compiled with ``-ffp-contract=off`` (no fused
multiply-adds), so maps and remeshes are bit for bit those of the numpy code. Index arrays are
int64 (``int`` only where SciPy's CSR arrays are int32). The OBJ writer's rows are formatted
here too, as Python's ``%`` formats them.
"""

import numpy as np
cimport cython
from libc.math cimport INFINITY, M_PI, NAN, acos, cos, fabs, floor, isfinite, sin, sqrt
from libc.stdint cimport int32_t, int64_t, uint64_t
from libc.stdlib cimport free, malloc, realloc
from libc.string cimport memcpy, strlen


cdef extern from "Python.h":
    char* PyOS_double_to_string(double val, char format_code, int precision, int flags,
                                int* ptype) except NULL
    void PyMem_Free(void* p)
    int Py_DTSF_ADD_DOT_0


def signed_double_areas(const int64_t[:, ::1] F, const double complex[::1] z, double[::1] out):
    """``out[t]`` = twice the signed area of image face ``t`` (corners ``z[F[t]]``):
    ``Im(conj(z1 − z0) (z2 − z0))``, positive for counter-clockwise faces."""
    cdef Py_ssize_t t
    for t in range(F.shape[0]):
        out[t] = _double_area(z[F[t, 0]], z[F[t, 1]], z[F[t, 2]])


cdef inline double _double_area(double complex z0, double complex z1, double complex z2
                                ) noexcept nogil:
    cdef double complex e1 = z1 - z0, e2 = z2 - z0
    return e1.real * e2.imag - e1.imag * e2.real


def laplacian_values(const double[::1] w, const int64_t[:, ::1] edges, const int64_t[::1] II_src,
                     const int64_t[::1] IB_src, const int64_t[::1] BB_src, double[::1] diag,
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


cdef void _gather(const double[::1] w, const double[::1] diag, const int64_t[::1] src,
                  double[::1] out) noexcept:
    cdef Py_ssize_t k, s, E = w.shape[0]
    for k in range(src.shape[0]):
        s = src[k]
        out[k] = -w[s] if s < E else diag[s - E]


def hold_rounds(const int64_t[:, ::1] F, const int[::1] vf_ptr, const int[::1] vf_idx,
                const double complex[::1] f, double complex[::1] g, double[::1] a2,
                int64_t count, int64_t allowed, int rounds):
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
    cdef int64_t[::1] seen = seen_arr
    cdef int64_t[::1] held = held_arr
    cdef int64_t[::1] touched = touched_arr
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


@cython.cdivision(True)
cdef _buckets_by_smaller_end(const int64_t[:, ::1] F, int64_t n, int shift, bint by_larger):
    """The edges ``(F[t, c+shift], F[t, c+shift+1])`` of every corner ``3 t + c`` bucketed by
    their smaller end (a counting sort: in corner order within a bucket), with ``by_larger``
    each bucket sorted by the larger end (insertion sort: a bucket holds a vertex's few
    edges). Returns ``(start, larger end, corner)``, int32 (half the memory traffic of int64:
    the pass is bound by it), bucket ``v`` at ``start[v]:start[v + 1]``."""
    cdef Py_ssize_t m = F.shape[0], N = 3 * m
    cdef Py_ssize_t t, c, k, p, lo_v
    cdef int64_t a, b
    if N >= 2 ** 31 or n >= 2 ** 31:
        raise OverflowError("more than 2**31 half-edges or vertices")
    start_arr = np.zeros(n + 2, dtype=np.int32)
    hi_arr = np.empty(N, dtype=np.int32)
    id_arr = np.empty(N, dtype=np.int32)
    cdef int32_t[::1] start = start_arr, hi = hi_arr, cid_of = id_arr
    for t in range(m):
        for c in range(3):
            a, b = F[t, (c + shift) % 3], F[t, (c + shift + 1) % 3]
            start[(a if a < b else b) + 2] += 1
    for k in range(n):
        start[k + 2] += start[k + 1]
    for t in range(m):                       # start[v + 1]: the next free slot of bucket v
        for c in range(3):
            a, b = F[t, (c + shift) % 3], F[t, (c + shift + 1) % 3]
            lo_v = a if a < b else b
            p = start[lo_v + 1]
            start[lo_v + 1] += 1
            hi[p] = <int32_t>(b if a < b else a)
            cid_of[p] = <int32_t>(3 * t + c)
    for lo_v in range(n if by_larger else 0):
        _sort_run(&hi[0], &cid_of[0], start[lo_v], start[lo_v + 1])
    return start_arr[:n + 1], hi_arr, id_arr


ctypedef fused payload_t:
    int32_t
    int64_t
    double


cdef inline void _sort_run(int32_t* key, payload_t* payload, Py_ssize_t lo, Py_ssize_t hi
                           ) noexcept nogil:
    """Insertion sort of ``key[lo:hi]`` (a run of a few entries), ``payload`` moved along;
    equal keys keep their order."""
    cdef Py_ssize_t p, q
    cdef int32_t k
    cdef payload_t v
    for p in range(lo + 1, hi):
        k, v = key[p], payload[p]
        q = p - 1
        while q >= lo and key[q] > k:
            key[q + 1], payload[q + 1] = key[q], payload[q]
            q -= 1
        key[q + 1], payload[q + 1] = k, v


def unique_edges(const int64_t[:, ::1] F, int64_t n):
    """The unique undirected edges of ``F`` sorted by ``(i, j)`` with ``i < j`` (E×2), and for
    every corner the index of its opposite edge (m×3): what ``np.unique`` of the keys
    ``i·n + j`` gives, by a counting sort on ``i`` and a sort of each vertex's few ``j``
    (O(m) instead of a sort of all 3m keys)."""
    cdef Py_ssize_t m = F.shape[0], p, lo_v, e, E
    start_arr, hi_arr, id_arr = _buckets_by_smaller_end(F, n, 1, True)
    ce_arr = np.empty(3 * m, dtype=np.int64)
    cdef int32_t[::1] start = start_arr, hi = hi_arr, cid_of = id_arr
    cdef int64_t[::1] ce = ce_arr
    E = 0
    for lo_v in range(n):
        for p in range(start[lo_v], start[lo_v + 1]):
            if p == start[lo_v] or hi[p] != hi[p - 1]:
                E += 1
            ce[cid_of[p]] = E - 1
    edges_arr = np.empty((E, 2), dtype=np.int64)
    cdef int64_t[:, ::1] edges = edges_arr
    e = 0
    for lo_v in range(n):
        for p in range(start[lo_v], start[lo_v + 1]):
            if p == start[lo_v] or hi[p] != hi[p - 1]:
                edges[e, 0], edges[e, 1] = lo_v, hi[p]
                e += 1
    return edges_arr, ce_arr.reshape(m, 3)


def stretch_weight_map(const int64_t[:, ::1] corner_edge, const double[::1] double_area, int64_t E):
    """CSR arrays ``(data, indices, indptr)`` of the E×E map ``W`` of
    :func:`pipeline.geometry.laplacian.stretch_weight_map`: for the corner of face τ opposite
    edge e, with the corner's edges a and b, ``+s`` at (e, a) and (e, b) and ``−s`` at (e, e),
    ``s = ¼ / (2|τ|)``; columns sorted in each row, duplicates summed (what a COO → CSR
    conversion gives). Rows are filled, sorted and compacted in place in the output arrays (no
    temporaries: at 1M faces their first-touch page faults cost more than the arithmetic)."""
    cdef Py_ssize_t m = corner_edge.shape[0]
    cdef Py_ssize_t t, c, k, p, r, out, row_start
    cdef int64_t eo
    cdef double s
    fill_arr = np.zeros(E + 1, dtype=np.int64)
    cdef int64_t[::1] fill = fill_arr
    for t in range(m):
        for c in range(3):
            fill[corner_edge[t, c] + 1] += 3
    for k in range(E):
        fill[k + 1] += fill[k]
    indptr_arr = np.empty(E + 1, dtype=np.int32)
    indices_arr = np.empty(9 * m, dtype=np.int32)
    data_arr = np.empty(9 * m, dtype=np.float64)
    cdef int[::1] indptr = indptr_arr
    cdef int32_t[::1] cols = indices_arr
    cdef double[::1] vals = data_arr
    for t in range(m):
        s = 0.25 / double_area[t]
        for c in range(3):
            eo = corner_edge[t, c]
            p = fill[eo]
            fill[eo] += 3
            cols[p], vals[p] = corner_edge[t, (c + 1) % 3], s
            cols[p + 1], vals[p + 1] = corner_edge[t, (c + 2) % 3], s
            cols[p + 2], vals[p + 2] = eo, -s
    # fill[r] is now the end of row r, fill[r - 1] its start
    out = 0
    row_start = 0
    indptr[0] = 0
    for r in range(E):
        _sort_run(&cols[0], &vals[0], row_start, fill[r])   # by column
        for p in range(row_start, fill[r]):               # compact: out <= p always
            if p > row_start and cols[p] == cols[p - 1]:
                vals[out - 1] += vals[p]
            else:
                cols[out], vals[out] = cols[p], vals[p]
                out += 1
        indptr[r + 1] = out
        row_start = fill[r]
    return data_arr[:out], indices_arr[:out], indptr_arr


def stretch_weights(const double[::1] W_data, const int[::1] W_indices, const int[::1] W_indptr,
                    const int64_t[:, ::1] edges, const double complex[::1] f, double[::1] l2,
                    double[::1] w):
    """``w = W ℓ²(f)`` (eq. 12 by :func:`stretch_weight_map`), with ``ℓ²_e = |f_i − f_j|²``
    written into ``l2``: the squared lengths and the CSR product in two passes, summing each
    row in stored order as SciPy's product does."""
    cdef Py_ssize_t e, p, E = edges.shape[0]
    cdef double complex d
    cdef double acc
    for e in range(E):
        d = f[edges[e, 0]] - f[edges[e, 1]]
        l2[e] = d.real * d.real + d.imag * d.imag
    for e in range(E):
        acc = 0.0
        for p in range(W_indptr[e], W_indptr[e + 1]):
            acc = acc + W_data[p] * l2[W_indices[p]]
        w[e] = acc


cdef inline void _store_clean(double* lam, double[:, ::1] bary, Py_ssize_t i) noexcept nogil:
    """The barycentrics ``lam`` (3) clamped at 0 and renormalised to sum 1 (:func:`_clean`),
    into ``bary[i]``."""
    cdef Py_ssize_t c
    _clean(lam)
    for c in range(3):
        bary[i, c] = lam[c]


cdef inline void _clean(double* lam) noexcept nogil:
    """In place, the barycentrics ``lam`` (3) clamped at 0 and renormalised to sum 1."""
    cdef Py_ssize_t c
    cdef double s
    for c in range(3):
        if lam[c] < 0.0:
            lam[c] = 0.0
    s = lam[0] + lam[1] + lam[2]
    for c in range(3):
        lam[c] = lam[c] / s


def walk_rows(const double[:, ::1] uv, const int64_t[:, ::1] F, const int64_t[::1] twin):
    """What a step of :func:`walk_to_faces` reads of a face of ``(uv, F)`` (m faces), one
    64-byte row a face (a cache line: the array starts on a 64-byte boundary): float64
    columns 0–5 its corners' coordinates ``x0 y0 x1 y1 x2 y2``; in the row's last 16 bytes,
    read as int32 (columns 12–14 of the m×16 int32 view), the faces across its three edges
    ``F[f, c] → F[f, c+1]`` (``twin // 3``, −1 at the rim). A walk over a map much finer than
    its steps reads one row a step instead of six places of three arrays.

    Returns
    -------
    (m, 8) float64
    """
    cdef Py_ssize_t f, c, m = F.shape[0]
    cdef int64_t t
    if 3 * m >= 2 ** 31:
        raise ValueError("more than 2**31 half-edges")
    buf = np.zeros(8 * m + 8, dtype=np.float64)
    cdef Py_ssize_t shift = ((-<Py_ssize_t>buf.ctypes.data) % 64) // 8
    out_arr = buf[shift:shift + 8 * m].reshape(m, 8)
    cdef double[:, ::1] out = out_arr
    cdef int32_t[:, ::1] nbr = out_arr.view(np.int32)
    for f in range(m):
        for c in range(3):
            out[f, 2 * c] = uv[F[f, c], 0]
            out[f, 2 * c + 1] = uv[F[f, c], 1]
            t = twin[3 * f + c]
            nbr[f, 12 + c] = <int32_t>(t // 3) if t >= 0 else -1
    return out_arr


cdef inline Py_ssize_t _face_test(const double[:, ::1] rows, int64_t f, double px, double py,
                                   double tol, double* lam) noexcept nogil:
    """A walk step's test of face ``f`` (its row of :func:`walk_rows`) for the point
    ``(px, py)``: −1 when inside (smallest barycentric ≥ ``−tol``; ``lam`` holds them), else the
    corner of the most negative one (the first of the smallest; a NaN counts as smallest)."""
    cdef double ax, ay, bx, by, cx, cy, d
    cdef Py_ssize_t c, cmin = 0
    ax, ay = rows[f, 0] - px, rows[f, 1] - py
    bx, by = rows[f, 2] - px, rows[f, 3] - py
    cx, cy = rows[f, 4] - px, rows[f, 5] - py
    d = ((rows[f, 2] - rows[f, 0]) * (rows[f, 5] - rows[f, 1])
         - (rows[f, 3] - rows[f, 1]) * (rows[f, 4] - rows[f, 0]))
    lam[0] = (bx * cy - by * cx) / d
    lam[1] = (cx * ay - cy * ax) / d
    lam[2] = (ax * by - ay * bx) / d
    for c in range(3):                            # argmin, NaN first (as numpy's)
        if lam[c] != lam[c]:
            cmin = c
            break
        if lam[c] < lam[cmin]:
            cmin = c
    if lam[cmin] >= -tol:                         # False for NaN
        return -1
    return cmin


cdef enum:
    WALK_LANES = 8        # points walked at once by walk_to_faces


def walk_to_faces(const double[:, ::1] rows, const double[:, ::1] P, const int64_t[::1] start,
                  const int64_t[::1] todo, int walk, double tol, int64_t[::1] face,
                  double[:, ::1] bary):
    """Walk each point ``P[i]`` (``i`` in ``todo``) from the face ``start[i]`` of a planar
    triangulation given by its :func:`walk_rows` ``rows``: test the face (:func:`_face_test`:
    barycentrics as :func:`pipeline.geometry.locate.barycentric_coordinates` computes them;
    inside when the smallest is ≥ ``−tol``), else step to the face across the edge of the most
    negative barycentric (the first of the smallest; a NaN counts as smallest), at most
    ``walk`` steps, stopping at the rim. A point found gets ``face[i]`` and its barycentrics
    clamped at 0 and renormalised. Returns the ``todo`` entries not found, in order.

    ``WALK_LANES`` points walk at once, a step of each in turn (a lane takes the next point
    when its own ends): the steps of one point depend on each other, those of different points
    do not, so the processor fetches the next rows of several walks together instead of
    waiting for one row at a time. Each point's walk, and so its answer, is the one it would
    have alone (``start`` may be ``face``: a point's start is read before its face is
    written)."""
    cdef Py_ssize_t n = todo.shape[0], nxt_idx = 0, live = 0, l, i, r
    cdef Py_ssize_t lidx[WALK_LANES]
    cdef int64_t lf[WALK_LANES]
    cdef int lstep[WALK_LANES]
    cdef int64_t g
    cdef double lam[3]
    cdef bint finished
    lost_arr = np.zeros(n, dtype=np.uint8)
    cdef unsigned char[::1] lost = lost_arr
    if rows.shape[0] == 0:
        return np.asarray(todo).copy()
    cdef const int32_t* nbr = <const int32_t*> &rows[0, 0]   # the rows as int32, 16 a row
    for l in range(WALK_LANES):
        if nxt_idx < n:
            lidx[l] = nxt_idx
            lf[l] = start[todo[nxt_idx]]
            lstep[l] = 0
            nxt_idx += 1
            live += 1
        else:
            lidx[l] = -1
    while live > 0:
        for l in range(WALK_LANES):
            if lidx[l] < 0:
                continue
            i = todo[lidx[l]]
            r = _face_test(rows, lf[l], P[i, 0], P[i, 1], tol, lam)
            finished = True
            if r < 0:
                face[i] = lf[l]
                _store_clean(lam, bary, i)
            elif lstep[l] == walk:
                lost[lidx[l]] = 1
            else:
                g = nbr[16 * lf[l] + 12 + (r + 1) % 3]
                if g < 0:
                    lost[lidx[l]] = 1
                else:
                    lf[l] = g
                    lstep[l] += 1
                    finished = False
            if finished:
                if nxt_idx < n:
                    lidx[l] = nxt_idx
                    lf[l] = start[todo[nxt_idx]]
                    lstep[l] = 0
                    nxt_idx += 1
                else:
                    lidx[l] = -1
                    live -= 1
    return np.asarray(todo)[lost_arr.view(np.bool_)]


def sphere_walk_to_faces(const double[:, ::1] S, const int64_t[:, ::1] F,
                         const int64_t[::1] twin, const double[:, ::1] P,
                         const int64_t[::1] start, const int64_t[::1] todo, int walk, double tol,
                         int64_t[::1] face, double[:, ::1] bary):
    """:func:`walk_to_faces` on a spherical triangulation ``(S, F)`` (unit vectors, a closed
    manifold): each direction ``P[i]`` (``i`` in ``todo``) walks from the face ``start[i]``
    with the central-projection barycentrics of
    :func:`pipeline.geometry.locate_sphere.sphere_barycentrics` (``det[p, b, c] = p · ((b − p)
    × (c − p))`` and cyclically, over their sum; all ``−inf`` where the sum is not > 0), inside
    when all are ≥ ``−tol``, else across the edge of the most negative one (the first of the
    smallest, a non-finite one counting as ``−inf``), at most ``walk`` steps. A point found gets
    ``face[i]`` and its barycentrics clamped at 0 and renormalised; one not found gets the last
    face its walk tested in ``face[i]`` (a start to walk on from). A start that is no face of
    ``F`` is not walked from (the point is not found). Returns the ``todo`` entries not
    found."""
    left_arr = np.empty(todo.shape[0], dtype=np.int64)      # the points not found
    cdef int64_t[::1] left = left_arr
    cdef Py_ssize_t idx, i, step, u, cmin, n_left = 0
    cdef int64_t f, nxt
    cdef double p[3]
    cdef double lam[3]
    cdef bint found
    for idx in range(todo.shape[0]):
        i = todo[idx]
        f = start[i]
        for u in range(3):
            p[u] = P[i, u]
        found = False
        for step in range(walk + 1):
            if f < 0 or f >= F.shape[0]:
                break
            cmin = _sphere_exit(S, F, f, p, tol, lam)
            found = cmin < 0
            if found:
                face[i] = f
                _store_clean(lam, bary, i)
            if found or step == walk:
                break
            nxt = twin[3 * f + (cmin + 1) % 3]
            if nxt < 0:
                break
            f = nxt // 3
        if not found:
            face[i] = f
            left[n_left] = i
            n_left += 1
    return left_arr[:n_left]


cdef inline Py_ssize_t _sphere_exit(const double[:, ::1] S, const int64_t[:, ::1] F, int64_t f,
                                    const double* p, double tol, double* lam) noexcept nogil:
    """The central-projection barycentrics of the direction ``p`` in face ``f`` into ``lam``
    (as :func:`sphere_walk_to_faces` defines them); returns −1 when all are ≥ ``−tol``, else
    the corner whose opposite edge a walk crosses (the first of the smallest, a non-finite
    one counting as ``−inf``; 0 where the sum is not > 0)."""
    cdef Py_ssize_t c, u, cmin = 0
    cdef double s, lo_val = INFINITY, v
    cdef double d[3][3]
    cdef double x[3]
    cdef bint ok
    for c in range(3):
        for u in range(3):
            d[c][u] = S[F[f, c], u] - p[u]
    for c in range(3):
        _cross(d[(c + 1) % 3][0], d[(c + 1) % 3][1], d[(c + 1) % 3][2],
               d[(c + 2) % 3][0], d[(c + 2) % 3][1], d[(c + 2) % 3][2], x)
        lam[c] = _dot3(p, x)
    s = lam[0] + lam[1] + lam[2]
    if not s > 0:
        return 0
    ok = True
    for c in range(3):
        lam[c] = lam[c] / s
        ok = ok and lam[c] >= -tol                   # False for NaN
    if ok:
        return -1
    for c in range(3):
        v = lam[c] if isfinite(lam[c]) else -INFINITY
        if v < lo_val:
            cmin, lo_val = c, v
    return cmin


def interior_edge_twins(const int64_t[:, ::1] F, int64_t n):
    """For every half-edge ``3 t + c`` (``F[t, c] → F[t, c+1]``), the other half-edge of its
    undirected edge when exactly two half-edges share it, else −1: half-edges bucketed by their
    smaller end; in each bucket, the half-edges of every larger end counted (the first two
    kept) in one pass and the ends met exactly twice paired in a second, which clears the
    counts."""
    cdef Py_ssize_t p, lo_v
    cdef int32_t v, seen
    start_arr, hi_arr, id_arr = _buckets_by_smaller_end(F, n, 0, False)
    twin_arr = np.full(3 * F.shape[0], -1, dtype=np.int64)
    count_arr = np.zeros(n, dtype=np.int32)
    first_arr = np.empty(n, dtype=np.int32)
    second_arr = np.empty(n, dtype=np.int32)
    cdef int64_t[::1] twin = twin_arr
    cdef int32_t[::1] start = start_arr, hi = hi_arr, hid_of = id_arr
    cdef int32_t[::1] count = count_arr, first = first_arr, second = second_arr
    for lo_v in range(n):
        for p in range(start[lo_v], start[lo_v + 1]):
            v = hi[p]
            seen = count[v]
            if seen == 0:
                first[v] = hid_of[p]
            elif seen == 1:
                second[v] = hid_of[p]
            count[v] = seen + 1
        for p in range(start[lo_v], start[lo_v + 1]):
            v = hi[p]
            if count[v] == 2:
                twin[first[v]] = second[v]
                twin[second[v]] = first[v]
            count[v] = 0
    return twin_arr


cdef inline int64_t _root(int64_t* parent, int64_t v) noexcept nogil:
    """The root of ``v``'s set, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


cdef inline void _join(int64_t* parent, int64_t u, int64_t w) noexcept nogil:
    """Join the sets of ``u`` and ``w``: the larger root is hung under the smaller."""
    u = _root(parent, u)
    w = _root(parent, w)
    if u < w:
        parent[w] = u
    elif w < u:
        parent[u] = w


def face_components(const int64_t[:, ::1] F, int64_t n):
    """``(count, labels)``: the faces of ``F`` (m, 3) over ``n`` vertices linked when they share
    a vertex, each face's component numbered by first face (component 0 holds face 0, the next
    new one in face order is 1, ...). A union-find over the vertices joined along each face's
    corners, then one pass in face order. Raises ValueError for an index outside ``[0, n)``."""
    cdef Py_ssize_t t, c, m = F.shape[0]
    cdef int64_t u, count = 0
    for t in range(m):
        for c in range(3):
            if F[t, c] < 0 or F[t, c] >= n:
                raise ValueError(f"face index {F[t, c]} is outside [0, {n})")
    parent_arr = np.arange(n, dtype=np.int64)
    label_arr = np.full(n, -1, dtype=np.int64)
    out_arr = np.empty(m, dtype=np.int64)
    cdef int64_t[::1] parent_view = parent_arr, label = label_arr, out = out_arr
    cdef int64_t* parent = &parent_view[0] if n else NULL
    with nogil:
        for t in range(m):
            for c in range(2):
                _join(parent, F[t, c], F[t, c + 1])
        for t in range(m):
            u = _root(parent, F[t, 0])
            if label[u] < 0:
                label[u] = count
                count += 1
            out[t] = label[u]
    return int(count), out_arr


def graph_components(const int64_t[::1] r, const int64_t[::1] c, int64_t n):
    """``(count, labels)``: the ``n`` vertices of the undirected graph with the edges
    ``(r[k], c[k])`` (k,) (repeated edges and loops allowed) in connected components, numbered
    by first vertex (component 0 holds vertex 0, the next new one in vertex order is 1, ...):
    the labels (n,) of SciPy's ``connected_components(G, directed=False)`` of the graph. A
    union-find joined along each edge, then one pass in vertex order. Raises ValueError for
    an index outside ``[0, n)``."""
    cdef Py_ssize_t k, e = r.shape[0]
    cdef int64_t v, u, count = 0
    if c.shape[0] != e:
        raise ValueError(f"{e} edge starts and {c.shape[0]} edge ends")
    for k in range(e):
        if r[k] < 0 or r[k] >= n or c[k] < 0 or c[k] >= n:
            raise ValueError(f"edge ({r[k]}, {c[k]}) has an end outside [0, {n})")
    parent_arr = np.arange(n, dtype=np.int64)
    label_arr = np.full(n, -1, dtype=np.int64)
    cdef int64_t[::1] parent_view = parent_arr, label = label_arr
    cdef int64_t* parent = &parent_view[0] if n else NULL
    with nogil:
        for k in range(e):
            _join(parent, r[k], c[k])
        for v in range(n):
            u = _root(parent, v)
            if label[u] < 0:
                label[u] = count
                count += 1
            label[v] = label[u]
    return int(count), label_arr


def fans_per_vertex(const int64_t[::1] a, const int64_t[::1] twin, int64_t n):
    """The number of fans at every vertex of a consistently oriented mesh with manifold edges
    (half-edge ``h`` from ``a[h]``, ``twin`` −1 on the boundary): rotating about the tail of
    ``h`` leads to ``succ[h] = next(twin[h])``, the half-edge from the same vertex in the face
    across ``h``; an open fan is a chain of ``succ`` from a half-edge no other leads to, a
    closed fan a cycle. Counts both by following every chain and then every cycle once."""
    cdef Py_ssize_t h, g, m3 = a.shape[0]
    succ_arr = np.full(m3, -1, dtype=np.int64)
    seen_arr = np.zeros(m3, dtype=np.uint8)
    fans_arr = np.zeros(n, dtype=np.int64)
    cdef int64_t[::1] succ = succ_arr, fans = fans_arr
    cdef unsigned char[::1] seen = seen_arr       # first: has a predecessor; then: visited
    for h in range(m3):
        if twin[h] >= 0:
            succ[h] = 3 * (twin[h] // 3) + (twin[h] % 3 + 1) % 3
            seen[succ[h]] = 1
    for h in range(m3):
        seen[h] = 2 if seen[h] == 0 else 0             # 2: the head of a chain
    for h in range(m3):
        if seen[h] == 2:
            fans[a[h]] += 1
            g = h
            while g >= 0 and seen[g] != 1:
                seen[g] = 1
                g = succ[g]
    for h in range(m3):                                # the rest: cycles
        if seen[h] == 0:
            fans[a[h]] += 1
            g = h
            while g >= 0 and seen[g] == 0:
                seen[g] = 1
                g = succ[g]
    return fans_arr


def group_by_key(const int64_t[::1] keys, const int64_t[::1] values, int64_t n):
    """CSR ``(indptr, grouped values)`` of ``values`` grouped by ``keys`` in ``[0, n)``; a
    stable counting sort (each group keeps the input order)."""
    cdef Py_ssize_t i, k, N = keys.shape[0]
    indptr_arr = np.zeros(n + 1, dtype=np.int64)
    out_arr = np.empty(N, dtype=np.int64)
    cdef int64_t[::1] indptr = indptr_arr, out = out_arr
    for i in range(N):
        indptr[keys[i] + 1] += 1
    for k in range(n):
        indptr[k + 1] += indptr[k]
    fill_arr = indptr_arr[:n].copy()
    cdef int64_t[::1] fill = fill_arr
    for i in range(N):
        out[fill[keys[i]]] = values[i]
        fill[keys[i]] += 1
    return indptr_arr, out_arr


cdef inline bint _in_row(const int64_t[::1] indptr, const int64_t[::1] indices, int64_t a,
                         int64_t b) noexcept nogil:
    """Whether ``b`` stands in row ``a`` of a CSR structure."""
    cdef Py_ssize_t p
    for p in range(indptr[a], indptr[a + 1]):
        if indices[p] == b:
            return True
    return False


def pairs_in_rows(const int64_t[::1] indptr, const int64_t[::1] indices, const int64_t[::1] a,
                  const int64_t[::1] b):
    """For every pair ``(a[i], b[i])``, whether ``b[i]`` stands in row ``a[i]`` of a CSR
    structure (bool)."""
    cdef Py_ssize_t i
    out_arr = np.empty(a.shape[0], dtype=np.bool_)
    cdef unsigned char[::1] out = out_arr.view(np.uint8)
    for i in range(a.shape[0]):
        out[i] = _in_row(indptr, indices, a[i], b[i])
    return out_arr


def short_edge_ends(const int64_t[:, ::1] F, const unsigned char[::1] look,
                    const double[:, ::1] X, double thr, const unsigned char[::1] is_rim,
                    const int64_t[::1] indptr, const int64_t[::1] indices):
    """The ends of the half-edges ``a → b`` shorter than ``thr`` in 3D in the faces of ``F``
    with a corner marked in ``look``, leaving out those whose head stands in the tail's row of
    the CSR structure ``indptr, indices`` (the refused edges): their tails, and the heads of
    those whose tail is on the rim. Returns ``(count, ends)``: how many such half-edges, and
    the vertices (n bool) at them."""
    cdef Py_ssize_t t, c, count = 0, n = is_rim.shape[0]
    cdef int64_t a, b
    ends_arr = np.zeros(n, dtype=np.bool_)
    cdef unsigned char[::1] ends = ends_arr.view(np.uint8)
    for t in range(F.shape[0]):
        if not (look[F[t, 0]] | look[F[t, 1]] | look[F[t, 2]]):
            continue
        for c in range(3):
            a, b = F[t, c], F[t, (c + 1) % 3]
            if not _length(X, a, b) < thr or _in_row(indptr, indices, a, b):
                continue
            count += 1
            ends[a] = 1
            if is_rim[a]:
                ends[b] = 1
    return count, ends_arr


def faces_with_mark(const int64_t[:, ::1] F, const unsigned char[::1] mark):
    """The faces with at least one corner ``v`` where ``mark[v]`` is set, in order (k×3):
    ``F[mark[F].any(axis=1)]``."""
    cdef Py_ssize_t t, out = 0
    out_arr = np.empty((F.shape[0], 3), dtype=np.int64)
    cdef int64_t[:, ::1] G = out_arr
    for t in range(F.shape[0]):
        if mark[F[t, 0]] | mark[F[t, 1]] | mark[F[t, 2]]:
            G[out, 0], G[out, 1], G[out, 2] = F[t, 0], F[t, 1], F[t, 2]
            out += 1
    return out_arr[:out]


def renumbered_faces(const int64_t[:, ::1] F, const int64_t[::1] new):
    """The faces ``new[F]`` that keep three distinct corners, in order (k×3): the faces left
    after collapses ``r → new[r]``."""
    cdef Py_ssize_t t, out = 0
    cdef int64_t a, b, c
    out_arr = np.empty((F.shape[0], 3), dtype=np.int64)
    cdef int64_t[:, ::1] G = out_arr
    for t in range(F.shape[0]):
        a, b, c = new[F[t, 0]], new[F[t, 1]], new[F[t, 2]]
        if a != b and b != c and c != a:
            G[out, 0], G[out, 1], G[out, 2] = a, b, c
            out += 1
    return out_arr[:out]


def faces_touching(const int64_t[:, ::1] F, const unsigned char[::1] mark):
    """Boolean mask of the faces with at least one corner ``v`` where ``mark[v]`` is set
    (``mark[F].any(axis=1)`` without the (m, 3) temporary and the slow reduction over a
    length-3 axis)."""
    cdef Py_ssize_t t, m = F.shape[0]
    out_arr = np.empty(m, dtype=np.bool_)
    cdef unsigned char[::1] out = out_arr.view(np.uint8)
    for t in range(m):
        out[t] = mark[F[t, 0]] | mark[F[t, 1]] | mark[F[t, 2]]
    return out_arr


def collapses_valid(const int64_t[::1] a_ptr, const int64_t[::1] a_idx,
                    const int64_t[::1] vf_ptr, const int64_t[::1] vf_idx,
                    const int64_t[:, ::1] F, const int64_t[::1] r, const int64_t[::1] k,
                    const unsigned char[::1] on_boundary, const double[:, ::1] uv,
                    const double[:, ::1] X, const unsigned char[::1] is_rim, double L_max,
                    double shape_min):
    """Whether each collapse ``r[i] → k[i]`` keeps the mesh valid: the link condition (rows
    ``r[i]`` and ``k[i]`` of the adjacency CSR share exactly 1 entry for a boundary edge, 2
    for an interior one) and, for each face of ``r[i]`` (incidence CSR ``vf``) without
    ``k[i]``, rewritten with ``k[i]`` for ``r[i]``: its disk area (twice, signed) above 1e-6 of
    the old one's magnitude, its 3D normal not turned over (positive dot with the old), not
    all three corners on the rim, no edge from ``k[i]`` longer than ``L_max``, and its disk
    shape (:func:`disk_shapes`) not below ``shape_min``."""
    cdef Py_ssize_t i, p, c, step
    cdef int64_t t, common, ri, ki
    cdef int64_t T[3]
    cdef int64_t Tn[3]
    mark_arr = np.full(uv.shape[0], -1, dtype=np.int64)
    ok_arr = np.empty(r.shape[0], dtype=np.bool_)
    cdef int64_t[::1] mark = mark_arr
    cdef unsigned char[::1] ok = ok_arr.view(np.uint8)
    for i in range(r.shape[0]):
        ri, ki = r[i], k[i]
        for p in range(a_ptr[ki], a_ptr[ki + 1]):
            mark[a_idx[p]] = i
        common = 0
        for p in range(a_ptr[ri], a_ptr[ri + 1]):
            if mark[a_idx[p]] == i:
                common += 1
        ok[i] = common == (1 if on_boundary[i] else 2)
        # the faces' edge lengths first: the cheap test that refuses most collapses
        for step in range(2):
            for p in range(vf_ptr[ri], vf_ptr[ri + 1]):
                if not ok[i]:
                    break
                t = vf_idx[p]
                if F[t, 0] == ki or F[t, 1] == ki or F[t, 2] == ki:
                    continue
                for c in range(3):
                    T[c] = F[t, c]
                    Tn[c] = ki if T[c] == ri else T[c]
                if step == 0:
                    ok[i] = not _longest_from(X, Tn, ki) > L_max
                else:
                    ok[i] = not _face_breaks(uv, X, is_rim, T, Tn, shape_min)
    return ok_arr


cdef inline double _longest_from(const double[:, ::1] X, const int64_t* Tn, int64_t kept
                                 ) noexcept nogil:
    """The longest 3D distance from ``kept`` to a corner of the face ``Tn`` (NaNs skipped)."""
    cdef Py_ssize_t c
    cdef double d, longest = 0.0
    for c in range(3):
        d = _length(X, Tn[c], kept)
        if d > longest:
            longest = d
    return longest


cdef inline bint _face_breaks(const double[:, ::1] uv, const double[:, ::1] X,
                              const unsigned char[::1] is_rim, const int64_t* T,
                              const int64_t* Tn, double shape_min) noexcept nogil:
    """Whether the face ``T`` rewritten by a collapse as ``Tn`` fails one of the face tests
    of :func:`collapses_valid` other than the edge length."""
    cdef double old2, new2
    cdef double no[3]
    cdef double nn[3]
    old2 = _signed2(uv, T[0], T[1], T[2])
    new2 = _signed2(uv, Tn[0], Tn[1], Tn[2])
    _normal(X, T[0], T[1], T[2], no)
    _normal(X, Tn[0], Tn[1], Tn[2], nn)
    return ((new2 <= 1e-6 * fabs(old2))
            or (_dot3(no, nn) <= 0)
            or (is_rim[Tn[0]] and is_rim[Tn[1]] and is_rim[Tn[2]])
            or _disk_shape(uv, Tn[0], Tn[1], Tn[2], new2) < shape_min)


cdef inline double _signed2(const double[:, ::1] uv, int64_t a, int64_t b, int64_t c
                            ) noexcept nogil:
    """Twice the signed area of face ``a, b, c`` in the domain: on the plane (two columns) the
    2D cross product; on the unit sphere (three columns) the triple product ``det[a, b, c]``,
    which is the same determinant with the plane's points read as ``(u, v, 1)``, computed as
    ``pipeline.geometry.sphere.triple_products`` does (``remesh.halfedge.double_areas``)."""
    cdef double x0, y0, z0, ux, uy, uz, vx, vy, vz
    if uv.shape[1] == 3:
        x0, y0, z0 = uv[a, 0], uv[a, 1], uv[a, 2]
        ux, uy, uz = uv[b, 0] - x0, uv[b, 1] - y0, uv[b, 2] - z0
        vx, vy, vz = uv[c, 0] - x0, uv[c, 1] - y0, uv[c, 2] - z0
        return x0 * (uy * vz - uz * vy) + y0 * (uz * vx - ux * vz) + z0 * (ux * vy - uy * vx)
    return ((uv[b, 0] - uv[a, 0]) * (uv[c, 1] - uv[a, 1])
            - (uv[b, 1] - uv[a, 1]) * (uv[c, 0] - uv[a, 0]))


cdef inline double _squared(const double[:, ::1] uv, int64_t a, int64_t b) noexcept nogil:
    """``|uv[b] − uv[a]|²`` over the domain's two or three columns."""
    cdef double x = uv[b, 0] - uv[a, 0], y = uv[b, 1] - uv[a, 1], z
    if uv.shape[1] == 3:
        z = uv[b, 2] - uv[a, 2]
        return x * x + y * y + z * z
    return x * x + y * y


cdef inline void _normal(const double[:, ::1] X, int64_t a, int64_t b, int64_t c, double* out
                         ) noexcept nogil:
    """``cross(X[b] − X[a], X[c] − X[a])`` into ``out`` (3), as :func:`..rows.cross`."""
    cdef double e1x = X[b, 0] - X[a, 0], e1y = X[b, 1] - X[a, 1], e1z = X[b, 2] - X[a, 2]
    cdef double e2x = X[c, 0] - X[a, 0], e2y = X[c, 1] - X[a, 1], e2z = X[c, 2] - X[a, 2]
    out[0] = e1y * e2z - e1z * e2y
    out[1] = e1z * e2x - e1x * e2z
    out[2] = e1x * e2y - e1y * e2x


@cython.cdivision(True)
def grid_cells(const double[:, ::1] uv, const int64_t[:, ::1] F, const double[:, ::1] lo,
               const double[:, ::1] hi, double ox, double oy, double cell, int64_t nx,
               int64_t ny):
    """The grid table of :class:`pipeline.geometry.locate.PointLocator`: every face
    registered in the cells of its bounding box ``lo``–``hi`` (m×2 each; cell
    ``clip(floor((p − origin) / cell), 0, n − 1)`` per axis, origin ``(ox, oy)``, ``nx × ny``
    cells, numbered ``cy · nx + cx``), a face of more than two such cells only in those
    :func:`_cell_touches_face` admits.

    Returns
    -------
    cell_faces : (p,) int64
        The faces, cell by cell, in face order within a cell.
    cell_start : (nx · ny + 1,) int64
        Cell ``c``'s faces at ``cell_faces[cell_start[c]:cell_start[c + 1]]``.
    """
    cdef Py_ssize_t t, j, m = F.shape[0], total = 0, p = 0
    cdef int64_t k, w, count, cx, cy, c, n_cells = nx * ny
    box_arr = np.empty((m, 4), dtype=np.int64)
    cdef int64_t[:, ::1] box = box_arr
    for t in range(m):
        box[t, 0] = _cell_index((lo[t, 0] - ox) / cell, nx)
        box[t, 1] = _cell_index((lo[t, 1] - oy) / cell, ny)
        box[t, 2] = _cell_index((hi[t, 0] - ox) / cell, nx)
        box[t, 3] = _cell_index((hi[t, 1] - oy) / cell, ny)
        total += (box[t, 2] - box[t, 0] + 1) * (box[t, 3] - box[t, 1] + 1)
    pair_cell_arr = np.empty(total, dtype=np.int64)
    pair_face_arr = np.empty(total, dtype=np.int64)
    start_arr = np.zeros(n_cells + 2, dtype=np.int64)
    cdef int64_t[::1] pair_cell = pair_cell_arr, pair_face = pair_face_arr, start = start_arr
    for t in range(m):
        w = box[t, 2] - box[t, 0] + 1
        count = w * (box[t, 3] - box[t, 1] + 1)
        for k in range(count):
            cx, cy = box[t, 0] + k % w, box[t, 1] + k // w
            if count > 2 and not _cell_touches_face(uv, F, t, cx, cy, ox, oy, cell):
                continue
            c = cy * nx + cx
            pair_cell[p], pair_face[p] = c, t
            p += 1
            start[c + 2] += 1
    for c in range(n_cells):
        start[c + 2] += start[c + 1]
    faces_arr = np.empty(p, dtype=np.int64)
    cdef int64_t[::1] faces = faces_arr
    for j in range(p):                       # start[c + 1]: the next free slot of cell c
        c = pair_cell[j]
        faces[start[c + 1]] = pair_face[j]
        start[c + 1] += 1
    return faces_arr, start_arr[:n_cells + 1]


cdef inline bint _cell_touches_face(const double[:, ::1] uv, const int64_t[:, ::1] F,
                                    int64_t f, int64_t cx, int64_t cy, double ox, double oy,
                                    double cell) noexcept nogil:
    """Whether the closed grid cell ``(cx, cy)`` (origin ``(ox, oy)``, side ``cell``) can
    meet the image face ``f`` (either orientation): False only when the whole cell lies
    strictly outside the line of one edge — the cell corner that minimises ``n·x`` for the
    edge's outward normal ``n`` is farther out than a margin of 1e-9 cell sizes, so points on
    cell borders are never missed."""
    cdef Py_ssize_t c
    cdef double x0, y0, A2, s, px, py, qx, qy, nx, ny, mx, my, dist
    cdef double tx[3]
    cdef double ty[3]
    for c in range(3):
        tx[c], ty[c] = uv[F[f, c], 0], uv[F[f, c], 1]
    x0 = ox + <double>cx * cell
    y0 = oy + <double>cy * cell
    A2 = (tx[1] - tx[0]) * (ty[2] - ty[0]) - (ty[1] - ty[0]) * (tx[2] - tx[0])
    s = -1.0 if A2 < 0 else 1.0
    for c in range(3):
        px, py, qx, qy = tx[c], ty[c], tx[(c + 1) % 3], ty[(c + 1) % 3]
        nx, ny = s * (qy - py), (-s) * (qx - px)
        mx = x0 if nx > 0 else x0 + cell
        my = y0 if ny > 0 else y0 + cell
        dist = nx * (mx - px) + ny * (my - py)
        if not dist <= 1e-9 * cell * (fabs(nx) + fabs(ny)):
            return False
    return True


@cython.cdivision(True)
def grid_candidates(const double[:, ::1] uv, const int64_t[:, ::1] F,
                    const int64_t[::1] cell_start, const int64_t[::1] cell_faces,
                    const double[:, ::1] P, double ox, double oy, double cell, int64_t nx,
                    int64_t ny):
    """For each point ``P[i]``, the best face of its grid cell (origin ``(ox, oy)``, side
    ``cell``, ``nx × ny`` cells; the CSR table ``cell_start``, ``cell_faces`` of
    :class:`pipeline.geometry.locate.PointLocator`): the first of the largest smallest
    barycentric, the barycentrics as :func:`pipeline.geometry.locate.barycentric_coordinates`
    computes them, a non-finite smallest one counted as −inf. The point's cell is
    ``floor((P − origin) / cell)`` clipped to the grid, as numpy's ``astype(int64)`` and
    ``clip`` make it (NaN and values beyond int64 become the first cell).

    Returns
    -------
    face : (k,) int64
        −1 where the cell is empty.
    bary : (k, 3) float64
        NaN where the cell is empty.
    score : (k,) float64
        The smallest barycentric, −inf where the cell is empty.
    """
    cdef Py_ssize_t i, c, k = P.shape[0]
    cdef int64_t j, f, ix, iy, cl, best_f
    cdef double q, px, py, ax, ay, bx, by, cx, cy, d, sc, best
    cdef double lam[3]
    cdef double best_lam[3]
    face_arr = np.empty(k, dtype=np.int64)
    bary_arr = np.empty((k, 3), dtype=np.float64)
    score_arr = np.empty(k, dtype=np.float64)
    cdef int64_t[::1] face = face_arr
    cdef double[:, ::1] bary = bary_arr
    cdef double[::1] score = score_arr
    for i in range(k):
        px, py = P[i, 0], P[i, 1]
        ix = _cell_index((px - ox) / cell, nx)
        iy = _cell_index((py - oy) / cell, ny)
        cl = iy * nx + ix
        best_f = -1
        best = -INFINITY
        best_lam[0] = best_lam[1] = best_lam[2] = NAN
        for j in range(cell_start[cl], cell_start[cl + 1]):
            f = cell_faces[j]
            ax, ay = uv[F[f, 0], 0] - px, uv[F[f, 0], 1] - py
            bx, by = uv[F[f, 1], 0] - px, uv[F[f, 1], 1] - py
            cx, cy = uv[F[f, 2], 0] - px, uv[F[f, 2], 1] - py
            d = ((uv[F[f, 1], 0] - uv[F[f, 0], 0]) * (uv[F[f, 2], 1] - uv[F[f, 0], 1])
                 - (uv[F[f, 1], 1] - uv[F[f, 0], 1]) * (uv[F[f, 2], 0] - uv[F[f, 0], 0]))
            lam[0] = (bx * cy - by * cx) / d
            lam[1] = (cx * ay - cy * ax) / d
            lam[2] = (ax * by - ay * bx) / d
            sc = lam[0]
            for c in range(1, 3):                 # np.minimum: a NaN wins, ties the second
                if lam[c] != lam[c] or lam[c] <= sc:
                    sc = lam[c] if sc == sc else sc
            if not isfinite(sc):
                sc = -INFINITY
            if best_f < 0 or sc > best:           # the first of the largest
                best_f, best = f, sc
                best_lam[0], best_lam[1], best_lam[2] = lam[0], lam[1], lam[2]
        face[i] = best_f
        score[i] = best
        for c in range(3):
            bary[i, c] = best_lam[c]
    return face_arr, bary_arr, score_arr


cdef inline int64_t _cell_index(double q, int64_t n) noexcept nogil:
    """``clip(floor(q).astype(int64), 0, n − 1)`` as numpy computes it on x86-64 (NaN and
    values beyond the int64 range convert to the smallest int64, clipped to 0)."""
    cdef int64_t i
    q = floor(q)
    if not (q >= -9.2e18 and q <= 9.2e18):
        return 0
    i = <int64_t>q
    if i < 0:
        return 0
    if i > n - 1:
        return n - 1
    return i


def faces_kept_by_collapses(const int64_t[::1] vf_ptr, const int64_t[::1] vf_idx,
                            const int64_t[:, ::1] F, const int64_t[::1] r, const int64_t[::1] k):
    """For collapses ``r[i] → k[i]``, the faces of ``r[i]`` that survive (those without
    ``k[i]``), in the incidence's row order: ``(i of each, the face, the face with r[i]
    replaced by k[i])``."""
    cdef Py_ssize_t i, p, c, out = 0, total = 0
    cdef int64_t t
    for i in range(r.shape[0]):
        total += vf_ptr[r[i] + 1] - vf_ptr[r[i]]
    fr_arr = np.empty(total, dtype=np.int64)
    T_arr = np.empty((total, 3), dtype=np.int64)
    Tn_arr = np.empty((total, 3), dtype=np.int64)
    cdef int64_t[::1] fr = fr_arr
    cdef int64_t[:, ::1] T = T_arr, Tn = Tn_arr
    for i in range(r.shape[0]):
        for p in range(vf_ptr[r[i]], vf_ptr[r[i] + 1]):
            t = vf_idx[p]
            if F[t, 0] == k[i] or F[t, 1] == k[i] or F[t, 2] == k[i]:
                continue
            fr[out] = i
            for c in range(3):
                T[out, c] = F[t, c]
                Tn[out, c] = k[i] if F[t, c] == r[i] else F[t, c]
            out += 1
    return fr_arr[:out], T_arr[:out], Tn_arr[:out]


def ring_minima(const int64_t[::1] pr, const int64_t[::1] pv, const int64_t[::1] prank,
                unsigned char[::1] open_, int64_t[::1] best):
    """One pass of a greedy independent set over closed rings: the open candidates whose rank
    is the smallest at every vertex of their ring among the open candidates', which it closes.

    Parameters
    ----------
    pr, pv, prank : (p,) int64
        The rings as pairs: entry ``j`` puts vertex ``pv[j]`` in the ring of candidate
        ``pr[j]``, whose rank (distinct per candidate, ``0 <= rank < c``) is ``prank[j]``.
    open_ : (c,) uint8
        The candidates still open; the winners are set to 0.
    best : (n,) int64
        Scratch, ``c`` at every vertex on entry, and so again on return.

    Returns
    -------
    (w,) int64
        The winners, increasing: what ``flatnonzero(open_ & (lost == 0))`` gives with
        ``best = minimum.at`` over the open entries and ``lost`` the count of their entries
        where ``best[pv] != prank``.
    """
    cdef Py_ssize_t j, i, w = 0, p = pr.shape[0], c = open_.shape[0]
    lost_arr = np.zeros(c, dtype=np.uint8)
    cdef unsigned char[::1] lost = lost_arr
    for j in range(p):
        if open_[pr[j]] and prank[j] < best[pv[j]]:
            best[pv[j]] = prank[j]
    for j in range(p):
        if open_[pr[j]] and best[pv[j]] != prank[j]:
            lost[pr[j]] = 1
    for j in range(p):
        best[pv[j]] = c
    win_arr = np.empty(c, dtype=np.int64)
    cdef int64_t[::1] win = win_arr
    for i in range(c):
        if open_[i] and not lost[i]:
            win[w] = i
            w += 1
            open_[i] = 0
    return win_arr[:w]


def close_rings_of(const int64_t[::1] pr, const int64_t[::1] pv, const int64_t[:] w,
                   unsigned char[::1] taken, unsigned char[::1] open_):
    """Mark the closed rings of the candidates ``w`` taken and close every candidate whose
    ring has a taken vertex: ``taken[pv[isin(pr, w)]] = 1``, then ``open_[pr[j]] = 0``
    wherever ``taken[pv[j]]``.

    Parameters
    ----------
    pr, pv : (p,) int64
        The rings as pairs (see :func:`ring_minima`).
    w : (k,) int64
        Candidates, ``0 <= w < c``.
    taken : (n,) uint8
        The vertices of taken rings; updated.
    open_ : (c,) uint8
        The candidates still open; updated.
    """
    cdef Py_ssize_t j, p = pr.shape[0]
    mark_arr = np.zeros(open_.shape[0], dtype=np.uint8)
    cdef unsigned char[::1] mark = mark_arr
    for j in range(w.shape[0]):
        mark[w[j]] = 1
    for j in range(p):
        if mark[pr[j]]:
            taken[pv[j]] = 1
    for j in range(p):
        if taken[pv[j]]:
            open_[pr[j]] = 0


def lift_rows(const double[:, ::1] values, const int64_t[:, ::1] F, const int64_t[::1] face,
              const double[:, ::1] bary):
    """Eq. (1) row by row: ``Σ_c bary[i, c] · values[F[face[i], c]]``, summed over the corners
    in order (k×d)."""
    cdef Py_ssize_t i, j, d = values.shape[1]
    cdef int64_t t0, t1, t2
    out_arr = np.empty((face.shape[0], d), dtype=np.float64)
    cdef double[:, ::1] out = out_arr
    for i in range(face.shape[0]):
        t0, t1, t2 = F[face[i], 0], F[face[i], 1], F[face[i], 2]
        for j in range(d):
            out[i, j] = (bary[i, 0] * values[t0, j] + bary[i, 1] * values[t1, j]
                         + bary[i, 2] * values[t2, j])
    return out_arr


def triangle_points(const double[:, ::1] V, const int64_t[:, ::1] F, const int64_t[::1] face,
                    const double[::1] u, const double[::1] v):
    """Row ``i`` (k×d): the point ``p0 + u' (p1 − p0) + v' (p2 − p0)`` of the triangle
    ``F[face[i]]`` of ``V`` (n×d), with ``(u', v') = (u[i], v[i])``, or ``(1 − u[i], 1 − v[i])``
    where ``u[i] + v[i] > 1`` (reflected into the triangle), one coordinate at a time."""
    cdef Py_ssize_t i, j, d = V.shape[1]
    cdef int64_t t0, t1, t2
    cdef double a, b, x0
    out_arr = np.empty((face.shape[0], d), dtype=np.float64)
    cdef double[:, ::1] out = out_arr
    with nogil:
        for i in range(face.shape[0]):
            a, b = u[i], v[i]
            if a + b > 1:
                a, b = 1 - a, 1 - b
            t0, t1, t2 = F[face[i], 0], F[face[i], 1], F[face[i], 2]
            for j in range(d):
                x0 = V[t0, j]
                out[i, j] = x0 + a * (V[t1, j] - x0) + b * (V[t2, j] - x0)
    return out_arr


def guided_draws(const double[::1] cdf, const int64_t[::1] guide, const double[::1] u,
                 int64_t walk):
    """For each draw ``u[i]`` in [0, 1), the first index of ``cdf`` (m,: non-decreasing, last
    entry 1) whose value exceeds it (``cdf.searchsorted(u, side="right")``): from
    ``guide[max(⌊u[i]·m⌋ − 1, 0)]`` (``guide[j]``: the first index whose value exceeds
    ``j / m``) forward one index at a time, or, when ``walk`` steps do not get there, by
    bisection."""
    cdef Py_ssize_t i, m = cdf.shape[0]
    cdef int64_t t, j, k, lo, hi, mid
    cdef double x
    out_arr = np.empty(u.shape[0], dtype=np.int64)
    cdef int64_t[::1] out = out_arr
    with nogil:
        for i in range(u.shape[0]):
            x = u[i]
            j = <int64_t>(x * <double>m) - 1
            t = guide[j if j > 0 else 0]
            k = 0
            while cdf[t] <= x:
                t += 1
                k += 1
                if k == walk:
                    lo, hi = 0, m
                    while lo < hi:
                        mid = lo + (hi - lo) // 2
                        if cdf[mid] <= x:
                            lo = mid + 1
                        else:
                            hi = mid
                    t = lo
                    break
            out[i] = t
    return out_arr


cdef inline double _length(const double[:, ::1] X, int64_t a, int64_t b) noexcept nogil:
    """``|X[a] − X[b]|`` summing the squares as numpy's einsum does here (x, z, then y)."""
    cdef double dx = X[a, 0] - X[b, 0], dy = X[a, 1] - X[b, 1], dz = X[a, 2] - X[b, 2]
    return sqrt((dx * dx + dz * dz) + dy * dy)


def half_edge_lengths(const int64_t[:, ::1] F, const double[:, ::1] X):
    """3D length of every half-edge ``F[t, c] → F[t, c+1]`` (3m, half-edge order)."""
    cdef Py_ssize_t t, c
    out_arr = np.empty(3 * F.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(F.shape[0]):
        for c in range(3):
            out[3 * t + c] = _length(X, F[t, c], F[t, (c + 1) % 3])
    return out_arr


def edge_halves(const int64_t[:, ::1] F, const int64_t[::1] twin):
    """Every edge of ``F`` once: its half-edge ``h`` with ``twin[h] < 0 or twin[h] > h``, as
    ``(h, a, b, twin[h])`` with ``h = a → b``, in half-edge order."""
    cdef Py_ssize_t h, out = 0, N = 3 * F.shape[0]
    for h in range(N):
        if twin[h] < 0 or twin[h] > h:
            out += 1
    h_arr = np.empty(out, dtype=np.int64)
    a_arr = np.empty(out, dtype=np.int64)
    b_arr = np.empty(out, dtype=np.int64)
    t_arr = np.empty(out, dtype=np.int64)
    cdef int64_t[::1] hs = h_arr, as_ = a_arr, bs = b_arr, ts = t_arr
    out = 0
    for h in range(N):
        if twin[h] >= 0 and twin[h] < h:
            continue
        hs[out], as_[out], ts[out] = h, F[h // 3, h % 3], twin[h]
        bs[out] = F[h // 3, (h % 3 + 1) % 3]
        out += 1
    return h_arr, a_arr, b_arr, t_arr


def short_edges(const int64_t[:, ::1] F, const int64_t[::1] twin, const double[:, ::1] X,
                double thr):
    """Every edge of ``F`` once (its half-edge ``h`` with ``twin[h] < 0 or twin[h] > h``)
    shorter than ``thr`` in 3D: ``(h, a, b, twin[h], length)`` with ``h = a → b``, in
    half-edge order."""
    cdef Py_ssize_t h, out = 0, N = 3 * F.shape[0]
    cdef int64_t a, b
    cdef double ln
    h_arr = np.empty(N, dtype=np.int64)
    a_arr = np.empty(N, dtype=np.int64)
    b_arr = np.empty(N, dtype=np.int64)
    t_arr = np.empty(N, dtype=np.int64)
    l_arr = np.empty(N, dtype=np.float64)
    cdef int64_t[::1] hs = h_arr, as_ = a_arr, bs = b_arr, ts = t_arr
    cdef double[::1] ls = l_arr
    for h in range(N):
        if twin[h] >= 0 and twin[h] < h:
            continue
        a, b = F[h // 3, h % 3], F[h // 3, (h % 3 + 1) % 3]
        ln = _length(X, a, b)
        if ln < thr:
            hs[out], as_[out], bs[out], ts[out], ls[out] = h, a, b, twin[h], ln
            out += 1
    return h_arr[:out], a_arr[:out], b_arr[:out], t_arr[:out], l_arr[:out]


cdef inline double _dot3(const double* a, const double* b) noexcept nogil:
    """``a · b`` summed as numpy's einsum does here (x, z, then y)."""
    return (a[0] * b[0] + a[2] * b[2]) + a[1] * b[1]


def flip_checks(const double[:, ::1] X, const double[:, ::1] uv,
                const unsigned char[::1] is_b, const int64_t[:, ::1] F, const int64_t[::1] h,
                const int64_t[::1] twin, double cos_max):
    """For the interior half-edges ``h`` (``a → b`` in face f, twin in face g, ``p``/``q`` the
    corners opposite in f/g), the quad's corners and two masks: ``flat`` — the normals of f
    and g within the dihedral angle whose cosine is ``cos_max``; ``valid`` — the new faces
    ``(p, a, q)`` and ``(q, b, p)`` agree with the quad's normal in 3D, are counter-clockwise
    on the disk by more than 1e-6 of the quad's area, and have not all three corners on the
    boundary."""
    cdef Py_ssize_t i, j, k = h.shape[0]
    cdef int64_t f, c, g, d, a, b, p, q
    cdef double nf[3]
    cdef double ng[3]
    cdef double n1[3]
    cdef double n2[3]
    cdef double ns[3]
    cdef double s1, s2, scale
    quad_arr = np.empty((4, k), dtype=np.int64)
    flat_arr = np.empty(k, dtype=np.bool_)
    valid_arr = np.empty(k, dtype=np.bool_)
    cdef int64_t[:, ::1] quad = quad_arr
    cdef unsigned char[::1] flat = flat_arr.view(np.uint8), valid = valid_arr.view(np.uint8)
    for i in range(k):
        f, c = h[i] // 3, h[i] % 3
        g, d = twin[h[i]] // 3, twin[h[i]] % 3
        a, b = F[f, c], F[f, (c + 1) % 3]
        p, q = F[f, (c + 2) % 3], F[g, (d + 2) % 3]
        quad[0, i], quad[1, i], quad[2, i], quad[3, i] = a, b, p, q
        _normal(X, a, b, p, nf)
        _normal(X, b, a, q, ng)
        _normal(X, p, a, q, n1)
        _normal(X, q, b, p, n2)
        for j in range(3):
            ns[j] = nf[j] + ng[j]
        flat[i] = _dot3(nf, ng) >= cos_max * sqrt(_dot3(nf, nf)) * sqrt(_dot3(ng, ng))
        s1, s2 = _signed2(uv, p, a, q), _signed2(uv, q, b, p)
        scale = _signed2(uv, a, b, p) + _signed2(uv, b, a, q)
        valid[i] = ((_dot3(n1, ns) > 0) and (_dot3(n2, ns) > 0)
                    and (s1 > 1e-6 * scale) and (s2 > 1e-6 * scale)
                    and not (is_b[p] and is_b[a] and is_b[q])
                    and not (is_b[q] and is_b[b] and is_b[p]))
    return quad_arr, flat_arr, valid_arr


def opposite_cots(const double[:, ::1] X, const int64_t[:, ::1] F):
    """Per face (k×3): column ``c`` is the cotangent of the angle opposite half-edge
    ``F[t,c] → F[t,c+1]``: ``−e_{c+1} · e_{c+2} / |e_0 × e_2|`` with the half-edges
    ``e_c = X[F[t,c+1]] − X[F[t,c]]`` (called by ``remesh.flips._opposite_cots``)."""
    cdef Py_ssize_t t, c, j
    cdef double e[3][3]
    cdef double n[3]
    cdef double inv, area2
    out_arr = np.empty((F.shape[0], 3), dtype=np.float64)
    cdef double[:, ::1] out = out_arr
    for t in range(F.shape[0]):
        for c in range(3):
            for j in range(3):
                e[c][j] = X[F[t, (c + 1) % 3], j] - X[F[t, c], j]
        n[0] = e[0][1] * e[2][2] - e[0][2] * e[2][1]
        n[1] = e[0][2] * e[2][0] - e[0][0] * e[2][2]
        n[2] = e[0][0] * e[2][1] - e[0][1] * e[2][0]
        area2 = sqrt(_dot3(n, n))
        inv = 1.0 / (area2 if not area2 < 1e-300 else 1e-300)     # NaN stays NaN
        out[t, 0] = -_dot3(e[1], e[2]) * inv
        out[t, 1] = -_dot3(e[2], e[0]) * inv
        out[t, 2] = -_dot3(e[0], e[1]) * inv
    return out_arr


cdef inline double _max_nan(double a, double b) noexcept nogil:
    """``np.maximum(a, b)``: NaN if either is."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


cdef inline double _disk_shape(const double[:, ::1] uv, int64_t a, int64_t b, int64_t c,
                               double d2) noexcept nogil:
    """``d2`` (the face's twice signed disk area) over its longest disk edge squared, as
    :func:`pipeline.geometry.remesh.halfedge.disk_shape` computes it."""
    cdef double l0 = _squared(uv, a, b), l1 = _squared(uv, b, c), l2 = _squared(uv, c, a)
    return d2 / _max_nan(_max_nan(_max_nan(l0, l1), l2), 1e-300)


def disk_shapes(const double[:, ::1] uv, const int64_t[:, ::1] F):
    """Per face, twice its signed disk area over its longest disk edge squared (called by
    ``remesh.halfedge.disk_shape``)."""
    cdef Py_ssize_t t
    out_arr = np.empty(F.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(F.shape[0]):
        out[t] = _disk_shape(uv, F[t, 0], F[t, 1], F[t, 2],
                             _signed2(uv, F[t, 0], F[t, 1], F[t, 2]))
    return out_arr


def fan_shapes_ok(const double[:, ::1] U, Py_ssize_t k, Py_ssize_t d, double shape_min):
    """For each of ``k`` positions ``U[i]`` of a vertex whose star has ``d`` faces, whether
    every face ``(i, k + m, k + d + m)`` of the points ``U`` (stacked ``[positions (k), B (d),
    C (d)]``) has a :func:`disk_shapes` value at least ``shape_min`` (k bool; NaN fails):
    ``(disk_shape(U, T) >= shape_min).reshape(k, d).all(axis=1)`` for those faces ``T``."""
    out_arr = np.ones(k, dtype=np.bool_)
    _fan_shapes(U, k, d, shape_min, out_arr.view(np.uint8))
    return out_arr


cdef void _fan_shapes(const double[:, ::1] U, Py_ssize_t k, Py_ssize_t d, double shape_min,
                      unsigned char[::1] out) noexcept:
    """:func:`fan_shapes_ok` into ``out`` (k, set to 1): 0 where a face fails."""
    cdef Py_ssize_t i, m
    cdef int64_t b, c
    for i in range(k):
        for m in range(d):
            b, c = k + m, k + d + m
            if not (_disk_shape(U, i, b, c, _signed2(U, i, b, c)) >= shape_min):
                out[i] = 0
                break


@cython.cdivision(True)
def disk_move_candidates(const double[:, ::1] uv, int64_t v, const int64_t[:, ::1] BC,
                         const double[:, ::1] aimed, const double[::1] steps,
                         const double[:, ::1] dirs, double shape_min):
    """The candidate disk positions of :meth:`..remesh.angles._Patch.move` for the vertex
    ``v`` whose star's faces are ``(v, BC[m, 0], BC[m, 1])`` (d×2), on the disk (``uv``
    n×2), and which keep the star's shape there, operation for operation as the numpy form
    computes them: the rows ``aimed`` (j×2) then the pattern points ``uv[v] + (h · steps[s])
    · dirs[r]`` (row ``j + s·r_count + r``; :func:`..remesh.angles.pattern_points`) with
    ``h`` the shortest disk edge of the star (``sqrt(dx·dx + dy·dy)``, as
    :func:`..rows.norms` computes a 2-vector's length, over ``BC`` in row order), and
    :func:`fan_shapes_ok` of each. Returns ``M`` (k×2) and the indices of those that keep
    the shape (increasing, int64)."""
    cdef Py_ssize_t d = BC.shape[0], j = aimed.shape[0], nd = dirs.shape[0]
    cdef Py_ssize_t k = j + steps.shape[0] * nd, i, m, c, s, r, n_ok = 0
    cdef double h = INFINITY, dx, dy, e, hs
    for m in range(d):
        for c in range(2):
            dx = uv[BC[m, c], 0] - uv[v, 0]
            dy = uv[BC[m, c], 1] - uv[v, 1]
            e = sqrt(dx * dx + dy * dy)
            if e < h or e != e:
                h = e
    U_arr = np.empty((k + 2 * d, 2), dtype=np.float64)
    cdef double[:, ::1] U = U_arr
    for i in range(j):
        U[i, 0] = aimed[i, 0]
        U[i, 1] = aimed[i, 1]
    for s in range(steps.shape[0]):
        hs = h * steps[s]
        for r in range(nd):
            i = j + s * nd + r
            U[i, 0] = uv[v, 0] + hs * dirs[r, 0]
            U[i, 1] = uv[v, 1] + hs * dirs[r, 1]
    for m in range(d):
        for c in range(2):
            U[k + m, c] = uv[BC[m, 0], c]
            U[k + d + m, c] = uv[BC[m, 1], c]
    ok_arr = np.ones(k, dtype=np.uint8)
    cdef unsigned char[::1] ok = ok_arr
    _fan_shapes(U, k, d, shape_min, ok)
    idx_arr = np.empty(k, dtype=np.int64)
    cdef int64_t[::1] idx = idx_arr
    for i in range(k):
        if ok[i]:
            idx[n_ok] = i
            n_ok += 1
    return U_arr[:k], idx_arr[:n_ok]


def domain_double_areas(const double[:, ::1] uv, const int64_t[:, ::1] F):
    """Twice the signed domain area of every face (m), ``remesh.halfedge.double_areas``' 2D
    cross product ``(u1 − u0)(v2 − v0) − (v1 − v0)(u2 − u0)`` (:func:`_signed2`) without its
    six gathered temporaries."""
    cdef Py_ssize_t t, m = F.shape[0]
    out_arr = np.empty(m, dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(m):
        out[t] = _signed2(uv, F[t, 0], F[t, 1], F[t, 2])
    return out_arr


@cython.cdivision(True)
def valence_gains(const int64_t[:, ::1] F, const int64_t[::1] twin, const int64_t[::1] dev):
    """The interior edges whose flip lowers ``Σ dev²`` over the quad's corners, for
    ``remesh.flips.valence_flips``: every half-edge ``h = 3 f + c`` with ``twin[h] > h``
    (``a → b`` with ``p`` the third corner of its face, ``q`` that of the twin's) and its gain
    ``2 (dev[a] + dev[b] − dev[p] − dev[q]) − 4`` when positive (the flip takes one from
    the valences of ``a`` and ``b`` and gives one to ``p`` and ``q``). Returns ``(h, gain)``,
    int64, ``h`` increasing."""
    cdef Py_ssize_t h, k = 0, N = 3 * F.shape[0]
    cdef int64_t f, c, t, g
    h_arr = np.empty(N, dtype=np.int64)
    gain_arr = np.empty(N, dtype=np.int64)
    cdef int64_t[::1] H = h_arr, G = gain_arr
    for h in range(N):
        t = twin[h]
        if t <= h:
            continue
        f = h // 3
        c = h - 3 * f
        g = 2 * (dev[F[f, c]] + dev[F[f, (c + 1) % 3]] - dev[F[f, (c + 2) % 3]]
                 - dev[F[t // 3, (t % 3 + 2) % 3]]) - 4
        if g > 0:
            H[k] = h
            G[k] = g
            k += 1
    return h_arr[:k], gain_arr[:k]


def put_rows(double[:, ::1] dst, const int64_t[::1] rows, const double[:, ::1] src):
    """``dst[rows] = src`` (k rows, ``rows`` distinct), the values copied as they are: numpy's
    fancy assignment of rows without its general index iterator. Raises IndexError for a row
    outside ``[0, len(dst))``."""
    cdef Py_ssize_t i, j, d = dst.shape[1], n = dst.shape[0]
    if src.shape[0] != rows.shape[0] or src.shape[1] != d:
        raise ValueError("put_rows: src must have one row of dst's width per index")
    for i in range(rows.shape[0]):
        if rows[i] < 0 or rows[i] >= n:
            raise IndexError(f"put_rows: row {rows[i]} is outside [0, {n})")
    for i in range(rows.shape[0]):
        for j in range(d):
            dst[rows[i], j] = src[i, j]


def thin_faces(const double[:, ::1] uv, const int64_t[:, ::1] F, const int64_t[::1] faces,
               const double[::1] area_floor, double shape_min):
    """The entries of ``faces`` (increasing, as given) whose twice signed disk area is at most
    ``area_floor[t]`` or whose disk shape is below ``shape_min`` (called by
    ``remesh.relax._thin_among``)."""
    cdef Py_ssize_t i, out = 0
    cdef int64_t t
    cdef double d2
    res_arr = np.empty(faces.shape[0], dtype=np.int64)
    cdef int64_t[::1] res = res_arr
    for i in range(faces.shape[0]):
        t = faces[i]
        d2 = _signed2(uv, F[t, 0], F[t, 1], F[t, 2])
        if d2 <= area_floor[t] or _disk_shape(uv, F[t, 0], F[t, 1], F[t, 2], d2) < shape_min:
            res[out] = t
            out += 1
    return res_arr[:out]


def ring_sums(const double[:, ::1] X, const int64_t[:, ::1] F, int64_t n):
    """Per vertex, over its faces in face order: ``W`` = Σ 2·area, ``G`` = Σ 2·area · centroid
    and ``N`` = Σ 2·area · unit normal (the cross product ``(P1 − P0) × (P2 − P0)``), as
    ``np.bincount`` sums them (called by ``remesh.relax.tangential_smoothing``): the face's
    ``A = |N_f|`` (squares summed x, z, then y), centroid ``((P0 + P1) + P2) / 3``."""
    cdef Py_ssize_t t, c, j
    cdef int64_t v
    cdef double e1[3]
    cdef double e2[3]
    cdef double nf[3]
    cdef double cen[3]
    cdef double A
    W_arr = np.zeros(n, dtype=np.float64)
    G_arr = np.zeros((n, 3), dtype=np.float64)
    N_arr = np.zeros((n, 3), dtype=np.float64)
    cdef double[::1] W = W_arr
    cdef double[:, ::1] G = G_arr, N = N_arr
    for t in range(F.shape[0]):
        for j in range(3):
            e1[j] = X[F[t, 1], j] - X[F[t, 0], j]
            e2[j] = X[F[t, 2], j] - X[F[t, 0], j]
            cen[j] = ((X[F[t, 0], j] + X[F[t, 1], j]) + X[F[t, 2], j]) / 3.0
        nf[0] = e1[1] * e2[2] - e1[2] * e2[1]
        nf[1] = e1[2] * e2[0] - e1[0] * e2[2]
        nf[2] = e1[0] * e2[1] - e1[1] * e2[0]
        A = sqrt(_dot3(nf, nf))
        for c in range(3):
            v = F[t, c]
            W[v] += A
            for j in range(3):
                G[v, j] += A * cen[j]
                N[v, j] += nf[j]
    return W_arr, G_arr, N_arr


@cython.cdivision(True)
def area_equalizing_steps(const double[:, ::1] X, const int64_t[:, ::1] F,
                          const int64_t[::1] mov, const double[:, ::1] D, double mu,
                          double share):
    """The steps of the vertices ``mov`` that even out the areas of their faces while keeping
    close to the centroid steps ``D`` (k×3), for ``remesh.relax.area_equalizing_steps`` (its
    docstring has the formula): per vertex ``H = Σ g gᵀ`` and ``b = Σ g r`` over its faces
    (``g = ∇A_f / Ā``, ``r = share (A_f / Ā − 1)``), then ``(H + β I) d = β D − b`` with
    ``β = μ tr(H) / 2``, solved by Cramer's rule."""
    cdef Py_ssize_t t, c, j, i, k = mov.shape[0], m = F.shape[0], n = X.shape[0]
    cdef int64_t v, a, b
    cdef double e1[3]
    cdef double e2[3]
    cdef double nf[3]
    cdef double g[3]
    cdef double A2, r, inv, beta, det
    cdef double h00, h01, h02, h11, h12, h22, r0, r1, r2
    cnt_arr = np.zeros(n, dtype=np.float64)
    area_arr = np.zeros(n, dtype=np.float64)
    N_arr = np.empty((m, 3), dtype=np.float64)
    A2_arr = np.empty(m, dtype=np.float64)
    H_arr = np.zeros((n, 6), dtype=np.float64)
    R_arr = np.zeros((n, 3), dtype=np.float64)
    out_arr = np.zeros((k, 3), dtype=np.float64)
    cdef double[::1] cnt = cnt_arr, area = area_arr, A2s = A2_arr
    cdef double[:, ::1] H = H_arr, R = R_arr, out = out_arr, N = N_arr
    for t in range(m):
        for j in range(3):
            e1[j] = X[F[t, 1], j] - X[F[t, 0], j]
            e2[j] = X[F[t, 2], j] - X[F[t, 0], j]
        N[t, 0] = e1[1] * e2[2] - e1[2] * e2[1]
        N[t, 1] = e1[2] * e2[0] - e1[0] * e2[2]
        N[t, 2] = e1[0] * e2[1] - e1[1] * e2[0]
        A2s[t] = sqrt(N[t, 0] * N[t, 0] + N[t, 1] * N[t, 1] + N[t, 2] * N[t, 2])
        for c in range(3):
            cnt[F[t, c]] += 1.0
            area[F[t, c]] += 0.5 * A2s[t]
    for v in range(n):
        if cnt[v] > 0:
            area[v] /= cnt[v]                         # the mean area of the vertex's faces
    for t in range(m):
        A2 = A2s[t]
        if A2 <= 0:
            continue
        for j in range(3):
            nf[j] = N[t, j] / A2
        for c in range(3):
            v, a, b = F[t, c], F[t, (c + 1) % 3], F[t, (c + 2) % 3]
            if area[v] <= 0:
                continue
            inv = 1.0 / area[v]
            # g = ½ n × (x_b − x_a) / Ā: the gradient of the face's area at v, scaled
            for j in range(3):
                e1[j] = X[b, j] - X[a, j]
            g[0] = 0.5 * (nf[1] * e1[2] - nf[2] * e1[1]) * inv
            g[1] = 0.5 * (nf[2] * e1[0] - nf[0] * e1[2]) * inv
            g[2] = 0.5 * (nf[0] * e1[1] - nf[1] * e1[0]) * inv
            r = share * (0.5 * A2 * inv - 1.0)
            H[v, 0] += g[0] * g[0]
            H[v, 1] += g[0] * g[1]
            H[v, 2] += g[0] * g[2]
            H[v, 3] += g[1] * g[1]
            H[v, 4] += g[1] * g[2]
            H[v, 5] += g[2] * g[2]
            for j in range(3):
                R[v, j] += g[j] * r
    for i in range(k):
        v = mov[i]
        beta = mu * 0.5 * (H[v, 0] + H[v, 3] + H[v, 5])
        if beta <= 0:
            for j in range(3):
                out[i, j] = D[i, j]
            continue
        h00, h01, h02 = H[v, 0] + beta, H[v, 1], H[v, 2]
        h11, h12, h22 = H[v, 3] + beta, H[v, 4], H[v, 5] + beta
        r0, r1, r2 = beta * D[i, 0] - R[v, 0], beta * D[i, 1] - R[v, 1], beta * D[i, 2] - R[v, 2]
        det = (h00 * (h11 * h22 - h12 * h12) - h01 * (h01 * h22 - h12 * h02)
               + h02 * (h01 * h12 - h11 * h02))
        out[i, 0] = (r0 * (h11 * h22 - h12 * h12) - h01 * (r1 * h22 - h12 * r2)
                     + h02 * (r1 * h12 - h11 * r2)) / det
        out[i, 1] = (h00 * (r1 * h22 - h12 * r2) - r0 * (h01 * h22 - h12 * h02)
                     + h02 * (h01 * r2 - r1 * h02)) / det
        out[i, 2] = (h00 * (h11 * r2 - r1 * h12) - h01 * (h01 * r2 - r1 * h02)
                     + r0 * (h01 * h12 - h11 * h02)) / det
    return out_arr


@cython.cdivision(True)
def corner_cosines(const double[:, ::1] X, const int64_t[:, ::1] F):
    """The cosine of the angle at every corner of every face (m×3), bit for bit
    :func:`..metrics.corner_angles`' ``u·v / (|u| |v|)`` before its ``arccos``: the dot
    summed as numpy's einsum does (x, z, then y), the norms as ``np.linalg.norm`` (x, y,
    then z; a zero norm gives nan or ±inf, as numpy does)."""
    cdef Py_ssize_t t
    out_arr = np.empty((F.shape[0], 3), dtype=np.float64)
    cdef double[:, ::1] out = out_arr
    for t in range(F.shape[0]):
        _face_cosines(&X[F[t, 0], 0], &X[F[t, 1], 0], &X[F[t, 2], 0], &out[t, 0])
    return out_arr


def face_max_cosines(const double[:, ::1] X, const int64_t[:, ::1] F):
    """The largest of every face's :func:`corner_cosines` (m): ``np.maximum`` folded over the
    face's three (nan where one is nan), without the m×3 cosines."""
    cdef Py_ssize_t t
    cdef double cos[3]
    out_arr = np.empty(F.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(F.shape[0]):
        _face_cosines(&X[F[t, 0], 0], &X[F[t, 1], 0], &X[F[t, 2], 0], cos)
        out[t] = _max_nan(_max_nan(cos[0], cos[1]), cos[2])
    return out_arr


@cython.cdivision(True)
cdef inline void _face_cosines(const double* a, const double* b, const double* c, double* out
                               ) noexcept nogil:
    """The cosines at the corners ``a``, ``b``, ``c`` of a triangle (3-vectors) into ``out``
    (3), each :func:`_corner_cosine`'s to the bit with the three edge lengths computed once:
    an edge's squared components are the same whichever way it is run."""
    cdef double ab = _edge_norm(a, b), bc = _edge_norm(b, c), ca = _edge_norm(c, a)
    out[0] = _corner_dot(a, b, c) / (ab * ca)
    out[1] = _corner_dot(b, c, a) / (bc * ab)
    out[2] = _corner_dot(c, a, b) / (ca * bc)


cdef inline double _edge_norm(const double* o, const double* p) noexcept nogil:
    """``|p − o|``, the squares summed x, y, then z."""
    cdef double ux = p[0] - o[0], uy = p[1] - o[1], uz = p[2] - o[2]
    return sqrt((ux * ux + uy * uy) + uz * uz)


cdef inline double _corner_dot(const double* o, const double* p, const double* q
                               ) noexcept nogil:
    """``(p − o) · (q − o)``, summed x, z, then y (as numpy's einsum sums it)."""
    cdef double ux = p[0] - o[0], uy = p[1] - o[1], uz = p[2] - o[2]
    cdef double vx = q[0] - o[0], vy = q[1] - o[1], vz = q[2] - o[2]
    return (ux * vx + uz * vz) + uy * vy


@cython.cdivision(True)
cdef inline double _corner_cosine(const double* o, const double* p, const double* q
                                  ) noexcept nogil:
    """The cosine of the angle at ``o`` of the triangle ``(o, p, q)`` (3-vectors), as
    :func:`corner_cosines` computes it: the dot summed x, z, then y (:func:`_corner_dot`),
    the norms x, y, then z (:func:`_edge_norm`)."""
    return _corner_dot(o, p, q) / (_edge_norm(o, p) * _edge_norm(o, q))


cdef inline void _cross(double ax, double ay, double az, double bx, double by, double bz,
                        double* out) noexcept nogil:
    out[0] = ay * bz - az * by
    out[1] = az * bx - ax * bz
    out[2] = ax * by - ay * bx


@cython.cdivision(True)
cdef inline void _apex(const double* a, const double* b, const double* c, const double* n,
                       double* out) noexcept nogil:
    """The apex of the triangle ``(a, b, c)`` with the normal ``n = (b − a) × (c − a)``
    (3-vectors) that makes it equilateral: ``w = n × (c − b)`` over its length (at least
    1e-300; nan stays nan), turned towards ``a``'s side of ``b–c`` (``w·(a − mid) ≥ 0``),
    ``mid + (√3/2 · |c − b|) · w``."""
    cdef double w[3]
    cdef double ex, ey, ez, mx, my, mz, length, side, h
    cdef double half_root3 = sqrt(3.0) / 2.0
    ex, ey, ez = c[0] - b[0], c[1] - b[1], c[2] - b[2]
    mx, my, mz = 0.5 * (b[0] + c[0]), 0.5 * (b[1] + c[1]), 0.5 * (b[2] + c[2])
    _cross(n[0], n[1], n[2], ex, ey, ez, w)
    length = sqrt((w[0] * w[0] + w[2] * w[2]) + w[1] * w[1])
    if length < 1e-300:
        length = 1e-300
    w[0], w[1], w[2] = w[0] / length, w[1] / length, w[2] / length
    side = ((w[0] * (a[0] - mx) + w[2] * (a[2] - mz)) + w[1] * (a[1] - my))
    if not (side >= 0):
        w[0], w[1], w[2] = w[0] * -1.0, w[1] * -1.0, w[2] * -1.0
    h = half_root3 * sqrt((ex * ex + ez * ez) + ey * ey)
    out[0] = mx + h * w[0]
    out[1] = my + h * w[1]
    out[2] = mz + h * w[2]


@cython.cdivision(True)
def star_targets(const double[:, ::1] X, const int64_t[:, ::1] star, Py_ssize_t worst):
    """For the star ``star`` (d×3, ``(v, B_m, C_m)`` counter-clockwise, ``v`` first) of a
    vertex ``v`` at ``X[v]``, what :meth:`..remesh.angles._Patch.move` computes before its
    steps, operation for operation: the corners ``B = X[star[:, 1]]``, ``C = X[star[:, 2]]``,
    the normals ``N = cross(B − X[v], C − X[v])``, their sum (``N.sum(axis=0)``: from 0, in
    row order, as numpy sums along the first axis) and the relocation targets (3×3): the mean
    of the faces' apexes (:func:`_apex`; summed so, then divided by d), the apex of the face
    ``worst``, and the mean of ``X`` over the distinct vertices of ``star[:, 1:]`` in
    increasing order (as ``X[np.unique(...)].mean(axis=0)``)."""
    cdef Py_ssize_t d = star.shape[0], m, c, i, j, nv = 0
    cdef int64_t v = star[0, 0] if d else 0, w
    cdef double x[3]
    cdef double apex[3]
    B_arr = np.empty((d, 3), dtype=np.float64)
    C_arr = np.empty((d, 3), dtype=np.float64)
    N_arr = np.empty((d, 3), dtype=np.float64)
    T_arr = np.zeros((3, 3), dtype=np.float64)
    S_arr = np.zeros(3, dtype=np.float64)
    V_arr = np.empty(2 * d, dtype=np.int64)
    cdef double[:, ::1] B = B_arr, C = C_arr, N = N_arr, T = T_arr
    cdef double[::1] total = S_arr
    cdef int64_t[::1] verts = V_arr
    for c in range(3):
        x[c] = X[v, c]
    for m in range(d):
        for c in range(3):
            B[m, c] = X[star[m, 1], c]
            C[m, c] = X[star[m, 2], c]
        _cross(B[m, 0] - x[0], B[m, 1] - x[1], B[m, 2] - x[2],
               C[m, 0] - x[0], C[m, 1] - x[1], C[m, 2] - x[2], &N[m, 0])
        _apex(x, &B[m, 0], &C[m, 0], &N[m, 0], apex)
        for c in range(3):
            total[c] = total[c] + N[m, c]
            T[0, c] = T[0, c] + apex[c]
            if m == worst:
                T[1, c] = apex[c]
        for c in range(1, 3):                 # insertion into the sorted distinct vertices
            w = star[m, c]
            i = 0
            while i < nv and verts[i] < w:
                i += 1
            if i < nv and verts[i] == w:
                continue
            for j in range(nv, i, -1):
                verts[j] = verts[j - 1]
            verts[i] = w
            nv += 1
    for i in range(nv):
        for c in range(3):
            T[2, c] = T[2, c] + X[verts[i], c]
    for c in range(3):
        T[0, c] = T[0, c] / <double>d
        T[2, c] = T[2, c] / <double>nv
    return B_arr, C_arr, N_arr, S_arr, T_arr


@cython.cdivision(True)
cdef inline void _fan_face(const double* q, const double* b, const double* c, double* cos_out,
                           double* area_out) noexcept nogil:
    """The largest cosine of the corners of the face ``(q, b, c)`` (3-vectors; those of
    :func:`corner_cosines`, their ``max``: nan where one is nan) and twice its area,
    ``|(b − q) × (c − q)|`` as :func:`..rows.cross` and :func:`..rows.norms` compute it."""
    cdef double P[3][3]
    cdef double N[3]
    cdef double cos, best = -INFINITY
    cdef Py_ssize_t c_, u
    for u in range(3):
        P[0][u] = q[u]
        P[1][u] = b[u]
        P[2][u] = c[u]
    for c_ in range(3):
        cos = _corner_cosine(P[c_], P[(c_ + 1) % 3], P[(c_ + 2) % 3])
        if cos != cos:
            best = NAN
            break
        if cos > best:
            best = cos
    cos_out[0] = best
    _cross(P[1][0] - P[0][0], P[1][1] - P[0][1], P[1][2] - P[0][2],
           P[2][0] - P[0][0], P[2][1] - P[0][1], P[2][2] - P[0][2], N)
    area_out[0] = sqrt((N[0] * N[0] + N[2] * N[2]) + N[1] * N[1])


def face_min_degrees(const double[:, ::1] X, const int64_t[:, ::1] T):
    """The smallest interior angle (degrees, k) of each face ``T`` (k×3) of ``X`` (n×3):
    :func:`..remesh.angles.angles_of_cosines` of the face's largest :func:`corner_cosines`
    (nan where one is nan, then 0), bit for bit, in one pass."""
    cdef Py_ssize_t t
    out_arr = np.empty(T.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(T.shape[0]):
        out[t] = _face_min_degrees(X, T, t)
    return out_arr


cdef inline double _face_min_degrees(const double[:, ::1] X, const int64_t[:, ::1] T,
                                     Py_ssize_t t) noexcept nogil:
    """:func:`face_min_degrees` of the face ``T[t]``."""
    return _corners_min_degrees(X, T[t, 0], T[t, 1], T[t, 2])


def corners_min_degrees(const double[:, ::1] X, int64_t a, int64_t b, int64_t c):
    """:func:`face_min_degrees` of the one face ``(a, b, c)`` of ``X``, as a float."""
    return _corners_min_degrees(X, a, b, c)


cdef inline double _corners_min_degrees(const double[:, ::1] X, int64_t a, int64_t b,
                                        int64_t d) noexcept nogil:
    """The smallest interior angle (degrees) of the face ``(a, b, d)`` of ``X``: the angle of
    its largest corner cosine (nan where one is nan, then 0)."""
    cdef Py_ssize_t c
    cdef int64_t f[3]
    cdef double cos, best = -INFINITY
    f[0], f[1], f[2] = a, b, d
    for c in range(3):
        cos = _corner_cosine(&X[f[c], 0], &X[f[(c + 1) % 3], 0], &X[f[(c + 2) % 3], 0])
        if cos != cos:
            best = NAN
            break
        if cos > best:
            best = cos
    return _degrees_of_cosine(best)


@cython.cdivision(True)
def replacement_angle(const double[:, ::1] X, const int64_t[:, ::1] T, Py_ssize_t n_old,
                      double threshold, bint count_below, double mean_area):
    """The judgement of :meth:`..remesh.angles._Patch.better` in one pass: the faces
    ``T[:n_old]`` (of ``X``) replaced by ``T[n_old:]`` (both non-empty). Their smallest angles
    as :func:`face_min_degrees`; the new faces must have a larger smallest angle, with
    ``count_below`` no more faces below ``threshold``, and with ``mean_area`` (nan: none)
    no larger sum of the squared relative area deviations ``(A / mean_area − 1)²`` (``A``:
    :func:`..laplacian.face_double_areas`' ``sqrt((cx² + cy²) + cz²)``, the sums as numpy's,
    :func:`_pairwise_sum`). Returns the new faces' smallest angle, or nan where they do not
    beat the old ones."""
    cdef Py_ssize_t t, k = T.shape[0]
    cdef double a, min_old = INFINITY, min_new = INFINITY
    cdef Py_ssize_t below_old = 0, below_new = 0
    dev_arr = np.empty(k, dtype=np.float64)
    cdef double[::1] dev = dev_arr
    for t in range(k):
        a = _face_min_degrees(X, T, t)
        if t < n_old:
            min_old = a if a < min_old else min_old
            below_old += a < threshold
        else:
            min_new = a if a < min_new else min_new
            below_new += a < threshold
    if min_new <= min_old:
        return NAN
    if count_below and below_new > below_old:
        return NAN
    if mean_area == mean_area:
        for t in range(k):
            dev[t] = _area_deviation(X, T, t, mean_area)
        if _pairwise_sum(&dev[n_old], k - n_old) > _pairwise_sum(&dev[0], n_old):
            return NAN
    return min_new


@cython.cdivision(True)
cdef inline double _area_deviation(const double[:, ::1] X, const int64_t[:, ::1] T,
                                   Py_ssize_t t, double mean_area) noexcept nogil:
    """The squared relative area deviation ``(A / mean_area − 1)²`` of the face ``T[t]`` of
    ``X`` (``A``: :func:`..laplacian.face_double_areas`' ``sqrt((cx² + cy²) + cz²)``)."""
    cdef Py_ssize_t c
    cdef double e1[3]
    cdef double e2[3]
    cdef double cx, cy, cz, q
    for c in range(3):
        e1[c] = X[T[t, 1], c] - X[T[t, 0], c]
        e2[c] = X[T[t, 2], c] - X[T[t, 0], c]
    cx = e1[1] * e2[2] - e1[2] * e2[1]
    cy = e1[2] * e2[0] - e1[0] * e2[2]
    cz = e1[0] * e2[1] - e1[1] * e2[0]
    q = sqrt((cx * cx + cy * cy) + cz * cz) / mean_area - 1.0
    return q * q


def area_spread(const double[:, ::1] X, const int64_t[:, ::1] T, double mean_area):
    """The sum of the squared relative area deviations ``(A / mean_area − 1)²`` of the faces
    ``T`` (k×3) of ``X`` (:func:`_area_deviation`), as numpy sums them (:func:`_pairwise_sum`,
    then added to 0): :meth:`..remesh.angles._Patch.spread` in one pass."""
    cdef Py_ssize_t t, k = T.shape[0]
    dev_arr = np.empty(max(k, 1), dtype=np.float64)
    cdef double[::1] dev = dev_arr
    for t in range(k):
        dev[t] = _area_deviation(X, T, t, mean_area)
    return 0.0 + _pairwise_sum(&dev[0], k)


def c_library(const double[::1] x, int fn):
    """``acos`` (``fn`` 0), ``cos`` (1) or ``sin`` (2) of each value of ``x`` (n float) as the
    C library computes it, into a new (n,) array (see :mod:`..libm`)."""
    cdef Py_ssize_t i, n = x.shape[0]
    out_arr = np.empty(n)
    cdef double[::1] out = out_arr
    with nogil:
        for i in range(n):
            if fn == 0:
                out[i] = acos(x[i])
            elif fn == 1:
                out[i] = cos(x[i])
            else:
                out[i] = sin(x[i])
    return out_arr


cdef inline double _degrees_of_cosine(double cos) noexcept nogil:
    """The angle (degrees) of ``cos`` as :func:`..remesh.angles.angles_of_cosines` computes
    it: ``np.degrees(np.arccos(np.clip(cos, −1, 1)))``, 0 for nan."""
    if cos != cos:
        cos = 1.0
    if cos < -1.0:
        cos = -1.0
    elif cos > 1.0:
        cos = 1.0
    return acos(cos) * (180.0 / M_PI)


cdef double _pairwise_sum(const double* a, Py_ssize_t n) noexcept nogil:
    """``a[0] + … + a[n − 1]`` summed as numpy's ``sum`` sums a contiguous float64 row (it
    then adds the result to 0): in order below 8 terms; else 8 running sums over blocks of 8,
    combined as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, then the rest in
    order; halves recursively above 128."""
    cdef double r[8]
    cdef double res
    cdef Py_ssize_t i, j, half
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    if n <= 128:
        for j in range(8):
            r[j] = a[j]
        i = 8
        while i < n - (n % 8):
            for j in range(8):
                r[j] += a[i + j]
            i += 8
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        while i < n:
            res += a[i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _pairwise_sum(a, half) + _pairwise_sum(a + half, n - half)


@cython.cdivision(True)
def fan_scores(const double[:, ::1] Q, const double[:, ::1] B, const double[:, ::1] C,
               const unsigned char[::1] inside, double threshold, Py_ssize_t below,
               double mean_area, double spread):
    """The score of each position ``Q[i]`` (k×3) of a vertex whose star's faces are ``(v,
    B[m], C[m])`` (d×3 each): the smallest angle (degrees, :func:`_degrees_of_cosine` of
    :func:`_fan_face`'s cosine; 180 for no face) of the star with ``v`` at ``Q[i]``, or −1
    where ``inside[i]`` is 0, where more than ``below`` faces are under ``threshold`` degrees
    (no such test for ``below < 0``), or where the sum (numpy's, :func:`_pairwise_sum`) of
    the squared relative deviations ``(A / mean_area − 1)²`` of the faces' double areas is
    above ``spread`` (no such test for a NaN ``mean_area``). Returns (k,) float."""
    cdef Py_ssize_t i, m, k = Q.shape[0], d = B.shape[0], count
    cdef double cos, area, angle, low, x
    score_arr = np.empty(k, dtype=np.float64)
    dev_arr = np.empty(max(d, 1), dtype=np.float64)
    cdef double[::1] score = score_arr
    cdef double[::1] dev = dev_arr
    for i in range(k):
        low = 180.0
        count = 0
        for m in range(d):
            _fan_face(&Q[i, 0], &B[m, 0], &C[m, 0], &cos, &area)
            angle = _degrees_of_cosine(cos)
            if angle < threshold:
                count += 1
            if angle < low:
                low = angle
            x = area / mean_area - 1.0
            dev[m] = x * x
        if not inside[i] or (below >= 0 and count > below) or \
                (mean_area == mean_area and 0.0 + _pairwise_sum(&dev[0], d) > spread):
            score[i] = -1.0
        else:
            score[i] = low
    return score_arr


cdef inline double _sphere_face(const double[:, ::1] S, const int64_t[:, ::1] F, Py_ssize_t t,
                                double P[3][3], double edge[3][3], double N[3]):
    """Face ``t`` of ``(S, F)``: its corners ``P``, the edges ``edge[c] = P[c+2] − P[c+1]``
    opposite them, ``N = (P1 − P0) × (P2 − P0)``; returns ``|N|`` (twice its area)."""
    cdef Py_ssize_t c, u
    for c in range(3):
        for u in range(3):
            P[c][u] = S[F[t, c], u]
    for c in range(3):
        for u in range(3):
            edge[c][u] = P[(c + 2) % 3][u] - P[(c + 1) % 3][u]
    _cross(P[1][0] - P[0][0], P[1][1] - P[0][1], P[1][2] - P[0][2],
           P[2][0] - P[0][0], P[2][1] - P[0][1], P[2][2] - P[0][2], N)
    return sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2])


def sphere_gauss_newton_terms(const double[:, ::1] S, const int64_t[:, ::1] F,
                              const double[:, ::1] e1, const double[:, ::1] e2,
                              const double[::1] A2, const double[::1] p, double kappa,
                              const int32_t[::1] slot, const int64_t[:, ::1] pair_index,
                              double[::1] H_upper, double[::1] D_upper, double[::1] g):
    """The per-face sums of :meth:`pipeline.geometry.sphere_newton.SphereGaussNewton.linearize`
    (its numpy form, ``_linearize_numpy``, is the reference; this loop computes the same
    formulas to rounding, not bit for bit): adds into ``H_upper`` / ``D_upper`` (the
    Gauss–Newton matrix and the Laplacian damping, on the distinct upper entries ``slot``
    points at, 21 per face) and ``g`` (2n, interleaved tangent coordinates). Two passes: the
    sums ``Σa``, ``Σb``, ``Σ a²/A`` and the mean corner term first. Returns ``Σa``."""
    cdef Py_ssize_t m = F.shape[0], t, c, j, k, q, u, sj, sk
    cdef double P[3][3]
    cdef double E[3][2][3]
    cdef double edge[3][3]
    cdef double N[3]
    cdef double ga[3][3]
    cdef double gb[3][3]
    cdef double da[6]
    cdef double db[6]
    cdef double dl[21]
    cdef double cot[3]
    cdef double a, b, sa = 0.0, sb = 0.0, energy = 0.0, cot_abs = 0.0, nx, ny, nz
    cdef double scale, ca, cb, wa, wb, w, floor_cot, M = 0.0
    cdef int64_t vi
    cdef int CJ[3]
    cdef int CK[3]
    CJ[0], CJ[1], CJ[2] = 1, 2, 0
    CK[0], CK[1], CK[2] = 2, 0, 1
    # pass 1: sums
    for t in range(m):
        a = _sphere_face(S, F, t, P, edge, N)
        sa += a
        sb += P[0][0] * N[0] + P[0][1] * N[1] + P[0][2] * N[2]
        energy += a * a / A2[t]
        M += A2[t]
        for c in range(3):
            cot_abs += fabs(edge[CK[c]][0] * edge[CJ[c]][0] + edge[CK[c]][1] * edge[CJ[c]][1]
                            + edge[CK[c]][2] * edge[CJ[c]][2]) / A2[t]
    scale = 2.0 * M / (sa * sa)
    floor_cot = 1e-3 * cot_abs / (3.0 * m)
    # pass 2: local terms and scatter
    for t in range(m):
        a = _sphere_face(S, F, t, P, edge, N)
        for c in range(3):
            vi = F[t, c]
            for u in range(3):
                E[c][0][u] = e1[vi, u]
                E[c][1][u] = e2[vi, u]
        b = P[0][0] * N[0] + P[0][1] * N[1] + P[0][2] * N[2]
        nx, ny, nz = N[0] / a, N[1] / a, N[2] / a
        for c in range(3):
            _cross(nx, ny, nz, edge[c][0], edge[c][1], edge[c][2], ga[c])
            j = CJ[c]
            _cross(P[j][0], P[j][1], P[j][2], edge[c][0], edge[c][1], edge[c][2], gb[c])
            for sj in range(2):
                da[2 * c + sj] = (ga[c][0] * E[c][sj][0] + ga[c][1] * E[c][sj][1]
                                  + ga[c][2] * E[c][sj][2])
                db[2 * c + sj] = (gb[c][0] * E[c][sj][0] + gb[c][1] * E[c][sj][1]
                                  + gb[c][2] * E[c][sj][2])
        ca = scale * (a / A2[t] - energy / sa)
        wa = scale / A2[t]
        if kappa != 0.0:
            cb = kappa * (1.0 / sb - p[t] / b)
            wb = kappa * p[t] / (b * b)
        else:
            cb = 0.0
            wb = 0.0
        for c in range(3):
            vi = F[t, c]
            g[2 * vi] += da[2 * c] * ca + db[2 * c] * cb
            g[2 * vi + 1] += da[2 * c + 1] * ca + db[2 * c + 1] * cb
        q = 0
        for u in range(6):
            for j in range(u, 6):
                H_upper[slot[21 * t + q]] += da[u] * da[j] * wa + db[u] * db[j] * wb
                q += 1
        # damping: ½ Σ_(j,k) w |δ_j − δ_k|², w = ½ max(corner term, floor)
        for q in range(21):
            dl[q] = 0.0
        for c in range(3):
            j, k = CJ[c], CK[c]
            cot[c] = -(edge[k][0] * edge[j][0] + edge[k][1] * edge[j][1]
                       + edge[k][2] * edge[j][2]) / A2[t]
            w = 0.5 * (cot[c] if cot[c] > floor_cot else floor_cot)
            for u in (j, k):
                dl[pair_index[2 * u, 2 * u]] += w
                dl[pair_index[2 * u + 1, 2 * u + 1]] += w
            for sj in range(2):
                for sk in range(2):
                    dl[pair_index[2 * j + sj, 2 * k + sk]] -= w * (
                        E[j][sj][0] * E[k][sk][0] + E[j][sj][1] * E[k][sk][1]
                        + E[j][sj][2] * E[k][sk][2])
        for q in range(21):
            D_upper[slot[21 * t + q]] += dl[q]
    return sa


def disk_gauss_newton_terms(const int64_t[:, ::1] F, const double complex[::1] f,
                            const double[::1] residual, const double[::1] inv_area,
                            const int64_t[:, ::1] cols, const unsigned char[:, ::1] on_boundary,
                            const int32_t[:, ::1] slot, double[::1] H_upper, double[::1] g):
    """The per-face sums of :meth:`pipeline.geometry.gauss_newton.GaussNewton.step`: with
    ``d`` the six derivatives of a face's double area by its unknowns (``∂a/∂u_i = v_j − v_k``,
    ``∂a/∂v_i = u_k − u_j``; a boundary corner's ``u`` slot holds ``∂a/∂θ``), adds
    ``d_p d_q / A_τ`` into ``H_upper[slot[t, q]]`` (the 21 pairs ``p ≤ q``; ``slot < 0`` for a
    pair with no unknown) and ``d_p residual_τ / A_τ`` into ``g[cols[t, p]]`` (``cols < 0``:
    none). ``H_upper`` and ``g`` are overwritten."""
    cdef Py_ssize_t m = F.shape[0], t, c, p, q, k
    cdef double u[3]
    cdef double v[3]
    cdef double d[6]
    cdef double w, rw
    cdef int CJ[3]
    cdef int CK[3]
    CJ[0], CJ[1], CJ[2] = 1, 2, 0
    CK[0], CK[1], CK[2] = 2, 0, 1
    H_upper[:] = 0.0
    g[:] = 0.0
    for t in range(m):
        for c in range(3):
            u[c] = f[F[t, c]].real
            v[c] = f[F[t, c]].imag
        for c in range(3):
            d[c] = v[CJ[c]] - v[CK[c]]
            d[3 + c] = u[CK[c]] - u[CJ[c]]
        for c in range(3):
            if on_boundary[t, c]:
                d[c] = -v[c] * d[c] + u[c] * d[3 + c]
        w = inv_area[t]
        rw = residual[t] * w
        for p in range(6):
            if cols[t, p] >= 0:
                g[cols[t, p]] += d[p] * rw
        k = 0
        for p in range(6):
            for q in range(p, 6):
                if slot[t, k] >= 0:
                    H_upper[slot[t, k]] += d[p] * d[q] * w
                k += 1


cdef void _bucket_pairs(const int64_t[:, ::1] cols, int64_t[::1] at, int64_t[::1] cand,
                        bint place):
    """The two passes of a counting sort of every pair ``lo ≤ hi`` of a face's unknowns
    ``cols[t]`` (``< 0``: none) by ``lo``: with ``place`` false, count them (``at[lo + 1]``);
    with ``place`` true, write ``hi`` at ``cand[at[lo]]`` and advance ``at[lo]``."""
    cdef Py_ssize_t t, p, q
    cdef int64_t lo
    for t in range(cols.shape[0]):
        for p in range(6):
            if cols[t, p] < 0:
                continue
            for q in range(p, 6):
                if cols[t, q] >= 0:
                    lo = cols[t, p] if cols[t, p] < cols[t, q] else cols[t, q]
                    if place:
                        cand[at[lo]] = cols[t, p] + cols[t, q] - lo
                        at[lo] += 1
                    else:
                        at[lo + 1] += 1


def face_pair_pattern(const int64_t[:, ::1] cols, int64_t N):
    """The upper triangle of the symmetric N×N pattern that the 21 unknown pairs ``p ≤ q`` of
    every face's six unknowns ``cols[t]`` (``< 0``: none) fill, and where each pair lands:
    returns ``(indptr, indices, slot)``, CSR arrays (int32, sorted rows, each entry once) and
    ``slot`` (m, 21) int32, the entry of each pair (−1 where a pair has no unknown). Rows are
    short on a mesh (one vertex's ring), so each is sorted by insertion."""
    cdef Py_ssize_t m = cols.shape[0], t, p, q, k, r, a, b, i, j, n_unique
    cdef int64_t lo, hi, x
    count_arr = np.zeros(N + 1, dtype=np.int64)
    cdef int64_t[::1] count = count_arr
    _bucket_pairs(cols, count, count, False)
    for r in range(N):
        count[r + 1] += count[r]
    fill_arr = count_arr[:N].copy()
    cand_arr = np.empty(count[N], dtype=np.int64)
    cdef int64_t[::1] cand = cand_arr
    _bucket_pairs(cols, fill_arr, cand, True)
    indptr_arr = np.zeros(N + 1, dtype=np.int32)
    cdef int[::1] indptr = indptr_arr
    n_unique = 0
    for r in range(N):                     # sort each row's candidates, keep each once
        a, b = count[r], count[r + 1]
        for i in range(a + 1, b):
            x = cand[i]
            j = i - 1
            while j >= a and cand[j] > x:
                cand[j + 1] = cand[j]
                j -= 1
            cand[j + 1] = x
        for i in range(a, b):
            if i == a or cand[i] != cand[i - 1]:
                cand[count[0] + n_unique] = cand[i]   # compact in place (never ahead of i)
                n_unique += 1
        indptr[r + 1] = <int>n_unique
    indices_arr = cand_arr[:n_unique].astype(np.int32)
    cdef int[::1] indices = indices_arr
    slot_arr = np.full((m, 21), -1, dtype=np.int32)
    cdef int32_t[:, ::1] slot = slot_arr
    for t in range(m):
        k = 0
        for p in range(6):
            for q in range(p, 6):
                if cols[t, p] >= 0 and cols[t, q] >= 0:
                    lo = cols[t, p] if cols[t, p] < cols[t, q] else cols[t, q]
                    hi = cols[t, p] + cols[t, q] - lo
                    i = indptr[lo]
                    while indices[i] != hi:
                        i += 1
                    slot[t, k] = <int32_t>i
                k += 1
    return indptr_arr, indices_arr, slot_arr


def face_distances(const double[:, ::1] P, const double[:, ::1] V, const int64_t[:, ::1] F,
                   const int64_t[:, ::1] faces):
    """For each point ``P[i]``, the smallest Euclidean distance to the triangles
    ``F[faces[i, j]]`` of ``V`` (a row's −1 entries are skipped; none at all: inf): the
    closest point of each triangle by the Voronoi-region cases of Ericson, *Real-Time
    Collision Detection* §5.1.5, as
    :func:`pipeline.geometry.remesh_quality.closest_points_on_triangles` finds it; a
    degenerate triangle's nearest corner. Each value is a distance to a point of the
    surface, so it bounds the distance to the whole surface from above."""
    cdef Py_ssize_t i, j, c, k = P.shape[0]
    cdef int64_t t
    cdef double best, d
    out_arr = np.empty(k, dtype=np.float64)
    cdef double[::1] out = out_arr
    for i in range(k):
        best = INFINITY
        for j in range(faces.shape[1]):
            t = faces[i, j]
            if t < 0:
                continue
            d = _point_triangle(&P[i, 0], &V[F[t, 0], 0], &V[F[t, 1], 0], &V[F[t, 2], 0])
            if not (d == d and d < INFINITY):            # degenerate: the nearest corner
                d = INFINITY
                for c in range(3):
                    d = min(d, _point_point(&P[i, 0], &V[F[t, c], 0]))
            best = min(best, d)
        out[i] = best
    return out_arr


cdef inline double _point_point(const double* p, const double* q) noexcept nogil:
    return sqrt(_squared_point_point(p, q))


cdef inline double _squared_point_point(const double* p, const double* q) noexcept nogil:
    return (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2


@cython.cdivision(True)
cdef void _closest_on_triangle(const double* p, const double* a, const double* b,
                               const double* c, double* q) noexcept nogil:
    """The closest point ``q`` of the triangle ``(a, b, c)`` to ``p`` (3-vectors) by the
    Voronoi-region cases of Ericson, *Real-Time Collision Detection* §5.1.5, in the order of
    :func:`..remesh_quality.closest_points_on_triangles`' priority: the corners a, b, c, then
    the edges ab, ac, bc, then the face's interior; not finite for a degenerate triangle whose
    interior case divides by zero."""
    cdef double ab[3]
    cdef double ac[3]
    cdef double ap[3]
    cdef double bp[3]
    cdef double cp[3]
    cdef double d1, d2, d3, d4, d5, d6, va, vb, vc, v, w, t, denom
    cdef int x
    for x in range(3):
        ab[x] = b[x] - a[x]
        ac[x] = c[x] - a[x]
        ap[x] = p[x] - a[x]
        bp[x] = p[x] - b[x]
        cp[x] = p[x] - c[x]
    d1, d2 = _dot3(ab, ap), _dot3(ac, ap)
    d3, d4 = _dot3(ab, bp), _dot3(ac, bp)
    d5, d6 = _dot3(ab, cp), _dot3(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    if d1 <= 0 and d2 <= 0:
        for x in range(3):
            q[x] = a[x]
    elif d3 >= 0 and d4 <= d3:
        for x in range(3):
            q[x] = b[x]
    elif d6 >= 0 and d5 <= d6:
        for x in range(3):
            q[x] = c[x]
    elif vc <= 0 and d1 >= 0 and d3 <= 0:
        t = d1 / (d1 - d3)
        for x in range(3):
            q[x] = a[x] + ab[x] * t
    elif vb <= 0 and d2 >= 0 and d6 <= 0:
        t = d2 / (d2 - d6)
        for x in range(3):
            q[x] = a[x] + ac[x] * t
    elif va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        for x in range(3):
            q[x] = b[x] + (c[x] - b[x]) * t
    else:
        denom = (va + vb) + vc
        v = vb / denom
        w = vc / denom
        for x in range(3):
            q[x] = (a[x] + ab[x] * v) + ac[x] * w


cdef double _point_triangle(const double* p, const double* a, const double* b,
                            const double* c) noexcept nogil:
    """Distance from ``p`` to the triangle ``(a, b, c)`` (3-vectors,
    :func:`_closest_on_triangle`); NaN or inf for a degenerate triangle whose face-interior
    case divides by zero."""
    return sqrt(_squared_point_triangle(p, a, b, c))


cdef inline double _squared_point_triangle(const double* p, const double* a, const double* b,
                                           const double* c) noexcept nogil:
    """The square of :func:`_point_triangle` (its distance is the square root of this
    value); NaN or inf for a degenerate triangle whose face-interior case divides by zero."""
    cdef double q[3]
    _closest_on_triangle(p, a, b, c, q)
    return _squared_point_point(p, q)


cdef inline double _squared_point_face(const double* p, const double* a, const double* b,
                                       const double* c) noexcept nogil:
    """:func:`_squared_point_triangle`, or for a degenerate triangle where that is not finite
    the squared distance to its nearest corner."""
    cdef double d = _squared_point_triangle(p, a, b, c)
    if d == d and d < INFINITY:
        return d
    return min(min(_squared_point_point(p, a), _squared_point_point(p, b)),
               _squared_point_point(p, c))


cdef enum:
    _LEAF = 2             # most triangles in a leaf of :func:`triangle_tree`
    _SPATIAL_DEPTH = 40   # deeper nodes of :func:`triangle_tree` split by count
    _STACK = 128          # the walk's stack: deeper than any tree of :func:`triangle_tree`


def triangle_tree(const double[:, ::1] C, int64_t leaf=_LEAF):
    """A bounding-volume hierarchy over triangles given by their centroids ``C`` (k×3): every
    node is a run ``[lo, hi)`` of the triangles in the returned ``order``, split in two at the
    middle of the longest side of its centroids' bounding box (below depth ``_SPATIAL_DEPTH``,
    or where that leaves a side empty, at the middle of the run) until at most ``leaf`` remain;
    the children of a node are consecutive nodes, a node's number below its children's.

    Returns ``(order, child, lo, hi, parent, leaf)``: ``order`` (k,) the triangles' numbers
    leaf by leaf, ``child[n]`` the first child of node ``n`` (−1: a leaf), ``lo``, ``hi`` its
    run of ``order``, ``parent[n]`` its parent (−1: the root, node 0), and ``leaf`` (k,) the
    leaf of each position of ``order``. A tree of no triangles is one empty leaf. (Depth is
    below ``_SPATIAL_DEPTH`` + 64, so :func:`tree_distances`' stack of ``_STACK`` suffices.)"""
    cdef Py_ssize_t k = C.shape[0], cap = max(2 * k - 1, 1), n, m = 1, i, a, b
    order_arr = np.arange(k, dtype=np.int64)
    child_arr = np.full(cap, -1, dtype=np.int64)
    lo_arr = np.zeros(cap, dtype=np.int64)
    hi_arr = np.zeros(cap, dtype=np.int64)
    depth_arr = np.zeros(cap, dtype=np.int64)
    parent_arr = np.full(cap, -1, dtype=np.int64)
    leaf_arr = np.zeros(k, dtype=np.int64)
    cdef int64_t[::1] order = order_arr, child = child_arr, lo = lo_arr, hi = hi_arr
    cdef int64_t[::1] depth = depth_arr, parent = parent_arr, leaf_of = leaf_arr
    cdef int64_t mid, t
    cdef int x, axis
    cdef double cut, c_lo[3], c_hi[3]
    with nogil:
        hi[0] = k
        n = 0
        while n < m:                                     # nodes in breadth-first order
            if hi[n] - lo[n] > leaf:
                a, b = lo[n], hi[n]
                mid = a
                if depth[n] < _SPATIAL_DEPTH:
                    for x in range(3):
                        c_lo[x], c_hi[x] = INFINITY, -INFINITY
                    for i in range(a, b):
                        for x in range(3):
                            c_lo[x] = min(c_lo[x], C[order[i], x])
                            c_hi[x] = max(c_hi[x], C[order[i], x])
                    axis = 0
                    for x in range(1, 3):
                        if c_hi[x] - c_lo[x] > c_hi[axis] - c_lo[axis]:
                            axis = x
                    cut = c_lo[axis] + (c_hi[axis] - c_lo[axis]) / 2
                    for i in range(a, b):                # those below the cut first
                        if C[order[i], axis] < cut:
                            order[i], order[mid] = order[mid], order[i]
                            mid += 1
                if mid == a or mid == b:
                    mid = a + (b - a) // 2
                child[n] = m
                lo[m], hi[m], lo[m + 1], hi[m + 1] = a, mid, mid, b
                depth[m] = depth[m + 1] = depth[n] + 1
                parent[m] = parent[m + 1] = n
                m += 2
            else:
                for i in range(lo[n], hi[n]):
                    leaf_of[i] = n
            n += 1
    return order_arr, child_arr[:m], lo_arr[:m], hi_arr[:m], parent_arr[:m], leaf_arr


def tree_boxes(const double[:, ::1] T, const int64_t[::1] child, const int64_t[::1] lo,
               const int64_t[::1] hi, double margin):
    """The bounding box (n×6: minimum then maximum corner) of each node of a
    :func:`triangle_tree` (``child, lo, hi``) over the triangles ``T`` (k×9: the three corners
    of each, in the tree's order), widened by ``margin`` on every side, so that the rounding of
    a computed point–triangle distance never takes it below its node's box distance."""
    cdef Py_ssize_t n, i, j, x
    box_arr = np.empty((child.shape[0], 6), dtype=np.float64)
    cdef double[:, ::1] box = box_arr
    with nogil:
        for n in range(child.shape[0] - 1, -1, -1):     # children before their parent
            if child[n] < 0:
                for x in range(3):
                    box[n, x], box[n, 3 + x] = INFINITY, -INFINITY
                for i in range(lo[n], hi[n]):
                    for j in range(3):
                        for x in range(3):
                            box[n, x] = min(box[n, x], T[i, 3 * j + x] - margin)
                            box[n, 3 + x] = max(box[n, 3 + x], T[i, 3 * j + x] + margin)
            else:
                for x in range(3):
                    box[n, x] = min(box[child[n], x], box[child[n] + 1, x])
                    box[n, 3 + x] = max(box[child[n], 3 + x], box[child[n] + 1, 3 + x])
    return box_arr


cdef inline double _squared_box_distance(const double* p, const double* b) noexcept nogil:
    """Squared distance from ``p`` to the box ``b`` (minimum then maximum corner)."""
    cdef double s = 0.0, t
    cdef int x
    for x in range(3):
        t = max(max(b[x] - p[x], p[x] - b[3 + x]), 0.0)
        s = s + t * t
    return s


cdef struct _Tree:
    const double* T          # k×9 triangle corners, in the tree's order
    const int64_t* face      # their face numbers
    const int64_t* child
    const int64_t* lo
    const int64_t* hi
    const double* box        # n×6


cdef inline void _leaf_distances(const double* p, const _Tree* tr, int64_t n, double* best,
                                 int64_t* best_t) noexcept nogil:
    """Lower ``best`` (a squared distance) and ``best_t`` (a triangle of the tree's order, −1:
    none yet) to any triangle of the leaf ``n`` closer than it, or as close with a smaller
    face number."""
    cdef int64_t t
    cdef double d
    cdef const double* T
    for t in range(tr.lo[n], tr.hi[n]):
        T = tr.T + 9 * t
        d = _squared_point_face(p, T, T + 3, T + 6)
        if d < best[0] or best_t[0] < 0 or (d == best[0] and tr.face[t] < tr.face[best_t[0]]):
            best[0], best_t[0] = d, t


cdef void _descend(const double* p, const _Tree* tr, int64_t start, double start_d,
                   double* best, int64_t* best_t) noexcept nogil:
    """:func:`_leaf_distances` over every leaf below the node ``start`` (whose box's squared
    distance is ``start_d``) that may hold a closer triangle: depth first, the nearer child
    first, skipping a node whose box lies farther than ``best``."""
    cdef int64_t stack[_STACK]
    cdef double stack_d[_STACK]
    cdef int64_t top = 1, n, c
    cdef double d0, d1
    stack[0], stack_d[0] = start, start_d
    while top > 0:
        top -= 1
        n = stack[top]
        if stack_d[top] > best[0]:
            continue
        c = tr.child[n]
        if c < 0:
            _leaf_distances(p, tr, n, best, best_t)
            continue
        d0 = _squared_box_distance(p, tr.box + 6 * c)
        d1 = _squared_box_distance(p, tr.box + 6 * (c + 1))
        if d0 > d1:                                      # the nearer child on top
            c, d0, d1 = c + 1, d1, d0
            if d1 <= best[0]:
                stack[top], stack_d[top], top = c - 1, d1, top + 1
        elif d1 <= best[0]:
            stack[top], stack_d[top], top = c + 1, d1, top + 1
        if d0 <= best[0]:
            stack[top], stack_d[top], top = c, d0, top + 1


def tree_distances(const double[:, ::1] P, const double[:, ::1] T, const int64_t[::1] face,
                   const int64_t[::1] child, const int64_t[::1] lo, const int64_t[::1] hi,
                   const int64_t[::1] parent, const int64_t[::1] leaf,
                   const double[:, ::1] box, double[::1] out_d, int64_t[::1] out_f):
    """For each point ``P[i]``, the smallest distance ``out_d[i]`` to the triangles ``T``
    (k×9, in the order of a :func:`triangle_tree` whose ``child, lo, hi, parent, leaf`` and
    :func:`tree_boxes` are given) and the triangle that has it, ``out_f[i]`` = its ``face``
    number (of equal distances, the smallest number; NaN and −1 for a point with a NaN
    coordinate): each triangle's distance is :func:`_squared_point_face`'s, compared squared,
    and a node is skipped only when its box lies farther than the best so far, so the result is
    that of all triangles one by one.

    The walk starts at the leaf of the previous point's triangle (points in a coherent order,
    such as Z-order, find theirs at once), then goes up to the root, at each step the other child
    and below it (:func:`_descend`); the first point from the root down. Runs without the GIL
    (several threads may query one tree)."""
    cdef Py_ssize_t i, k = P.shape[0]
    cdef int64_t n, s, best_t, hint = -1
    cdef double best, d
    cdef const double* p
    cdef _Tree tr
    if T.shape[0] == 0:
        out_d[:] = INFINITY
        out_f[:] = -1
        return
    tr.T, tr.face, tr.child, tr.lo, tr.hi, tr.box = &T[0, 0], &face[0], &child[0], &lo[0], \
        &hi[0], &box[0, 0]
    with nogil:
        for i in range(k):
            p = &P[i, 0]
            best, best_t = INFINITY, -1
            if hint < 0:
                _descend(p, &tr, 0, _squared_box_distance(p, tr.box), &best, &best_t)
            else:
                n = leaf[hint]
                _leaf_distances(p, &tr, n, &best, &best_t)
                while n > 0:
                    s = n + 1 if child[parent[n]] == n else n - 1
                    d = _squared_box_distance(p, tr.box + 6 * s)
                    if d <= best:
                        _descend(p, &tr, s, d, &best, &best_t)
                    n = parent[n]
            if best_t < 0 or best != best:               # a point with a NaN coordinate
                out_d[i], out_f[i] = NAN, -1
                continue
            out_d[i], out_f[i] = sqrt(best), face[best_t]
            hint = best_t


cdef class _Text:
    """A growing byte buffer."""
    cdef char* data
    cdef Py_ssize_t size, cap

    def __cinit__(self, Py_ssize_t cap):
        self.cap = max(cap, 16)
        self.size = 0
        self.data = <char*>malloc(self.cap)
        if self.data == NULL:
            raise MemoryError()

    def __dealloc__(self):
        free(self.data)

    cdef int put(self, const char* s, Py_ssize_t k) except -1:
        cdef char* grown
        if self.size + k > self.cap:
            self.cap = 2 * (self.size + k)
            grown = <char*>realloc(self.data, self.cap)
            if grown == NULL:
                raise MemoryError()
            self.data = grown
        memcpy(self.data + self.size, s, k)
        self.size += k
        return 0

    cdef str text(self):
        return self.data[:self.size].decode("ascii")


cdef inline int _decimal(int64_t v, char* buf) noexcept nogil:
    """``v`` in decimal written at the end of ``buf`` (32 chars); returns its length."""
    cdef int k = 0
    cdef uint64_t u = <uint64_t>(-(v + 1)) + 1 if v < 0 else <uint64_t>v
    while True:
        k += 1
        buf[32 - k] = <char>(48 + u % 10)
        u //= 10
        if u == 0:
            break
    if v < 0:
        k += 1
        buf[32 - k] = b'-'
    return k


ctypedef fused row_value:
    double
    int64_t


def format_rows(list pieces, const row_value[:, ::1] A):
    """Every row of ``A`` (k×c) written as ``pieces[0] a0 pieces[1] a1 … pieces[c]``: what
    ``(fmt * k) % tuple(A.ravel().tolist())`` gives for a ``fmt`` of ``%r`` fields (floats,
    written as ``repr`` writes them: the shortest string that reads back to the value) or of
    ``%d`` fields (int64, in decimal) between the pieces (ASCII)."""
    cdef Py_ssize_t i, j, c = A.shape[1]
    cdef char buf[32]
    cdef char* s
    cdef int k
    cdef bytes piece
    cdef list raw = [p.encode("ascii") for p in pieces]
    cdef _Text out = _Text(A.shape[0] * (24 * c + 8))
    for i in range(A.shape[0]):
        for j in range(c):
            piece = raw[j]
            out.put(piece, len(piece))
            if row_value is double:
                s = PyOS_double_to_string(A[i, j], b'r', 0, Py_DTSF_ADD_DOT_0, NULL)
                try:
                    out.put(s, strlen(s))
                finally:
                    PyMem_Free(s)
            else:
                k = _decimal(A[i, j], buf)
                out.put(buf + 32 - k, k)
        piece = raw[c]
        out.put(piece, len(piece))
    return out.text()


def sag_along_block(const double[:, ::1] P, const int64_t[::1] mf, const double[:, ::1] N_in,
                    const double[:, ::1] X, const int64_t[::1] a, const int64_t[::1] b,
                    const double[::1] ts, const double[:, ::1] n_a, const double[:, ::1] n_b,
                    Py_ssize_t lo, double[::1] best, double[::1] t_best):
    """The sags of the edges ``lo … lo + m − 1`` of :func:`.remesh.sag.edge_sag_along` from
    their lifted samples ``P`` (s·m × 3, sample-major: row ``j·m + q`` is ``t = ts[j]`` on edge
    ``lo + q``) in the input faces ``mf``: at each sample :func:`_sample_sag`, and per edge
    the largest over the samples (:func:`_larger_sag`) into ``best[e]`` and its ``t`` into
    ``t_best[e]``."""
    cdef Py_ssize_t s = ts.shape[0], m = P.shape[0] // s if s else 0
    cdef Py_ssize_t q, j, i, e, jb
    cdef double v, vb
    for q in range(m):
        e = lo + q
        jb = -1
        vb = 0.0
        for j in range(s):
            i = j * m + q
            v = _sample_sag(&P[i, 0], &N_in[mf[i], 0], &X[a[e], 0], &X[b[e], 0], ts[j],
                            &n_a[e, 0], &n_b[e, 0])
            if _larger_sag(jb, v, vb):
                jb, vb = j, v
        best[e] = vb
        t_best[e] = ts[jb]


cdef inline double _sample_sag(const double* p, const double* n, const double* xa,
                               const double* xb, double t, const double* na, const double* nb
                               ) noexcept nogil:
    """The sag at one sample: the offset ``D = p − ((1 − t)·xa + t·xb)`` between the lifted
    sample ``p`` and the edge's 3D point, and its largest absolute component along the input
    normal there (``n``) and the ends' normals (``na``, ``nb``; NaN if any is, as
    ``np.maximum``)."""
    cdef double D[3]
    cdef double u = 1.0 - t, v
    cdef Py_ssize_t c
    for c in range(3):
        D[c] = p[c] - (u * xa[c] + t * xb[c])
    v = fabs(_dot3(D, n))
    v = _max_nan(v, fabs(_dot3(D, na)))
    return _max_nan(v, fabs(_dot3(D, nb)))


cdef inline bint _larger_sag(Py_ssize_t jb, double v, double vb) noexcept nogil:
    """Whether the sample's sag ``v`` replaces the edge's largest so far ``vb`` (none yet when
    ``jb < 0``): the first of equals wins and a NaN wins, as ``np.argmax``."""
    return jb < 0 or v > vb or (v != v and vb == vb)


cdef inline int64_t _walk_one(const double[:, ::1] rows, double px, double py, int64_t f,
                              int walk, double tol, double* lam) noexcept nogil:
    """One point's walk of :func:`walk_to_faces` from the face ``f``: the face found (its
    clamped, renormalised barycentrics in ``lam``), or −1 where the walk leaves the rim or
    takes more than ``walk`` steps."""
    cdef const int32_t* nbr = <const int32_t*> &rows[0, 0]
    cdef Py_ssize_t r
    cdef int step = 0
    while True:
        r = _face_test(rows, f, px, py, tol, lam)
        if r < 0:
            _clean(lam)
            return f
        if step == walk:
            return -1
        f = nbr[16 * f + 12 + (r + 1) % 3]
        if f < 0:
            return -1
        step += 1


def walked_sags(const double[:, ::1] rows, const double[:, ::1] uv, const int64_t[::1] face,
                const int64_t[::1] a, const int64_t[::1] b, const double[::1] ts, int walk,
                double tol, const double[:, ::1] V_in, const int64_t[:, ::1] F_in,
                const double[:, ::1] N_in, const double[:, ::1] X, double[::1] best,
                double[::1] t_best):
    """:func:`.remesh.sag.edge_sag_along` of the edges ``a–b`` (k) at the points ``ts`` in
    one pass, where every sample is found by a walk: each domain point ``(1 − t)·uv[a] +
    t·uv[b]`` (:func:`points_along`) walked (:func:`_walk_one`, as ``PointLocator.relocate``
    with ``walk`` steps and ``tol``) from the face under the nearer end, lifted (eq. 1, as
    :func:`lift_rows`), its :func:`_sample_sag` with the normals of ``N_in`` under it and under
    the ends ``face[a]``, ``face[b]``; per edge the largest (:func:`_larger_sag`) into
    ``best`` and its ``t`` into ``t_best``. Returns False, with ``best`` and ``t_best``
    incomplete, as soon as a walk does not find its point (the caller then locates them all
    the general way)."""
    cdef Py_ssize_t e, j, c, jb
    cdef int64_t f, t0, t1, t2
    cdef double lam[3]
    cdef double M[2]
    cdef double P[3]
    cdef double t, u, v, vb
    if rows.shape[0] == 0 or ts.shape[0] == 0:
        return False
    for e in range(a.shape[0]):
        jb = -1
        vb = 0.0
        for j in range(ts.shape[0]):
            t = ts[j]
            u = 1.0 - t
            for c in range(2):
                M[c] = u * uv[a[e], c] + t * uv[b[e], c]
            f = _walk_one(rows, M[0], M[1], face[a[e]] if t <= 0.5 else face[b[e]], walk, tol,
                          lam)
            if f < 0:
                return False
            t0, t1, t2 = F_in[f, 0], F_in[f, 1], F_in[f, 2]
            for c in range(3):
                P[c] = lam[0] * V_in[t0, c] + lam[1] * V_in[t1, c] + lam[2] * V_in[t2, c]
            v = _sample_sag(P, &N_in[f, 0], &X[a[e], 0], &X[b[e], 0], t,
                            &N_in[face[a[e]], 0], &N_in[face[b[e]], 0])
            if _larger_sag(jb, v, vb):
                jb, vb = j, v
        best[e] = vb
        t_best[e] = ts[jb]
    return True


def closest_points(const double[:, ::1] P, const double[:, ::1] A, const double[:, ::1] B,
                   const double[:, ::1] C):
    """The closest point of triangle ``(A[i], B[i], C[i])`` to ``P[i]`` (all k×3,
    :func:`_closest_point`)."""
    cdef Py_ssize_t i, k = P.shape[0]
    out_arr = np.empty((k, 3), dtype=np.float64)
    cdef double[:, ::1] Q = out_arr
    for i in range(k):
        _closest_point(&P[i, 0], &A[i, 0], &B[i, 0], &C[i, 0], &Q[i, 0])
    return out_arr


cdef void _closest_point(const double* p, const double* a, const double* b, const double* c,
                         double* q) noexcept nogil:
    """The closest point ``q`` of the triangle ``(a, b, c)`` to ``p`` (3-vectors,
    :func:`_closest_on_triangle`: the vertex regions a, b, c first, then the edges ab, ac,
    bc, else the face interior); a point that comes out not finite (a degenerate triangle)
    goes to the nearest corner (the first of equals; a NaN distance wins)."""
    cdef Py_ssize_t c_, x, j
    cdef double t, s, best = 0.0
    cdef const double* corner[3]
    _closest_on_triangle(p, a, b, c, q)
    if isfinite(q[0]) and isfinite(q[1]) and isfinite(q[2]):
        return
    corner[0], corner[1], corner[2] = a, b, c
    j = 0
    for c_ in range(3):
        t = corner[c_][0] - p[0]
        s = t * t
        t = corner[c_][1] - p[1]
        s = s + t * t
        t = corner[c_][2] - p[2]
        s = s + t * t
        if c_ == 0:
            best = s
        elif best == best and (s < best or s != s):
            j, best = c_, s
    for x in range(3):
        q[x] = corner[j][x]


def point_faces_distance(const double[::1] p, const double[:, ::1] X,
                         const int64_t[:, ::1] T):
    """The smallest distance from the point ``p`` (3,) to the triangles ``X[T]`` (``T``: k×3
    vertex indices): ``norms(p − closest_points(p, X[T[:, 0]], X[T[:, 1]], X[T[:, 2]])).min()``
    operation for operation (the squares summed x, z, then y; NaN if any distance is, as
    ``ndarray.min``; inf for no triangle)."""
    cdef Py_ssize_t i, x
    cdef double q[3]
    cdef double e[3]
    cdef double d, best = INFINITY
    for i in range(T.shape[0]):
        _closest_point(&p[0], &X[T[i, 0], 0], &X[T[i, 1], 0], &X[T[i, 2], 0], q)
        for x in range(3):
            e[x] = p[x] - q[x]
        d = sqrt(_dot3(e, e))
        if d != d:
            return d
        if d < best:
            best = d
    return best


def replacement_normals(const double[:, ::1] X, const int64_t[:, ::1] old,
                        const int64_t[:, ::1] new):
    """The normals ``cross(X[b] − X[a], X[c] − X[a])`` of the faces ``new`` (j×3 → j×3) and
    the sum of those of the faces ``old`` (k×3 → 3,), as :func:`..rows.cross` and
    ``.sum(axis=0)`` compute them (from 0, in row order), for
    :func:`..remesh.angles._same_side`."""
    cdef Py_ssize_t m, x
    cdef double n[3]
    total_arr = np.zeros(3, dtype=np.float64)
    normals_arr = np.empty((new.shape[0], 3), dtype=np.float64)
    cdef double[::1] total = total_arr
    cdef double[:, ::1] normals = normals_arr
    for m in range(old.shape[0]):
        _normal(X, old[m, 0], old[m, 1], old[m, 2], n)
        for x in range(3):
            total[x] = total[x] + n[x]
    for m in range(new.shape[0]):
        _normal(X, new[m, 0], new[m, 1], new[m, 2], &normals[m, 0])
    return normals_arr, total_arr


def faces_keep_side(const double[:, ::1] n0, const double[::1] a1, const double[:, ::1] B,
                    const double[:, ::1] C):
    """Whether every face ``(A, B[m], C[m])`` with the normal ``n0[m]`` (k×3) keeps its side
    when ``A`` moves to ``a1`` (3,): ``(dots(n0, cross(B − a1, C − a1)) > 0).all()``, the dot
    summed x, z, then y as numpy's einsum does."""
    cdef Py_ssize_t m
    cdef double n1[3]
    for m in range(B.shape[0]):
        _cross(B[m, 0] - a1[0], B[m, 1] - a1[1], B[m, 2] - a1[2],
               C[m, 0] - a1[0], C[m, 1] - a1[1], C[m, 2] - a1[2], n1)
        if not (_dot3(&n0[m, 0], n1) > 0):
            return False
    return True


def pair_lengths(const double[:, ::1] X, const int64_t[::1] a, const int64_t[::1] b):
    """``|X[a[i]] − X[b[i]]|`` for every pair (k), as ``norms(X[a] − X[b])`` computes it."""
    cdef Py_ssize_t i
    out_arr = np.empty(a.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for i in range(a.shape[0]):
        out[i] = _length(X, a[i], b[i])
    return out_arr


def points_along(const double[:, ::1] uv, const int64_t[::1] face, const int64_t[::1] a,
                 const int64_t[::1] b, const double[::1] t):
    """The domain points ``(1 − t)·uv[a] + t·uv[b]`` (k×2, as numpy computes them with ``t``
    a column) and the face under the nearer end of each (``face[a]`` where ``t ≤ 1/2``, else
    ``face[b]``; called by ``remesh.sag.lift_samples``)."""
    cdef Py_ssize_t i, c, k = a.shape[0], d = uv.shape[1]
    cdef double u
    M_arr = np.empty((k, d), dtype=np.float64)
    hint_arr = np.empty(k, dtype=np.int64)
    cdef double[:, ::1] M = M_arr
    cdef int64_t[::1] hint = hint_arr
    for i in range(k):
        u = 1.0 - t[i]
        for c in range(d):
            M[i, c] = u * uv[a[i], c] + t[i] * uv[b[i], c]
        hint[i] = face[a[i]] if t[i] <= 0.5 else face[b[i]]
    return M_arr, hint_arr


@cython.cdivision(True)
def centroid_steps(const double[:, ::1] G, const double[::1] W, const double[:, ::1] X,
                   const int64_t[::1] mov):
    """``G[mov] / max(W[mov], 1e-300) − X[mov]`` (k×3): each moving vertex's step to the
    area-weighted centroid of its ring (:func:`ring_sums`' sums; NaN as ``np.maximum``;
    called by ``remesh.relax.tangential_smoothing``)."""
    cdef Py_ssize_t i, c, k = mov.shape[0]
    cdef double w
    D_arr = np.empty((k, 3), dtype=np.float64)
    cdef double[:, ::1] D = D_arr
    for i in range(k):
        w = _max_nan(W[mov[i]], 1e-300)
        for c in range(3):
            D[i, c] = G[mov[i], c] / w - X[mov[i], c]
    return D_arr


@cython.cdivision(True)
def tangential_parts(double[:, ::1] D, const double[:, ::1] N, const int64_t[::1] mov):
    """In place, each step ``D[i]`` less its component along the unit normal of
    ``N[mov[i]]`` (normalised as ``N / max(norms(N), 1e-300)``; the dot product and the length
    summed as numpy's einsum does here): ``D − (D · n) n`` (called by
    ``remesh.relax.tangential_smoothing``)."""
    cdef Py_ssize_t i, c
    cdef double n[3]
    cdef double length, d
    for i in range(mov.shape[0]):
        for c in range(3):
            n[c] = N[mov[i], c]
        length = _max_nan(sqrt(_dot3(n, n)), 1e-300)
        for c in range(3):
            n[c] = n[c] / length
        d = _dot3(&D[i, 0], n)
        for c in range(3):
            D[i, c] = D[i, c] - d * n[c]


def pulled_back_steps(const double[:, :, ::1] J, const int64_t[::1] face,
                      const int64_t[::1] mov, const double[:, ::1] D, double step,
                      double[:, ::1] du):
    """In place, ``du[mov[i]] = step · J[face[mov[i]]] D[i]`` (each row of the matrix dotted
    with the 3D step as numpy's einsum sums it here, x, z, then y): the moving vertices' steps
    pulled back to the domain (called by ``remesh.relax.tangential_smoothing``)."""
    cdef Py_ssize_t i, r, v
    cdef int64_t f
    for i in range(mov.shape[0]):
        v = mov[i]
        f = face[v]
        for r in range(J.shape[1]):
            du[v, r] = step * _dot3(&J[f, r, 0], &D[i, 0])


cdef extern from "math.h" nogil:
    double fma(double x, double y, double z)
    double hypot(double x, double y)


@cython.cdivision(True)
def stretch_dilatations(const double[:, ::1] V, const double[:, ::1] uv, const int64_t[:, ::1] F,
                        const double[::1] double_area):
    """Per face the dilatation ``K`` of :func:`..metrics.stretch_anisotropy` (m,), operation
    for operation as numpy computes it on these machines with ``np.linalg.inv``, ``@`` and
    ``einsum``: ``D⁻¹`` of the image edge matrix ``D`` as LAPACK's LU with partial pivoting
    gives it (the multiplier and the back substitution by reciprocals), each entry of
    ``J = E D⁻¹`` as OpenBLAS's product forms it (``fma(e₁, d₁, e₀ d₀)``, an explicit fused
    multiply-add: the module's other arithmetic is unfused), ``G = JᵀJ`` summed over the rows
    in order (checked bit for bit on the shared meshes' maps and on noisy ones with flipped
    faces); ``inf`` where ``|det D| ≤ 1e-300`` or ``K`` is not finite, at least 1 elsewhere.

    Parameters
    ----------
    V : (n, 3) float64, uv : (n, 2) float64, F : (m, 3) int64, double_area : (m,) float64
        Surface points, map, faces and the faces' ``2|τ|``.
    """
    cdef Py_ssize_t t, k, i
    cdef int64_t v0, v1, v2
    cdef bint swap
    cdef double a, b, c, d, det, P, Q, R, S, rp, l, ru, x0, x1, y0, y1, K
    cdef double Di[2][2]
    cdef double J[3][2]
    cdef double g00, g01, g11, root, lmax, ratio
    out_arr = np.empty(F.shape[0], dtype=np.float64)
    cdef double[::1] out = out_arr
    for t in range(F.shape[0]):
        v0, v1, v2 = F[t, 0], F[t, 1], F[t, 2]
        a = uv[v1, 0] - uv[v0, 0]
        b = uv[v2, 0] - uv[v0, 0]
        c = uv[v1, 1] - uv[v0, 1]
        d = uv[v2, 1] - uv[v0, 1]
        det = a * d - b * c
        if not fabs(det) > 1e-300:
            out[t] = INFINITY
            continue
        swap = fabs(c) > fabs(a)          # the pivot row: the first of the largest |column 0|
        if swap:
            P, Q, R, S = c, d, a, b
        else:
            P, Q, R, S = a, b, c, d
        rp = 1.0 / P
        l = R * rp
        ru = 1.0 / (S - l * Q)
        # columns of the permuted identity: e₀ → (1, −l), e₁ → (0, 1) after L⁻¹
        x1 = -l * ru
        x0 = (1.0 - Q * x1) * rp
        y1 = 1.0 * ru
        y0 = (0.0 - Q * y1) * rp
        if swap:
            Di[0][0], Di[1][0], Di[0][1], Di[1][1] = y0, y1, x0, x1
        else:
            Di[0][0], Di[1][0], Di[0][1], Di[1][1] = x0, x1, y0, y1
        for k in range(3):
            a = V[v1, k] - V[v0, k]
            b = V[v2, k] - V[v0, k]
            for i in range(2):
                J[k][i] = fma(b, Di[1][i], a * Di[0][i])
        g00 = (J[0][0] * J[0][0] + J[1][0] * J[1][0]) + J[2][0] * J[2][0]
        g01 = (J[0][0] * J[0][1] + J[1][0] * J[1][1]) + J[2][0] * J[2][1]
        g11 = (J[0][1] * J[0][1] + J[1][1] * J[1][1]) + J[2][1] * J[2][1]
        root = hypot(g00 - g11, 2 * g01)
        lmax = (g00 + g11 + root) / 2
        ratio = double_area[t] / det
        K = lmax / sqrt(ratio * ratio)
        if not isfinite(K):
            K = INFINITY
        out[t] = K if K > 1.0 else 1.0
    return out_arr


def laplacian_block(const int64_t[:, ::1] edges, const int64_t[::1] rows_of,
                    const int64_t[::1] cols_of, Py_ssize_t n_rows):
    """CSR structure ``(indptr, indices)`` (int32) of one block of a mesh Laplacian and, for
    every stored entry, the index of its value in ``[−w (E edges), d (n vertices)]`` (int64):
    the entries ``(i, j)`` and ``(j, i)`` of every edge ``e = (i, j)`` (source ``e``) and
    ``(v, v)`` of every vertex (source ``E + v``), kept where ``rows_of`` and ``cols_of`` (−1:
    not in the block) give the row and the column, columns ascending in each row (the entries
    of a row have distinct columns, so this order is unique). Called by
    :func:`..laplacian.laplacian_pattern`.

    Parameters
    ----------
    edges : (E, 2) int64
    rows_of, cols_of : (n,) int64
        Block row and column of every vertex, −1 outside the block.
    n_rows : int
    """
    cdef Py_ssize_t E = edges.shape[0], n = rows_of.shape[0], e, v, r, k
    cdef int64_t i, j
    indptr_arr = np.zeros(n_rows + 1, dtype=np.int32)
    cdef int32_t[::1] indptr = indptr_arr
    for e in range(E):
        i, j = edges[e, 0], edges[e, 1]
        if rows_of[i] >= 0 and cols_of[j] >= 0:
            indptr[rows_of[i] + 1] += 1
        if rows_of[j] >= 0 and cols_of[i] >= 0:
            indptr[rows_of[j] + 1] += 1
    for v in range(n):
        if rows_of[v] >= 0 and cols_of[v] >= 0:
            indptr[rows_of[v] + 1] += 1
    for r in range(n_rows):
        indptr[r + 1] += indptr[r]
    indices_arr = np.empty(indptr[n_rows], dtype=np.int32)
    src_arr = np.empty(indptr[n_rows], dtype=np.int64)
    fill_arr = np.array(indptr_arr[:n_rows], dtype=np.int64)
    cdef int32_t[::1] indices = indices_arr
    cdef int64_t[::1] src = src_arr, fill = fill_arr
    for e in range(E):
        i, j = edges[e, 0], edges[e, 1]
        if rows_of[i] >= 0 and cols_of[j] >= 0:
            k = fill[rows_of[i]]
            indices[k], src[k] = <int32_t>cols_of[j], e
            fill[rows_of[i]] = k + 1
        if rows_of[j] >= 0 and cols_of[i] >= 0:
            k = fill[rows_of[j]]
            indices[k], src[k] = <int32_t>cols_of[i], e
            fill[rows_of[j]] = k + 1
    for v in range(n):
        if rows_of[v] >= 0 and cols_of[v] >= 0:
            k = fill[rows_of[v]]
            indices[k], src[k] = <int32_t>cols_of[v], E + v
            fill[rows_of[v]] = k + 1
    for r in range(n_rows):
        _sort_run(&indices[0], &src[0], indptr[r], indptr[r + 1])
    return indptr_arr, indices_arr, src_arr


@cython.cdivision(True)
def corner_dots_over_area(const double[:, ::1] P, const int64_t[:, ::1] F,
                          const double[::1] double_area):
    """``(p_j − p_i)·(p_k − p_i) / (2|τ|)`` at every corner of every face (m×3) for points of
    any dimension, as :func:`..laplacian.corner_dot_over_area` defines it: with the edge
    vectors ``d_c = p_{c+1} − p_c``, ``−d_c · d_{c−1}`` accumulated coordinate by coordinate
    from 0, then divided by the face's ``double_area``."""
    cdef Py_ssize_t t, k
    cdef double x0, x1, x2, d0, d1, d2, o0, o1, o2
    out_arr = np.empty((F.shape[0], 3), dtype=np.float64)
    cdef double[:, ::1] out = out_arr
    for t in range(F.shape[0]):
        o0 = o1 = o2 = 0.0
        for k in range(P.shape[1]):
            x0, x1, x2 = P[F[t, 0], k], P[F[t, 1], k], P[F[t, 2], k]
            d0, d1, d2 = x1 - x0, x2 - x1, x0 - x2
            o0 = o0 - d0 * d2
            o1 = o1 - d1 * d0
            o2 = o2 - d2 * d1
        out[t, 0] = o0 / double_area[t]
        out[t, 1] = o1 / double_area[t]
        out[t, 2] = o2 / double_area[t]
    return out_arr
