"""Uniform remeshing of a closed genus-0 mesh through its equiareal sphere map (paper §8 on the
sphere): sample → triangulate → locate → lift → improve.

1. **Sample** the unit sphere evenly: the Fibonacci (golden-angle spiral) lattice of ``n``
   points (:func:`fibonacci_sphere`), deterministic and about as even as a point set on the
   sphere gets. The map is equiareal, so even on the sphere means an even area density on the
   surface. Pattern ``jittered`` (the remesh's default, as on the disk,
   :mod:`.sampling`) moves every point by a seeded offset in its tangent plane
   (:func:`jittered_sphere`): the lattice is locally a sheared hexagonal one (its hull's mean
   smallest angle is 47°, 96 % of the vertices of valence 6 at 20k points), and a
   topologically regular patch is a fixed point of the improvement's smoothing however it
   is sheared (every 1-ring is point-symmetric) and makes no Delaunay flip while its angles
   stay below 90°, so without the offsets the lattice's and the map's shear survive the
   improvement; ``hexagonal`` keeps the exact lattice (the other disk patterns have no
   sphere version).
2. **Triangulate**: the spherical Delaunay triangulation of points on a sphere is their convex
   hull (:func:`hull_triangulation`), every face turned outward (``det[p0, p1, p2] > 0``).
3. **Locate** every sample in the spherical image of the input mesh
   (:class:`..locate_sphere.SphereLocator`, central-projection barycentrics).
4. **Lift** it by eq. (1): ``Σ_c λ_c v_{F[face, c]}``.
5. **Improve** the triangles' shape on the surface with the disk remesher's pass
   (:func:`.improve.improve_remesh`, split / collapse / flip / relaxation judged by 3D lengths
   and angles), every vertex a sphere position lifted by eq. (1) and every face positively
   oriented on the sphere (:mod:`.domain`), so the result is a closed genus-0 manifold; then,
   as on the disk, the vertices offset along their normals to the least-squares fit of the
   input (``fit_surface``, :mod:`.fit`).

Landmarks go to the nearest new vertex (:mod:`.landmarks`); with ``exact_landmarks`` the
improvement first puts a locked vertex on each one's input vertex
(:func:`.uniform.interior_landmarks`), so that this vertex is the nearest.
"""

from __future__ import annotations

import numpy as np

from ..laplacian import face_double_areas
from ..libm import cos, sin
from ..locate import lift
from ..locate_sphere import SphereLocator
from ..sphere_newton import tangent_basis
from .corners import interior_corners
from .improve import Stopwatch
from .landmarks import carry_landmarks
from .sampling import DiskSamples
from .state import RemeshState
from .uniform import (RemeshResult, built_input_distance, check_remesh, check_topology,
                      improve_state, interior_landmarks)

GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))
SPHERE_PATTERNS = ("jittered", "hexagonal")
# jittered: offsets uniform in [−SPHERE_JITTER/2, SPHERE_JITTER/2] × h along each tangent axis,
# each point anywhere in the square of side h about its lattice point (twice the disk's
# sampling.JITTER: the Fibonacci lattice is sheared before the map shears it, and the disk's
# half-size offsets leave part of that shear in the remesh)
SPHERE_JITTER = 1.0


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` points evenly spread on the unit sphere: the Fibonacci lattice, point ``i`` at
    height ``z = 1 − (2i + 1)/n`` (equal-area bands) and longitude ``i`` × the golden angle.

    Parameters
    ----------
    n : int
        At least 4.

    Returns
    -------
    (n, 3) float
        Unit vectors.
    """
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = GOLDEN_ANGLE * i
    return np.column_stack([r * cos(phi), r * sin(phi), z])


def sphere_spacing(n: int) -> float:
    """The side of the equilateral triangles of ``2n − 4`` faces covering the unit sphere's
    area ``4π``: ``√(8π / (√3 (2n − 4)))``, the spacing of ``n`` points spread evenly on it."""
    return float(np.sqrt(8 * np.pi / (np.sqrt(3) * (2 * n - 4))))


def jittered_sphere(n: int, seed: int = 0, jitter: float = SPHERE_JITTER) -> np.ndarray:
    """The Fibonacci lattice of :func:`fibonacci_sphere`, each point moved by a seeded uniform
    offset in ``[−jitter/2, jitter/2] · h`` along each axis of its tangent plane
    (:func:`..sphere_newton.tangent_basis`; ``h`` = :func:`sphere_spacing` of ``n``) and put
    back on the sphere (the disk's ``jittered`` pattern, :mod:`.sampling`, with offsets of
    ``SPHERE_JITTER``).

    Parameters
    ----------
    n : int
        At least 4.
    seed : int
    jitter : float

    Returns
    -------
    (n, 3) float
        Unit vectors.
    """
    P = fibonacci_sphere(n)
    e1, e2 = tangent_basis(P)
    t = jitter * sphere_spacing(n) * (np.random.default_rng(seed).random((n, 2)) - 0.5)
    P = P + t[:, :1] * e1 + t[:, 1:] * e2
    return P / np.linalg.norm(P, axis=1, keepdims=True)


def hull_triangulation(P: np.ndarray) -> np.ndarray:
    """The spherical Delaunay triangulation of points on the unit sphere: their convex hull
    (``scipy.spatial.ConvexHull``), each face ordered so that ``det[p0, p1, p2] > 0``
    (outward, counter-clockwise seen from outside).

    Parameters
    ----------
    P : (n, 3) float
        Unit vectors, not all on one great circle.

    Returns
    -------
    (2n − 4, 3) int
        Faces; a closed genus-0 manifold when every point is a hull vertex (on the sphere they
        all are).
    """
    from scipy.spatial import ConvexHull

    F = np.ascontiguousarray(ConvexHull(P).simplices, dtype=np.int64)
    det = np.einsum("ij,ij->i", P[F[:, 0]], np.cross(P[F[:, 1]], P[F[:, 2]]))
    F[det < 0] = F[det < 0][:, [0, 2, 1]]
    return F


def vertices_for_spacing(V: np.ndarray, F: np.ndarray, spacing: float) -> int:
    """The vertex count whose equilateral triangles of side ``spacing`` cover the surface:
    ``area / (√3/2 · spacing²)`` (a closed surface of ``n`` vertices has ``2n − 4`` faces)."""
    area = float(face_double_areas(V, F).sum() / 2)
    return max(int(round(area / (np.sqrt(3) / 2 * spacing ** 2))), 4)


def target_length(V: np.ndarray, F: np.ndarray, n: int) -> float:
    """The edge length (mesh units) of ``n`` vertices spread evenly over the surface:
    ``2n − 4`` equilateral faces of side ``L`` share the area, ``L = √(4·area / (√3 (2n − 4)))``."""
    area = float(face_double_areas(V, F).sum() / 2)
    return float(np.sqrt(4.0 * area / (np.sqrt(3) * (2 * n - 4))))


def sphere_remesh(V: np.ndarray, F: np.ndarray, S_in: np.ndarray, *,
                  vertices: int | None = None, spacing: float | None = None,
                  improve: bool = True, corner_angle_deg: float = 30.0,
                  refine_sag: float = 0.2, min_angle_deg: float = 20.0,
                  landmarks: dict | None = None, exact_landmarks: bool = False,
                  pattern: str = "jittered", seed: int = 0, **params) -> RemeshResult:
    """Remesh a closed genus-0 mesh uniformly through its bijective equiareal sphere map
    (module docstring).

    The values are taken as given (the caller validates them).

    Parameters
    ----------
    V : (N, 3) float
    F : (M, 3) int
    S_in : (N, 3) float
        The sphere map: unit vectors, every spherical triangle positively oriented.
    vertices : int, optional
        The requested vertex count (met within 2 %, usually exactly), or …
    spacing : float, optional
        … the target edge length in the mesh's units.
    improve : bool
        Run the improvement pass (:func:`.improve.improve_remesh`).
    corner_angle_deg : float
        Input vertices sharper than this keep a vertex (0: none).
    refine_sag : float
        The improvement's sag tolerance, × the target length ``L`` and at least × the input's
        own spacing, the length its vertex count would have evenly spread
        (:func:`target_length` of ``N``; :func:`.improve.improve_remesh`'s ``sag_floor``):
        a remesh denser than its input sees the input's facets, its edges sag across the
        input's creases, which splits cannot remove (0: no sag refinement).
    min_angle_deg : float
        The improvement's minimum-angle pass threshold (0: no pass).
    landmarks : dict, optional
        ``{name: input vertex index}``.
    exact_landmarks : bool
        With ``improve``, each landmark gets a locked vertex on it
        (:func:`.improve.improve_remesh`'s ``landmarks_uv``).
    pattern : {"jittered", "hexagonal"}
        The samples: the Fibonacci lattice with seeded offsets (:func:`jittered_sphere`) or
        exact (:func:`fibonacci_sphere`).
    seed : int
        For ``jittered``.
    **params
        The improvement's other keywords (``flips``, ``relax_iterations``, ``relax_step``, …;
        :func:`.improve.improve_remesh`, its defaults when left out); the stage passes the
        same ``ImproveConfig`` as on the disk.

    Returns
    -------
    RemeshResult
        ``uv`` holds the vertices' sphere positions (n×3); ``samples.pattern`` is
        ``"fibonacci"`` or ``"fibonacci_jittered"``, with ``samples.spacing`` the mean sample
        spacing on the unit sphere (:func:`sphere_spacing`).
    """
    seconds = dict.fromkeys(("sample", "delaunay", "locate", "lift", "improve", "landmarks"),
                            0.0)
    lap = Stopwatch(seconds)
    locator = SphereLocator(S_in, F)
    lap("locate")
    n = int(vertices) if vertices is not None else vertices_for_spacing(V, F, spacing)
    jittered = pattern == "jittered"
    P = jittered_sphere(n, seed) if jittered else fibonacci_sphere(n)
    samples = DiskSamples(P, 0, sphere_spacing(n),
                          "fibonacci_jittered" if jittered else "fibonacci")
    lap("sample")
    F_out = hull_triangulation(P)
    lap("delaunay")
    face, bary = locator.locate(P)
    lap("locate")
    X = lift(V, F, face, bary)
    lap("lift")
    lifted = (X, F_out)
    uv_out = P
    imp = {"enabled": bool(improve)}
    L = target_length(V, F, n)
    input_tree = None
    if improve:
        S = RemeshState(X, F_out, P.copy(), np.zeros(n, bool), face, bary, V, F, S_in, locator,
                        np.zeros((0, 3)), surface_middles=True)
        corners = S_in[interior_corners(V, F, corner_angle_deg, L)]
        imp.update(improve_state(S, L, vertices, corners, min_angle_deg=min_angle_deg,
                                 refine_sag=refine_sag,
                                 sag_floor=refine_sag * target_length(V, F, len(V)),
                                 landmarks_uv=S_in[interior_landmarks(
                                     landmarks if exact_landmarks else None, [])],
                                 **params))
        X, F_out, uv_out, face, bary = S.X, S.F, S.uv, S.face, S.bary
        input_tree = built_input_distance(S)
    lap("improve")
    check_remesh(X, F_out, uv_out)
    facts = check_topology(X, F_out, closed=True)
    carried = carry_landmarks(landmarks or {}, V, S_in, X, uv_out, F_out)
    lap("landmarks")
    info = {
        "domain": "sphere",
        "pattern": samples.pattern,
        "vertices": int(len(X)),
        "samples": int(n),
        "rim_samples": 0,
        "spacing_sphere": samples.spacing,
        "spacing_mesh_units": L,
        "count_evaluations": 0,
        "improve": imp,
    }
    return RemeshResult(X, F_out, uv_out, face, bary, samples, lifted, carried, info, seconds,
                        facts, input_tree)
