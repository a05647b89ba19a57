"""The remesh command's fixed costs on an input, outside the map and the remesher: reading the
file, repairing it, and the input's side of the measures.

    python benchmarks/bench_intake.py [--meshes choi_hand igl_lion ...] [--paths a.obj ...]
                                      [--scan] [--repeat 3]

Per mesh (default: every disk mesh of ``../shared/data/meshes``): its vertex and face counts,
and the CPU seconds (best of ``--repeat``) of ``read_mesh``, ``repair_mesh`` and the input's
measures in ``remesh_metrics.json`` (its distance samples and distance tree,
:class:`~pipeline.geometry.remesh_quality.SampledSurface`, and its own quality,
``remesh_quality(..., distance=False)``), all after the command's imports. ``--scan`` adds a
face-scan-sized case made here: the ICT face ``ict_A_neutral_disk`` Loop-subdivided twice
(about 106k vertices), each vertex moved along its normal by N(0, 0.05 % of the bounding-box
diagonal), written as OBJ with 8 decimals (as scanners write) to a temporary folder.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", REPO.parent / "shared" / "data"))


def scan_proxy(folder: Path, iterations: int = 2, name: str = "scan_proxy.obj",
               source: str = "ict_A_neutral_disk.obj") -> Path:
    """The ``--scan`` case (see the module docstring) written to ``folder / name``; with
    ``iterations`` Loop subdivisions instead of 2 (3: about 425k vertices, 850k faces), the
    same noise; made from the ICT face ``source`` (``ict_A_neutral_holes.obj``: with its eye
    and mouth openings)."""
    import trimesh

    m = trimesh.load(data_dir() / "faces" / "ict" / source, process=False)
    V, F = trimesh.remesh.subdivide_loop(m.vertices, m.faces, iterations=iterations)
    t = trimesh.Trimesh(V, F, process=False)
    rng = np.random.default_rng(1)
    diag = np.linalg.norm(t.bounds[1] - t.bounds[0])
    V = V + t.vertex_normals * rng.normal(0, 0.0005 * diag, (len(V), 1))
    path = folder / name
    rows = "".join(f"v {x:.8f} {y:.8f} {z:.8f}\n" for x, y, z in V.tolist())
    path.write_text(rows + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F.tolist()))
    return path


def best_cpu(fn, repeat: int):
    """``(result, least CPU seconds of repeat calls)``."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return out, best


def row(path: Path, repeat: int) -> str:
    from pipeline.geometry.remesh_quality import (DISTANCE_SAMPLES, SampledSurface,
                                                  remesh_quality)
    from pipeline.geometry.repair import repair_mesh
    from pipeline.geometry.topology import kept_edge_groups
    from pipeline.io.meshio import read_mesh

    raw, t_read = best_cpu(lambda: read_mesh(path), repeat)
    mesh, t_repair = best_cpu(lambda: repair_mesh(raw.V, raw.faces, raw.colors,
                                                  name=path.name), repeat)

    def measures():
        with kept_edge_groups():
            ref = SampledSurface(mesh.V, mesh.F, DISTANCE_SAMPLES)
            ref.distance
            return remesh_quality(mesh.V, mesh.F, mesh.V, mesh.F, distance=False,
                                  double_area=ref.double_area)

    _, t_measure = best_cpu(measures, repeat)
    return (f"{path.stem:24s} {len(raw.V):8d} {len(mesh.F):8d} {t_read:8.3f} {t_repair:8.3f} "
            f"{t_measure:8.3f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=None,
                    help="names in ../shared/data/meshes (default: all)")
    ap.add_argument("--paths", nargs="+", default=[], help="more mesh files")
    ap.add_argument("--scan", action="store_true", help="add the face-scan-sized case")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    import pipeline.runner  # noqa: F401  (the command's imports, not timed)

    names = args.meshes if args.meshes is not None else sorted(
        p.stem for p in (data_dir() / "meshes").glob("*.obj"))
    paths = [data_dir() / "meshes" / f"{n}.obj" for n in names] + [Path(p) for p in args.paths]
    print(f"{'mesh':24s} {'vertices':>8s} {'faces':>8s} {'read s':>8s} {'repair s':>8s} "
          f"{'input measures s':>8s}   (CPU, best of {args.repeat})")
    with tempfile.TemporaryDirectory() as tmp:
        if args.scan:
            paths.append(scan_proxy(Path(tmp)))
        for p in paths:
            print(row(p, args.repeat), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
