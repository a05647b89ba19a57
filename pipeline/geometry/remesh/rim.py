"""The rim follows the input's boundary: splits at the boundary vertices its chords cut off.

The remesh's rim vertices lie on the image polygon (the input boundary's image), so they lift
onto the input's boundary, but a rim edge is a straight chord between two of them: the input
boundary vertices the polygon passes between its ends are cut off. Where the boundary is
jagged or turns at several vertices closer together than the rim spacing (a scanned face's
ragged border), those vertices end up farther from the remesh than anything else, and the
input-to-remesh Hausdorff distance is decided there. :func:`refine_rim` splits every rim edge
that leaves an input boundary vertex farther than the sag tolerance, exactly at the farthest
such vertex (its image is a polygon corner, so the new vertex lifts onto the input vertex
itself), in rounds until the rim is within the tolerance everywhere or a split would make a
needle or a face too thin on the disk. Rim vertices do not move in smoothing, and the
collapses' gap guard refuses to remove one that stands out farther than the sag tolerance.

A ragged boundary vertex (``S.ragged``, :func:`.corners.ragged_boundary`: sharp at the input's
own scale, but a spur's, a tooth's or a notch's, not a corner at the remesh's) is never split
at: a rim vertex there would have a sharp or reflex corner that no later step could raise to
the minimum angle nor move or remove. The chord crosses it (the farthest other vertex it cuts
off is split at), so the input-to-remesh distance there grows by the tooth's depth at most.
"""

from __future__ import annotations

import numpy as np

from ..locate import lift
from ..metrics import corner_angles
from ..rows import dots, norms
from .halfedge import edge_table, independent_edges
from .refine import split_edges, split_keeps_shape
from .sampling import arc_polygon
from .state import RemeshState

#: the rim is held to this × the sag tolerance: a chord that cuts off a boundary vertex is
#: the distance itself (the input-to-remesh Hausdorff distance of a jagged border), not a sag
#: that later smoothing moves (the choice is measured in the closing note of issue #19)
RIM_TOL = 0.25


def segment_distances(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distance (k,) from each point ``P`` (k×3) to the segment ``A``–``B`` (k×3 each)."""
    e = B - A
    t = np.clip(dots(P - A, e) / np.maximum(dots(e, e), 1e-300), 0.0, 1.0)
    return norms(P - (A + t[:, None] * e))


def rim_gaps(S: RemeshState, corners_X: np.ndarray, corner_s: np.ndarray,
             skip: np.ndarray | None = None):
    """For every rim edge of ``S``, the input boundary vertex (polygon corner) farthest from it
    among those the polygon passes between its ends, none of ``skip`` (k bool; default
    ``S.ragged``).

    Parameters
    ----------
    S : RemeshState
    corners_X : (k, 3) float
        The input boundary vertices, in polygon order.
    corner_s : (k,) float
        Their arc lengths along the polygon.

    Returns
    -------
    h, a, b : (r,) int
        The rim half-edges ``a → b`` (counter-clockwise, as the polygon runs) and their ends.
    corner : (r,) int
        The farthest corner of each, none of ``skip`` (−1 where the polygon has none
        between the ends).
    gap : (r,) float
        Its distance to the chord ``X[a]``–``X[b]`` (0 where there is none).
    """
    h, a, b, twin = edge_table(S.F, twin=S.twins())
    rim = twin < 0
    h, a, b = h[rim], a[rim], b[rim]
    s_a = S.of_input(polygon_arcs).arc_position(S.uv[a])
    order = np.argsort(s_a, kind="stable")
    # the rim edge each corner falls on: the last one starting at or before it (cyclically)
    e = order[(np.searchsorted(s_a[order], corner_s, side="right") - 1) % len(order)]
    d = np.where(S.ragged if skip is None else skip, -1.0,
                 segment_distances(corners_X, S.X[a[e]], S.X[b[e]]))
    corner = np.full(len(h), -1, np.int64)
    gap = np.zeros(len(h))
    by = np.lexsort((-d, e))                    # per edge, the farthest corner first
    first = by[np.r_[True, e[by][1:] != e[by][:-1]]]
    first = first[d[first] >= 0]
    corner[e[first]], gap[e[first]] = first, d[first]
    return h, a, b, corner, gap


def rim_corners(S: RemeshState) -> tuple[np.ndarray, np.ndarray]:
    """The input boundary's vertices (the image polygon's corners) on the surface (k×3: located
    in the input map and lifted) and their arc lengths along the polygon (k); a value of the
    input map (:meth:`.state.RemeshState.of_input`)."""
    f, bary, _ = S.locator.locate_with_inside(S.polygon)
    return lift(S.V_in, S.F_in, f, bary), S.of_input(polygon_arcs).arc_position(S.polygon)


def polygon_arcs(S: RemeshState):
    """The image polygon of ``S`` made for arc lengths along it (:func:`.sampling.arc_polygon`:
    ``arc_position(points)`` is :func:`.sampling.arc_parameters` of ``S.polygon``); a value of
    the input map (:meth:`.state.RemeshState.of_input`), so that the rim steps' questions
    share one closest-segment tree."""
    return arc_polygon(S.polygon)


def refine_rim(S: RemeshState, tol: float, min_gap: float, budget: int,
               max_rounds: int = 8) -> int:
    """Split rim edges that leave an input boundary vertex farther than ``tol`` at that vertex
    (the farthest first, none of ``S.ragged``), in rounds of independent splits; a split is
    skipped when the vertex is within ``min_gap`` of an end of the edge (a needle) or a new
    face would be too thin on the disk (:func:`.refine.split_keeps_shape`). At most ``budget``
    splits; returns their number. A closed remesh (no polygon) has no rim: nothing to do."""
    if tol is None or budget <= 0 or len(S.polygon) == 0:
        return 0
    corners_X, corner_s = S.of_input(rim_corners)
    done = 0
    for _ in range(max_rounds):
        h, a, b, corner, gap = rim_gaps(S, corners_X, corner_s)
        cand = np.flatnonzero(gap > tol)
        P = corners_X[corner[cand]]
        cand = cand[np.minimum(norms(P - S.X[a[cand]]), norms(P - S.X[b[cand]])) >= min_gap]
        twin = np.full(len(cand), -1, np.int64)
        points = S.polygon[corner[cand]]
        keep = split_keeps_shape(S, h[cand], twin, points=points)
        cand, twin, points = cand[keep], twin[keep], points[keep]
        sel = independent_edges(len(S.F), h[cand], twin, -gap[cand])
        sel = sel[np.argsort(-gap[cand][sel], kind="stable")][:budget - done]
        if len(sel) == 0:
            break
        done += split_edges(S, h[cand][sel], twin[sel], points=points[sel])
        if done >= budget:
            break
    S.tally("rim_splits", done)
    return done


#: a face whose angle at a rim vertex is wider than this (degrees) has its opposite edge split
RIM_FAN_MAX_DEG = 120.0


def open_rim_fans(S: RemeshState, max_angle_deg: float = RIM_FAN_MAX_DEG,
                  rounds: int = 3) -> int:
    """Split, at its middle on the disk, the interior edge opposite every angle wider than
    ``max_angle_deg`` at a rim vertex, in rounds of independent splits; returns their number.

    At a reflex corner of the input boundary (a rim vertex whose input faces span more than
    180°) the rim refinement leaves a rim vertex whose few faces must span that angle: one of
    them is a cap, flat and wide at the rim vertex, thin at its other corners, that flips
    cannot remove where the quad across is folded. Splitting the edge across from the wide
    angle halves it and gives the rim vertex one more face."""
    done = 0
    for _ in range(rounds):
        h, twin = fan_edges(S, S.is_rim, max_angle_deg)
        sel = independent_edges(len(S.F), h, twin, np.zeros(len(h)))
        if len(sel) == 0:
            break
        done += split_edges(S, h[sel], twin[sel])
    S.tally("rim_fan_splits", done)
    return done


def fan_edges(S: RemeshState, at: np.ndarray, max_angle_deg: float = RIM_FAN_MAX_DEG
              ) -> tuple[np.ndarray, np.ndarray]:
    """The interior half-edges across the angles wider than ``max_angle_deg`` at the vertices
    ``at`` (n bool, rim vertices) whose split keeps the faces' shapes on the disk
    (:func:`.refine.split_keeps_shape`), face by face: what :func:`open_rim_fans` splits.

    Returns
    -------
    h, twin : (k,) int
        The half-edges (each opposite its wide corner in its face) and their twins.
    """
    F = S.F
    wide = np.degrees(corner_angles(S.X, F)) > max_angle_deg
    t, c = np.nonzero(wide & at[F])
    h = 3 * t + (c + 1) % 3                             # the half-edge opposite corner c
    twin = S.twins()[h]
    inner = twin >= 0
    h, twin = h[inner], twin[inner]
    keep = split_keeps_shape(S, h, twin)
    return h[keep], twin[keep]
