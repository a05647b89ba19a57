"""A ragged rim followed at the scale of the remesh.

A scanned surface's border is ragged: spurs, single-face teeth and notches, a few input edges
wide, far smaller than the remesh's spacing ``h``. The rim samples are spread evenly along the
image polygon (:func:`.sampling.sample_disk`), so they land anywhere on that border: at the tip
of a spur (the rim turns sharply there: the faces at it are needles) or at the bottom of a
notch (a reflex rim corner: a cap its fan cannot open), and the rim refinement
(:func:`.rim.refine_rim`) adds one at every tooth the chords cut off. None of these rim
vertices can be moved or removed later without cutting off the input's boundary again.

:func:`straighten_rim` slides each rim sample, within ``REACH × h`` of its place along the
polygon, onto the input boundary vertex (polygon corner) nearest to the chord between its two
neighbours' lifts, when that is nearer than where it is by more than a tolerance: the rim stays
on the input boundary, its chords pass across the teeth narrower than the spacing instead of
into them, and a smooth border (every corner about as near the chord) keeps its samples.
:func:`narrow_teeth` tells the rim refinement which cut-off boundary vertices are such teeth.
"""

from __future__ import annotations

import numpy as np

from .sampling import _Polygon

#: a rim sample may slide along the polygon by at most this × the rim spacing
REACH = 0.35
#: a boundary vertex the chord cuts off is a narrow tooth when the boundary stays farther from
#: the chord than the tolerance over less than this × the chord's length
TOOTH_WIDTH = 0.5


def lift_on_polygon(poly: _Polygon, X_corners: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The 3D points (k×3) at arc lengths ``s`` (k,) along the polygon ``poly`` whose corners
    lift to ``X_corners`` (b×3): linear along each edge (an input boundary edge)."""
    s = np.mod(s, poly.length)
    i = np.clip(np.searchsorted(poly.cum, s, side="right") - 1, 0, len(poly.P) - 1)
    t = (s - poly.cum[i]) / np.maximum(poly.cum[i + 1] - poly.cum[i], 1e-300)
    j = (i + 1) % len(poly.P)
    return X_corners[i] + t[:, None] * (X_corners[j] - X_corners[i])


def chord_distances(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distances (k, w) of the points ``P`` (k, w, 3) to the segments ``A``–``B`` (k×3 each)."""
    e = (B - A)[:, None, :]
    d = P - A[:, None, :]
    t = np.clip(np.einsum("kwj,kwj->kw", d, e) / np.maximum(np.einsum("kwj,kwj->kw", e, e),
                                                            1e-300), 0.0, 1.0)
    return np.linalg.norm(d - t[..., None] * e, axis=2)


def straighten_rim(rim: np.ndarray, polygon: np.ndarray, X_corners: np.ndarray, tol: float,
                   fixed: np.ndarray | None = None, rounds: int = 3) -> np.ndarray:
    """Rim samples slid onto the polygon corners nearest the chords of their neighbours
    (module docstring).

    Parameters
    ----------
    rim : (k, 2) float
        The rim samples, on the polygon, in its order, evenly spread.
    polygon : (b, 2) float
        The image polygon (CCW).
    X_corners : (b, 3) float
        The input boundary vertices its corners lift to.
    tol : float
        A sample moves only where a corner is nearer the chord by more than this (the mesh's
        units).
    fixed : (k,) bool, optional
        Samples that stay (snapped input corners).
    rounds : int
        Rounds of moves, each of the even then the odd samples (a sample's neighbours stay
        while it moves).

    Returns
    -------
    (k, 2) float
        The rim samples, each within ``REACH`` × the rim spacing of where it was.
    """
    poly = _Polygon(np.asarray(polygon, dtype=np.float64))
    k, b = len(rim), len(polygon)
    if k < 4 or b < 4:
        return rim
    s0 = poly.arc_position(rim)
    reach = REACH * poly.length / k
    corner_s = poly.cum[:-1]
    ext = np.r_[corner_s - poly.length, corner_s, corner_s + poly.length]
    lo = np.searchsorted(ext, s0 - reach, side="left")
    hi = np.searchsorted(ext, s0 + reach, side="right")
    w = int((hi - lo).max(initial=0))
    if w == 0:
        return rim
    cand = lo[:, None] + np.arange(w)
    valid = cand < hi[:, None]
    cand_s = np.where(valid, ext[np.minimum(cand, len(ext) - 1)], s0[:, None])
    cand_X = X_corners[np.minimum(cand, len(ext) - 1) % b]
    s = s0.copy()
    X = lift_on_polygon(poly, X_corners, s)
    movable = np.ones(k, bool) if fixed is None else ~np.asarray(fixed, bool)
    for _ in range(rounds):
        for parity in (0, 1):
            i = np.flatnonzero(movable & (np.arange(k) % 2 == parity))
            if parity == 1 and k % 2 == 1:
                i = i[i != k - 1]           # the last odd sample neighbours the first even one
            A, B = X[(i - 1) % k], X[(i + 1) % k]
            here = chord_distances(X[i][:, None], A, B)[:, 0]
            d = np.where(valid[i], chord_distances(cand_X[i], A, B), np.inf)
            best = d.argmin(axis=1)
            better = d[np.arange(len(i)), best] < here - tol
            j = i[better]
            s[j] = cand_s[j, best[better]]
            X[j] = cand_X[j, best[better]]
    return poly.at_arclength(s)


def narrow_teeth(d: np.ndarray, chord: np.ndarray, width: np.ndarray, tol: float
                 ) -> np.ndarray:
    """Which cut-off boundary vertices are narrow teeth (k bool): ``d`` (k,) their distances to
    the chords of lengths ``chord`` (k,), ``width`` (k,) the length along the chord over which
    the boundary around each stays farther than ``tol`` from it; narrow: less than
    ``TOOTH_WIDTH`` × the chord."""
    return (d > tol) & (width < TOOTH_WIDTH * chord)
