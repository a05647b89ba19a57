"""Where a remesh is far from its input: the farthest samples of both directions of the
distance and the share of the mean squared distance near the input's rim.

    python benchmarks/trace_far.py INPUT REMESH [REMESH ...] [--top 50]

Per remesh (any OBJ: ours, pymeshlab's), by the samples of the evaluator
(:class:`pipeline.geometry.remesh_quality.SampledSurface`: vertices, edge midpoints, face
centroids and the seeded area-uniform random samples) and its exact distances, for each
direction (input → remesh, remesh → input): the farthest sample, its distance and its distance
to the input's boundary (% of the input's bounding-box diagonal), the median boundary distance
of the ``--top`` farthest, and the share of the random samples and of their summed squared
distances (the RMS's) within 0.5, 1 and 3 % of the diagonal of the input's boundary.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.geometry import topology as topo  # noqa: E402
from pipeline.geometry.remesh.rim import segment_distances  # noqa: E402
from pipeline.geometry.remesh_quality import (DISTANCE_SAMPLES, SampledSurface,  # noqa: E402
                                              bounding_box_diagonal, face_centroids)
from pipeline.io.meshio import read_mesh  # noqa: E402

BANDS = (0.005, 0.01, 0.03)   # boundary distances (fractions of the diagonal) of the RMS shares
NEAREST_SEGMENTS = 16         # boundary segments nearest by midpoint searched per point


def boundary_distances(P: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The distance (k,) of each point ``P`` (k×3) to the boundary of ``(V, F)`` (n×3, m×3):
    the least over the ``NEAREST_SEGMENTS`` boundary edges whose midpoints are nearest (exact
    where the boundary's edges are shorter than the points' distances to it; an upper bound
    otherwise)."""
    from scipy.spatial import cKDTree

    E = topo.boundary_edges(F)
    A, B = V[E[:, 0]], V[E[:, 1]]
    k = min(NEAREST_SEGMENTS, len(E))
    _, near = cKDTree((A + B) / 2).query(P, k=k)
    near = near.reshape(len(P), k)
    return np.min([segment_distances(P, A[near[:, j]], B[near[:, j]]) for j in range(k)],
                  axis=0)


def structured_samples(S: SampledSurface) -> np.ndarray:
    """The vertices, edge midpoints and face centroids of ``S`` (one row each, in that
    order)."""
    return np.vstack([S.V, (S.V[S.E[:, 0]] + S.V[S.E[:, 1]]) / 2, face_centroids(S.V, S.F)])


def one_direction(source: SampledSurface, target: SampledSurface, V_in: np.ndarray,
                  F_in: np.ndarray, scale: float, top: int) -> str:
    """The printed trace of the distances from ``source``'s samples to ``target``; boundary
    distances to the input ``(V_in, F_in)``, lengths as % of ``scale``."""
    P = np.vstack([structured_samples(source), source.random])
    d, _ = target.distance(P)
    rim = boundary_distances(P, V_in, F_in)
    far = np.argsort(-d, kind="stable")[:top]
    random = slice(len(P) - len(source.random), len(P))
    square, rim_random = d[random] ** 2, rim[random] / scale
    shares = " ".join(f"<{100 * b:g}%: {100 * np.mean(rim_random < b):.1f}% of samples, "
                      f"{100 * square[rim_random < b].sum() / square.sum():.0f}% of MS;"
                      for b in BANDS)
    i = far[0]
    return (f"max {100 * d[i] / scale:.3f}% at {np.round(P[i], 3).tolist()} "
            f"(rim {100 * rim[i] / scale:.3f}%), top {top} rim median "
            f"{100 * np.median(rim[far]) / scale:.3f}%; RMS "
            f"{100 * np.sqrt(square.mean()) / scale:.4f}%; {shares}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("input")
    ap.add_argument("remeshes", nargs="+")
    ap.add_argument("--top", type=int, default=50)
    args = ap.parse_args()
    m = read_mesh(args.input)
    V_in, F_in = np.asarray(m.V, np.float64), np.asarray(m.faces)
    scale = bounding_box_diagonal(V_in)
    reference = SampledSurface(V_in, F_in, DISTANCE_SAMPLES)
    for path in args.remeshes:
        r = read_mesh(path)
        ours = SampledSurface(np.asarray(r.V, np.float64), np.asarray(r.faces), DISTANCE_SAMPLES)
        print(path)
        print("  input → remesh:", one_direction(reference, ours, V_in, F_in, scale, args.top))
        print("  remesh → input:", one_direction(ours, reference, V_in, F_in, scale, args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main())
