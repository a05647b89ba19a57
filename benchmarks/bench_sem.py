"""SEM at scale: total and per-iteration time against the solver floor, assembly, peak memory.

    python benchmarks/bench_sem.py [--sizes 10k 100k 1M] [--solvers cholmod scipy]
                                   [--iterations 10] [--scipy-iterations-1M 2]
    python benchmarks/bench_sem.py --converged [--meshes choi_hand ...] [--solver pardiso]

``--converged`` prints issue #20's done-when table instead: per mesh, the face-based area
distortion ``Σ_τ | |τ|/|M| − |f(τ)|/|f(M)| |`` of the 1000-iteration gradient schedule
(``descent="gradient"``, the converged default before Gauss–Newton; cached in
``benchmarks/outputs/sem_reference.json`` so it is computed once per mesh and solver), that of
converged mode with its default options, their ratio, flipped faces and SEM seconds (wall
clock, and the process's CPU time, which a loaded shared machine inflates less; SEM runs on
one thread below ``solvers.PARALLEL_ABOVE`` unknowns, and PARDISO on all of MKL's threads above,
where CPU time exceeds wall time), and pass/fail against: ratio ≤ 1.05, 0 flips, SEM wall seconds ≤ 3 below 500k
faces and ≤ 40 above. Mesh
names are shared meshes, ``NAME_loopK`` for K Loop subdivisions (``trimesh``'s
``subdivide_loop``, cached under benchmarks/.cache/) and ``NAME_decN`` for the mesh decimated to
N faces (fast-simplification, aggressiveness 7, border kept: slivers and obtuse triangles, on
which plain SEM steps fold; ``--meshes decimated`` runs ``DECIMATED_MESHES``). Each converged run
is a fresh subprocess.

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
#: the done-when meshes of issue #20: two ~100k scans and a 1.07M-face Loop subdivision
CONVERGED_MESHES = ["choi_hand", "choi_human_brain", "igl_lion_loop3"]
#: the other shared disk meshes (--converged --meshes all)
#: decimated shared meshes (--converged --meshes decimated): inputs with many obtuse triangles
DECIMATED_MESHES = ["choi_hand_dec5000", "choi_hand_dec10000", "choi_human_brain_dec10000",
                    "choi_human_brain_dec30000",
                    "igl_camelhead_dec4000", "igl_lion_dec4000", "choi_human_face_dec5000",
                    "choi_chinese_lion_dec5000", "igl_camel_b_dec1500"]
OTHER_MESHES = ["gpp_face", "gpp_bunny", "igl_camel_b", "c3d_alligator", "igl_lion",
                "igl_camelhead", "choi_human_face", "choi_chinese_lion"]
REFERENCE_ITERATIONS = 1000


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


def named_mesh(name: str):
    """``(V, F)`` of a shared mesh (repaired into a disk), of ``NAME_loopK``: K Loop
    subdivisions of it, cached as .npz under benchmarks/.cache/, or of ``NAME_decN``: it
    decimated to N faces."""
    from pipeline.stages.load import load_stage
    import trimesh

    base, _, faces = name.partition("_dec")
    if faces:
        import fast_simplification as fs
        from pipeline.geometry.repair import disk_blockers

        V, F = named_mesh(base)
        V, F = fs.simplify(V, F, target_count=int(faces), agg=7, preserve_border=True)
        V, F = np.asarray(V, np.float64), np.asarray(F, np.int64).reshape(-1, 3)
        blockers = disk_blockers(F, len(V))
        if blockers:
            raise SystemExit(f"{name}: the decimation leaves {', '.join(blockers)}; "
                             "choose another face count")
        return V, F
    base, _, loops = name.partition("_loop")
    loops = int(loops or 0)
    cache = HERE / ".cache" / f"{base}_loop{loops}.npz"
    if loops and cache.exists():
        data = np.load(cache)
        return data["V"], data["F"].astype(np.int64)
    intake = load_stage(data_dir() / "meshes" / f"{base}.obj")
    V, F = np.asarray(intake.mesh.V, np.float64), np.asarray(intake.mesh.F, np.int64)
    for _ in range(loops):
        V, F = trimesh.remesh.subdivide_loop(V, F)
    if loops:
        cache.parent.mkdir(exist_ok=True)
        np.savez(cache, V=V, F=F)
    return V, F


def converged_run(name: str, solver: str, reference: bool) -> dict:
    """One converged-mode run in this process: the default options, or (``reference``) the
    1000-iteration gradient schedule."""
    from pipeline.geometry.metrics import distortion_summary
    from pipeline.geometry.sem import SEMOptions, stretch_energy_minimization
    from pipeline.geometry.topology import boundary_loops

    V, F = named_mesh(name)
    boundary = boundary_loops(F, V)[0]
    options = SEMOptions(solver=solver)
    if reference:
        options = SEMOptions(solver=solver, descent="gradient", tol=1e-7, patience=20,
                             max_iter=REFERENCE_ITERATIONS)
    cpu = []

    def started(entry):                   # the harmonic map's entry: SEM's clock starts
        if not cpu:
            cpu.append(time.process_time())

    result = stretch_energy_minimization(V, F, boundary, options, progress=started)
    cpu_s = time.process_time() - cpu[0]
    summary = distortion_summary(V, F, result.uv)
    return {"mesh": name, "faces": len(F), "solver": result.solver,
            "face_area_distortion": summary["face_area_distortion"],
            "flipped": summary["flipped_faces"], "sem_s": result.timings["sem"], "sem_cpu_s": cpu_s,
            "iterations": result.iterations, "status": result.status, "steps": result.steps}


def _subprocess_run(name: str, solver: str, reference: bool) -> dict:
    out = subprocess.run([sys.executable, __file__, "--_converged", name, solver,
                          "reference" if reference else "default"],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def converged_table(meshes: list[str], solver: str, out_dir: Path) -> list[dict]:
    """Issue #20's done-when table (see the module docstring); prints it and returns the rows."""
    load = os.getloadavg()
    cache = out_dir / "sem_reference.json"
    refs = json.loads(cache.read_text()) if cache.exists() else {}
    rows = []
    for name in meshes:
        key = f"{name}/{solver}"
        if key not in refs:
            refs[key] = _subprocess_run(name, solver, reference=True)
            out_dir.mkdir(parents=True, exist_ok=True)
            cache.write_text(json.dumps(refs, indent=2))
        new = _subprocess_run(name, solver, reference=False)
        ratio = new["face_area_distortion"] / refs[key]["face_area_distortion"]
        budget = 3.0 if new["faces"] < 500_000 else 40.0
        ok = ratio <= 1.05 and new["flipped"] == 0 and new["sem_s"] <= budget
        rows.append(dict(new, reference=refs[key]["face_area_distortion"], ratio=ratio,
                         budget_s=budget, passed=ok))
        print(f"  {name}: {new['sem_s']:.2f} s", file=sys.stderr, flush=True)
    print(f"load average before/after: {load[0]:.1f} / {os.getloadavg()[0]:.1f} "
          f"({os.cpu_count()} CPUs)")
    print("| mesh | faces | 1000-iteration face distortion | converged face distortion | ratio "
          "| flips | SEM s (budget) | SEM CPU s | steps SEM / GN / gradient / continuation "
          "| pass |")
    print("|" + "|".join(["---"] * 10) + "|")
    for r in rows:
        st = r["steps"]
        print(f"| {r['mesh']} | {r['faces']:,} | {r['reference']:.5f} | "
              f"{r['face_area_distortion']:.5f} | {r['ratio']:.3f} | {r['flipped']} | "
              f"{r['sem_s']:.2f} ({r['budget_s']:.0f}) | {r['sem_cpu_s']:.2f} | "
              f"{st['sem'] + st['sem_damped']} / {st['gauss_newton']} / {st['gradient']} / "
              f"{st.get('continuation', 0)} | "
              f"{'pass' if r['passed'] else 'FAIL'} |")
    return rows


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
    ap.add_argument("--converged", action="store_true",
                    help="issue #20's table: converged mode against the 1000-iteration map")
    ap.add_argument("--meshes", nargs="+", default=CONVERGED_MESHES,
                    help="with --converged: mesh names, NAME_loopK, NAME_decN, 'all' or "
                         "'decimated'")
    ap.add_argument("--solver", default="pardiso", help="with --converged: the solver")
    ap.add_argument("--out", default=str(HERE / "outputs"),
                    help="with --converged: folder of the reference cache")
    ap.add_argument("--_one", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--_converged", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args._converged:
        name, solver, which = args._converged
        print(json.dumps(converged_run(name, solver, which == "reference")))
        return
    if args.converged:
        meshes = {"all": CONVERGED_MESHES + OTHER_MESHES,
                  "decimated": DECIMATED_MESHES}.get(" ".join(args.meshes), args.meshes)
        rows = converged_table(meshes, args.solver, Path(args.out))
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=2))
        return
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
