"""Even shares at a sharp rim corner: its two faces' middle vertex put on the corner's wedge.

A rim vertex ``c`` on an input corner too sharp for two faces of ``min_angle_deg``
(:func:`.angles.sharp_vertices`) keeps two faces at best, ``(c, b, w)`` and ``(c, w, a)``, with
``b`` and ``a`` its rim neighbours and ``w`` the interior vertex between them. Their angles at
``c`` share the corner's angle: each is at most half of it, and both reach half where ``w``
lies on the corner's bisector on the surface. The minimum-angle operations, each judged on the
star it changes, stop short of that where ``w`` starts near a rim neighbour: every step towards
the bisector squeezes another face of ``w``'s star before the corner's faces gain.

:func:`even_split_moves` looks for ``w``'s position among points of the corner's wedge on the
domain (:func:`wedge_points`, chords between ``c`` and the line from ``b`` to ``a``), lifted by
eq. (1), judged on the smallest angle of the corner's two faces (the faces beyond are left to
the operations that follow, :meth:`.improve._Operations.share_corner`), under the guards of
the local moves (:meth:`.angles._Patch.move`): the star counter-clockwise and not too thin on
the domain, no face of it turned over on the surface, the old position within the sag
tolerance of the new star, and no edge of ``w`` farther from the surface than the tolerance or
than it was. :func:`even_split_points` looks for the point of a new middle vertex ``p`` on the
edge ``c–w`` instead (``w`` stays, beyond it): where ``w`` is squeezed between rim vertices,
no position of its own gives the corner's faces their share without squeezing its other
faces.
"""

from __future__ import annotations

import numpy as np

from .._kernels import point_faces_distance
from ..locate import lift
from .angles import MOVE_WALK, SAG_TS, _same_side_points, star_shapes_ok, triangle_min_angles
from .sag import edge_sag_along
from .state import RemeshState

#: the wedge's points: fractions of the chord between the corner's rim neighbours on the domain
WEDGE_FRACTIONS = np.arange(1, 50) / 50.0
#: and of the way from the corner to the chord, for a move of the fan's middle vertex
WEDGE_RADII = np.array([0.4, 0.55, 0.7, 0.85, 1.0, 1.15, 1.3, 1.6, 2.0])
#: the same for a new middle vertex (:func:`even_split_points`)
SPLIT_RADII = np.array([0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9])


def two_face_fan(star: np.ndarray) -> tuple[int, int, int] | None:
    """The fan ``(b, w, a)`` of a corner whose star ``star`` (d×3, the corner first in each
    face, counter-clockwise) is two faces ``(c, b, w)`` and ``(c, w, a)``: ``w`` the vertex they
    share, ``b`` and ``a`` the others in counter-clockwise order; None for any other star."""
    if len(star) != 2:
        return None
    first, second = (0, 1) if star[0, 2] == star[1, 1] else (1, 0)
    if star[first, 2] != star[second, 1]:
        return None
    return int(star[first, 1]), int(star[first, 2]), int(star[second, 2])


def wedge_points(o: np.ndarray, rim: np.ndarray, fractions: np.ndarray = WEDGE_FRACTIONS,
                 radii: np.ndarray = WEDGE_RADII) -> np.ndarray:
    """Points of the wedge at the domain point ``o`` (2,) spanned by the polyline ``rim`` (k×2,
    from one rim neighbour of the corner to the other): ``o + ρ·(q(s) − o)`` for each ``s`` in
    ``fractions`` (j) and ``ρ`` in ``radii`` (i), ``q(s)`` the point at ``s`` along the polyline
    (its segments each an equal share of ``[0, 1]``); below 1 inside the fan ``o, rim`` where
    that is star-shaped from ``o``. Chords, not arcs: at a sharp rim corner the map opens the
    wedge to nearly 180° on the disk, and its faces are slivers an arc around ``o`` would miss.

    Returns
    -------
    (j·i, 2) float
        Fraction after fraction, each at every ``ρ``.
    """
    t = np.asarray(fractions, np.float64) * (len(rim) - 1)
    k = np.minimum(t.astype(np.int64), len(rim) - 2)
    q = rim[k] + (t - k)[:, None] * (rim[k + 1] - rim[k])
    rho = np.asarray(radii, np.float64)[None, :, None]
    return (o + rho * (q[:, None, :] - o)).reshape(-1, 2)


def fan_scores(P: np.ndarray, B: np.ndarray, C: np.ndarray, at_corner: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """For each position ``P[j]`` (k×3) of a vertex whose star is the faces ``(v, B, C)``
    (d×3 each): the smallest angle (degrees) of the faces ``at_corner`` (d bool) and that of the
    others (180 where there are none), each k.
    """
    k, d = len(P), len(B)
    A = triangle_min_angles(np.repeat(P, d, axis=0), np.tile(B, (k, 1)),
                            np.tile(C, (k, 1))).reshape(k, d)
    return (A[:, at_corner].min(axis=1, initial=180.0),
            A[:, ~at_corner].min(axis=1, initial=180.0))


def even_split_moves(S: RemeshState, c: int, star_w: np.ndarray, tol: float | None,
                     threshold: float) -> list[tuple]:
    """Positions for the middle vertex ``w = star_w[0, 0]`` of the two-face fan at the rim
    corner ``c`` (:func:`two_face_fan`; ``star_w``: ``w``'s star, d×3, ``w`` first,
    counter-clockwise) among the points of :func:`wedge_points` (``WEDGE_RADII`` of the way
    from ``c`` to the chord between its rim neighbours) in the map's image that keep the star
    counter-clockwise on the domain: the one that gives the corner's faces the largest smallest
    angle with no other face of the star below the smaller of ``threshold`` and their smallest
    angle now, the one that gives the corner's faces the largest smallest angle, and the one
    that gives the largest smallest angle of all the star's faces; each the first in its order
    that passes the guards of the module docstring (:func:`move_guards_ok`; ``tol`` None: no
    sag or gap guard), each only where it beats ``w``'s own position on that measure.

    Returns
    -------
    list of (uv (2,), face int, bary (3,), X (3,))
        Up to three positions, in that order, distinct.
    """
    w = int(star_w[0, 0])
    at = (star_w == c).any(axis=1)
    fan = two_face_fan(np.stack([np.roll(f, -int(np.argmax(f == c))) for f in star_w[at]]))
    if fan is None or S.is_rim[w] or S.locked[w]:
        return []
    b, _, a = fan
    M = wedge_points(S.uv[c], S.uv[[b, a]])
    ok = star_shapes_ok(S.uv, M, star_w[:, 1:])
    face, bary, inside = S.locator.relocate(M, np.full(len(M), S.face[w]), walk=MOVE_WALK)
    ok &= inside
    P = lift(S.V_in, S.F_in, face, bary)
    B, C = S.X[star_w[:, 1]], S.X[star_w[:, 2]]
    corner, others = fan_scores(P, B, C, at)
    now = fan_scores(S.X[w][None], B, C, at)
    found = []
    floor = min(now[1][0], threshold)
    for score, current in ((np.where(others >= floor, corner, -1.0), now[0][0]),
                           (corner, now[0][0]),
                           (np.minimum(corner, others), min(now[0][0], now[1][0]))):
        for j in np.argsort(-np.where(ok, score, -1.0), kind="stable"):
            if not ok[j] or score[j] <= current or any(j == i for i, _ in found):
                break
            if move_guards_ok(S, w, star_w, M[j], face[j], bary[j], P[j], tol):
                found.append((j, (M[j], int(face[j]), bary[j], P[j])))
                break
    return [where for _, where in found]


def move_guards_ok(S: RemeshState, w: int, star_w: np.ndarray, uv: np.ndarray, face: int,
                   bary: np.ndarray, x: np.ndarray, tol: float | None) -> bool:
    """Whether moving ``w`` (its star ``star_w``, d×3, ``w`` first) to ``uv`` (2,), lifted at
    ``face``/``bary`` to ``x`` (3,), turns no face of its star over on the surface and — with a
    tolerance ``tol`` — leaves its old position within ``tol`` of the new star and no edge of
    ``w`` farther from the surface than ``tol`` or than it was (:func:`.sag.edge_sag_along` at
    :data:`.angles.SAG_TS`). ``S`` is left as it was."""
    X = S.X
    B, C = X[star_w[:, 1]], X[star_w[:, 2]]
    normals = np.cross(B - X[w], C - X[w])
    if not _same_side_points(normals, x, B, C):
        return False
    if tol is None:
        return True
    ends = np.ascontiguousarray(star_w[:, 1], dtype=np.int64)
    starts = np.full(len(ends), w, np.int64)
    before = edge_sag_along(S, starts, ends, SAG_TS)[0]
    old = (S.uv[w].copy(), S.face[w], S.bary[w].copy(), S.X[w].copy())
    S.uv[w], S.face[w], S.bary[w], S.X[w] = uv, face, bary, x
    try:
        gap = point_faces_distance(np.ascontiguousarray(old[3], dtype=np.float64),
                                   np.ascontiguousarray(S.X, dtype=np.float64),
                                   np.ascontiguousarray(star_w, dtype=np.int64))
        after = edge_sag_along(S, starts, ends, SAG_TS)[0]
    finally:
        S.uv[w], S.face[w], S.bary[w], S.X[w] = old
    return bool(gap <= tol and (after <= np.maximum(before, tol)).all())


def half_edge(F: np.ndarray, a: int, b: int, either: bool = False) -> int:
    """The half-edge ``a → b`` of the faces ``F`` (m×3): ``3·f + i`` with ``F[f, i] = a`` and
    ``F[f, (i + 1) % 3] = b``; with ``either``, ``b → a`` where the edge has no ``a → b`` (a
    rim edge)."""
    hit = (F == a) & (np.roll(F, -1, axis=1) == b)
    if either and not hit.any():
        hit = (F == b) & (np.roll(F, -1, axis=1) == a)
    f, i = np.argwhere(hit)[0]
    return int(3 * f + i)


def put_vertex(S: RemeshState, w: int, where: tuple) -> bool:
    """Put vertex ``w`` at ``where`` (domain point, input face, barycentrics, 3D point: an
    entry of :func:`even_split_moves`); returns True (a change was made)."""
    S.uv[w], S.face[w], S.bary[w], S.X[w] = where
    return True


def even_split_points(S: RemeshState, c: int, b: int, w: int, a: int) -> list[np.ndarray]:
    """Points for a new vertex ``p`` splitting the middle edge ``c–w`` of the two-face fan
    ``(c, b, w)``, ``(c, w, a)`` at the rim corner ``c`` (:func:`two_face_fan`): ``p`` becomes
    the fan's middle vertex, its faces ``(p, a, c)``, ``(p, c, b)``, ``(p, b, w)`` and
    ``(p, w, a)``. Among the points of :func:`wedge_points` in the fan (``SPLIT_RADII`` of the
    way from ``c`` to the polyline ``b, w, a``), located and lifted, that keep those faces
    counter-clockwise and not too thin on the domain: the one that gives the corner's two
    faces the largest smallest angle, then the one best for all four (the smallest angle of
    the corner's faces and of the others together), each the first in its order whose faces
    turn none over against the two they replace (:func:`split_keeps_sides`; the caller checks
    the new edges' sag).

    Returns
    -------
    list of (2,) float
        Up to two domain points, in that order, distinct.
    """
    BC = np.array([[a, c], [c, b], [b, w], [w, a]], np.int64)
    M = wedge_points(S.uv[c], S.uv[[b, w, a]], radii=SPLIT_RADII)
    face, bary, inside = S.locator.relocate(M, np.full(len(M), S.face[w]), walk=MOVE_WALK)
    ok = np.flatnonzero(star_shapes_ok(S.uv, M, BC) & inside)
    P = lift(S.V_in, S.F_in, face, bary)
    corner, others = fan_scores(P[ok], S.X[BC[:, 0]], S.X[BC[:, 1]],
                                np.array([True, True, False, False]))
    X = S.X
    old = np.cross(X[w] - X[c], X[a] - X[c]) + np.cross(X[b] - X[c], X[w] - X[c])
    found = []
    for score in (corner, np.minimum(corner, others)):
        order = ok[np.argsort(-score, kind="stable")].tolist()
        j = next((j for j in order if split_keeps_sides(S, P[j], BC, old)), None)
        if j is not None and j not in found:
            found.append(j)
    return [M[j] for j in found]


def split_keeps_sides(S: RemeshState, x: np.ndarray, BC: np.ndarray, normal: np.ndarray
                      ) -> bool:
    """Whether a new vertex at ``x`` (3,) with the faces ``(p, B, C)`` (``BC``: d×2) turns
    none of them against ``normal`` (3,: the summed normals of the faces they replace)."""
    X = S.X
    return bool((np.cross(X[BC[:, 0]] - x, X[BC[:, 1]] - x) @ normal > 0).all())
