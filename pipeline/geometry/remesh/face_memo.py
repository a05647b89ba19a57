"""Per-face measures of a remesh kept between counts and recomputed only where it changed.

The minimum-angle pass's grading (:meth:`.improve._Operations.grade`) counts the faces turned
over before and after its rounds of insertions and local operations, each time over the whole
remesh, though a round changes only the faces around its insertions. A
:class:`FaceMemo` keeps the values of a per-face measure from its last call and computes them
again only for the faces whose corners (rows of ``F``) or whose corners' vertices (their
``X``, ``uv`` and input face) differ from what it saw then: a measure that depends on nothing
else gives the same values as computed over all faces.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .state import RemeshState


@dataclass
class FaceMemo:
    """The values of ``measure(S, faces)`` (k faces → k rows) for every face of a remesh,
    recomputed on each call only for the faces changed since the last one
    (:func:`changed_faces`).

    Attributes
    ----------
    measure : callable ``measure(S, faces) -> (k, ...) array``
        A per-face measure that depends only on each face's corners and their ``X``, ``uv``
        and ``face`` (and on the input map, which does not change).
    """

    measure: Callable[[RemeshState, np.ndarray], np.ndarray]
    _seen: tuple | None = None
    _values: np.ndarray | None = None

    def __call__(self, S: RemeshState) -> np.ndarray:
        """The values (m rows, one per face of ``S``); the caller must not change them."""
        if self._seen is None:
            values = self.measure(S, np.arange(len(S.F)))
        else:
            stale = np.flatnonzero(changed_faces(S, self._seen))
            kept = min(len(self._values), len(S.F))
            values = np.empty((len(S.F),) + self._values.shape[1:], self._values.dtype)
            values[:kept] = self._values[:kept]
            if len(stale):
                values[stale] = self.measure(S, stale)
        self._seen = snapshot(S)
        self._values = values
        return values

    def kept(self) -> tuple:
        """What the memo holds now, for :meth:`restore`."""
        return self._seen, self._values

    def restore(self, kept: tuple) -> None:
        """Hold again what :meth:`kept` returned: after the remesh is put back as it was then,
        the next call recomputes nothing. (Any other remesh is compared with it as usual.)"""
        self._seen, self._values = kept


def snapshot(S: RemeshState) -> tuple:
    """Copies of what :func:`changed_faces` compares: ``X``, ``uv``, ``face`` and ``F``."""
    return S.X.copy(), S.uv.copy(), S.face.copy(), S.F.copy()


def changed_faces(S: RemeshState, seen: tuple) -> np.ndarray:
    """The faces of ``S`` (m bool) that differ from the :func:`snapshot` ``seen``: new rows,
    rows whose corners changed, and faces at a vertex that is new or whose ``X``, ``uv`` or
    input face changed (indices are compared as they are: a vertex or face renumbered counts
    as changed wherever what it holds differs).

    Parameters
    ----------
    S : RemeshState
    seen : tuple
        ``(X, uv, face, F)`` as :func:`snapshot` copied them.

    Returns
    -------
    (m,) bool
    """
    X0, uv0, face0, F0 = seen
    n = min(len(X0), S.n)
    moved = np.ones(S.n, bool)
    moved[:n] = S.face[:n] != face0[:n]
    for now, then in ((S.X, X0), (S.uv, uv0)):
        for c in range(now.shape[1]):
            moved[:n] |= now[:n, c] != then[:n, c]
    m = min(len(F0), len(S.F))
    out = np.ones(len(S.F), bool)
    out[:m] = False
    for c in range(3):
        out[:m] |= S.F[:m, c] != F0[:m, c]
        out |= moved[S.F[:, c]]
    return out
