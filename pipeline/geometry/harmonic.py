"""The harmonic disk map that starts SEM (§3.1, steps 2–3 of Algorithm 1)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .laplacian import (LaplacianPattern, corner_dot_over_area, edge_weights, face_double_areas,
                        laplacian_blocks)
from .metrics import flipped_faces
from .solvers import NotPositiveDefinite, make_solver, solve_complex


def arc_length_circle(V: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """Boundary loop onto the unit circle by arc length (Algorithm 1, step 2):
    ``θ_j = 2π Σ_{l<j} |v_B(l+1) − v_B(l)| / perimeter``, the first vertex at θ = 0."""
    P = V[boundary]
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    theta = 2.0 * np.pi * np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()
    return np.exp(1j * theta)


@dataclass
class HarmonicMap:
    """The result of :func:`harmonic_map`: the map ``f`` (n,) complex, the ``weights`` it was
    solved with, the cotangent weights ≤ 0 on the input mesh and its flipped faces."""

    f: np.ndarray               # complex, n
    weights: str                # "cotangent", "cotangent, clamped positive" or "uniform (Tutte)"
    negative_weights: int       # cotangent weights ≤ 0 on the input mesh
    flipped_faces: int          # of the returned map


def clamp_positive(w: np.ndarray) -> np.ndarray:
    """Replace non-positive edge weights by a small positive one (1e-6 × mean |w|).

    With positive symmetric weights every interior vertex is a convex combination of its
    neighbours, so with the boundary on a convex polygon the solve is a Tutte embedding and has no
    flipped face (Tutte; Floater 2003)."""
    floor = 1e-6 * np.mean(np.abs(w))
    return np.maximum(w, floor)


def harmonic_map(V: np.ndarray, F: np.ndarray, pattern: LaplacianPattern, solver=None,
                 double_area: np.ndarray | None = None) -> HarmonicMap:
    """Discrete harmonic map with the cotangent Laplacian (eq. 5–6): ``L_II f_I = −L_IB f_B``.

    Cotangent weights are negative across edges with obtuse opposite angles summing past π, and
    the map can then fold (or ``L_II`` stop being SPD). Then it is recomputed with those weights
    clamped positive, which is bijective by Tutte's theorem. In floating point a clamped weight (1e-6 × the mean) can
    leave a sliver face with a non-positive computed area; if any face is still flipped, the map
    is Tutte's own embedding, all weights 1. The result says which weights were used.
    ``double_area``: ``2|τ|`` per face when the caller has it.
    """
    solver = solver or make_solver()
    dA = face_double_areas(V, F) if double_area is None else double_area
    w = edge_weights(pattern, corner_dot_over_area(V, F, dA))
    fB = arc_length_circle(V, pattern.boundary)
    n_negative = int(np.count_nonzero(w <= 0))

    def solve(weights):
        L_II, L_IB, _ = laplacian_blocks(pattern, weights)
        f = np.empty(pattern.n, dtype=complex)
        f[pattern.boundary] = fB
        f[pattern.interior] = solve_complex(solver, L_II, -(L_IB @ fB))
        return f

    def attempt(weights):
        """``(map, flipped faces)``, or ``(None, None)`` if ``L_II`` is not SPD (Remark 1)."""
        try:
            f = solve(weights)
        except NotPositiveDefinite:
            return None, None
        return f, len(flipped_faces(np.column_stack([f.real, f.imag]), F))

    f, flips = attempt(w)
    label = "cotangent"
    if (f is None or flips) and n_negative:
        f, flips = attempt(clamp_positive(w))
        label = "cotangent, clamped positive"
    if f is None or flips:
        f_tutte, flips_tutte = attempt(np.ones_like(w))
        if f is None or flips_tutte < flips:
            f, flips, label = f_tutte, flips_tutte, "uniform (Tutte)"
    return HarmonicMap(f, label, n_negative, flips)
