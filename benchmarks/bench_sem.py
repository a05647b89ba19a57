"""SEM at scale: total and per-iteration time against the solver floor, assembly, peak memory.

    python benchmarks/bench_sem.py [--sizes 10k 100k 1M] [--solvers cholmod scipy]
                                   [--iterations 10] [--scipy-iterations-1M 2]

Meshes are made from shared meshes by midpoint subdivision (every face → 4, original vertices
kept; the shape does not change): gpp_bunny ×4 ≈ 10k faces, igl_camelhead ×4 ≈ 91k faces,
igl_lion ×64 ≈ 1.07M faces. They are cached as .npz under benchmarks/.cache/ (git-ignored).

Each (size, solver) runs in a fresh subprocess so that its peak resident memory can be read:
the peak is reset (``/proc/self/clear_refs``) after the mesh arrays are loaded and read back
(``VmHWM``) after SEM, so "peak MB" is memory above the mesh arrays. The floor is one numeric
refactorization of ``L_II`` plus the two-column solve, measured in the same process after SEM
with the analysis already done. Paper mode, exactly 10 SEM steps
(``stop_when_energy_rises=False``).

"total s" and the peak are the first run's. A short run (under 5 s) is then repeated
``--repeat`` times, each repeat followed by a floor measurement, and "per iter s" and "floor s"
are the medians of those pairs, because iterations of a few milliseconds scatter widely from
run to run on a shared machine. Longer runs give one SEM run and the median of 3 floors.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

SIZES = {"10k": ("gpp_bunny", 1), "100k": ("igl_camelhead", 1), "1M": ("igl_lion", 3)}


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", REPO.parent / "shared" / "data"))


def subdivided_mesh(size: str) -> Path:
    """Cached midpoint subdivision of the size's base mesh (repaired into a disk first)."""
    from pipeline.stages.load import load_stage
    import trimesh

    base, times = SIZES[size]
    cache = HERE / ".cache" / f"{base}_x{4 ** times}.npz"
    if cache.exists():
        return cache
    intake = load_stage(data_dir() / "meshes" / f"{base}.obj")
    V, F = intake.mesh.V, intake.mesh.F
    for _ in range(times):
        V, F = trimesh.remesh.subdivide(V, F)
    cache.parent.mkdir(exist_ok=True)
    np.savez(cache, V=V, F=F)
    return cache


def _rss(field: str) -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _floor(s, L_II, rhs) -> float:
    """One numeric refactorization of ``L_II`` plus the two-column solve, seconds."""
    tf = time.perf_counter()
    s.factorize(L_II)
    s.solve(rhs)
    return time.perf_counter() - tf


def measure(mesh_path: str, solver: str, iterations: int, repeat: int) -> dict:
    """One run in this process (called in a subprocess by main)."""
    from pipeline.geometry.laplacian import laplacian_blocks
    from pipeline.geometry.sem import SEMOptions, _Problem, stretch_energy_minimization
    from pipeline.geometry.solvers import make_solver
    from pipeline.geometry.topology import boundary_loops

    data = np.load(mesh_path)
    V, F = data["V"], data["F"].astype(np.int64)
    boundary = boundary_loops(F, V)[0]
    options = SEMOptions(mode="paper", max_iter=iterations, solver=solver,
                         stop_when_energy_rises=False)
    try:
        Path("/proc/self/clear_refs").write_text("5")   # reset the peak RSS (VmHWM)
    except OSError:
        pass
    rss0 = _rss("VmRSS")
    t0 = time.perf_counter()
    result = stretch_energy_minimization(V, F, boundary, options)
    total = time.perf_counter() - t0
    peak = _rss("VmHWM") - rss0

    # Assembly (stretch weights + block values) and the floor, at the final map.
    problem = _Problem(V, F, boundary, solver)
    f = result.uv[:, 0] + 1j * result.uv[:, 1]
    ta = time.perf_counter()
    w = problem.weights(f)
    L_II, L_IB, L_BB = laplacian_blocks(problem.pattern, w)
    assembly = time.perf_counter() - ta
    s = make_solver(solver, refactored=True)   # as SEM makes its interior solver
    s.factorize(L_II)
    rhs = np.random.default_rng(0).standard_normal((L_II.shape[0], 2))
    its = max(result.iterations, 1)
    per_iter = [result.timings["sem"] / its]
    floors = [_floor(s, L_II, rhs) for _ in range(3)]
    if total < 5.0 and repeat > 0:
        per_iter, floors = [], []
        for _ in range(repeat):
            again = stretch_energy_minimization(V, F, boundary, options)
            per_iter.append(again.timings["sem"] / max(again.iterations, 1))
            floors.append(_floor(s, L_II, rhs))
    return {"vertices": len(V), "faces": len(F), "solver": result.solver,
            "iterations": result.iterations, "status": result.status,
            "total_s": total, "setup_s": result.timings["setup"],
            "harmonic_s": result.timings["harmonic"], "per_iter_s": float(np.median(per_iter)),
            "floor_s": float(np.median(floors)), "repeats": len(per_iter),
            "assembly_s": assembly, "peak_mb": peak, "flipped": result.flipped_faces}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=list(SIZES), choices=list(SIZES))
    ap.add_argument("--solvers", nargs="+", default=["pardiso", "cholmod", "scipy"])
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--scipy-iterations-1M", type=int, default=2,
                    help="SciPy at 1M faces takes ~40 s an iteration; run fewer")
    ap.add_argument("--repeat", type=int, default=15,
                    help="runs under 5 s: median per-iteration time and floor of this many pairs")
    ap.add_argument("--json", help="also write the rows to this JSON file")
    ap.add_argument("--_one", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args._one:
        print(json.dumps(measure(args._one[0], args._one[1], int(args._one[2]), int(args._one[3]))))
        return
    rows = []
    for size in args.sizes:
        path = subdivided_mesh(size)
        for solver in args.solvers:
            its = args.scipy_iterations_1M if (solver == "scipy" and size == "1M") \
                else args.iterations
            out = subprocess.run([sys.executable, __file__, "--_one", str(path), solver,
                                  str(its), str(args.repeat)],
                                 capture_output=True, text=True, check=True)
            row = dict(json.loads(out.stdout.strip().splitlines()[-1]), size=size)
            rows.append(row)
            print(f"  {size} {solver}: {row['total_s']:.2f} s", file=sys.stderr, flush=True)
    head = ("| size | faces | solver | its | total s | per iter s | floor s | per iter / floor "
            "| runs | assembly s | setup+harmonic s | peak MB above mesh | flips |")
    print(head)
    print("|" + "|".join(["---"] * 13) + "|")
    for r in rows:
        print(f"| {r['size']} | {r['faces']:,} | {r['solver']} | {r['iterations']} | "
              f"{r['total_s']:.2f} | {r['per_iter_s']:.3f} | {r['floor_s']:.3f} | "
              f"{r['per_iter_s'] / r['floor_s']:.2f} | {r['repeats']} | {r['assembly_s']:.3f} | "
              f"{r['setup_s'] + r['harmonic_s']:.2f} | {r['peak_mb']:.0f} | {r['flipped']} |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
