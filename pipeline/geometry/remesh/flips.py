"""Delaunay flips on the lifted surface.

An interior edge is flipped when its two opposite **3D** angles sum to more than π (the
Delaunay criterion on the lifted surface), in rounds of independent flips until none is left. A
flip is allowed only when the quad is convex on the disk (so the new edge cannot exist yet: the
triangulation is an embedding there), no new face has three boundary corners, the new faces'
normals agree with the old ones and are not thinner on the disk than ``DISK_SHAPE_MIN``
(:func:`.halfedge.disk_shape`), and either the quad is nearly planar (dihedral angle below
``max_dihedral_deg``), so the surface changes by no more than a shallow fold, or — given a
``sag`` measure (:func:`.sag.edge_sag`) — the new edge is no farther from the input surface
than the old one. The second rule lets the caps and needles that the map's angle distortion
leaves on curved regions (noses, lips, fingers, sulci) flip.

:func:`valence_flips` flips towards regular valences instead (Botsch & Kobbelt 2004: 6 inside,
4 on the rim), under the same checks for nearly planar quads, and only where the new faces'
smallest 3D angle is at least the old faces' or ``min_angle_deg``.

:func:`sag_flips` flips the edges farther than a threshold from the input surface whose other
diagonal is within it, whatever the Delaunay criterion says (an edge across an input crease), under
the same checks, the same angle rule and a test of the new faces against the input's normals.
"""

from __future__ import annotations

import math

import numpy as np

from .. import topology as topo
from .._kernels import flip_checks, opposite_cots, valence_gains
from ..metrics import corner_angles
from ..rows import row_min
from .halfedge import DISK_SHAPE_MIN, disk_shape, independent_by, independent_by_faces, touching


def _opposite_cots(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Per face (k×3): column ``c`` is the cotangent of the angle opposite half-edge
    ``F[t,c] → F[t,c+1]`` (at corner ``c+2``), from one cross product per face (its norm,
    twice the area, is shared by the three corners); compiled."""
    return opposite_cots(np.ascontiguousarray(X, dtype=np.float64),
                         np.ascontiguousarray(F, dtype=np.int64))


def flip_edges(X: np.ndarray, F: np.ndarray, uv: np.ndarray, max_dihedral_deg: float = 20.0,
               max_rounds: int = 12, eps: float = 1e-9, sag=None,
               boundary: np.ndarray | None = None, active: np.ndarray | None = None,
               twin: np.ndarray | None = None, fixed=None) -> tuple[np.ndarray, int, int]:
    """Flip interior edges towards the Delaunay triangulation of the lifted surface.

    The criterion ``α + β > π`` for the angles opposite an edge is tested as
    ``cot α + cot β < 0``, with the cotangents kept per half-edge and recomputed only for the
    faces a round changed. After the first round only the edges of changed faces are tested
    again, and the half-edge twins are updated in place. Each round flips a set of violating
    edges no two of which share a face, the most violating first.

    Parameters
    ----------
    X : (n, 3) float
        Lifted positions.
    F : (m, 3) int
        Faces, counter-clockwise on the disk; not modified.
    uv : (n, 2) float
        Disk positions.
    max_dihedral_deg : float
        Quads folded less than this flip on the Delaunay criterion alone.
    max_rounds : int
    eps : float
        A flip needs ``−(cot α + cot β) > eps``.
    sag : callable ``sag(i, j) -> (k,) float``, optional
        The distance of edges ``i–j`` from the input surface; a quad folded more than
        ``max_dihedral_deg`` then flips when ``sag(p, q) ≤ sag(a, b)``. Without it, it never
        flips.
    boundary : (n,) bool, optional
        The boundary vertices, when the caller has them.
    active : (n,) bool, optional
        Only the edges of faces with an active corner are tested first (after a local
        change), and the cotangents are computed only for the faces the rounds reach.
    twin : (3m,) int, optional
        The half-edge twins of ``F``; updated in place to those of the result.
    fixed : callable ``fixed(a, b) -> (k,) bool``, optional
        The edges ``a–b`` never flipped (:meth:`.state.RemeshState.is_joined`).

    Returns
    -------
    F : (m, 3) int
        The flipped faces (a new array; same count, still counter-clockwise on the disk).
    flips : int
    rounds : int
    """
    F = np.array(F, dtype=np.int64, copy=True)
    X, uv = np.ascontiguousarray(X, dtype=np.float64), np.ascontiguousarray(uv, dtype=np.float64)
    n, m = len(X), len(F)
    is_b = topo.boundary_vertices_mask(F, n) if boundary is None else boundary
    is_b = np.ascontiguousarray(is_b, dtype=bool).view(np.uint8)
    cos_max = math.cos(math.radians(max_dihedral_deg))
    twin = topo.interior_edge_twins(F) if twin is None else twin
    slot = np.arange(3 * m)                                             # old slot → new slot
    if active is None:
        cot = _opposite_cots(X, F).ravel()                              # per half-edge
        have = None
        h = np.flatnonzero(twin > slot)                                 # each interior edge once
    else:
        cot = np.empty(3 * m)
        have = np.zeros(m, bool)                                        # faces with their cots
        h = _interior_edges_of(np.flatnonzero(touching(F, active)), twin, m)
    total, rounds = 0, 0
    for rounds in range(1, max_rounds + 1):
        if len(h) == 0:
            break
        if have is not None:
            need = np.concatenate([h // 3, twin[h] // 3])
            need = topo.distinct_indices(need[~have[need]], m)
            cot.reshape(m, 3)[need] = _opposite_cots(X, F[need])
            have[need] = True
        viol = -(cot[h] + cot[twin[h]])                                 # > 0: not Delaunay
        cand = np.flatnonzero(viol > eps)
        if len(cand) == 0:
            break
        h, viol = h[cand], viol[cand]
        (a, b, p, q), ok, valid = flip_checks(X, uv, is_b, F, h, twin, cos_max)
        if sag is not None:
            # a folded quad may still flip when the new edge is no farther from the input
            # surface than the old one (caps over a crease, the skewed triangles of the map)
            folded = np.flatnonzero(~ok & valid)
            if len(folded):
                k = len(folded)
                both = sag(np.r_[p[folded], a[folded]], np.r_[q[folded], b[folded]])
                ok[folded] = both[:k] <= both[k:]
        ok &= valid
        if fixed is not None:
            ok[ok] = ~fixed(a[ok], b[ok])
        ok[ok] = _shapes_kept(uv, p[ok], a[ok], q[ok], b[ok])
        sel = np.flatnonzero(ok)
        if len(sel) == 0:
            break
        win = sel[independent_by_faces(m, h[sel] // 3, twin[h[sel]] // 3, -viol[sel])]
        changed = flip_in_place(F, twin, h[win], (a[win], b[win], p[win], q[win]), slot)
        cot.reshape(m, 3)[changed] = _opposite_cots(X, F[changed])
        if have is not None:
            have[changed] = True
        total += len(win)
        h = _interior_edges_of(changed, twin, m)          # next round: the changed faces' edges
    return F, total, rounds


VALENCE_ROUNDS = 2      # valence flips: at most this many rounds (a third finds almost none)


def valence_flips(X: np.ndarray, F: np.ndarray, uv: np.ndarray, boundary: np.ndarray,
                  max_dihedral_deg: float = 20.0, min_angle_deg: float = 35.0,
                  max_rounds: int = VALENCE_ROUNDS, twin: np.ndarray | None = None,
                  fixed=None) -> tuple[np.ndarray, int]:
    """Flip interior edges that bring the valences of the quad's four corners closer to the
    regular ones (Botsch & Kobbelt 2004).

    An edge ``a–b`` with opposite corners ``p``, ``q`` flips when it lowers
    ``Σ (valence − target)²`` over ``a, b, p, q`` (target 6 inside, 4 on the boundary), the
    quad is folded less than ``max_dihedral_deg``, the flip is valid (:func:`flip_edges`'
    checks) and the new faces' smallest 3D angle is at least ``min(old faces' smallest,
    min_angle_deg)``. Each round flips a set of such edges no two of which share a corner,
    the largest gain first.

    Parameters
    ----------
    X : (n, 3) float
        Lifted positions.
    F : (m, 3) int
        Faces, counter-clockwise on the disk; not modified.
    uv : (n, 2) float
        Disk positions.
    boundary : (n,) bool
        The boundary vertices.
    max_dihedral_deg, min_angle_deg : float
    max_rounds : int
    twin : (3m,) int, optional
        The half-edge twins of ``F``; updated in place to those of the result.
    fixed : callable ``fixed(a, b) -> (k,) bool``, optional
        The edges ``a–b`` never flipped.

    Returns
    -------
    F : (m, 3) int
        The flipped faces (a new array; still counter-clockwise on the disk).
    flips : int
    """
    F = np.array(F, dtype=np.int64, copy=True)
    X, uv = np.ascontiguousarray(X, dtype=np.float64), np.ascontiguousarray(uv, dtype=np.float64)
    n, m = len(X), len(F)
    is_b = np.ascontiguousarray(boundary, dtype=bool).view(np.uint8)
    target = np.where(boundary, 4, 6)
    cos_max, floor = math.cos(math.radians(max_dihedral_deg)), math.radians(min_angle_deg)
    total = 0
    twin = topo.interior_edge_twins(F) if twin is None else twin
    slot = np.arange(3 * m)
    for _ in range(max_rounds):
        dev = np.bincount(F.ravel(), minlength=n) - target
        # the edges whose flip lowers Σ dev² (before − after: the gain), compiled
        h, gain = valence_gains(F, np.ascontiguousarray(twin, dtype=np.int64),
                                np.ascontiguousarray(dev, dtype=np.int64))
        (a, b, p, q), flat, valid = flip_checks(X, uv, is_b, F, h, twin, cos_max)
        ok = np.flatnonzero(flat & valid)
        ok = ok[_shapes_kept(uv, p[ok], a[ok], q[ok], b[ok])]
        ok = ok[_angles_kept(X, a[ok], b[ok], p[ok], q[ok], floor)]
        if fixed is not None:
            ok = ok[~fixed(a[ok], b[ok])]
        if len(ok) == 0:
            break
        win = ok[independent_by(n, (a[ok], b[ok], p[ok], q[ok]), -gain[ok])]
        flip_in_place(F, twin, h[win], (a[win], b[win], p[win], q[win]), slot)
        total += len(win)
    return F, total


def sag_flips(X: np.ndarray, F: np.ndarray, uv: np.ndarray, boundary: np.ndarray, sag,
              threshold: float, min_angle_deg: float, max_rounds: int = 4,
              twin: np.ndarray | None = None, fixed=None, turned=None, screen=None
              ) -> tuple[np.ndarray, int]:
    """Flip the interior edges farther than ``threshold`` from the input surface whose other
    diagonal is within it, whatever the Delaunay criterion says: an edge across a crease
    of the input (a lip's, an eyelid's, a ridge narrower than the faces) sags into the fold
    or bridges over it, while the diagonal along the crease lies on it.

    An edge ``a–b`` with opposite corners ``p``, ``q`` flips when ``sag(p, q) ≤ threshold``
    (not merely below ``sag(a, b)``: the measure can rank two diagonals across a crease
    wrongly, and the flip must not make the remesh's side of the distance the larger),
    the flip is valid (:func:`flip_edges`' checks other than the fold's), neither new face is
    ``turned`` and the new faces' smallest 3D angle is at least ``min(old faces' smallest,
    min_angle_deg)``. Each round flips a set of such edges no two of which share a face, the
    farthest first; the next round looks at the edges of the flipped quads only.

    Parameters
    ----------
    X : (n, 3) float
        Lifted positions.
    F : (m, 3) int
        Faces, counter-clockwise on the disk; not modified.
    uv : (n, 2) float
        Disk positions.
    boundary : (n,) bool
        The boundary vertices.
    sag : callable ``sag(i, j) -> (k,) float``
        The distance of edges ``i–j`` from the input surface.
    threshold : float
        In the mesh's units.
    min_angle_deg : float
    max_rounds : int
    twin : (3m,) int, optional
        The half-edge twins of ``F``; updated in place to those of the result.
    fixed : callable ``fixed(a, b) -> (k,) bool``, optional
        The edges ``a–b`` never flipped (:meth:`.state.RemeshState.is_joined`).
    turned : callable ``turned(faces) -> (k,) bool``, optional
        The faces (k×3) not to make (those turned over against the input,
        :func:`.improve.turned_from_input`).
    screen : callable ``screen(i, j) -> (k,) bool``, optional
        The edges ``i–j`` that may be farther than ``threshold``, by a cheaper measure than
        ``sag``; the others are not measured.

    Returns
    -------
    F : (m, 3) int
        The flipped faces (a new array; still counter-clockwise on the disk).
    flips : int
    """
    F = np.array(F, dtype=np.int64, copy=True)
    X, uv = np.ascontiguousarray(X, dtype=np.float64), np.ascontiguousarray(uv, dtype=np.float64)
    m = len(F)
    is_b = np.ascontiguousarray(boundary, dtype=bool).view(np.uint8)
    floor = np.radians(min_angle_deg)
    twin = topo.interior_edge_twins(F) if twin is None else twin
    slot = np.arange(3 * m)
    h = np.flatnonzero(twin > slot)
    total = 0
    for _ in range(max_rounds):
        if len(h) == 0:
            break
        if screen is not None:
            h = h[screen(F[h // 3, h % 3], F[h // 3, (h % 3 + 1) % 3])]
        old_sag = sag(F[h // 3, h % 3], F[h // 3, (h % 3 + 1) % 3])
        h, old_sag = h[old_sag > threshold], old_sag[old_sag > threshold]
        (a, b, p, q), _, valid = flip_checks(X, uv, is_b, F, h, twin, 1.0)
        ok = np.flatnonzero(valid)
        if fixed is not None:
            ok = ok[~fixed(a[ok], b[ok])]
        ok = ok[_shapes_kept(uv, p[ok], a[ok], q[ok], b[ok])]
        ok = ok[sag(p[ok], q[ok]) <= threshold]
        if turned is not None:
            ok = ok[~turned(np.column_stack([p, a, q, q, b, p])[ok].reshape(-1, 3)
                            ).reshape(-1, 2).any(axis=1)]
        ok = ok[_angles_kept(X, a[ok], b[ok], p[ok], q[ok], floor)]
        if len(ok) == 0:
            break
        win = ok[independent_by_faces(m, h[ok] // 3, twin[h[ok]] // 3, -old_sag[ok])]
        changed = flip_in_place(F, twin, h[win], (a[win], b[win], p[win], q[win]), slot)
        total += len(win)
        h = _interior_edges_of(changed, twin, m)
    return F, total


def flip_in_place(F: np.ndarray, twin: np.ndarray, h: np.ndarray, quad: tuple,
                  slot: np.ndarray | None = None) -> np.ndarray:
    """Flip the interior half-edges ``h`` (k, no two in one face) of ``F``: the faces
    ``a, b, p`` and ``b, a, q`` of each become ``p, a, q`` and ``q, b, p``.

    Parameters
    ----------
    F : (m, 3) int
        Changed in place.
    twin : (3m,) int
        Its half-edge twins; changed in place to those of the result.
    h : (k,) int
    quad : tuple of four (k,) int
        ``a, b, p, q`` (as :func:`.._kernels.flip_checks` gives them).
    slot : (3m,) int, optional
        ``arange(3m)``, scratch (made if not given).

    Returns
    -------
    (2k,) int
        The changed faces.
    """
    a, b, p, q = quad
    f, c, g, d = h // 3, h % 3, twin[h] // 3, twin[h] % 3
    _flipped_twins(twin, np.arange(3 * len(F)) if slot is None else slot, f, c, g, d)
    F[f] = np.column_stack([p, a, q])
    F[g] = np.column_stack([q, b, p])
    return np.concatenate([f, g])


def _flipped_twins(twin: np.ndarray, slot: np.ndarray, f: np.ndarray, c: np.ndarray,
                   g: np.ndarray, d: np.ndarray) -> None:
    """Update the half-edge twins in place for flips of the edges at slot ``c`` of faces
    ``f`` and slot ``d`` of faces ``g`` (no two flips sharing a face) whose faces become
    ``f = (p, a, q)`` and ``g = (q, b, p)``: the four outer half-edges of each quad move to
    new slots (p→a, a→q in f; q→b, b→p in g; their twins may sit in another flipped quad)
    and the new diagonal's two halves are each other's twins.

    Parameters
    ----------
    twin : (3m,) int
        Changed in place.
    slot : (3m,) int
        ``arange(3m)``, used as scratch and restored.
    f, c, g, d : (k,) int
    """
    old = np.concatenate([3 * f + (c + 2) % 3, 3 * g + (d + 1) % 3,
                          3 * g + (d + 2) % 3, 3 * f + (c + 1) % 3])
    new = np.concatenate([3 * f, 3 * f + 1, 3 * g, 3 * g + 1])
    tw = twin[old]
    slot[old] = new
    inner = tw >= 0
    twin[new] = np.where(inner, slot[np.maximum(tw, 0)], -1)
    twin[slot[tw[inner]]] = new[inner]
    twin[3 * f + 2] = 3 * g + 2                  # the new diagonal q→p / p→q
    twin[3 * g + 2] = 3 * f + 2
    slot[old] = old


def _angles_kept(X: np.ndarray, a, b, p, q, floor: float) -> np.ndarray:
    """Whether the new faces ``(p, a, q)`` and ``(q, b, p)`` of a flip of ``a–b`` (k each)
    have a smallest 3D angle of at least the old faces' ``(a, b, p)``, ``(b, a, q)`` or
    ``floor`` (radians), whichever is smaller (k bool)."""
    old = corner_angles(X, np.column_stack([a, b, p, b, a, q]).reshape(-1, 3))
    new = corner_angles(X, np.column_stack([p, a, q, q, b, p]).reshape(-1, 3))
    return row_min(new.reshape(-1, 6)) >= np.minimum(row_min(old.reshape(-1, 6)), floor)


def _shapes_kept(uv: np.ndarray, p, a, q, b) -> np.ndarray:
    """Whether both new faces ``(p, a, q)`` and ``(q, b, p)`` of a flip keep a disk shape of at
    least ``DISK_SHAPE_MIN`` (:func:`.halfedge.disk_shape`)."""
    if len(p) == 0:
        return np.zeros(0, bool)
    shape = disk_shape(uv, np.column_stack([p, a, q, q, b, p]).reshape(-1, 3)).reshape(-1, 2)
    return row_min(shape) >= DISK_SHAPE_MIN


def _interior_edges_of(faces: np.ndarray, twin: np.ndarray, m: int) -> np.ndarray:
    """Every interior edge of the given faces once, as its smaller half-edge."""
    hs = (3 * faces[:, None] + np.arange(3)).ravel()
    ts = twin[hs]
    return topo.distinct_indices(np.where(ts > hs, hs, ts)[ts >= 0], 3 * m)
