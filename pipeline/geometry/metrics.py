"""Distortion measures of a disk map f: M → D (§7.1 of the paper and ``shared/docs/ALGORITHM.md``).

All functions take the surface vertices ``V`` (n×3), faces ``F`` (m×3) and the map ``uv`` (n×2)
and are pure. Areas: ``|τ|`` on the surface, ``|f(τ)|`` in the plane, ``|M| = Σ|τ|``,
``|f(M)| = Σ|f(τ)|``.
"""

from __future__ import annotations

import math

import numpy as np

from . import _kernels
from .laplacian import face_double_areas
from .libm import arccos
from .topology import _as_faces, boundary_loops


def as_complex_points(uv: np.ndarray) -> np.ndarray:
    """An n×2 float array as n complex numbers ``u + iv`` (a view when it is contiguous
    float64)."""
    return np.ascontiguousarray(uv, dtype=np.float64).view(np.complex128).reshape(-1)


def signed_double_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Twice the signed area of every image face, ``(u1 − u0)(v2 − v0) − (v1 − v0)(u2 − u0)``;
    positive = counter-clockwise; shape (m,) for ``uv`` (n, 2) and ``F`` (m, 3). A compiled loop:
    the numpy form's (m, 3) gathers and temporaries cost several times its arithmetic, and SEM
    evaluates it several times an iteration."""
    F = np.ascontiguousarray(_as_faces(F))
    out = np.empty(len(F))
    _kernels.signed_double_areas(F, as_complex_points(uv), out)
    return out


def flipped_faces(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Indices of image faces with non-positive signed area (flipped or collapsed)."""
    return np.flatnonzero(signed_double_areas(uv, F) <= 0.0)


def boundary_self_crossings(uv: np.ndarray, boundary: np.ndarray) -> int:
    """How many pairs of non-adjacent edges of the closed polygon ``uv[boundary]`` meet
    (cross, touch or overlap); 0 when the boundary image is a simple closed curve. A point
    that is not finite makes no curve: then the count is that of the edges at such points.

    With every face positively oriented, a disk map is one-to-one exactly when its boundary
    image is simple: the number of faces covering an image point is the boundary's winding
    number around it. A map can have no flipped face and still wind twice around an interior
    vertex (angle sum 4π); its boundary then runs backwards somewhere and crosses itself.

    Candidate pairs come from a k-d tree of the edge midpoints: two meeting edges have
    midpoints at most the longer one's length apart, so each edge asks only within its own
    length.

    Parameters
    ----------
    uv : (n, 2) float array
        The map.
    boundary : (b,) int array
        The boundary loop's vertices in order.
    """
    from scipy.spatial import cKDTree

    P = np.asarray(uv, dtype=np.float64)[np.asarray(boundary)]
    b = len(P)
    finite = np.isfinite(P).all(axis=1)
    if not finite.all():                      # no curve at all: every edge at such a point
        return int(np.count_nonzero(~(finite & np.roll(finite, -1))))
    if b < 4:
        return 0
    A, B = P, np.roll(P, -1, axis=0)
    lengths = np.hypot(*(B - A).T)
    near = cKDTree((A + B) / 2).query_ball_point((A + B) / 2, lengths, return_sorted=False)
    i = np.repeat(np.arange(b), [len(q) for q in near])
    j = np.fromiter((k for q in near for k in q), dtype=np.intp, count=len(i))
    gap = (j - i) % b
    longer = (lengths[i] > lengths[j]) | ((lengths[i] == lengths[j]) & (i < j))
    keep = (gap > 1) & (gap < b - 1) & longer        # each pair once, not neighbours
    i, j = i[keep], j[keep]

    def side(p, q, r):
        return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1])
                       - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))

    a, c = side(A[i], B[i], A[j]), side(A[i], B[i], B[j])
    d, e = side(A[j], B[j], A[i]), side(A[j], B[j], B[i])
    meet = (a * c <= 0) & (d * e <= 0)
    collinear = (a == 0) & (c == 0)
    if collinear.any():                       # on one line: they meet when their spans overlap
        k = np.flatnonzero(collinear)
        axis = np.argmax(np.abs(B[i[k]] - A[i[k]]), axis=1)[:, None]

        def span(e):                          # (lo, hi) of the edges e along that axis
            return np.sort(np.hstack([np.take_along_axis(A[e], axis, 1),
                                      np.take_along_axis(B[e], axis, 1)]), axis=1)

        span_i, span_j = span(i[k]), span(j[k])
        meet[k] = (span_i[:, 0] <= span_j[:, 1]) & (span_j[:, 0] <= span_i[:, 1])
    return int(np.count_nonzero(meet))


def stretch_energy(V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                   surface_double_area: np.ndarray | None = None) -> float:
    """``E_S(f) = Σ_τ |f(τ)|² / |τ|`` (eq. 15, equal to ``½ fᴴ L(f) f``)."""
    A = face_double_areas(V, F) if surface_double_area is None else surface_double_area
    a = signed_double_areas(uv, F)
    return float(0.5 * np.sum(a * a / A))


def energy_ratio(V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                 surface_double_area: np.ndarray | None = None) -> float:
    """``E_S(f) / (|f(M)|² / |M|)`` ≥ 1 by Cauchy–Schwarz, with equality iff f is equiareal."""
    A = face_double_areas(V, F) if surface_double_area is None else surface_double_area
    a = np.abs(signed_double_areas(uv, F))
    return float(np.sum(a * a / A) * np.sum(A) / np.sum(a) ** 2)


def vertex_area_fractions(F: np.ndarray, n: int, areas: np.ndarray, incidence=None
                          ) -> np.ndarray:
    """``Σ_{τ∋v} |τ| / Σ_τ |τ|`` per vertex for any per-face areas (the sums of eq. 28–29).
    ``incidence``: the n×m vertex–face matrix (float CSR, faces in increasing order in each row)
    when it is kept between calls; its product sums in the same order as the bincount, so gives
    the same bits, in a third of the time."""
    if incidence is not None:
        return incidence @ (areas / areas.sum())
    return np.bincount(F.ravel(), weights=np.repeat(areas / areas.sum(), 3), minlength=n)


def area_distortions(F: np.ndarray, n: int, surface_areas: np.ndarray, image_areas: np.ndarray,
                     surface_fractions: np.ndarray | None = None, incidence=None
                     ) -> tuple[float, float]:
    """``(D(f) eq. 28, face-based total area distortion)`` from per-face areas (any common
    scale; image areas unsigned). ``surface_fractions`` and ``incidence`` (see
    :func:`vertex_area_fractions`) may be passed when computed once."""
    A, a = surface_areas, np.abs(image_areas)
    if surface_fractions is None:
        surface_fractions = vertex_area_fractions(F, n, A, incidence)
    D = np.abs(surface_fractions - vertex_area_fractions(F, n, a, incidence)).sum() / 3.0
    return float(D), float(np.abs(A / A.sum() - a / a.sum()).sum())


def _vertex_area_fractions(V, F, uv):
    n = len(V)
    return (vertex_area_fractions(F, n, face_double_areas(V, F)),
            vertex_area_fractions(F, n, np.abs(signed_double_areas(uv, F))))


def total_area_distortion(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> float:
    """Per-vertex total area distortion D(f), eq. (28):
    ``⅓ Σ_v | Σ_{τ∋v}|τ|/|M| − Σ_{τ∋v}|f(τ)|/|f(M)| |``."""
    return area_distortions(F, len(V), face_double_areas(V, F), signed_double_areas(uv, F))[0]


def local_area_ratios(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Local area ratio R(v) per vertex, eq. (29); 1 everywhere for an equiareal map."""
    return _ratios(*_vertex_area_fractions(V, F, uv))


def _ratios(surface_fractions: np.ndarray, image_fractions: np.ndarray) -> np.ndarray:
    """R(v) of eq. (29) from the vertices' surface and image area fractions (inf or nan where
    the image fraction is 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return surface_fractions / image_fractions


def face_area_distortion(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> float:
    """Face-based total area distortion ``Σ_τ | |τ|/|M| − |f(τ)|/|f(M)| |`` (0 iff equiareal)."""
    return area_distortions(F, len(V), face_double_areas(V, F), signed_double_areas(uv, F))[1]


def corner_angles(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Interior angle (radians) at every corner of every face (m×3), for 2D or 3D points:
    ``arccos(u·v / (|u| |v|))`` with ``u``, ``v`` the corner's two edge vectors, the cosines
    from the compiled :func:`._kernels.corner_cosines` (2D points as 3D points with z = 0,
    which adds exact zeros). A degenerate corner (a zero-length edge) gives nan."""
    return arccos(np.clip(_corner_cosines(P, F), -1.0, 1.0))


def min_corner_angles(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The smallest interior angle (radians, m) of every face: the values of
    ``row_min(corner_angles(P, F))`` bit for bit, taken as the angle of the face's largest
    cosine (``arccos`` and the clip are monotone: one ``arccos`` a face instead of three; a
    nan cosine gives nan, as the row minimum of the angles does)."""
    return arccos(np.clip(_face_max_cosines(P, F), -1.0, 1.0))


def min_corner_angles_below(P: np.ndarray, F: np.ndarray, angle: float
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The faces that may have an angle below ``angle`` (radians) and their
    :func:`min_corner_angles` (bit for bit): every face whose smallest angle is below it,
    and the few just above (a largest cosine within 1e-6 of ``cos(angle)``; the caller
    compares the angles itself, in radians or degrees). Only those faces' cosines go
    through ``arccos``.

    Returns
    -------
    faces : (k,) int
        Increasing.
    angles : (k,) float
    """
    cos = _face_max_cosines(P, F)
    faces = np.flatnonzero(cos > math.cos(angle) - 1e-6)
    return faces, arccos(np.clip(cos[faces], -1.0, 1.0))


def _corner_cosines(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The cosines (m×3) of :func:`corner_angles`."""
    return _kernels.corner_cosines(*_points_and_faces(P, F))


def _face_max_cosines(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The largest of each face's cosines (m): ``row_max(_corner_cosines(P, F))`` bit for bit
    (:func:`._kernels.face_max_cosines`)."""
    return _kernels.face_max_cosines(*_points_and_faces(P, F))


def _points_and_faces(P: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``P`` (n×2 or n×3) as contiguous 3D points (2D ones with z = 0) and ``F`` as
    contiguous int64 faces (m×3), for the compiled corner cosines."""
    P = np.asarray(P, dtype=np.float64)
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    return np.ascontiguousarray(P), np.ascontiguousarray(_as_faces(F), dtype=np.int64)


def angular_distortion(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``|angle on M − angle on the disk|`` per corner, in degrees (paper Fig. 5)."""
    return np.degrees(np.abs(corner_angles(V, F) - corner_angles(uv, F)))


def stretch_anisotropy(V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                       surface_double_area: np.ndarray | None = None) -> np.ndarray:
    """Per face the dilatation ``K = σ₁/σ₂ ≥ 1`` of the affine map ``τ → f(τ)`` (its singular
    values; the same for the inverse map the remesh lifts through).

    ``K = 1`` iff the face is mapped conformally (a similarity); an equiareal map has
    ``σ₁σ₂ = |f(M)|/|M|`` on every face but may have any ``K``, and a circle of radius ``r`` on
    the disk lifts to an ellipse with axes ``r/σ₂`` and ``r/σ₁``: uniform disk samples have the
    right density on the surface but are ``K`` times farther apart along one direction than the
    other. Computed from the metric ``G = D⁻ᵀ EᵀE D⁻¹`` (``E``: the face's 3D edge vectors,
    ``D``: its image's), ``K = √(λmax/λmin)`` with ``λmax = (tr G + √((G₀₀ − G₁₁)² + 4G₀₁²))/2``
    (no cancellation) and ``λmin = det G / λmax``, ``det G = (2|τ| / det D)²``. Faces with
    ``|det D| ≤ 1e-300`` (zero image area) or a non-finite ``K`` get ``inf``. One compiled
    pass (:func:`._kernels.stretch_dilatations`): in numpy, the (m, 3, 2) stacks and the
    batched 2×2 inverses and products cost ten times as much.
    ``surface_double_area``: :func:`.laplacian.face_double_areas` of ``(V, F)`` when known.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    uv : (n, 2) float array
    surface_double_area : (m,) float array, optional

    Returns
    -------
    (m,) float array, every value ≥ 1 or inf"""
    A = face_double_areas(V, F) if surface_double_area is None else surface_double_area
    return _kernels.stretch_dilatations(
        np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(uv, dtype=np.float64),
        np.ascontiguousarray(_as_faces(F), dtype=np.int64),
        np.ascontiguousarray(A, dtype=np.float64))


def area_weighted_quantile(values: np.ndarray, weights: np.ndarray, q):
    """The smallest value whose cumulative weight (values ascending, equal values in index
    order) reaches ``q`` of the total: a float for a float ``q``, a list of floats for a sequence
    of them (one sort for all). The sort is numpy's default (several times faster than its
    stable sort, and the same permutation when the values are distinct); when the sorted values
    are not strictly ascending (equal or nan values) the stable sort is taken instead, as the
    order of equal values decides the cumulative sum's rounding.

    Parameters
    ----------
    values, weights : (m,) float arrays
    q : float or sequence of floats in [0, 1]
    """
    order = np.argsort(values)
    ascending = values[order]
    if not np.all(ascending[1:] > ascending[:-1]):
        order = np.argsort(values, kind="stable")
        ascending = values[order]
    cum = np.cumsum(weights[order])
    picked = ascending[np.searchsorted(cum, np.multiply(q, cum[-1]), side="left")]
    return float(picked) if np.ndim(q) == 0 else [float(x) for x in picked]


ANISOTROPY_LIMIT = 10.0     # K above this: samples ≥ 10× farther apart along one direction


def anisotropy_summary(V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                       surface_double_area: np.ndarray | None = None) -> dict:
    """Surface-area-weighted median and 90th percentile of :func:`stretch_anisotropy`, and the
    share of the surface area where it exceeds ``ANISOTROPY_LIMIT`` (``surface_double_area``:
    :func:`.laplacian.face_double_areas` of ``(V, F)`` when known)."""
    A = face_double_areas(V, F) if surface_double_area is None else surface_double_area
    K = stretch_anisotropy(V, F, uv, A)
    median, p90 = area_weighted_quantile(K, A, (0.5, 0.9))
    return {"anisotropy_median": median, "anisotropy_p90": p90,
            "anisotropy_area_above_10": float(A[K > ANISOTROPY_LIMIT].sum() / A.sum())}


def distortion_summary(V: np.ndarray, F: np.ndarray, uv: np.ndarray,
                       boundary: np.ndarray | None = None,
                       surface_double_area: np.ndarray | None = None) -> dict:
    """Every measure of §7.1 as plain floats, the content of ``metrics.json``'s ``distortion``
    (the surface and image areas and their vertex sums computed once for all of them), and the
    two fold counts: flipped faces and :func:`boundary_self_crossings` of the loop
    ``boundary`` (by default the longest boundary loop of ``F``). ``surface_double_area``:
    :func:`.laplacian.face_double_areas` of ``(V, F)`` (m,) when known (SEM's result has it)."""
    if boundary is None:
        boundary = max(boundary_loops(F), key=len)
    n = len(V)
    A = face_double_areas(V, F) if surface_double_area is None else surface_double_area
    a = signed_double_areas(uv, F)
    surface = vertex_area_fractions(F, n, A)
    R = _ratios(surface, vertex_area_fractions(F, n, np.abs(a)))
    D28, D_face = area_distortions(F, n, A, a, surface)
    ang = angular_distortion(V, F, uv)
    R_finite = R[np.isfinite(R)]
    return {
        "total_area_distortion_eq28": D28,
        "face_area_distortion": D_face,
        "local_area_ratio_mean": float(R_finite.mean()),
        "local_area_ratio_sd": float(R_finite.std()),
        "angular_distortion_mean_deg": float(ang.mean()),
        "angular_distortion_sd_deg": float(ang.std()),
        "flipped_faces": int(len(flipped_faces(uv, F))),
        "boundary_self_crossings": boundary_self_crossings(uv, boundary),
        "stretch_energy": stretch_energy(V, F, uv, A),
        "energy_ratio": energy_ratio(V, F, uv, A),
        "surface_area": float(A.sum() / 2),
        "image_area": float(np.abs(a).sum() / 2),
        **anisotropy_summary(V, F, uv, A),
    }
