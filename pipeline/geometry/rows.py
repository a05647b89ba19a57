"""Row-wise 3-vector arithmetic for the hot loops of remeshing.

``np.cross`` and ``np.linalg.norm(axis=1)`` are general (any axis, any dtype) and pay for it
on many short rows (n, 3): the written-out cross product and ``sqrt(einsum)`` skip that
generality and its temporaries. The cross product is the same arithmetic as numpy's
(bit-identical results). Reductions along the short axis (``a.min(axis=1)``,
``np.any(a, axis=1)``) are several times slower than the same operation column by column
(:func:`row_min`, :func:`nonzero_rows`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["cross", "norms", "dots", "row_min", "row_max", "nonzero_rows"]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` per row (k×3, k×3 → k×3)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a · b`` per row (k×d, k×d → k)."""
    return np.einsum("ij,ij->i", a, b)


def norms(a: np.ndarray) -> np.ndarray:
    """Euclidean length per row (k×d → k)."""
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def row_min(a: np.ndarray) -> np.ndarray:
    """The smallest entry per row (k×c → k), column by column: the values of
    ``a.min(axis=1)`` (a NaN in a row gives NaN)."""
    return _by_columns(np.minimum, a)


def row_max(a: np.ndarray) -> np.ndarray:
    """The largest entry per row (k×c → k), column by column: the values of
    ``a.max(axis=1)`` (a NaN in a row gives NaN)."""
    return _by_columns(np.maximum, a)


def _by_columns(ufunc, a: np.ndarray) -> np.ndarray:
    """``ufunc`` (a binary ufunc) folded over the columns of ``a`` (k×c → k)."""
    out = a[:, 0].copy()
    for c in range(1, a.shape[1]):
        ufunc(out, a[:, c], out=out)
    return out


def nonzero_rows(a: np.ndarray) -> np.ndarray:
    """Whether each row has an entry other than 0 (k×c → k bool): ``np.any(a != 0, axis=1)``."""
    out = a[:, 0] != 0
    for c in range(1, a.shape[1]):
        out |= a[:, c] != 0
    return out
