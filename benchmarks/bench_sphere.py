"""Spherical equiareal maps (:func:`pipeline.geometry.sphere.spherical_sem`) on every closed mesh.

    python benchmarks/bench_sphere.py [--time-limit 10] [--method newton hemisphere]
                                      [--meshes igl_bunny ...] [--repeat 1] [--synthetic]

One row per (mesh, method): faces, face-based area distortion (flat image triangles, the
measure of issue #22) and the same against the geodesic triangle areas, folded faces, energy
ratio ``E_S |M| / |f(M)|²``, seconds (the whole call: genus check, start, minimization) and the
status. Meshes: every ``.obj`` of ``../shared/data/closed`` (or ``$SEM_DATA/closed``); those
that are not genus 0 get a row with the refusal. ``--synthetic`` adds constructed closed
genus-0 meshes with long thin protrusions (an icosphere pushed out along a few directions into
spikes, a long ellipsoid, the elephant subdivided to 48k faces, the arm decimated by 50 and 70 %),
stand-ins for meshes we do not have. ``--repeat`` runs each map several times and reports the median seconds (the other
columns are the last run's): timings on a shared machine scatter, so the process CPU seconds
are printed beside the wall-clock ones (a busy machine inflates the wall clock most). The target (issue #22): 0 folds and distortion ≤ 0.02, converged, within 10 s at 40k
faces.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from pipeline.errors import UserError  # noqa: E402
from pipeline.geometry import sphere  # noqa: E402


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", REPO.parent / "shared" / "data")) / "closed"


def load_closed(path: Path):
    from pipeline.geometry.repair import triangulate_polygons
    from pipeline.io.meshio import read_mesh
    mesh = read_mesh(str(path))
    F, _, _ = triangulate_polygons(mesh.faces, len(mesh.V))
    return np.asarray(mesh.V, float), F


def icosphere(level: int):
    """Unit icosphere: the icosahedron with ``level`` midpoint subdivisions, outward faces
    (``trimesh.creation.icosphere``)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=level)
    return np.array(m.vertices, dtype=np.float64), np.array(m.faces, dtype=np.int64)


def spiky(level: int, directions: int, length: float, width: float, seed: int = 0):
    """An icosphere pushed out radially into ``directions`` spikes of the given ``length``
    (in radii) and angular ``width`` (radians): ``r = 1 + length · Σ exp(−(θ/width)²)``."""
    V, F = icosphere(level)
    rng = np.random.default_rng(seed)
    D = rng.standard_normal((directions, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    theta = np.arccos(np.clip(V @ D.T, -1, 1))
    r = 1 + length * np.exp(-(theta / width) ** 2).sum(axis=1)
    return V * r[:, None], F


def subdivided(name: str):
    """A shared closed mesh with every face split into four at its edge midpoints (the shape
    unchanged, four times the faces)."""
    V, F = load_closed(data_dir() / f"{name}.obj")
    F = np.asarray(F, dtype=np.int64)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, inv = np.unique(E, axis=0, return_inverse=True)
    mid = len(V) + inv.ravel().reshape(3, -1).T
    V = np.vstack([V, (V[edges[:, 0]] + V[edges[:, 1]]) / 2])
    a, b, c = F.T
    ab, bc, ca = mid.T
    F = np.vstack([np.c_[a, ab, ca], np.c_[b, bc, ab], np.c_[c, ca, bc], np.c_[ab, bc, ca]])
    return V, F


def decimated(name: str, reduction: float):
    """A shared closed mesh decimated by fast_simplification (``target_reduction``): fewer,
    less regular faces, whose Tutte start crowds long limbs much further than the original's."""
    import fast_simplification

    V, F = load_closed(data_dir() / f"{name}.obj")
    return fast_simplification.simplify(V, F, target_reduction=reduction)


SYNTHETIC = {
    "spiky6_l3": lambda: spiky(5, 6, 3.0, 0.25),        # 20 480 faces
    "spiky12_l2": lambda: spiky(5, 12, 2.0, 0.2, seed=1),
    "ellipsoid_8": lambda: (icosphere(5)[0] * [8.0, 1.0, 1.0], icosphere(5)[1]),
    "igl_elephant_x4": lambda: subdivided("igl_elephant"),   # 48 256 faces, limbs
    "igl_arm_dec50": lambda: decimated("igl_arm", 0.5),
    "igl_arm_dec70": lambda: decimated("igl_arm", 0.7),
}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--method", nargs="+", default=["newton"],
                    choices=["newton", "hemisphere"])
    ap.add_argument("--meshes", nargs="*", default=None)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--synthetic", action="store_true")
    ap.add_argument("--solver", default="auto")
    args = ap.parse_args(argv)

    cases = []
    for path in sorted(data_dir().glob("*.obj")):
        if args.meshes is None or path.stem in args.meshes:
            cases.append((path.stem, lambda p=path: load_closed(p)))
    if args.synthetic:
        cases += [(k, f) for k, f in SYNTHETIC.items()
                  if args.meshes is None or k in args.meshes]

    head = (f"{'mesh':24s} {'method':10s} {'faces':>7s} {'distortion':>10s} {'spherical':>9s} "
            f"{'folds':>5s} {'ratio':>9s} {'seconds':>7s} {'cpu s':>6s} status")
    print(f"time limit {args.time_limit:g} s")
    print(head)
    print("-" * len(head))
    for name, make in cases:
        V, F = make()
        for method in args.method:
            seconds, cpu = [], []
            try:
                for _ in range(args.repeat):
                    t, c = time.perf_counter(), time.process_time()
                    r = sphere.spherical_sem(V, F, time_limit=args.time_limit, method=method,
                                             solver=args.solver)
                    seconds.append(time.perf_counter() - t)
                    cpu.append(time.process_time() - c)
            except UserError as exc:
                print(f"{name:24s} {method:10s} {len(F):7d} refused: {exc}")
                break
            m = r.measures
            print(f"{name:24s} {method:10s} {len(F):7d} {m['face_area_distortion']:10.4f} "
                  f"{m['face_area_distortion_spherical']:9.4f} {m['folded_faces']:5d} "
                  f"{m['energy_ratio']:9.6f} {statistics.median(seconds):7.2f} "
                  f"{statistics.median(cpu):6.2f} {r.status}",
                  flush=True)


if __name__ == "__main__":
    main()
