"""Uniform remeshing through an equiareal disk map (paper §8): sample → triangulate → locate →
lift → improve.

1. **Sample** the image polygon evenly (:mod:`.sampling`) at the spacing that gives the
   requested vertex count; the map is equiareal, so even on the disk means even on the surface.
   Rim samples nearest the images of sharp boundary corners move onto them (:mod:`.corners`).
2. **Triangulate** the samples (Delaunay; a disk without leaf faces, counter-clockwise).
3. **Locate** every sample in the image of the input mesh (:mod:`..locate`).
4. **Lift** it by eq. (1): a sample ``z`` in image face ``[f_i, f_j, f_k]`` goes to
   ``(|[z, f_j, f_k]| v_i + |[f_i, z, f_k]| v_j + |[f_i, f_j, z]| v_k) / |[f_i, f_j, f_k]|``.
5. **Improve** (optional, :mod:`.improve`) the triangles' shape on the surface, every vertex
   staying on it and every face counter-clockwise on the disk; then (``fit_surface``) offset
   the vertices along their normals to the least-squares fit of the input (:mod:`.fit`): the
   remesh approximates the surface instead of interpolating it.

Landmarks go to the nearest new vertex (:mod:`.landmarks`); with ``exact_landmarks`` and the
improvement pass, the interior ones have a locked vertex put on their input vertex first (a
landmark lands on a remesh vertex exactly unless it is within ``CORNER_GAP × L`` of a vertex
locked before: a corner's, a feature line's or an earlier landmark's), which the triangles
around it pay for. Given the loops of the holes an input's fans fill, the improvement keeps
them as locked, joined vertices along each loop and cuts the faces inside them away at the
end (:mod:`.holes`): the remesh is a disk with those holes, as the input was before the fans.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..laplacian import face_double_areas
from ..locate import PointLocator, lift
from ..metrics import signed_double_areas
from ..remesh_quality import MeshDistance
from .angles import corner_angles_deg, forced_corners, input_vertex_under
from .corners import boundary_corners, interior_corners, ragged_boundary, vertex_turning
from .domain import on_sphere
from .fidelity import input_distance
from .fit import fit_to_input
from .holes import cut_holes, lift_with_holes_cut, loop_of_fans
from .halfedge import double_areas
from .improve import Stopwatch, improve_remesh, skinny_faces
from .landmarks import carry_landmarks
from .sampling import DiskSamples, sample_disk, snap_rim, triangulate_samples
from .state import RemeshFailed, RemeshState


@dataclass
class RemeshResult:
    """A uniform remesh of a disk and what is needed to report on it.

    Attributes
    ----------
    V : (n, 3) float
        Vertices: on the input surface, or with ``fit_surface`` within ``OFFSET_CAP × L`` of
        it along their normals (:mod:`.fit`).
    F : (m, 3) int
        Faces, counter-clockwise on the disk.
    uv : (n, 2) float
        The vertices' disk positions (the remesh's own parameterization).
    face, bary : (n,) int, (n, 3) float
        The input face under each vertex and its barycentric coordinates there (eq. 1).
    samples : DiskSamples
        The disk samples before improvement.
    lifted : tuple of (k, 3) float, (l, 3) int
        ``(V, F)`` straight after lifting, before improvement.
    landmarks : dict
        ``{name: {"input_vertex", "vertex", "distance"}}`` (:func:`.landmarks.carry_landmarks`).
    info : dict
        Counts and spacings; ``info["improve"]``: the improvement's counts and seconds.
    seconds : dict
        Seconds per step: sample, delaunay, locate, lift, improve, landmarks.
    facts : dict
        The remesh's :func:`..remesh_quality.mesh_facts`, as :func:`check_topology` found them.
    input_distance : MeshDistance or None
        The input's distance tree (:func:`.fidelity.input_distance`) if the improvement built
        one, for the measures to use again (:func:`built_input_distance`).
    """

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    samples: DiskSamples
    lifted: tuple
    landmarks: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    facts: dict = field(default_factory=dict)
    input_distance: MeshDistance | None = None


def area_scale(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> float:
    """``|f(M)| / |M|``: how the equiareal map scales areas (lengths by its square root on
    average)."""
    return float(np.abs(signed_double_areas(uv, F)).sum() / face_double_areas(V, F).sum())


def uniform_remesh(V: np.ndarray, F: np.ndarray, uv: np.ndarray, boundary: np.ndarray, *,
                   vertices: int | None = None, spacing: float | None = None,
                   pattern: str = "jittered", rim_relax: int = 3, seed: int = 0,
                   improve: bool = True, flips: bool = True, relax_iterations: int = 2,
                   relax_step: float = 1.0, max_dihedral_deg: float = 20.0,
                   refine_sag: float = 0.2, refine_budget: float = 0.3,
                   corner_angle_deg: float = 30.0, isotropic_iterations: int = 4,
                   final_relax_iterations: int = 6, pinned_relax_iterations: int = 2,
                   min_angle_deg: float = 20.0, follow_input: float = 0.25,
                   feature_angle_deg: float = 0.0, landmarks: dict | None = None,
                   exact_landmarks: bool = False, hole_loops: list | None = None,
                   fans: np.ndarray | None = None, fit_surface: bool = True) -> RemeshResult:
    """Remesh a disk uniformly through its bijective equiareal disk map (module docstring).

    The values are taken as given (the caller validates them).

    Parameters
    ----------
    V : (N, 3) float
    F : (M, 3) int
    uv : (N, 2) float
        The disk map, counter-clockwise and bijective.
    boundary : (b,) int
        The boundary loop; ``uv[boundary]`` is the image polygon.
    vertices : int, optional
        The requested vertex count (met within 2 %, usually exactly), or …
    spacing : float, optional
        … the target edge length in the mesh's units.
    pattern : {"hexagonal", "jittered", "blue_noise", "concentric"}
    rim_relax : int
        ODT sweeps of the sample band along the rim.
    seed : int
        For ``jittered`` and ``blue_noise``.
    improve : bool
        Run the improvement pass; ``flips`` … ``refine_budget`` and ``isotropic_iterations``
        … ``feature_angle_deg`` are its parameters (:func:`.improve.improve_remesh`).
    corner_angle_deg : float
        Input corners sharper than this keep a vertex (0: none).
    landmarks : dict, optional
        ``{name: input vertex index}``.
    exact_landmarks : bool
        With ``improve``, each interior landmark gets a locked vertex on it
        (:func:`.improve.improve_remesh`'s ``landmarks_uv``).
    hole_loops : list of (k,) int, optional
        With ``improve``: the loops of the input's holes that ``fans`` fill, kept open
        (:mod:`.holes`): the disk is remeshed with the vertex count that leaves about
        ``vertices`` once the faces in the holes are cut away (:func:`with_holes_filled`).
    fans : (M,) bool, optional
        The input faces that fill the holes (with ``hole_loops``).
    fit_surface : bool
        With ``improve``, offset the vertices along their normals to the least-squares fit
        of the input (:mod:`.fit`); else every vertex stays on the input surface.

    Returns
    -------
    RemeshResult
    """
    seconds = dict.fromkeys(("sample", "delaunay", "locate", "lift", "improve", "landmarks"),
                            0.0)
    if hole_loops and not improve:
        raise ValueError("uniform_remesh: keeping holes needs the improvement pass")
    holes = len(hole_loops) if hole_loops else 0
    if holes and vertices is not None:
        vertices = with_holes_filled(V, F, boundary, hole_loops, fans, vertices)
    lap = Stopwatch(seconds)
    locator = PointLocator(uv, F, boundary)
    lap("locate")
    ratio = area_scale(V, F, uv)
    samples = sample_disk(vertices, None if spacing is None else spacing * np.sqrt(ratio),
                          pattern, polygon=uv[boundary], relax=rim_relax, seed=seed,
                          rim_points=V[boundary] * np.sqrt(ratio))
    L = samples.spacing / np.sqrt(ratio)                                 # target length in 3D
    # the input's angle defects and rim turnings, for the rim's corners, its ragged vertices
    # and the interior corners
    turning = vertex_turning(V, F) if corner_angle_deg else None
    corners = boundary_corners(V, F, boundary, corner_angle_deg, L, turning)
    snapped = snap_rim(samples, uv[corners]) if len(corners) else np.zeros(0, np.int64)
    lap("sample")
    F_out = triangulate_samples(samples)
    lap("delaunay")
    face, bary = locator.locate(samples.points)
    lap("locate")
    X = lift(V, F, face, bary)
    lap("lift")
    lifted = (X, F_out)
    uv_out = samples.points
    ragged = ragged_boundary(V, F, boundary, corner_angle_deg, corners, turning)
    imp = {"enabled": bool(improve), "rim_corners_snapped": int(len(snapped)),
           "rim_ragged_vertices": int(ragged.sum())}
    input_tree = None
    if improve:
        S = _state(V, F, uv, boundary, locator, X, F_out, samples, face, bary, snapped, ragged)
        imp.update(improve_state(
            S, L, vertices, uv[interior_corners(V, F, corner_angle_deg, L, turning)],
            relax_iterations=relax_iterations, flips=flips, max_dihedral_deg=max_dihedral_deg,
            relax_step=relax_step, refine_sag=refine_sag, refine_budget=refine_budget,
            isotropic_iterations=isotropic_iterations,
            final_relax_iterations=final_relax_iterations,
            pinned_relax_iterations=pinned_relax_iterations, min_angle_deg=min_angle_deg,
            follow_input=follow_input, feature_angle_deg=feature_angle_deg,
            landmarks_uv=uv[interior_landmarks(landmarks if exact_landmarks else None,
                                               boundary)],
            fit_surface=fit_surface,
            **({"hole_loops": hole_loops, "fans": fans} if holes else {})))
        X, F_out, uv_out, face, bary = S.X, S.F, S.uv, S.face, S.bary
        input_tree = built_input_distance(S)
    lap("improve")
    check_remesh(X, F_out, uv_out)
    if holes:
        holes -= len(imp["holes_covered"])
        lifted = lift_with_holes_cut(*lifted, samples.points, locator,
                                     loop_of_fans(F, fans, hole_loops),
                                     imp["holes_covered_index"])
    facts = check_topology(X, F_out, holes=holes)
    carried = carry_landmarks(landmarks or {}, V, uv, X, uv_out, F_out)
    lap("landmarks")
    info = {
        "pattern": samples.pattern,
        "vertices": int(len(X)),
        "samples": int(len(samples.points)),
        "rim_samples": int(samples.n_rim),
        "spacing_disk": samples.spacing,
        "spacing_mesh_units": samples.spacing / np.sqrt(ratio),
        "count_evaluations": samples.iterations,
        "improve": imp,
    }
    if holes:
        info.update(holes_kept=holes, vertices_with_holes_filled=vertices)
    return RemeshResult(X, F_out, uv_out, face, bary, samples, lifted, carried, info, seconds,
                        facts, input_tree)


def with_holes_filled(V: np.ndarray, F: np.ndarray, boundary: np.ndarray, hole_loops: list,
                      fans: np.ndarray, vertices: int) -> int:
    """The vertex count to remesh the disk ``(V, F)`` with so that ``vertices`` are left once
    the faces in the holes (in the ``fans``, m bool) are cut away. A triangulation with ``f``
    faces and ``b`` boundary vertices on a surface of Euler characteristic ``χ`` has
    ``χ + (f + b) / 2`` vertices; the faces go with the area (the map is equiareal, the
    samples even), a share ``ρ`` (the area outside the fans over the whole) of them is kept,
    and the boundary vertices are about the lengths of the ``boundary`` and of the
    ``hole_loops`` over the target length ``L = √(2 A / (√3 n))`` of the area ``A`` outside
    the fans at ``vertices``: ``1 + b₀ / 2 + (2 n − 2 + 2 k − b₀ − b_h) / (2 ρ)``."""
    dA = face_double_areas(V, F)
    rho = dA[~fans].sum() / dA.sum()
    L = np.sqrt(dA[~fans].sum() / (np.sqrt(3) * vertices))
    b_out = loop_length(V, boundary) / L
    b_holes = sum(loop_length(V, loop) for loop in hole_loops) / L
    k = len(hole_loops)
    return int(round(1 + b_out / 2 + (2 * vertices - 2 + 2 * k - b_out - b_holes) / (2 * rho)))


def loop_length(V: np.ndarray, loop: np.ndarray) -> float:
    """The length of the closed polyline through ``V[loop]`` (k int)."""
    P = V[loop]
    return float(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum())


def interior_landmarks(landmarks: dict | None, boundary: np.ndarray) -> np.ndarray:
    """The input vertices (k int, in the order given, each once) of the ``landmarks``
    (``{name: input vertex index}``) that are not on the ``boundary`` loop: the rim keeps its
    own samples, so a landmark there goes to the nearest of them."""
    idx = np.fromiter((landmarks or {}).values(), dtype=np.int64)
    idx = idx[np.sort(np.unique(idx, return_index=True)[1])]
    return idx[~np.isin(idx, boundary)]


def built_input_distance(S: RemeshState) -> MeshDistance | None:
    """The input's distance tree (:func:`.fidelity.input_distance`) if the improvement of ``S``
    built one (the settle step does), else None: the measures of the remesh against the
    input can use it instead of building their own."""
    return S.made_of_input(input_distance)


def improve_state(S: RemeshState, L: float, target: int | None, corners: np.ndarray, *,
                  min_angle_deg: float, fans: np.ndarray | None = None,
                  fit_surface: bool = True, **params) -> dict:
    """Run :func:`.improve.improve_remesh` on ``S`` (either domain), with ``fans`` (M bool,
    the input faces that fill the holes of ``params["hole_loops"]``) cut the holes out
    (:func:`.holes.cut_holes`), with ``fit_surface`` offset the vertices to the
    least-squares fit of the input (:func:`.fit.fit_to_input`), and return what the remesh's
    ``info["improve"]`` says of it: the operation counts and seconds per step, the target
    length, the fit's offsets and the faces left below ``min_angle_deg``
    (:func:`below_min_angle`).

    Parameters
    ----------
    S : RemeshState
        Changed in place.
    L : float
        Target edge length on the surface, in the mesh's units.
    target : int, optional
        The vertex count to restore.
    corners : (k, 2) or (k, 3) float
        Domain positions of the sharp interior input vertices, sharpest first.
    min_angle_deg : float
    fit_surface : bool
    **params
        The other keywords of :func:`.improve.improve_remesh`.

    Returns
    -------
    dict
    """
    improve_remesh(S, L, target_vertices=target, corners_uv=corners,
                   min_angle_deg=min_angle_deg, fans=fans, **params)
    if fans is not None:
        cut_holes(S, loop_of_fans(S.F_in, fans, params["hole_loops"]))
    imp = {"enabled": True, "target_edge_length": float(L), **S.log}
    if fit_surface:
        lap = Stopwatch(imp, within="seconds")
        if fans is None:
            imp["fit"] = fit_to_input(S, L, min_angle_deg, S.F_in, S.of_input(input_distance))
        else:
            open_faces = S.F_in[~fans]
            imp["fit"] = fit_to_input(S, L, min_angle_deg, open_faces,
                                      MeshDistance(S.V_in, open_faces))
        lap("fit")
    imp["below_min_angle"] = below_min_angle(S, S.V_in, min_angle_deg)
    imp["seconds"] = {k: float(v) for k, v in imp.get("seconds", {}).items()}
    return imp


def check_remesh(X: np.ndarray, F: np.ndarray, uv: np.ndarray) -> None:
    """Raise :class:`RemeshFailed` if a face of the remesh is degenerate on the surface
    (:func:`..remesh_quality.degenerate_faces`) or not counter-clockwise in its domain: on the
    disk ``uv`` (n×2), or on the sphere (``uv`` n×3 unit vectors,
    :func:`.halfedge.double_areas`)."""
    from ..remesh_quality import degenerate_faces

    flat = degenerate_faces(X, F)
    areas = double_areas(uv, F) if on_sphere(uv) else signed_double_areas(uv, F)
    clockwise = np.flatnonzero(~(areas > 0))
    if len(flat) or len(clockwise):
        where = "on the sphere" if on_sphere(uv) else "on the disk"
        raise RemeshFailed(f"remesh: {len(flat)} degenerate faces and {len(clockwise)} faces "
                           f"not counter-clockwise {where} are left (first: "
                           f"{np.r_[flat, clockwise][:5].tolist()}); nothing is written")


def check_topology(X: np.ndarray, F: np.ndarray, closed: bool = False, holes: int = 0) -> dict:
    """Raise :class:`RemeshFailed` unless ``(X, F)`` is one manifold disk (one boundary loop,
    Euler characteristic 1), with ``holes`` one manifold disk with that many holes (1 +
    ``holes`` boundary loops, χ = 1 − ``holes``) or, with ``closed``, one closed, manifold,
    consistently oriented component with Euler characteristic 2 (a sphere). Returns the facts
    it checked (:func:`..remesh_quality.mesh_facts`), for the remesh's measures."""
    from ..remesh_quality import is_disk_with_holes, is_sphere, mesh_facts

    f = mesh_facts(X, F)
    if not (is_sphere(f) if closed else is_disk_with_holes(f, holes)):
        what = "sphere remesh is not a closed genus-0 manifold" if closed else \
            "remesh is not one manifold disk" + (f" with {holes} holes" if holes else "")
        raise RemeshFailed(f"remesh: the {what} ({f}); nothing is written")
    return f


def below_min_angle(S: RemeshState, V: np.ndarray, min_angle_deg: float) -> dict:
    """The faces the minimum-angle pass left below ``min_angle_deg``: how many (``faces``),
    how many of them the input forces (``at_input_corners``: an angle below it at a kept input
    corner too sharp for any fan, :func:`.angles.forced_by_corners`) and how many it does not
    (``unforced_faces``), which input vertices those corners are (``input_corner_vertices``,
    the nearest input vertex of each) and, per corner (``input_corners``), its input angle
    sum, how many faces below the minimum it has and their smallest angle there, and the even
    split of its sum among the fewest faces a vertex there can have (``even_split_deg``: 2 on
    the rim or a hole's loop, 3 inside; degrees): the best the corner's faces can share where
    the remesh's faces there span the input's angle sum
    (:meth:`.improve._Operations.raise_forced` aims at it)."""
    from scipy.spatial import cKDTree

    bad = skinny_faces(S.X, S.F, min_angle_deg) if min_angle_deg > 0 else np.zeros(0, int)
    at = forced_corners(S, min_angle_deg, bad)
    forced = at.any(axis=1)
    T, at = S.F[bad[forced]], at[forced]
    corners = np.unique(T[at])
    names = cKDTree(V).query(S.X[corners])[1] if len(corners) else np.zeros(0, int)
    sums = S.angle_sums_in()[input_vertex_under(S, corners)]
    A = corner_angles_deg(S.X, T)
    fewest = np.where(S.on_boundary(corners), 2, 3)
    per = [{"vertex": int(i), "angle_sum_deg": float(s), "faces": int((T[at] == v).sum()),
            "smallest_angle_deg": float(A[at & (T == v)].min()), "even_split_deg": float(s / k)}
           for v, i, s, k in zip(corners, np.atleast_1d(names), sums, fewest)]
    return {"threshold_deg": float(min_angle_deg), "faces": int(len(bad)),
            "at_input_corners": int(forced.sum()), "unforced_faces": int((~forced).sum()),
            "input_corner_vertices": sorted({int(i) for i in np.atleast_1d(names)}),
            "input_corners": per}


def _state(V, F, uv, boundary, locator, X, F_out, samples, face, bary, snapped, ragged
           ) -> RemeshState:
    """The lifted samples as a :class:`.state.RemeshState`: the rim samples on the rim, the
    snapped rim corners locked, the ``ragged`` boundary vertices (b bool) the rim crosses."""
    n = len(samples.points)
    is_rim = np.zeros(n, bool)
    is_rim[:samples.n_rim] = True
    locked = np.zeros(n, bool)
    locked[snapped] = True
    return RemeshState(X, F_out, samples.points, is_rim, face, bary, V, F, uv, locator,
                       uv[boundary], locked, ragged=ragged, surface_middles=True)
