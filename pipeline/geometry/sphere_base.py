"""Spherical-map primitives shared by :mod:`.sphere` and :mod:`.sphere_newton` (kept apart so
that neither imports the other): the orientation determinants of the image faces, the energy
ratio of the flat image triangles, and the fold-guarded damped step. Notation as in
:mod:`.sphere`."""

from __future__ import annotations

import numpy as np

from .laplacian import face_double_areas


def triple_products(S: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``det[s0, s1, s2]`` per face, shape (m,); positive = outward CCW on the sphere.

    Computed as ``s0 · ((s1 − s0) × (s2 − s0))`` (the same determinant): for tiny triangles
    the edge vectors keep their relative precision, where ``s0 · (s1 × s2)`` of three nearly
    equal unit vectors would cancel to rounding noise and report false folds (a Tutte start
    crowds whole limbs into such triangles)."""
    x, y, z = (np.ascontiguousarray(S[:, k]) for k in range(3))
    i, j, k = F[:, 0], F[:, 1], F[:, 2]
    x0, y0, z0 = x[i], y[i], z[i]
    ux, uy, uz = x[j] - x0, y[j] - y0, z[j] - z0
    vx, vy, vz = x[k] - x0, y[k] - y0, z[k] - z0
    return x0 * (uy * vz - uz * vy) + y0 * (uz * vx - ux * vz) + z0 * (ux * vy - uy * vx)


def energy_ratio(surface_double_areas: np.ndarray, S: np.ndarray, F: np.ndarray) -> float:
    """``E_S(f) · |M| / |f(M)|²`` with flat image areas (eq. 15 normalized; ≥ 1, = 1 iff
    equiareal)."""
    a2 = face_double_areas(S, F)
    return float(np.sum(a2 * a2 / surface_double_areas) * surface_double_areas.sum()
                 / a2.sum() ** 2)


def shrink_folding_steps(S: np.ndarray, G: np.ndarray, F: np.ndarray, alpha: float,
                         allowed: int, rounds: int = 12) -> np.ndarray:
    """The damped candidate ``normalize(S + α_v (G − S))`` with a per-vertex step ``α_v``:
    all start at ``alpha``; each round halves ``α_v`` at the vertices of every face the
    candidate folds (after ``rounds`` rounds those vertices stay at ``S``), until at most
    ``allowed`` faces are folded. A local form of the damping of :mod:`.sem`: a few
    near-degenerate faces no longer block the step of every other vertex. (n, 3) → (n, 3)."""
    a = np.full(len(S), float(alpha))
    C = S + alpha * (G - S)
    C /= np.linalg.norm(C, axis=1, keepdims=True)
    det = triple_products(C, F)
    for k in range(rounds):
        bad = det <= 0
        if np.count_nonzero(bad) <= allowed:
            break
        idx = np.unique(F[bad])
        a[idx] = 0.0 if k == rounds - 1 else a[idx] / 2
        moved = S[idx] + a[idx, None] * (G[idx] - S[idx])
        C[idx] = moved / np.linalg.norm(moved, axis=1, keepdims=True)
        mark = np.zeros(len(S), bool)
        mark[idx] = True
        touched = np.flatnonzero(mark[F].any(axis=1))     # only these faces changed
        det[touched] = triple_products(C, F[touched])
    return C
