"""The remesh being improved: a triangulation of the disk lifted onto the input surface.

Every vertex is a disk position ``uv`` located in the input map (input face and barycentrics)
and lifted by eq. (1): ``X = Σ bary_i · V_in[F_in[face, i]]``, so it lies exactly on the input
surface. The operations keep two invariants: every face is counter-clockwise on the disk (the
output stays a parameterized disk) and ``X`` is always the lift of ``uv``. For a closed mesh
the domain is the unit sphere instead (``uv`` and ``uv_in`` n×3 unit vectors, ``locator`` a
:class:`..locate_sphere.SphereLocator`, no rim; :mod:`.domain`), with the same invariants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import topology as topo
from ..locate import PointLocator, lift
from ..metrics import corner_angles
from ..rows import cross, dots, norms


class RemeshFailed(RuntimeError):
    """The remesh breaks an invariant of the product (a degenerate face, a face clockwise on
    the disk, a lost hole); it is never written."""


def at_points(X: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Which rows of ``X`` (n×3) are exactly, bit for bit, one of the points ``P`` (k×3): how
    locks are carried through operations that renumber the vertices (a locked vertex keeps its
    position). Only the rows whose first coordinate has the bits of one of ``P``'s are
    compared whole (the points are few, the rows many).

    Returns
    -------
    (n,) bool
    """
    out = np.zeros(len(X), bool)
    if len(P) == 0 or len(X) == 0:
        return out
    X = np.ascontiguousarray(X, dtype=np.float64)
    P = np.ascontiguousarray(P, dtype=np.float64)
    rows = np.flatnonzero(np.isin(X[:, 0].view(np.uint64), P[:, 0].view(np.uint64)))
    key = {p.tobytes() for p in P}
    out[rows] = [X[i].tobytes() in key for i in rows.tolist()]
    return out


def face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit normals (m×3) of the faces ``F`` (m×3) of ``V`` (n×3); zero for a degenerate face."""
    A = V.take(F[:, 0], axis=0)
    N = cross(V.take(F[:, 1], axis=0) - A, V.take(F[:, 2], axis=0) - A)
    return N / np.maximum(norms(N)[:, None], 1e-300)


def turned_against(X: np.ndarray, faces: np.ndarray, corner_normals: np.ndarray) -> np.ndarray:
    """Whether each of the ``faces`` (k×3 vertex indices) of ``X`` (n×3) faces away from the
    normals under all three of its corners (``corner_normals``, k×3×3: its normal's dot
    product with each is negative): the remesher's test of a fold against the input.

    Parameters
    ----------
    X : (n, 3) float
    faces : (k, 3) int
    corner_normals : (k, 3, 3) float

    Returns
    -------
    (k,) bool
    """
    P = X.take(faces, axis=0)
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    return np.all(np.einsum("ij,ikj->ik", normal, corner_normals) < 0, axis=1)


def pullback_matrices(V_in: np.ndarray, F_in: np.ndarray, uv_in: np.ndarray) -> np.ndarray:
    """Per input face the matrix ``J⁺`` (2×3) taking a 3D displacement ``d`` to the disk.

    ``Δu = J⁺ d`` is the disk displacement whose image under the face's affine map (uv → 3D,
    Jacobian ``J`` 3×2) is the projection of ``d`` onto the face's plane:
    ``J⁺ = E₂ G⁻¹ E₃ᵀ`` with ``E₃`` / ``E₂`` the face's two edge vectors in 3D / on the disk
    and ``G = E₃ᵀE₃``.

    On the sphere (``uv_in`` n×3) ``E₂`` are the edges of the chordal triangle and ``J⁺`` takes
    ``d`` to a 3D step in its plane (m×3×3).

    Parameters
    ----------
    V_in : (n, 3) float
    F_in : (m, 3) int
    uv_in : (n, 2) or (n, 3) float

    Returns
    -------
    (m, 2, 3) or (m, 3, 3) float
        Zero for a degenerate face.
    """
    a, b, c = F_in[:, 0], F_in[:, 1], F_in[:, 2]
    V0, U0 = V_in.take(a, axis=0), uv_in.take(a, axis=0)
    E3a, E3b = V_in.take(b, axis=0) - V0, V_in.take(c, axis=0) - V0
    E2a, E2b = uv_in.take(b, axis=0) - U0, uv_in.take(c, axis=0) - U0
    g11, g12, g22 = dots(E3a, E3a), dots(E3a, E3b), dots(E3b, E3b)
    det = g11 * g22 - g12 * g12
    det = np.where(det > 0, det, np.inf)
    R1 = (g22[:, None] * E3a - g12[:, None] * E3b) / det[:, None]        # rows of G⁻¹E₃ᵀ
    R2 = (g11[:, None] * E3b - g12[:, None] * E3a) / det[:, None]
    return E2a[:, :, None] * R1[:, None, :] + E2b[:, :, None] * R2[:, None, :]


@dataclass
class RemeshState:
    """A remesh on the disk, its lift, and the input map it lives on.

    Attributes
    ----------
    X : (n, 3) float
        Lifted positions (eq. 1 of ``uv``).
    F : (m, 3) int
        Faces, counter-clockwise on the disk. Replace it (``S.F = ...``) or, when the new
        faces' half-edge twins are known, :meth:`set_faces`.
    uv : (n, 2) float
        Disk positions.
    is_rim : (n,) bool
        Vertices on the image polygon (the remesh's boundary).
    face : (n,) int
        Input face under each vertex.
    bary : (n, 3) float
        Its barycentric coordinates there.
    V_in, F_in, uv_in : (N, 3) float, (M, 3) int, (N, 2) float
        The input mesh and its disk map.
    locator : PointLocator
        Point location in the input map's image.
    polygon : (k, 2) float
        The image polygon ``uv_in[boundary]``.
    locked : (n,) bool
        Vertices never moved or removed (snapped corners); none by default.
    ragged : (k,) bool
        The polygon's corners (input boundary vertices) that the rim crosses rather than
        follows (:func:`.corners.ragged_boundary`); none by default.
    fixed : (k, 3) float
        Where the vertices on the input's hole loops are (:mod:`.holes`): locked for good,
        their kept edges (:meth:`is_fixed`) never dropped or flipped. None by default.
    hole_chains : list of (j, 2, 3) float or None
        Each hole loop's kept edges as the positions of their ends, None for a loop that
        could not be placed (:func:`.holes.place_holes`). None by default.
    fans : (M,) bool
        The input faces that fill the holes kept open (:func:`.holes.place_holes`): left out
        of the input's angle sums (:meth:`angle_sums_in`). None by default.
    joined : (k, 2) int
        Vertex pairs whose edge is kept (the input's feature lines, :mod:`.features`): no flip
        removes it and no split divides it; their ends are locked. None by default.
    log : dict
        Operation counts (:meth:`tally`) and, from the improvement pass, seconds per step.
    surface_middles : bool
        Long edges are split at their middle on the surface rather than in the domain, and no
        split (long or sagging edge) is made whose point lifts next to an end
        (:func:`.refine.split_long_edges`, :func:`.refine.refine_by_sag`); both remeshers
        set it (on the disk, where the map is most anisotropic — the thin tips of a flat
        outline — the domain midpoint lifts next to an end or an opposite corner and leaves a
        needle no collapse may remove).
    """

    X: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    is_rim: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    V_in: np.ndarray
    F_in: np.ndarray
    uv_in: np.ndarray
    locator: PointLocator
    polygon: np.ndarray
    locked: np.ndarray | None = None
    joined: np.ndarray | None = None
    ragged: np.ndarray | None = None
    fixed: np.ndarray | None = None
    hole_chains: list | None = None
    fans: np.ndarray | None = None
    log: dict = field(default_factory=dict)
    surface_middles: bool = False
    _twin: tuple | None = field(default=None, repr=False)   # (the F they belong to, twins)
    _pullback: np.ndarray | None = field(default=None, repr=False)
    _normals_in: np.ndarray | None = field(default=None, repr=False)
    _angle_sums_in: np.ndarray | None = field(default=None, repr=False)
    _of_input: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        if self.locked is None:
            self.locked = np.zeros(len(self.uv), bool)
        if self.joined is None:
            self.joined = np.zeros((0, 2), np.int64)
        if self.ragged is None:
            self.ragged = np.zeros(len(self.polygon), bool)
        if self.fixed is None:
            self.fixed = np.zeros((0, 3))

    @property
    def n(self) -> int:
        """The number of vertices."""
        return len(self.uv)

    # ------------------------------------------------------------------ the input map, cached

    def normals_in(self) -> np.ndarray:
        """Unit normals (M×3) of the input faces, computed once."""
        if self._normals_in is None:
            self._normals_in = face_normals(self.V_in, self.F_in)
        return self._normals_in

    def angle_sums_in(self) -> np.ndarray:
        """The sum (degrees, N) of the input faces' angles at each input vertex, computed
        once: without the ``fans``, if given (a hole loop's vertex has the angle of the input
        with its holes open, as a rim vertex has)."""
        if self._angle_sums_in is None:
            F = self.F_in if self.fans is None else self.F_in[~self.fans]
            A = np.degrees(corner_angles(self.V_in, F))
            self._angle_sums_in = np.bincount(F.ravel(), A.ravel(), len(self.V_in))
        return self._angle_sums_in

    def on_boundary(self, v: np.ndarray | None = None) -> np.ndarray:
        """Which of the vertices ``v`` (k int; all n by default) are on the remesh's
        boundary once the holes are cut: the rim's and those at the hole loops' ``fixed``
        points; k bool."""
        rim = self.is_rim if v is None else self.is_rim[v]
        if len(self.fixed) == 0:
            return rim
        return rim | at_points(self.X if v is None else self.X[v], self.fixed)

    def pullback(self) -> np.ndarray:
        """:func:`pullback_matrices` (M×2×3) of the input map, computed once."""
        if self._pullback is None:
            self._pullback = pullback_matrices(self.V_in, self.F_in, self.uv_in)
        return self._pullback

    def of_input(self, make):
        """``make(self)``, computed once per ``make``: for a value of the input map alone
        (``V_in``, ``F_in``, ``uv_in``), which no change of the remesh alters."""
        if make not in self._of_input:
            self._of_input[make] = make(self)
        return self._of_input[make]

    def made_of_input(self, make):
        """What :meth:`of_input` made of ``make``, or None if nothing asked for it yet."""
        return self._of_input.get(make)

    # ------------------------------------------------------------------ faces and their twins

    def twins(self) -> np.ndarray:
        """The half-edge twins (3m int) of ``F``, kept until ``F`` is replaced; read-only."""
        if self._twin is None or self._twin[0] is not self.F:
            self._twin = (self.F, topo.interior_edge_twins(self.F))
        return self._twin[1]

    def cached_twins(self) -> np.ndarray | None:
        """The twins of the current ``F`` if they are known without computing them, else None."""
        return self._twin[1] if self._twin is not None and self._twin[0] is self.F else None

    def set_faces(self, F: np.ndarray, twins: np.ndarray | None = None) -> None:
        """Replace the faces; ``twins`` (3m int), when given, are those of ``F`` and are kept."""
        self.F = F
        self._twin = None if twins is None else (F, twins)

    # ------------------------------------------------------------------------------- vertices

    def append_vertices(self, M: np.ndarray, face: np.ndarray, bary: np.ndarray,
                        on_rim: np.ndarray, locked: bool = False) -> np.ndarray:
        """Append vertices at the disk points ``M`` (k×2), located at ``face`` (k) /
        ``bary`` (k×3) in the input map and lifted by eq. (1); returns their indices (k)."""
        k = len(M)
        w = self.n + np.arange(k)
        self.uv = np.vstack([self.uv, M])
        self.face = np.concatenate([self.face, face])
        self.bary = np.vstack([self.bary, bary])
        self.X = np.vstack([self.X, lift(self.V_in, self.F_in, face, bary)])
        self.is_rim = np.concatenate([self.is_rim, on_rim])
        self.locked = np.concatenate([self.locked, np.full(k, locked)])
        return w

    def keep_vertices(self, alive: np.ndarray) -> None:
        """Drop the vertices where ``alive`` (n bool) is False, none of which a face uses; the
        others keep their order, and ``F`` and ``joined`` are renumbered (a pair with a dropped
        end is dropped)."""
        new = np.cumsum(alive) - 1
        self.F = new[self.F]
        self.joined = new[self.joined[alive[self.joined].all(axis=1)]]
        kept = np.flatnonzero(alive)            # (np.take by index: faster than a bool mask)
        self.uv, self.X, self.face, self.bary, self.is_rim, self.locked = (
            np.take(x, kept, axis=0)
            for x in (self.uv, self.X, self.face, self.bary, self.is_rim, self.locked))

    def is_joined(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which edges ``a–b`` (k int each) are kept ones (``joined``, either way round);
        k bool."""
        if len(self.joined) == 0:
            return np.zeros(len(a), bool)
        key = np.sort(self.joined, axis=1)
        key = np.unique(key[:, 0] * (self.n + 1) + key[:, 1])
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        q = lo * (self.n + 1) + hi
        i = np.minimum(np.searchsorted(key, q), len(key) - 1)
        return key[i] == q

    def is_fixed(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which edges ``a–b`` (k int each) are kept edges between two vertices at ``fixed``
        points (a hole loop's edges); k bool."""
        at = at_points(self.X, self.fixed)
        return at[a] & at[b] & self.is_joined(a, b)

    # ------------------------------------------------------------------------------------ log

    def tally(self, key: str, k: int) -> None:
        """Add ``k`` to the count ``log[key]`` (operations done, for the report)."""
        self.log[key] = self.log.get(key, 0) + int(k)
