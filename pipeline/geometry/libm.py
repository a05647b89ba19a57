"""Elementwise ``arccos``, ``cos`` and ``sin`` through the C library, whatever CPU runs them.

numpy computes these (and ``exp``, ``log``) with the C library's functions on most CPUs, but on
one with AVX-512 it takes vectorised loops of its own whose last bit can differ. The remesher's
decisions compare such values (an angle from a compiled kernel against one from numpy, a spacing
found by a search), so a last bit decides which remesh comes out. Its transcendental
functions therefore go through the C library: here for arrays (compiled,
:func:`._kernels.c_library`), ``math`` for single numbers; the same remesh on every machine
that has the same C library.
"""

from __future__ import annotations

import numpy as np

from . import _kernels

_ACOS, _COS, _SIN = 0, 1, 2


def _elementwise(x: np.ndarray, fn: int) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return _kernels.c_library(np.ascontiguousarray(x).reshape(-1), fn).reshape(x.shape)


def arccos(x: np.ndarray) -> np.ndarray:
    """``acos`` of each value of ``x`` (any shape, in [−1, 1] or nan; radians, same shape)."""
    return _elementwise(x, _ACOS)


def cos(x: np.ndarray) -> np.ndarray:
    """``cos`` of each value of ``x`` (any shape, radians; same shape)."""
    return _elementwise(x, _COS)


def sin(x: np.ndarray) -> np.ndarray:
    """``sin`` of each value of ``x`` (any shape, radians; same shape)."""
    return _elementwise(x, _SIN)
