"""Equiareal maps of closed genus-0 triangle meshes onto the unit sphere (spherical SEM).

Pure functions on arrays. Notation: ``V`` (n, 3) surface vertices, ``F`` (m, 3) faces
(consistently oriented), ``S`` (n, 3) unit vectors (the spherical map). Image areas are the
areas of the *flat* triangles spanned by the image points, ``|f(τ)| = ½ |(s1 − s0) × (s2 − s0)|``,
and a face is folded when ``det[s0, s1, s2] ≤ 0`` (outward CCW faces have a positive determinant).

Pipeline (:func:`spherical_sem`):

1. :func:`check_genus_zero` — closed, manifold, connected, ``χ = V − E + F = 2`` (``χ = 2 − 2g``);
   otherwise a :class:`~pipeline.errors.UserError` naming the genus. Faces are oriented outward
   (positive enclosed volume).
2. :func:`tutte_sphere_start` — puncture the largest face, Tutte-embed the remaining disk into
   the plane with that face as the outer (equilateral) triangle and positive (clamped cotangent)
   weights — an embedding by Tutte/Floater's theorem — then inverse stereographic projection,
   eq. (S2) below, with the plane scale chosen to minimize the energy ratio among fold-free scales.
3. Free phase (:func:`_free_phase`, below) and :func:`unfold`: a few full alternating-
   hemisphere half steps spread the limbs that the Tutte start crowds into triangles many
   orders of magnitude below their share of the area (long protrusions under a near-conformal
   map, where the barrier's Gauss–Newton system is too ill-conditioned to start); the folds
   they leave are smoothed away, and the result replaces the start if it has no more folded faces
   (and, with as many, a lower energy ratio).
4. Gauss–Newton minimization (:mod:`.sphere_newton`, ``method="newton"``, the default): Levenberg–
   Marquardt steps on all vertices at once, in the tangent planes, on the energy ratio plus a
   relative-entropy barrier on the orientations ``det[s_i, s_j, s_k]`` whose weight goes down a
   schedule; every iterate is fold free. It stops when the ratio is within ``newton_floor`` of
   its bound (``R − 1 ≤ 10⁻⁴`` by default, which bounds the face-based distortion by
   ``√(R − 1) = 0.01``: ``Σ|q − p| ≤ (Σ (q − p)²/p)^½ (Σ p)^½`` with ``p = |τ|/|M|``,
   ``q = |f(τ)|/|f(M)|``) or progress stalls; a stall with ``R − 1`` above
   ``newton_accept`` (10⁻³) is reported as "stalled", not "converged". If a folded face is
   left after step 3 (no barrier can start there), the hemisphere method below runs instead;
   ``method="hemisphere"`` selects it.
5. Area continuation (:func:`_area_continuation`), when step 4 stalls: where the free phase
   leaves folds that :func:`unfold` cannot remove (decimated meshes with long limbs: the
   Tutte start crowds a hand to ~10⁻¹⁰ of its share), step 4 starts from the crowded Tutte
   map and stalls far from the bound. The continuation minimizes again from the map step 4
   started from, towards surface areas that move in a few stages (geometric interpolation)
   from that map's own image areas, at which it is already equiareal, to the true ones: each
   stage starts near its minimizer. Its result replaces step 4's if its ratio is lower.

The hemisphere method: the alternating-hemisphere stretch-energy minimization of the
spherical SEM of Yueh et al., with the stereographic projection from the north pole

       h = (x − i y) / (1 − z)                                                     (S1)
       s = (2 Re h, −2 Im h, |h|² − 1) / (1 + |h|²)                                  (S2)

   (the conjugate keeps outward CCW faces counter-clockwise in the plane), the vertices with
   ``|h| < radius`` (the southern hemisphere and a margin, 1.5 by default: with exactly one
   hemisphere, 1.0, the iteration stalls on the shared meshes) are moved by the
   stretch-Laplacian solve ``L_II(f) h_I = −L_IB(f) h_B`` (the disk paper's eq. 22) with the
   rest fixed, where ``L(f)`` has the weights of eq. (12) computed from the flat image
   triangles on the sphere and the surface areas ``|τ|``; then back by (S2); then the same
   from the south pole (the map rotated so that the north pole goes south), and by default
   also around ±x and ±y (``poles``). Three phases:

   a. free (:func:`_free_phase`): full half steps kept whenever they lower the energy ratio,
      folded or not, for a few iterations; then :func:`unfold` (step 3 above);
   b. guarded: each half step is accepted only if it lowers the energy ratio
      and adds no folded face; otherwise it is damped, ``normalize(f + α (f_new − f))`` for
      ``α = 1/2, 1/4, …``, with the step shrunk further at the vertices of faces it would fold
      (:func:`shrink_folding_steps`; :mod:`.sem` holds such vertices for its disk steps);
   c. gradient (:func:`_gradient_phase`): preconditioned gradient descent of the energy ratio
      on the sphere with the same fold guard, where the hemisphere iteration has slowed (the
      half steps stall with the energy still falling along the gradient). Phases b and c
      alternate (``cycles``) while a round still lowers the ratio: each restarts where the
      other has stalled.

   Its half steps move one hemisphere with the other held, and its gradient steps are
   first-order: on meshes with long limbs both slow down with the excess spread over the
   whole map, which the Gauss–Newton steps remove.

The objective is the stretch energy of the flat image triangles, ``E_S(f) = Σ |f(τ)|² / |τ|``
(eq. 15), through the scale-free ratio ``E_S · |M| / |f(M)|² ≥ 1`` (Cauchy–Schwarz; equality iff
``|f(τ)| ∝ |τ|``). The surface is scaled to area 4π and the image lies on the unit sphere; the
reported area distortion is face-based: ``Σ_τ | |τ|/|M| − |f(τ)|/|f(M)| |`` with flat image
areas (normalized to total 4π, i.e. the same fractions); :func:`sphere_measures` also reports it
against the spherical triangle areas (spherical excess).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from pipeline.errors import UserError

from . import sphere_newton
from .harmonic import clamp_positive
from .laplacian import (corner_dot_over_area, edge_weights, face_double_areas,
                        laplacian_blocks, laplacian_pattern)
from .solvers import NotPositiveDefinite, make_solver, solve_complex
from .sphere_base import energy_ratio, shrink_folding_steps, triple_products  # noqa: F401
from .topology import (boundary_edges, boundary_loops, connected_components,
                       euler_characteristic, nonmanifold_edges, nonmanifold_vertices,
                       orient_faces_consistently, vertex_neighbours)


# ----------------------------------------------------------------------------------------------
# topology

def genus(F: np.ndarray, n: int | None = None) -> int:
    """Genus ``g = (2 − χ) / 2`` of a closed connected orientable mesh, ``χ = V − E + F``.

    Parameters
    ----------
    F : (m, 3) int array
    n : int, optional
        Vertex count (default: the vertices referenced by ``F``).

    Returns
    -------
    int
        The genus; raises :class:`UserError` when ``χ`` is odd or above 2 (not a closed
        connected orientable surface).
    """
    chi = euler_characteristic(F, n)
    if chi > 2 or chi % 2:
        raise UserError(f"mesh has Euler characteristic {chi}, which no closed connected "
                        f"orientable surface has; repair the mesh")
    return (2 - chi) // 2


def check_genus_zero(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Check that ``(V, F)`` is a closed, manifold, connected genus-0 mesh; return ``F``
    consistently oriented with outward normals.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array

    Returns
    -------
    (m, 3) int64 array
        The faces, consistently oriented so that the enclosed signed volume is positive.

    Raises
    ------
    UserError
        Boundary edges, non-manifold edges/vertices, several components, unused vertices, or a
        genus other than 0 (the message names the genus and ``χ = 2 − 2g``).
    """
    F = np.ascontiguousarray(F, dtype=np.int64)
    n = len(V)
    nb = len(boundary_edges(F))
    if nb:
        raise UserError(f"mesh has {nb} boundary edges (not closed); spherical maps need a "
                        f"closed genus-0 mesh")
    if len(nonmanifold_edges(F)) or len(nonmanifold_vertices(F, n)):
        raise UserError("mesh is not manifold; repair it before a spherical map")
    if len(np.unique(F)) != n:
        raise UserError(f"mesh has {n - len(np.unique(F))} unreferenced vertices; remove them "
                        f"before a spherical map")
    count, _ = connected_components(F, n)
    if count != 1:
        raise UserError(f"mesh has {count} connected components; spherical maps need one")
    F, _ = orient_faces_consistently(F)
    chi = euler_characteristic(F, n)
    g = genus(F, n)
    if g != 0:
        raise UserError(f"mesh is closed with genus {g} (Euler characteristic {chi}); "
                        f"spherical maps need genus 0")
    if signed_volume(V, F) < 0:
        F = F[:, [0, 2, 1]]
    return np.ascontiguousarray(F)


def signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Enclosed signed volume ``Σ det[v0, v1, v2] / 6`` (positive for outward faces)."""
    return float(triple_products(V, F).sum() / 6.0)


# ----------------------------------------------------------------------------------------------
# measures

def folded_faces(S: np.ndarray, F: np.ndarray) -> int:
    """Number of faces with ``det[s0, s1, s2] ≤ 0`` (folded or degenerate on the sphere)."""
    return int(np.count_nonzero(triple_products(S, F) <= 0))


def spherical_triangle_areas(S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Areas of the geodesic triangles (spherical excess), shape (m,), by Van Oosterom and
    Strackee: ``tan(E/2) = det[a,b,c] / (1 + a·b + b·c + c·a)`` for unit ``a, b, c``; signed
    (negative for folded faces). They sum to 4π for a fold-free map."""
    a, b, c = S[F[:, 0]], S[F[:, 1]], S[F[:, 2]]
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = 1.0 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c) \
        + np.einsum("ij,ij->i", c, a)
    return 2.0 * np.arctan2(num, den)


def face_distortion(surface_areas: np.ndarray, image_areas: np.ndarray) -> float:
    """Face-based area distortion ``Σ_τ | |τ|/Σ|τ| − |f(τ)|/Σ|f(τ)| |`` (shapes (m,))."""
    A, a = surface_areas, np.abs(image_areas)
    return float(np.abs(A / A.sum() - a / a.sum()).sum())


def sphere_measures(V: np.ndarray, F: np.ndarray, S: np.ndarray) -> dict:
    """Distortion measures of a spherical map.

    Returns
    -------
    dict
        ``face_area_distortion`` (flat image triangles, scaled to total 4π),
        ``face_area_distortion_spherical`` (geodesic triangle areas), ``folded_faces``,
        ``energy_ratio``, ``max_radius_error`` (``max | |s| − 1 |``).
    """
    A2 = face_double_areas(V, F)
    return {"face_area_distortion": face_distortion(A2, face_double_areas(S, F)),
            "face_area_distortion_spherical": face_distortion(A2, spherical_triangle_areas(S, F)),
            "folded_faces": folded_faces(S, F),
            "energy_ratio": energy_ratio(A2, S, F),
            "max_radius_error": float(np.abs(np.linalg.norm(S, axis=1) - 1).max())}


# ----------------------------------------------------------------------------------------------
# stereographic projection

def stereographic(S: np.ndarray) -> np.ndarray:
    """Projection (S1) from the north pole, ``h = (x − i y)/(1 − z)``; (n, 3) → (n,) complex.
    The southern hemisphere maps into the unit disk; outward CCW faces stay CCW. A point at the
    pole itself goes to infinity (``h`` is ``inf``/``nan`` there, without a warning)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return (S[:, 0] - 1j * S[:, 1]) / (1.0 - S[:, 2])


def inverse_stereographic(h: np.ndarray) -> np.ndarray:
    """Inverse (S2) of :func:`stereographic`; (n,) complex → (n, 3) unit vectors."""
    r2 = h.real ** 2 + h.imag ** 2
    return np.column_stack([2 * h.real, -2 * h.imag, r2 - 1.0]) / (1.0 + r2)[:, None]


# ----------------------------------------------------------------------------------------------
# start map

def tutte_sphere_start(V: np.ndarray, F: np.ndarray, solver: str = "auto",
                       scales: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Spherical start map: punctured Tutte embedding + inverse stereographic projection.

    The largest face ``(a, b, c)`` is removed; the remaining disk's boundary loop goes to an
    equilateral triangle on the unit circle (counter-clockwise), and the interior solves
    ``L_II h_I = −L_IB h_B`` with cotangent weights clamped positive (a Tutte map: an embedding
    of the disk, since a triangulated sphere without repeated edges is 3-connected). The plane
    is then scaled, ``h ↦ s h``, and lifted by (S2); ``s`` is the candidate in ``scales``
    (default 1.05 … 10⁴, log-spaced) with no folded face and the smallest energy ratio.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array, outward oriented (:func:`check_genus_zero`)

    Returns
    -------
    S : (n, 3) float array of unit vectors
    info : dict
        ``punctured_face``, ``scale``, ``folded_faces``.
    """
    A2 = face_double_areas(V, F)
    t = int(np.argmax(A2))
    keep = np.ones(len(F), bool)
    keep[t] = False
    Fd = F[keep]
    loop = boundary_loops(Fd, V)[0]
    pattern = laplacian_pattern(Fd, len(V), loop)
    w = clamp_positive(edge_weights(pattern, corner_dot_over_area(V, Fd, A2[keep])))
    L_II, L_IB, _ = laplacian_blocks(pattern, w)
    hB = np.exp(2j * np.pi * np.arange(3) / 3)
    h = np.empty(len(V), complex)
    h[pattern.boundary] = hB
    h[pattern.interior] = solve_complex(make_solver(solver), L_II, -(L_IB @ hB))
    if scales is None:
        scales = np.geomspace(1.05, 1e4, 60)
    best = None
    for s in scales:
        S = inverse_stereographic(s * h)
        folds = folded_faces(S, F)
        ratio = energy_ratio(A2, S, F)
        key = (folds, ratio)
        if best is None or key < best[0]:
            best = (key, s, S)
    (folds, _), s, S = best
    return S, {"punctured_face": t, "scale": float(s), "folded_faces": int(folds)}


# ----------------------------------------------------------------------------------------------
# spherical SEM

@dataclass
class SphereResult:
    """Result of :func:`spherical_sem`: ``S`` (n, 3) unit vectors, ``F`` the oriented faces,
    the measures of the start and the result, the per-iteration ``history`` and ``timings``."""
    S: np.ndarray
    F: np.ndarray
    start: dict
    measures: dict
    iterations: int
    status: str
    history: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)


class _Split:
    """A half step's free set with its Laplacian pattern and solver, kept between iterations
    so that CHOLMOD refactors on the analysed pattern instead of analysing a new one (the
    analysis was most of a half step's time). Rebuilt after ``max_age`` uses, or once a free
    vertex has left the disk ``|h| < 2·radius``."""

    def __init__(self, F, h, radius, solver, max_age=8):
        self.free = np.abs(h) < radius
        self.pattern = laplacian_pattern(F, len(h), np.flatnonzero(~self.free))
        self.near = self.free[F].any(axis=1)
        self.solver = make_solver(solver, refactored=True)
        self.age, self.max_age = 0, max_age

    def stale(self, h, radius):
        return self.age >= self.max_age or bool(np.any(np.abs(h[self.free]) >= 2 * radius))


def _hemisphere_step(V, F, A2, S, radius, solver, cache=None, key=None):
    """One half step from the north pole: the vertices with ``|h| < radius`` (h by (S1)) solve
    ``L_II(f) h_I = −L_IB(f) h_B`` with the rest fixed (the disk paper's eq. 22), where ``L(f)``
    has the stretch weights of eq. (12) computed from the flat image triangles on the sphere and
    the surface areas ``|τ|`` (only faces with a free vertex enter). With a ``cache`` dict, the
    free set of ``key`` is reused for a few iterations (:class:`_Split`). Returns the new (n, 3)
    map (the fixed vertices exactly as they were), or None if no vertex or every vertex is
    free."""
    h = stereographic(S)
    split = None if cache is None else cache.get(key)
    if split is None or split.stale(h, radius):
        split = _Split(F, h, radius, solver)
        if cache is not None:
            cache[key] = split
    split.age += 1
    if not split.free.any() or split.free.all():
        return None
    pattern, near = split.pattern, split.near
    corner = np.zeros((len(F), 3))
    corner[near] = corner_dot_over_area(S, F[near], A2[near])
    w = edge_weights(pattern, corner)
    hB = h[pattern.boundary]
    try:
        L_II, L_IB, _ = laplacian_blocks(pattern, w)
        hI = solve_complex(split.solver, L_II, -(L_IB @ hB))
    except NotPositiveDefinite:
        L_II, L_IB, _ = laplacian_blocks(pattern, clamp_positive(w))
        hI = solve_complex(split.solver, L_II, -(L_IB @ hB))
    out = S.copy()
    out[pattern.interior] = inverse_stereographic(hI)
    return out


def unfold(S: np.ndarray, F: np.ndarray, rounds: int = 200) -> tuple[np.ndarray, int]:
    """Remove folds by local smoothing: each round moves the vertices of every folded face to
    the normalized mean of their neighbours (a uniform-weight Tutte step on the sphere), until
    no face is folded or ``rounds`` rounds ran. Returns ``(map (n, 3), folded faces left)``.
    Only the folded faces' own vertices move, so the rest of the map keeps its areas."""
    S = S.copy()
    nbr = vertex_neighbours(F, len(S))
    nbr = (nbr > 0).astype(np.float64).tocsr()
    deg = np.asarray(nbr.sum(axis=1)).ravel()
    det = triple_products(S, F)
    for _ in range(rounds):
        bad = det <= 0
        if not bad.any():
            break
        idx = np.unique(F[bad])
        M = (nbr[idx] @ S) / deg[idx, None]
        S[idx] = M / np.linalg.norm(M, axis=1, keepdims=True)
        det = triple_products(S, F)
    return S, int(np.count_nonzero(det <= 0))


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    R = np.eye(3)
    R[i, i] = R[j, j] = c
    R[i, j], R[j, i] = -s, s
    return R


#: Rotations ``R`` applied before a half step (``S ↦ S Rᵀ``, undone after): the half step frees
#: the vertices around ``−z``, so these free the hemispheres around −z, +z ("z": the two poles
#: of the spherical SEM) and also ±x, ±y ("xyz").
_POLES = {"z": [np.eye(3), _rotation(0, np.pi)]}
_POLES["xyz"] = _POLES["z"] + [_rotation(1, np.pi / 2), _rotation(1, -np.pi / 2),
                               _rotation(0, np.pi / 2), _rotation(0, -np.pi / 2)]


def _rotated_step(V, F, A2, S, R, radius, solver, cache, key):
    """:func:`_hemisphere_step` around the pole that the rotation ``R`` (3, 3) takes to the
    north: the map rotated by ``R``, stepped, rotated back. None where the step is."""
    G = _hemisphere_step(V, F, A2, S @ R.T, radius, solver, cache, key)
    return None if G is None else G @ R


def _free_phase(V, F, A2, S, ratio, iterations, tol, radius, poles, solver,
                deadline=np.inf):
    """Full half steps, each kept if it lowers the energy ratio, folded or not (as Algorithm 1
    of the disk paper passes through folded maps), for at most ``iterations`` iterations or
    until an iteration lowers the ratio by less than ``tol`` (relative). Returns ``(map,
    iterations, folded faces)``, or None if no step was kept. It exists for starts crowded to
    tiny area ratios (a Tutte map of a mesh with long limbs), from which the guarded iteration
    stalls: a few free iterations spread the map, and :func:`unfold` removes the folds they
    leave. No iteration starts after ``deadline`` (``time.perf_counter()``). A vertex at the
    projection pole (small meshes) makes its half step's map non-finite; that step is not
    kept."""
    kept, it, cache = False, 0, {}
    for it in range(1, iterations + 1):
        if time.perf_counter() > deadline:
            break
        before = ratio
        for p, R in enumerate(_POLES[poles]):
            with np.errstate(divide="ignore", invalid="ignore"):
                G = _rotated_step(V, F, A2, S, R, radius, solver, cache, p)
                if G is None:
                    continue
                g_ratio = energy_ratio(A2, G, F)
            if g_ratio < ratio:
                S, ratio, kept = G, g_ratio, True
        if before - ratio < tol * before:
            break
    return (S, it, folded_faces(S, F)) if kept else None


def ratio_gradient(A2: np.ndarray, S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Gradient of the energy ratio ``R = E_S |M| / A²`` (``A = Σ|f(τ)|`` flat image areas) in
    the image points, projected onto the sphere's tangent planes; (n, 3).

    With the unit normal ``n̂_τ`` and, at corner ``i`` of ``τ = (i, j, k)``,
    ``∇_i |f(τ)| = ½ n̂_τ × (s_k − s_j)``: ``∇E_S = Σ_τ 2 (|f(τ)|/|τ|) ∇|f(τ)|`` and
    ``∇R = |M| / A² (∇E_S − 2 E_S / A ∇A)``."""
    n = len(S)
    p0, p1, p2 = S[F[:, 0]], S[F[:, 1]], S[F[:, 2]]
    N = np.cross(p1 - p0, p2 - p0)
    a2 = np.linalg.norm(N, axis=1)
    nh = N / a2[:, None]
    a, area = a2 / 2, A2 / 2
    E, A, M = float(np.sum(a * a / area)), float(a.sum()), float(area.sum())
    coef = 2 * a / area - 2 * E / A               # per face: ∇E_S − 2E/A ∇A
    g = np.zeros((n, 3))
    for c, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):
        v = 0.5 * np.cross(nh, S[F[:, k]] - S[F[:, j]]) * coef[:, None]
        for d in range(3):
            g[:, d] += np.bincount(F[:, c], weights=v[:, d], minlength=n)
    g *= M / A ** 2
    return g - np.sum(g * S, axis=1, keepdims=True) * S


def _gradient_phase(V, F, A2, S, ratio, folds, deadline, iterations, tol, patience, solver):
    """Preconditioned gradient descent of the energy ratio on the sphere: direction
    ``d = P⁻¹ ∇R`` (:func:`ratio_gradient`) with ``P`` the stretch Laplacian of the current
    map (eq. 12 weights, clamped at 1e-8 of their mean from below, plus 1e-3 of the mean weight
    on the diagonal: SPD), tangential part; step ``normalize(S − t d)`` with per-vertex damping
    at folding faces (:func:`shrink_folding_steps`), ``t`` halved until the ratio falls without
    a new fold and doubled while it keeps falling. Returns ``(S, ratio, folds, steps)``."""
    pattern = laplacian_pattern(F, len(S), np.zeros(0, np.int64))
    P_solver = make_solver(solver, refactored=True)
    quiet, t, step = 0, 1.0, 0
    while step < iterations and time.perf_counter() < deadline:
        w = edge_weights(pattern, corner_dot_over_area(S, F, A2))
        w = np.maximum(w, 1e-8 * np.abs(w).mean())
        L = laplacian_blocks(pattern, w)[0]
        L = L + 1e-3 * w.mean() * sp.identity(L.shape[0], format="csr")
        P_solver.factorize(L)
        d = P_solver.solve(ratio_gradient(A2, S, F))
        d -= np.sum(d * S, axis=1, keepdims=True) * S
        t, found = min(2 * t, 8.0), None
        while t >= 1e-6:
            C = shrink_folding_steps(S, S - d, F, t, folds)
            c_folds, c_ratio = folded_faces(C, F), energy_ratio(A2, C, F)
            if c_folds <= folds and c_ratio < ratio:
                found = (C, c_ratio, c_folds)
                break
            t /= 2
        if found is None:
            break
        step += 1
        before = ratio
        S, ratio, folds = found
        if before - ratio < tol * (before - 1.0):     # relative to the excess over 1
            quiet += 1
            if quiet >= patience:
                break
        else:
            quiet = 0
    return S, ratio, folds, step


def spherical_sem(V: np.ndarray, F: np.ndarray, max_iter: int = 40, tol: float = 1e-6,
                  patience: int = 4, radius: float = 1.5, min_step: float = 1.0 / 64,
                  time_limit: float | None = None, solver: str = "auto",
                  poles: str = "xyz", free_iter: int = 10,
                  gradient_iter: int = 2000, gradient_tol: float = 1e-4,
                  cycles: int = 10, method: str = "newton",
                  barriers: tuple = (2.0, 0.2, 0.02), newton_iter: int = 500,
                  newton_tol: float = 1e-2, newton_patience: int = 3,
                  newton_floor: float = 1e-4, newton_accept: float = 1e-3,
                  continuation: int = 4) -> SphereResult:
    """Equiareal map of a closed genus-0 mesh onto the unit sphere by stretch-energy
    minimization.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    method : {"newton", "hemisphere"}
        ``"newton"`` (default): the free phase from the Tutte start, :func:`unfold`, then
        Gauss–Newton steps on the energy ratio with a fold barrier (:mod:`.sphere_newton`),
        and the area continuation if they stall (``continuation``); if a folded face is
        left, the hemisphere method runs instead. ``"hemisphere"``: the
        alternating-hemisphere SEM with its free, guarded and gradient phases.
    barriers : tuple of float
        The barrier weights ``κ`` of the Newton stages (decreasing).
    newton_iter, newton_tol, newton_patience, newton_floor : int, float, int, float
        Newton iterations at most; a stage ends after ``newton_patience`` iterations in a
        row that lower its objective by less than ``newton_tol`` (relative), or once the
        energy ratio is within ``newton_floor`` of its bound 1; the last one's end is
        convergence (:func:`.sphere_newton.minimize`).
    newton_accept : float
        Largest ``R − 1`` at which a minimization that stops above ``newton_floor`` is
        "converged" (``√newton_accept`` bounds the face-based distortion); further from 1 the
        status is "stalled".
    continuation : int
        Stages of the area continuation (:func:`_area_continuation`; 0: none) run from the
        map handed to the Gauss–Newton minimization when that minimization stalls; its result
        replaces the stalled one if its energy ratio is lower.
    max_iter : int
        Guarded hemisphere iterations (each = one half step around each pole).
    tol, patience : float, int
        Stop once the relative decrease of the energy ratio per iteration stays below ``tol``
        for ``patience`` iterations (hemisphere method; Newton: ``patience`` only).
    radius : float
        Half steps move the vertices with ``|h| < radius`` (1 = exactly one hemisphere).
    min_step : float
        Smallest damping factor tried before a half step is skipped.
    cycles : int
        Rounds of (guarded hemisphere iterations, gradient phase); a round that lowers the
        ratio by less than ``tol`` (relative) ends them: each phase restarts where the other
        has stalled.
    gradient_iter : int
        Steps of the final preconditioned gradient phase (:func:`_gradient_phase`; 0: none),
        which runs after the guarded hemisphere iterations until it stalls, ``patience``
        steps in a row lower the ratio's excess ``R − 1`` by less than ``gradient_tol``
        (relative), or ``time_limit``.
    free_iter : int
        Iterations of the free phase (:func:`_free_phase`; 0: none) before the guarded one
        (hemisphere) or the Gauss–Newton minimization (newton). With fewer, the map it hands
        on can keep long thin image triangles whose vertices lie near a great circle
        (orientation ``det`` ≪ flat area), at which the Newton steps stall above the floor.
    poles : {"xyz", "z"}
        Half steps per iteration: around −z and +z only (the two poles of the spherical SEM),
        or around all six of ±x, ±y, ±z (default: with the two poles only, the iteration
        stalls far above the six-pole result on the shared meshes).
    time_limit : float, optional
        Seconds after which no further iteration starts.

    Returns
    -------
    SphereResult
        The map never has more folded faces than the start (0 when the start has none): every
        accepted step adds none. ``status``: "converged" (``R − 1 ≤ newton_accept`` where the
        minimization stopped), "stalled" (stopped further from the bound), "max_iter" or
        "time_limit". ``timings`` has ``start``, ``newton`` (and ``continuation`` when it
        ran) or ``free``/``sem``/``gradient``, and ``total``.
    """
    if method not in ("newton", "hemisphere"):
        raise UserError(f"unknown spherical method '{method}'; use newton or hemisphere")
    t_all = time.perf_counter()
    V = np.asarray(V, dtype=np.float64)
    F = check_genus_zero(V, F)
    A2 = face_double_areas(V, F)
    V = V * np.sqrt(4 * np.pi / (A2.sum() / 2))          # surface area 4π
    A2 = face_double_areas(V, F)
    timings = {}
    t0 = time.perf_counter()
    S, start_info = tutte_sphere_start(V, F, solver)
    timings["start"] = time.perf_counter() - t0
    start = {**start_info, **sphere_measures(V, F, S)}
    folds = start["folded_faces"]
    ratio = energy_ratio(A2, S, F)
    history = [{"iteration": 0, "energy_ratio": ratio, "folded_faces": folds,
                "seconds": time.perf_counter() - t_all}]
    deadline = np.inf if time_limit is None else t_all + time_limit
    if method == "newton":
        t0 = time.perf_counter()
        S, ratio, folds = _spread(V, F, A2, S, ratio, folds, free_iter, tol, radius, poles,
                                  solver, history, t_all, deadline)
        timings["free"] = time.perf_counter() - t0
        if folds == 0:
            t0 = time.perf_counter()
            S_newton = S
            S, status, it = sphere_newton.minimize(
                F, A2, S, kappas=barriers, deadline=deadline, max_iter=newton_iter,
                tol=newton_tol, patience=newton_patience, floor=newton_floor, solver=solver,
                history=history, clock_start=t_all, accept=newton_accept)
            timings["newton"] = time.perf_counter() - t0
            if status == "stalled" and continuation:
                t0 = time.perf_counter()
                C, c_status, c_it = _area_continuation(
                    F, A2, S_newton, continuation, deadline=deadline, kappas=barriers,
                    max_iter=newton_iter, tol=newton_tol, patience=newton_patience,
                    floor=newton_floor, solver=solver, history=history, clock_start=t_all,
                    accept=newton_accept)
                timings["continuation"] = time.perf_counter() - t0
                if energy_ratio(A2, C, F) < energy_ratio(A2, S, F):
                    S, status, it = C, c_status, it + c_it
            timings["total"] = time.perf_counter() - t_all
            return SphereResult(S=S, F=F, start=start, measures=sphere_measures(V, F, S),
                                iterations=it, status=status, history=history,
                                timings=timings)
        free_iter = 0                              # the hemisphere method goes on from here
    return _hemisphere_sem(V, F, A2, S, ratio, folds, start, history, timings, t_all,
                           deadline, max_iter, tol, patience, radius, min_step, solver,
                           poles, free_iter, gradient_iter, gradient_tol, cycles,
                           newton_accept)


def _area_continuation(F, A2, S, stages, deadline=np.inf, max_iter=500, stage_iter=60,
                       history=None, **newton):
    """Gauss–Newton minimization (:func:`.sphere_newton.minimize`) along a path of surface
    areas from those of the map ``S`` (fold free) to the true ones: stage ``k = 1 … stages``
    minimizes towards the double areas ``A_k = a^(1 − t) A2^t``, ``t = k / stages``
    (geometric interpolation of the normalized image areas ``a`` of ``S`` and ``A2``), from the
    previous stage's map; the intermediate stages run at most ``stage_iter`` iterations, the
    last one ``max_iter``. In ``history`` (phase "continuation", with its ``stage``) the
    intermediate iterations have their ``stage_energy_ratio``; a stage's last iteration also
    has the ``energy_ratio`` against ``A2``. At ``t = 0`` the map is already equiareal for its targets, and
    each stage moves the areas by a bounded factor, so every stage starts near its own
    minimizer — where a start crowded to many orders of magnitude below the true areas (a
    Tutte map of a mesh with long limbs) stalls the direct minimization far from the bound.
    Returns ``(map, status of the last stage, iterations)``."""
    a = np.maximum(face_double_areas(S, F), np.finfo(float).tiny)
    log_a, log_A = np.log(a / a.sum()), np.log(A2 / A2.sum())
    status, total = "time_limit", 0
    for k in range(1, stages + 1):
        if time.perf_counter() > deadline:
            status = "time_limit"
            break
        t = k / stages
        target = A2 if k == stages else np.exp((1 - t) * log_a + t * log_A)
        mark = None if history is None else len(history)
        S, status, it = sphere_newton.minimize(
            F, target, S, deadline=deadline, max_iter=max_iter if k == stages else stage_iter,
            history=history, **newton)
        total += it
        if history is not None:
            for h in history[mark:]:
                h["phase"], h["stage"] = "continuation", k
                if k < stages:          # their ratio is against the stage's areas: renamed
                    h["stage_energy_ratio"] = h.pop("energy_ratio")
            if k < stages and len(history) > mark:
                history[-1]["energy_ratio"] = energy_ratio(A2, S, F)
    return S, status, total


def _spread(V, F, A2, S, ratio, folds, free_iter, tol, radius, poles, solver, history, t_all,
            deadline=np.inf):
    """The free phase (:func:`_free_phase`) and :func:`unfold`; the result replaces ``S`` if
    it has no more folded faces and a lower energy ratio (always tried, also from a start
    with folds, which :func:`unfold` alone then tries to remove). Returns ``(S, ratio,
    folds)``."""
    free = _free_phase(V, F, A2, S, ratio, free_iter, tol, radius, poles, solver,
                       deadline) if free_iter else None
    if free is None and folds == 0:
        return S, ratio, folds
    U, left = unfold(S if free is None else free[0], F)
    u_ratio = energy_ratio(A2, U, F)
    accepted = left < folds or (left <= folds and u_ratio < ratio)
    history.append({"iteration": 0, "phase": "free+unfold", "energy_ratio": u_ratio,
                    "folded_faces": left, "free_iterations": 0 if free is None else free[1],
                    "free_folded_faces": left if free is None else free[2],
                    "accepted": accepted, "seconds": time.perf_counter() - t_all})
    if accepted:
        S, ratio, folds = U, u_ratio, left
    return S, ratio, folds


def _hemisphere_sem(V, F, A2, S, ratio, folds, start, history, timings, t_all, deadline,
                    max_iter, tol, patience, radius, min_step, solver, poles, free_iter,
                    gradient_iter, gradient_tol, cycles, accept=1e-3) -> SphereResult:
    """The alternating-hemisphere method of :func:`spherical_sem` (phases a–c of the module
    docstring) from the start map ``S``; an end with ``R − 1 > accept`` that would be
    "converged" (progress stopped) is "stalled"."""
    t0 = time.perf_counter()
    S, ratio, folds = _spread(V, F, A2, S, ratio, folds, free_iter, tol, radius, poles,
                              solver, history, t_all, deadline)
    timings["free"] = timings.get("free", 0.0) + time.perf_counter() - t0
    status, it, cache = "max_iter", 0, {}
    timings["sem"] = timings["gradient"] = 0.0
    for cycle in range(cycles):
        cycle_start, quiet, cycle_it = ratio, 0, 0
        t0 = time.perf_counter()
        while cycle_it < max_iter:
            if time.perf_counter() > deadline:
                status = "time_limit"
                break
            it += 1
            cycle_it += 1
            before = ratio
            for p, R in enumerate(_POLES[poles]):
                G = _rotated_step(V, F, A2, S, R, radius, solver, cache, p)
                if G is None:
                    continue
                alpha = 1.0
                while alpha >= min_step:
                    C = shrink_folding_steps(S, G, F, alpha, folds)
                    c_folds = folded_faces(C, F)
                    c_ratio = energy_ratio(A2, C, F)
                    if c_folds <= folds and c_ratio < ratio:
                        S, ratio, folds = C, c_ratio, c_folds
                        break
                    alpha /= 2
            history.append({"iteration": it, "energy_ratio": ratio, "folded_faces": folds,
                            "seconds": time.perf_counter() - t_all})
            if before - ratio < tol * before:
                quiet += 1
                if quiet >= patience:
                    status = "converged"
                    break
            else:
                quiet = 0
        timings["sem"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        if gradient_iter and status != "time_limit":
            S, ratio, folds, steps = _gradient_phase(V, F, A2, S, ratio, folds, deadline,
                                                     gradient_iter, gradient_tol, 3 * patience,
                                                     solver)
            history.append({"iteration": it, "phase": "gradient", "steps": steps,
                            "energy_ratio": ratio, "folded_faces": folds,
                            "seconds": time.perf_counter() - t_all})
            status = "time_limit" if time.perf_counter() >= deadline else "converged"
        timings["gradient"] += time.perf_counter() - t0
        if status == "time_limit" or cycle_start - ratio < tol * cycle_start:
            break
    if status == "converged" and ratio - 1.0 > accept:
        status = "stalled"
    timings["total"] = time.perf_counter() - t_all
    return SphereResult(S=S, F=F, start=start, measures=sphere_measures(V, F, S),
                        iterations=it, status=status, history=history, timings=timings)
