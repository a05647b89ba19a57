"""Morphing between a face and its registered image on the shared connectivity (§8).

A frame at time ``t ∈ [0, 1]`` is ``V(t) = (1 − t) V_source + t V_registered``: every vertex moves
on a straight line from its own position to the position the registration gave it on the
target surface, so ``V(0) = V_source`` and ``V(1) = V_registered`` exactly and the connectivity
never changes. ``K`` frames are spaced by an easing of the uniform times ``s_k = k / (K − 1)``:

* ``linear``: ``t = s``;
* ``ease-in-out`` (smoothstep): ``t = 3s² − 2s³`` (zero speed at both ends);
* ``cosine``: ``t = (1 − cos πs) / 2``.
"""

from __future__ import annotations

import numpy as np

EASINGS = ("linear", "ease-in-out", "cosine")

__all__ = ["EASINGS", "ease", "frame_times", "interpolate", "morph_frames"]


def ease(s, easing: str = "linear") -> np.ndarray:
    """The easing curve at ``s`` (array in [0, 1]); maps 0 → 0 and 1 → 1 exactly."""
    s = np.clip(np.asarray(s, dtype=np.float64), 0.0, 1.0)
    if easing == "linear":
        return s
    if easing == "ease-in-out":
        return s * s * (3.0 - 2.0 * s)
    if easing == "cosine":
        t = 0.5 * (1.0 - np.cos(np.pi * s))
        return np.where(s >= 1.0, 1.0, t)          # cos(π) rounding: end exactly at 1
    raise ValueError(f"easing must be one of {EASINGS}, got {easing!r}")


def frame_times(frames: int, easing: str = "linear") -> np.ndarray:
    """``frames`` (≥ 2) times from 0 to 1 inclusive, spaced by ``easing``."""
    if frames < 2:
        raise ValueError("a morph needs at least 2 frames")
    return ease(np.linspace(0.0, 1.0, frames), easing)


def interpolate(V_source: np.ndarray, V_registered: np.ndarray, t: float) -> np.ndarray:
    """``(1 − t) V_source + t V_registered`` (exact at t = 0 and t = 1)."""
    t = float(t)
    return (1.0 - t) * V_source + t * V_registered


def morph_frames(V_source: np.ndarray, V_registered: np.ndarray, frames: int,
                 easing: str = "linear") -> tuple[np.ndarray, list[np.ndarray]]:
    """The frame times and the vertex arrays of every frame."""
    V0 = np.asarray(V_source, dtype=np.float64)
    V1 = np.asarray(V_registered, dtype=np.float64)
    if V0.shape != V1.shape or V0.ndim != 2 or V0.shape[1] != 3:
        raise ValueError(f"source and registered vertices must be the same n×3 shape, got "
                         f"{V0.shape} and {V1.shape}")
    times = frame_times(frames, easing)
    return times, [interpolate(V0, V1, t) for t in times]
