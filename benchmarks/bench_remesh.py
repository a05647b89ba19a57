"""Uniform remeshing through the SEM map: time per step, and point location at 10^6 faces.

    python benchmarks/bench_remesh.py [--vertices 20000 100000] [--meshes camelhead_x4 ...]
                                      [--repeat 3] [--locate] [--no-remesh]

Remesh table: for each mesh (parameterized once with ``SEMOptions(mode="paper")``, not timed
in the total) and each vertex count, the median over ``--repeat`` runs of every step of
:func:`pipeline.stages.remesh.remesh_stage`: sample (lattice + count solve + rim band ODT +
corner snapping), Delaunay (band ``Delaunay`` + lattice by construction), locate (grid build +
queries), lift, improve (flips, relaxation, refinement, count) and the total. The goal is
≤ 3 s for a ~100k-face mesh remeshed to 100k vertices (``camelhead_x4``: igl_camelhead
subdivided ×4 = 90 816 faces, the same mesh as ``bench_sem.py``'s 100k size).

``--locate``: ``PointLocator`` (grid bucketing) against matplotlib's ``TrapezoidMapTriFinder``
followed by the same barycentric computation, on a SEM map subdivided to ≈1.45M faces, with
10^5 uniform queries in the disk: build and query times (median of 3) and agreement.

Meshes: ``camelhead_x4`` (cached under benchmarks/.cache/, git-ignored), or any name of
``../shared/data/meshes`` (``choi_hand``, ``choi_human_brain``, …).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", REPO.parent / "shared" / "data"))


def load(name: str):
    """The repaired mesh of a benchmark name."""
    from pipeline.geometry.repair import repair_mesh
    from pipeline.stages.load import load_stage

    if name.endswith("_x4"):                       # midpoint subdivision (1 → 4), cached
        import trimesh

        base = name[:-3] if name.startswith("igl_") else "igl_" + name[:-3]
        cache = HERE / ".cache" / f"{base}_x4.npz"          # the same file as bench_sem.py's
        if not cache.exists():
            intake = load_stage(data_dir() / "meshes" / f"{base}.obj")
            V, F = trimesh.remesh.subdivide(intake.mesh.V, intake.mesh.F)
            cache.parent.mkdir(exist_ok=True)
            np.savez(cache, V=V, F=F)
        d = np.load(cache)
        return repair_mesh(d["V"], d["F"], name=name)
    return load_stage(data_dir() / "meshes" / f"{name}.obj").mesh


def parameterize(mesh):
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.parameterize import parameterize_stage

    t = time.perf_counter()
    p = parameterize_stage(mesh, SEMOptions(mode="paper"))
    return p, time.perf_counter() - t


STEPS = ("sample", "delaunay", "locate", "lift", "improve", "total")
SUB = ("flips", "relax", "refine", "count")


def bench_remesh(names, counts, repeat):
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    rows = []
    for name in names:
        mesh = load(name)
        p, t_sem = parameterize(mesh)
        for n in counts:
            runs = []
            for _ in range(repeat):
                r = remesh_stage(mesh, p.uv, RemeshConfig(vertices=n))
                sub = r.info["improve"].get("seconds", {})
                runs.append([r.seconds.get(k, 0.0) for k in STEPS] + [sub.get(k, 0.0)
                                                                      for k in SUB])
            med = np.median(np.array(runs), axis=0)
            rows.append((name, len(mesh.F), n, len(r.V), t_sem, med))
            print_row(rows[-1], header=len(rows) == 1)
    return rows


def print_row(row, header=False):
    name, faces, n, got, t_sem, med = row
    if header:
        print(f"{'mesh':16s} {'faces':>8s} {'request':>8s} {'got':>8s} {'SEM map':>8s} | "
              + " ".join(f"{k:>8s}" for k in STEPS) + " | "
              + " ".join(f"{k:>7s}" for k in SUB))
    print(f"{name:16s} {faces:8d} {n:8d} {got:8d} {t_sem:8.2f} | "
          + " ".join(f"{v:8.3f}" for v in med[:len(STEPS)]) + " | "
          + " ".join(f"{v:7.3f}" for v in med[len(STEPS):]), flush=True)


def bench_locate(name="camelhead_x4", queries=100_000):
    import trimesh
    from matplotlib.tri import Triangulation, TrapezoidMapTriFinder

    from pipeline.geometry import topology as topo
    from pipeline.geometry.locate import PointLocator, barycentric_coordinates

    mesh = load(name)
    p, _ = parameterize(mesh)
    uv3 = np.column_stack([p.uv, np.zeros(len(p.uv))])
    V, F = trimesh.remesh.subdivide(uv3, mesh.F)
    V, F = trimesh.remesh.subdivide(V, F)
    uv = np.ascontiguousarray(V[:, :2])
    loop = topo.boundary_loops(F)[0]
    rng = np.random.default_rng(0)
    r = np.sqrt(rng.random(queries))
    a = 2 * np.pi * rng.random(queries)
    P = np.column_stack([r * np.cos(a), r * np.sin(a)])
    t_grid_b, t_grid_q, t_tf_b, t_tf_q = [], [], [], []
    for _ in range(3):
        t0 = time.perf_counter()
        L = PointLocator(uv, F, loop)
        t1 = time.perf_counter()
        fg, bg = L.locate(P)
        t2 = time.perf_counter()
        tri = Triangulation(uv[:, 0], uv[:, 1], F)
        tf = TrapezoidMapTriFinder(tri)
        t3 = time.perf_counter()
        ft = tf(P[:, 0], P[:, 1])
        inside = ft >= 0
        T = F[ft[inside]]
        barycentric_coordinates(P[inside], uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]])
        t4 = time.perf_counter()
        t_grid_b.append(t1 - t0)
        t_grid_q.append(t2 - t1)
        t_tf_b.append(t3 - t2)
        t_tf_q.append(t4 - t3)
    same = np.mean(fg[inside] == ft[inside])
    print(f"\npoint location: {len(F)} faces, {queries} queries in the unit disk "
          f"({(~inside).sum()} outside the inscribed polygon)")
    print(f"{'method':36s} {'build s':>8s} {'query s':>8s} {'total s':>8s}")
    for label, b, q in (("PointLocator (grid, this package)", t_grid_b, t_grid_q),
                        ("TrapezoidMapTriFinder + barycentrics", t_tf_b, t_tf_q)):
        print(f"{label:36s} {np.median(b):8.3f} {np.median(q):8.3f} "
              f"{np.median(b) + np.median(q):8.3f}")
    print(f"same face for {100 * same:.3f} % of the inside queries (the rest lie on a shared "
          f"edge); TrapezoidMapTriFinder gives no face for the {(~inside).sum()} outside ones, "
          f"PointLocator projects them onto the boundary")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=["camelhead_x4"])
    ap.add_argument("--vertices", nargs="+", type=int, default=[20000, 100000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--locate", action="store_true", help="also the point-location comparison")
    ap.add_argument("--no-remesh", action="store_true")
    args = ap.parse_args(argv)
    if not args.no_remesh:
        print("remesh_stage, seconds per step (median of "
              f"{args.repeat}); the SEM map (paper mode) is not in the total\n")
        bench_remesh(args.meshes, args.vertices, args.repeat)
    if args.locate:
        bench_locate()


if __name__ == "__main__":
    main()
