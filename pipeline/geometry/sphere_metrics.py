"""Distortion measures of a spherical map f: M → S² (the disk's §7.1 measures on the sphere).

Pure functions of the surface vertices ``V`` (n, 3), the outward faces ``F`` (m, 3) and the map
``S`` (n, 3, unit vectors). The image area of a face is the area of its *geodesic* triangle on
the unit sphere, ``|f(τ)|`` = spherical excess (:func:`.sphere.spherical_triangle_areas`), so
``|f(M)| = Σ|f(τ)| = 4π`` for a fold-free map; the disk's formulas of :mod:`.metrics` (eq. 28,
29, the face-based distortion, eq. 15's energy ratio) are applied to these areas. (The kernel
:func:`.sphere.spherical_sem` minimizes the energy of the flat chord triangles; its own
``sphere_measures`` report both.) Angles: the geodesic corner angles of the spherical triangles
(:func:`spherical_corner_angles`) against the surface's corner angles.
"""

from __future__ import annotations

import numpy as np

from .laplacian import face_double_areas
from .metrics import area_distortions, corner_angles, vertex_area_fractions
from .sphere import folded_faces, spherical_triangle_areas, triple_products

__all__ = ["spherical_corner_angles", "sphere_angular_distortion", "sphere_local_area_ratios",
           "sphere_distortion_summary"]


def spherical_corner_angles(S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Corner angles (radians) of the geodesic triangles on the unit sphere, shape (m, 3).

    At corner ``a`` of ``(a, b, c)`` the angle between the great-circle arcs ``ab`` and ``ac``
    is the angle between the tangent vectors ``t_b = b − (a·b) a`` and ``t_c = c − (a·c) a``:
    ``t_b · t_c = b·c − (a·b)(a·c)`` and ``(t_b × t_c) · a = det[a, b, c]``, so
    ``angle = atan2(det[a, b, c], b·c − (a·b)(a·c))``, negative at the corners of a folded
    face. The three angles of a fold-free triangle sum to ``π + its area`` (Girard).
    """
    S = np.asarray(S, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    det = triple_products(S, F)
    out = np.empty((len(F), 3))
    for c in range(3):
        a, b, d = S[F[:, c]], S[F[:, (c + 1) % 3]], S[F[:, (c + 2) % 3]]
        ab, ad, bd = (np.einsum("ij,ij->i", x, y) for x, y in ((a, b), (a, d), (b, d)))
        out[:, c] = np.arctan2(det, bd - ab * ad)
    return out


def sphere_angular_distortion(V: np.ndarray, F: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``|angle on M − geodesic angle on the sphere|`` per corner in degrees, shape (m, 3) (the
    disk's Fig. 5 measure, :func:`.metrics.angular_distortion`, with
    :func:`spherical_corner_angles`)."""
    return np.degrees(np.abs(corner_angles(np.asarray(V, np.float64), F)
                             - spherical_corner_angles(S, F)))


def _fractions(V, F, S):
    n = len(V)
    return (vertex_area_fractions(F, n, face_double_areas(V, F)),
            vertex_area_fractions(F, n, np.abs(spherical_triangle_areas(S, F))))


def sphere_local_area_ratios(V: np.ndarray, F: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Local area ratio ``R(v)`` of eq. (29) per vertex, shape (n,), with geodesic image areas:
    ``Σ_{τ∋v}|τ|/|M|`` over ``Σ_{τ∋v}|f(τ)|/|f(M)|`` (1 everywhere for an equiareal map;
    > 1 where the sphere compresses the surface)."""
    surface, image = _fractions(V, F, S)
    with np.errstate(divide="ignore", invalid="ignore"):
        return surface / image


def sphere_distortion_summary(V: np.ndarray, F: np.ndarray, S: np.ndarray) -> dict:
    """The disk's ``distortion`` section of ``metrics.json`` (:func:`.metrics.distortion_summary`)
    for a spherical map, against the geodesic triangle areas.

    Returns
    -------
    dict
        ``total_area_distortion_eq28`` (eq. 28), ``face_area_distortion``
        (``Σ_τ | |τ|/|M| − |f(τ)|/|f(M)| |``), ``local_area_ratio_mean`` / ``_sd`` (eq. 29),
        ``angular_distortion_mean_deg`` / ``_sd_deg`` / ``_max_deg``
        (:func:`sphere_angular_distortion`), ``flipped_faces`` (folded: ``det[s0, s1, s2] ≤ 0``),
        ``stretch_energy`` ``Σ |f(τ)|²/|τ|`` (eq. 15) and ``energy_ratio``
        ``E_S |M| / |f(M)|²`` (≥ 1, = 1 iff equiareal), ``surface_area``, ``image_area`` (4π
        when fold-free), ``max_radius_error`` ``max | |s| − 1 |``.
    """
    V = np.asarray(V, dtype=np.float64)
    S = np.asarray(S, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    A = face_double_areas(V, F) / 2
    a = np.abs(spherical_triangle_areas(S, F))
    D28, Dface = area_distortions(F, len(V), A, a)
    R = sphere_local_area_ratios(V, F, S)
    R = R[np.isfinite(R)]
    ang = sphere_angular_distortion(V, F, S)
    E = float(np.sum(a * a / A))
    return {
        "total_area_distortion_eq28": D28,
        "face_area_distortion": Dface,
        "local_area_ratio_mean": float(R.mean()),
        "local_area_ratio_sd": float(R.std()),
        "angular_distortion_mean_deg": float(ang.mean()),
        "angular_distortion_sd_deg": float(ang.std()),
        "angular_distortion_max_deg": float(ang.max()),
        "flipped_faces": folded_faces(S, F),
        "stretch_energy": E,
        "energy_ratio": float(E * A.sum() / a.sum() ** 2),
        "surface_area": float(A.sum()),
        "image_area": float(a.sum()),
        "max_radius_error": float(np.abs(np.linalg.norm(S, axis=1) - 1).max()),
    }
