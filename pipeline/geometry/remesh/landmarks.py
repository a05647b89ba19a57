"""Landmarks carried from the input mesh to the remesh."""

from __future__ import annotations

import numpy as np

from .domain import locator


def carry_landmarks(landmarks: dict, V_in: np.ndarray, uv_in: np.ndarray, X: np.ndarray,
                    uv: np.ndarray, F: np.ndarray) -> dict:
    """Each landmark goes to the nearest new vertex: the corner, nearest in 3D, of the remesh
    face that contains the landmark's disk position.

    Parameters
    ----------
    landmarks : dict
        ``{name: input vertex index}``.
    V_in, uv_in : (N, 3) float, (N, 2) or (N, 3) float
        The input vertices and their domain positions (disk, or sphere: :mod:`.domain`).
    X, uv : (n, 3) float, (n, 2) or (n, 3) float
        The remesh's vertices and their domain positions.
    F : (m, 3) int
        The remesh's faces.

    Returns
    -------
    dict
        ``{name: {"input_vertex": i, "vertex": j, "distance": |X[j] − V_in[i]|}}``.
    """
    if not landmarks:
        return {}
    names = list(landmarks)
    idx = np.array([landmarks[k] for k in names], np.int64)
    face, _ = locator(uv, F).locate(uv_in[idx])
    corners = F[face]                                                # (k, 3)
    d = np.linalg.norm(X[corners] - V_in[idx][:, None, :], axis=2)
    j = np.argmin(d, axis=1)
    out = {}
    for i, name in enumerate(names):
        out[name] = {"input_vertex": int(idx[i]), "vertex": int(corners[i, j[i]]),
                     "distance": float(d[i, j[i]])}
    return out
