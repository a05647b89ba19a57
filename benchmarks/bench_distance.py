"""Exact point–mesh distance: :class:`pipeline.geometry.remesh_quality.MeshDistance` against
libigl's AABB tree (``igl.AABB``, when libigl is installed; it is not a dependency).

    python benchmarks/bench_distance.py [--meshes igl_lion choi_human_brain ...] [--points 100000]
                                        [--repeat 3]

Per shared mesh: the tree's build time and the query time of ``--points`` points (the
surface's area-uniform samples moved off it by a normal offset of up to 1 % of the
bounding-box diagonal, seeded: the remesh measures' kind of query), the median of ``--repeat``
runs in seconds of wall clock and of the process's CPU (ours splits a large query between two
threads, so its CPU time may exceed its wall time); then the largest difference of the
distances from libigl's, relative to the distance and to the bounding-box diagonal (both
compute a closest point and its distance in floating point, so a point close to the surface
has a relative difference of several ulps of the coordinates over its distance), and the share
of points whose closest face differs (ties: libigl keeps the first face its walk meets, ours
the lowest-numbered; a point closest to a vertex or an edge is at the same distance from all
the faces around it).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.geometry.laplacian import face_double_areas  # noqa: E402
from pipeline.geometry.remesh_quality import (MeshDistance, _random_samples,  # noqa: E402
                                              bounding_box_diagonal)
from pipeline.io.meshio import read_mesh  # noqa: E402

DATA = Path(os.environ.get("SEM_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def query_points(V: np.ndarray, F: np.ndarray, k: int, seed: int = 0) -> np.ndarray:
    """``k`` area-uniform samples of ``(V, F)`` each moved along its face's unit normal by a
    uniform offset in ±1 % of the bounding-box diagonal (seeded)."""
    rng = np.random.default_rng(seed)
    dA = face_double_areas(V, F)
    P = _random_samples(V, F, k, seed, dA)
    f = rng.choice(len(F), k, p=dA / dA.sum())
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    return P + N[f] * rng.uniform(-0.01, 0.01, (k, 1)) * bounding_box_diagonal(V)


def timed(fn, repeat: int):
    """``(result, median wall s, median CPU s)`` of ``repeat`` calls of ``fn()``."""
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return out, float(np.median(walls)), float(np.median(cpus))


def igl_distance(V: np.ndarray, F: np.ndarray):
    """libigl's AABB tree of ``(V, F)`` and a query function ``P -> (distance, face)``."""
    import igl

    tree = igl.AABB()
    tree.init(V, F)

    def query(P):
        sq, face, _ = tree.squared_distance(V, F, P)
        return np.sqrt(sq), face
    return tree, query


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["igl_lion", "igl_camel_b", "choi_human_brain"])
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    try:
        import igl  # noqa: F401
        have_igl = True
    except ImportError:
        have_igl = False
    print(f"{'mesh':18} {'faces':>7} {'method':7} {'build s':>8} {'query s':>8} {'(CPU s)':>8}"
          f" {'max Δd/d':>9} {'max Δd/diag':>11} {'faces differ':>12}")
    for name in a.meshes:
        mesh = read_mesh(DATA / "meshes" / f"{name}.obj")
        V = np.ascontiguousarray(mesh.V, dtype=np.float64)
        F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        P = query_points(V, F, a.points)
        rows = []
        tree, build, _ = timed(lambda: MeshDistance(V, F), a.repeat)
        (d, f), query, cpu = timed(lambda: tree(P), a.repeat)
        rows.append(("ours", build, query, cpu, "", "", ""))
        if have_igl:
            (_, fn), build, _ = timed(lambda: igl_distance(V, F), a.repeat)
            (d_igl, f_igl), query, cpu = timed(lambda: fn(P), a.repeat)
            diff = np.abs(d - d_igl)
            rel = diff / np.maximum(d_igl, 1e-300)
            rows.append(("libigl", build, query, cpu, f"{rel.max():.1e}",
                         f"{diff.max() / bounding_box_diagonal(V):.1e}",
                         f"{np.mean(f != f_igl):.1e}"))
        for method, build, query, cpu, rel, absolute, differ in rows:
            print(f"{name:18} {len(F):7d} {method:7} {build:8.4f} {query:8.4f} {cpu:8.4f}"
                  f" {rel:>9} {absolute:>11} {differ:>12}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
