"""What users remesh with today, at the same vertex count, for the side-by-side report.

* :func:`isotropic_remesh` — MeshLab's *isotropic explicit remeshing* (pymeshlab filter
  ``meshing_isotropic_explicit_remeshing``: edge splits, collapses, flips and tangential
  smoothing with reprojection, 10 iterations, feature angle 30°), with an absolute target edge
  length. The vertex count is not an input of the filter, so the length is solved for: a first
  guess from the area (``n ≈ 2|M| / (√3 L²)``), then secant steps on ``log n`` against
  ``log L`` until the count is within ``tol`` (2 %) or ``max_runs`` runs were made.
* :func:`decimate` — quadric decimation by ``fast_simplification`` (border preserved), with the
  target face count solved for the vertex count the same way. Decimation only removes
  vertices: for a request at or above the input's vertex count it returns ``None``.

Both return a :class:`Baseline` with the mesh, the wall time of the *last* run (the one
reported), the total time of all runs and the runs made.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry.laplacian import face_double_areas

__all__ = ["Baseline", "isotropic_remesh", "decimate", "pymeshlab_available"]


@dataclass
class Baseline:
    name: str
    V: np.ndarray
    F: np.ndarray
    seconds: float                  # the run whose mesh is reported
    seconds_all_runs: float
    runs: list = field(default_factory=list)     # (parameter, vertex count) per run
    parameter: dict = field(default_factory=dict)
    cpu_seconds: float = float("nan")   # the reported run's CPU seconds (all its threads)


def pymeshlab_available() -> bool:
    try:
        import pymeshlab  # noqa: F401
    except Exception:  # noqa: BLE001 - any failure to import means "not available"
        return False
    return True


def _secant(target: int, x0: float, run, slope0: float, tol: float, max_runs: int,
            lo: float, hi: float):
    """Find ``x`` with ``run(x)`` giving about ``target`` vertices; ``count ∝ x^slope``."""
    runs, results = [], []
    x = float(np.clip(x0, lo, hi))
    for _ in range(max_runs):
        res, count = run(x)
        runs.append((x, count))
        results.append(res)
        if abs(count - target) <= tol * target:
            break
        if len(runs) >= 2 and runs[-1][1] != runs[-2][1] and runs[-1][0] != runs[-2][0]:
            slope = (np.log(runs[-1][1]) - np.log(runs[-2][1])) / \
                    (np.log(runs[-1][0]) - np.log(runs[-2][0]))
            if not np.isfinite(slope) or slope * slope0 <= 0:
                slope = slope0
        else:
            slope = slope0
        # the step in log x, clipped before exp: a near-flat secant (a count that hardly
        # moves with x) asks for a step far beyond the range
        x = float(np.exp(np.clip(np.log(x) + (np.log(target) - np.log(max(count, 1))) / slope,
                                 np.log(lo), np.log(hi))))
    i = int(np.argmin([abs(c - target) for _, c in runs]))
    return results[i], runs, i


def isotropic_remesh(V: np.ndarray, F: np.ndarray, target_vertices: int, iterations: int = 10,
                     tol: float = 0.02, max_runs: int = 4) -> Baseline:
    """pymeshlab isotropic explicit remeshing at about ``target_vertices`` (see module doc)."""
    import pymeshlab

    area = face_double_areas(V, F).sum() / 2
    L0 = np.sqrt(2 * area / (np.sqrt(3.0) * target_vertices))
    value = getattr(pymeshlab, "PureValue", None) or getattr(pymeshlab, "AbsoluteValue")

    def run(L):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(V, np.float64),
                                   face_matrix=np.asarray(F, np.int32)))
        t, c = time.perf_counter(), time.process_time()
        ms.meshing_isotropic_explicit_remeshing(iterations=iterations, targetlen=value(L))
        sec, cpu = time.perf_counter() - t, time.process_time() - c
        m = ms.current_mesh()
        Vo = np.asarray(m.vertex_matrix(), np.float64)
        Fo = np.asarray(m.face_matrix(), np.int64)
        return (Vo, Fo, sec, cpu), len(Vo)

    t0 = time.perf_counter()
    (Vo, Fo, sec, cpu), runs, i = _secant(target_vertices, L0, run, -2.0, tol, max_runs,
                                          L0 / 8, L0 * 8)
    return Baseline("pymeshlab isotropic explicit remeshing", Vo, Fo, sec,
                    time.perf_counter() - t0, [{"target_length": x, "vertices": c}
                                               for x, c in runs],
                    {"target_length": runs[i][0], "iterations": iterations}, cpu)


def decimate(V: np.ndarray, F: np.ndarray, target_vertices: int, tol: float = 0.02,
             max_runs: int = 4) -> Baseline | None:
    """fast_simplification quadric decimation to about ``target_vertices``; None when the input
    has no more vertices than requested."""
    import fast_simplification as fs

    if target_vertices >= len(V):
        return None

    def run(faces):
        t = time.perf_counter()
        try:
            P, T = fs.simplify(np.asarray(V, np.float64), np.asarray(F, np.int64),
                               target_count=int(round(faces)), agg=7, preserve_border=True)
        except TypeError:                        # fast-simplification without preserve_border
            P, T = fs.simplify(np.asarray(V, np.float64), np.asarray(F, np.int64),
                               target_count=int(round(faces)), agg=7)
        sec = time.perf_counter() - t
        P, T = np.asarray(P, np.float64), np.asarray(T, np.int64).reshape(-1, 3)
        used = np.unique(T)                      # drop unreferenced vertices, if any
        if len(used) < len(P):
            remap = np.full(len(P), -1, np.int64)
            remap[used] = np.arange(len(used))
            P, T = P[used], remap[T]
        return (P, T, sec), len(P)

    # fast_simplification takes a target below the input's face count: a request just under
    # the input's vertex count (2 faces a vertex, fewer on an open mesh) is clipped to that
    faces0 = 2.0 * target_vertices
    t0 = time.perf_counter()
    (P, T, sec), runs, i = _secant(target_vertices, faces0, run, 1.0, tol, max_runs,
                                   16, len(F) - 1)
    return Baseline("fast-simplification quadric decimation", P, T, sec,
                    time.perf_counter() - t0, [{"target_faces": int(round(x)), "vertices": c}
                                               for x, c in runs],
                    {"target_faces": int(round(runs[i][0])), "aggressiveness": 7,
                     "preserve_border": True})
