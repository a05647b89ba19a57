# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""The numbers of an OBJ file's ``v`` and ``f`` statements, read in one pass over its bytes
(:func:`obj_numbers`), for :func:`pipeline.io.meshio.read_mesh`.

Only the common form is read here: ``v`` lines of decimal numbers, ``f`` lines of integer
tokens with optional ``/vt/vn`` parts, any other statement or comment skipped. Anything else
gives ``None`` and the reader's general parser reads the file, so every file is read as that
parser reads it and every error is its message.
"""

import numpy as np
from cpython.object cimport PyObject
from libc.math cimport NAN, isfinite
from libc.stdint cimport int64_t, uint64_t
from libc.stdlib cimport free, realloc
from libc.string cimport memchr, memcpy

cdef extern from "Python.h":
    double PyOS_string_to_double(const char* s, char** endptr, PyObject* overflow_exception)
    void PyErr_Clear()


cdef struct _Column:
    char* data            # 8-byte items (float64 or int64)
    Py_ssize_t size       # items
    Py_ssize_t capacity   # items


cdef int _grow(_Column* c) noexcept:
    """Twice the room (and 1024 items more); 0 when out of memory."""
    cdef Py_ssize_t cap = 2 * c.capacity + 1024
    cdef char* grown = <char*>realloc(c.data, cap * 8)
    if grown == NULL:
        return 0
    c.data, c.capacity = grown, cap
    return 1


cdef inline int _push(_Column* c, const void* item) noexcept:
    """Append one 8-byte item; 0 when out of memory."""
    if c.size == c.capacity and not _grow(c):
        return 0
    memcpy(c.data + 8 * c.size, item, 8)
    c.size += 1
    return 1


cdef object _array(_Column* c, dtype):
    """The column's items as a new numpy array of ``dtype`` (8 bytes an item)."""
    out = np.empty(c.size, dtype=dtype)
    cdef char[::1] view = out.view(np.int8)
    if c.size:
        memcpy(&view[0], c.data, c.size * 8)
    return out


cdef inline bint _separator(char c) noexcept:
    return c == b' ' or c == b'\t'


cdef inline bint _statement_end(char c) noexcept:
    """The end of a statement's numbers: a comment, a line end (``\\r`` alone ends a line as
    in Python's universal newlines) or the end of the text (its terminating NUL)."""
    return c == b'#' or c == b'\r' or c == b'\n' or c == 0


cdef inline bint _float_char(char c) noexcept:
    return (b'0' <= c <= b'9') or c == b'.' or c == b'-' or c == b'+' or c == b'e' or c == b'E'


cdef double[23] _POWERS_OF_TEN = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                  1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21,
                                  1e22]


cdef bint _short_decimal(const char* s, const char* end, double* out) noexcept:
    """The decimal number ``[±]digits[.digits][(e|E)[±]digits]`` in ``s`` up to ``end`` into
    ``out`` when its digits without the point make an integer ``m`` ≤ 2⁵³ and its power of
    ten ``p`` is at most 22 in magnitude: then ``m`` and ``10^|p|`` are exact doubles and the
    value ``m·10^p`` or ``m/10^−p`` is one correctly rounded operation, the double
    Python's ``float()`` reads (Clinger's fast path). False for any other text."""
    cdef bint negative = False, exp_negative = False
    cdef uint64_t m = 0
    cdef int64_t p = 0, e = 0
    cdef int digits = 0, exp_digits = 0
    cdef double x
    if s < end and (s[0] == b'+' or s[0] == b'-'):
        negative = s[0] == b'-'
        s += 1
    while s < end and b'0' <= s[0] <= b'9':
        if m > 900719925474099:             # one more digit could pass 2⁵³
            return False
        m = 10 * m + <uint64_t>(s[0] - c'0')
        digits += 1
        s += 1
    if s < end and s[0] == b'.':
        s += 1
        while s < end and b'0' <= s[0] <= b'9':
            if m > 900719925474099:
                return False
            m = 10 * m + <uint64_t>(s[0] - c'0')
            digits += 1
            p -= 1
            s += 1
    if digits == 0:
        return False
    if s < end and (s[0] == b'e' or s[0] == b'E'):
        s += 1
        if s < end and (s[0] == b'+' or s[0] == b'-'):
            exp_negative = s[0] == b'-'
            s += 1
        while s < end and b'0' <= s[0] <= b'9':
            if e > 1000:
                return False
            e = 10 * e + (s[0] - c'0')
            exp_digits += 1
            s += 1
        if exp_digits == 0:
            return False
        p += -e if exp_negative else e
    if s != end or m > 9007199254740992 or p > 22 or p < -22:
        return False
    x = <double>m
    x = x * _POWERS_OF_TEN[p] if p >= 0 else x / _POWERS_OF_TEN[-p]
    out[0] = -x if negative else x
    return True


def obj_numbers(bytes text):
    """The numbers of the ``v`` and ``f`` statements of the OBJ file ``text`` (its bytes), or
    ``None`` when the file holds anything this reader leaves to the general one.

    A statement is a line whose first word, after blanks and tabs, is ``v`` or ``f`` followed
    by a blank or tab; its numbers end at ``#`` or the line's end (``\\n``, ``\\r\\n`` or
    ``\\r``). Read here: ``v`` numbers of the characters ``0-9 . + - e E`` whole and finite, each the
    double Python's ``float()`` reads (:func:`_short_decimal`, else
    ``PyOS_string_to_double``, ``float()``'s own reader); ``f`` tokens
    ``[-]digits`` (at most 18) with an optional ``/`` part of digits, ``-`` and ``/`` (its
    ``vt``/``vn`` indices, skipped). Any other character in a ``v`` or ``f`` statement gives
    ``None``; other lines are skipped unread.

    Returns
    -------
    None, or a tuple of
    vertex_numbers : (sum(vertex_counts),) float64
    vertex_counts : (lines,) int64
        Numbers on each ``v`` line, in file order.
    face_indices : (sum(face_counts),) int64
        The ``f`` tokens' vertex indices as written (1-based, or negative: relative).
    face_counts : (lines,) int64
    vertices_before : (lines,) int64
        For each ``f`` line, the ``v`` lines before it.
    """
    cdef const char* s = text
    cdef Py_ssize_t n = len(text), i = 0, start, digits
    cdef char c
    cdef char* end
    cdef double x
    cdef int64_t value, count, v_lines = 0
    cdef bint negative, ok = True
    cdef _Column vnum, vcnt, fidx, fcnt, fbefore
    vnum = _Column(NULL, 0, 0)
    vcnt = _Column(NULL, 0, 0)
    fidx = _Column(NULL, 0, 0)
    fcnt = _Column(NULL, 0, 0)
    fbefore = _Column(NULL, 0, 0)
    if memchr(s, 0, n) != NULL:          # a NUL in the text: not an end of statement here
        return None
    try:
        while i < n and ok:
            while _separator(s[i]):
                i += 1
            c = s[i]
            if (c == b'v' or c == b'f') and _separator(s[i + 1]):
                i += 2
                count = 0
                while ok:
                    while _separator(s[i]):
                        i += 1
                    if _statement_end(s[i]):
                        break
                    start = i
                    if c == b'v':
                        while _float_char(s[i]):
                            i += 1
                        if not (_separator(s[i]) or _statement_end(s[i])) or i == start:
                            ok = False
                            break
                        if not _short_decimal(s + start, s + i, &x):
                            x = PyOS_string_to_double(s + start, &end, NULL)
                            if end != s + i:
                                x = NAN
                        if not isfinite(x):
                            PyErr_Clear()
                            ok = False
                            break
                        ok = _push(&vnum, &x)
                    else:
                        negative = s[i] == b'-'
                        if negative:
                            i += 1
                        value, digits = 0, 0
                        while b'0' <= s[i] <= b'9' and digits < 19:
                            value = 10 * value + (s[i] - c'0')
                            digits += 1
                            i += 1
                        if s[i] == b'/':
                            while (b'0' <= s[i] <= b'9') or s[i] == b'/' or s[i] == b'-':
                                i += 1
                        if digits == 0 or digits > 18 or not (_separator(s[i])
                                                              or _statement_end(s[i])):
                            ok = False
                            break
                        if negative:
                            value = -value
                        ok = _push(&fidx, &value)
                    count += 1
                if not ok:
                    break
                if c == b'v':
                    ok = _push(&vcnt, &count)
                    v_lines += 1
                else:
                    ok = _push(&fcnt, &count) and _push(&fbefore, &v_lines)
            while i < n and s[i] != b'\n' and s[i] != b'\r':
                i += 1
            i += 1
        if not ok:
            return None
        return (_array(&vnum, np.float64), _array(&vcnt, np.int64), _array(&fidx, np.int64),
                _array(&fcnt, np.int64), _array(&fbefore, np.int64))
    finally:
        free(vnum.data)
        free(vcnt.data)
        free(fidx.data)
        free(fcnt.data)
        free(fbefore.data)
