"""The remesh command on face-scan proxies made here: how often a scan leaves faces below the
minimum angle that no input corner forces, and the folds and time.

    python benchmarks/bench_scans.py [--vertices 5000 20000 100000]
                                     [--scans noisy jagged bowtie mild large] [--compare]

Real face scans are noisy and their rims ragged (the scanner loses the faces at grazing
angles), which the shared meshes are not. The proxies, written to a temporary folder from the
ICT faces of ``../shared/data/faces/ict`` (seeded, so every run makes the same files):

* ``noisy``: :func:`bench_intake.scan_proxy` (ict_A_neutral Loop-subdivided twice, about 106k
  vertices, each moved along its normal by N(0, 0.05 % of the diagonal));
* ``jagged``: ``noisy`` with a ragged rim: 6 passes that each drop, with probability 0.4, the
  faces with a corner on the boundary; the largest connected part kept (about 104k vertices);
* ``bowtie``: the same passes on ``noisy``, the largest part connected through vertices kept
  with its bowtie vertices (fans meeting at a vertex alone: teeth hanging on the rim by a
  vertex, notches closed at their mouths), which the intake splits; run with
  ``--keep-largest-component`` (the teeth become pieces of their own);
* ``mild``: ict_B_smile_jawopen Loop-subdivided once (about 26k vertices), noise 0.01 % of the
  diagonal, 3 such passes.
* ``holes``: ``noisy`` made from ict_A_neutral with its eye and mouth openings
  (``ict_A_neutral_holes.obj``), 3 such passes, which make the openings' rims ragged too; run
  with ``--close-holes`` (the remesh keeps the openings).

* ``large`` (only when named in ``--scans``): ict_A_neutral Loop-subdivided three times (about 425k
  vertices, 850k faces: a real scan's size), the noise of ``noisy``
  (:func:`bench_intake.scan_proxy` with 3 subdivisions).

Per proxy and vertex count, ``sem-pipeline remesh PROXY --vertices N --no-compare --no-report``
end to end (wall and CPU seconds) and, from its ``remesh_metrics.json``: the mean and the
smallest of the faces' smallest angles, the share of faces with an angle under 30°, the faces
below 20° (``improve.below_min_angle``: all, and those no input corner forces), the faces turned
over against the input, the area CV and the Hausdorff and RMS distances (% of the bounding-box
diagonal). With ``--compare``, under each row the same measures of one call of pymeshlab's
isotropic explicit remeshing on the same proxy, as issue #19 sets it (10 iterations, the target
edge length from the area for N vertices, :func:`pipeline.stages.baselines.isotropic_remesh`
with one run), by the evaluator the command uses
(:func:`pipeline.geometry.remesh_quality.remesh_quality`), the call's wall and CPU seconds and
the vertices it leaves (its count is not solved for: on a noisy scan it keeps the noise).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_intake import REPO, data_dir, scan_proxy  # noqa: E402  (puts REPO on the path)

from pipeline.io.meshio import read_mesh, write_obj  # noqa: E402

SCANS = ("noisy", "jagged", "bowtie", "mild", "holes")
# the command's flags per proxy: the pieces bowtie's bowties hold on; the openings of holes
FLAGS = {"bowtie": ("--keep-largest-component",), "holes": ("--close-holes",)}
LARGE = "large"


def ragged_rim(V: np.ndarray, F: np.ndarray, passes: int, p: float, rng,
               bowties: bool = False) -> tuple:
    """``(V, F)`` (n×3 float, m×3 int) after ``passes`` rounds that each drop, with probability
    ``p``, every face with a corner on the boundary: the largest part connected through edges
    (trimesh's ``split``), its vertices renumbered in order, and the faces at a vertex where
    fans meet at that vertex alone (a bowtie) dropped until none is left, as a scanner's mesher
    leaves none. With ``bowties``, the largest part connected through vertices instead, its
    bowties kept: teeth hanging on the rim by a vertex, notches closed at their mouths."""
    import trimesh

    from pipeline.geometry import topology as topo

    for _ in range(passes):
        on_rim = topo.boundary_vertices_mask(F, len(V))[F].any(axis=1)
        F = F[~(on_rim & (rng.random(len(F)) < p))]
    if bowties:
        _, label = topo.connected_components(F, len(V))
        F = F[label == np.bincount(label).argmax()]
        used, F = np.unique(F, return_inverse=True)
        return V[used], F.reshape(-1, 3)
    while True:
        parts = trimesh.Trimesh(V, F, process=False).split(only_watertight=False)
        largest = max(parts, key=lambda part: len(part.faces))
        V, F = np.asarray(largest.vertices), np.asarray(largest.faces)
        bowtie = topo.nonmanifold_vertices(F, len(V))
        if len(bowtie) == 0:
            return V, F
        F = F[~np.isin(F, bowtie).any(axis=1)]


def make_scans(folder: Path, names) -> dict:
    """The proxies ``names`` (of :data:`SCANS` and :data:`LARGE`) written to ``folder``: name →
    path."""
    import trimesh

    out = {}
    if {"noisy", "jagged", "bowtie"} & set(names):
        out["noisy"] = scan_proxy(folder)
    for name, bowties in (("jagged", False), ("bowtie", True)):
        if name in names:
            m = read_mesh(out["noisy"])
            V, F = ragged_rim(m.V, np.asarray(m.faces), 6, 0.4, np.random.default_rng(2),
                              bowties)
            out[name] = write_obj(folder / f"scan_{name}.obj", V, F)
    if "mild" in names:
        m = trimesh.load(data_dir() / "faces" / "ict" / "ict_B_smile_jawopen_disk.obj",
                         process=False)
        V, F = trimesh.remesh.subdivide_loop(m.vertices, m.faces, iterations=1)
        t = trimesh.Trimesh(V, F, process=False)
        rng = np.random.default_rng(3)
        diag = np.linalg.norm(t.bounds[1] - t.bounds[0])
        V = V + t.vertex_normals * rng.normal(0, 0.0001 * diag, (len(V), 1))
        V, F = ragged_rim(np.asarray(V), np.asarray(F), 3, 0.4, rng)
        out["mild"] = write_obj(folder / "scan_mild.obj", V, F)
    if "holes" in names:
        m = read_mesh(scan_proxy(folder, name="scan_holes_smooth.obj",
                                 source="ict_A_neutral_holes.obj"))
        V, F = ragged_rim(m.V, np.asarray(m.faces), 3, 0.4, np.random.default_rng(4))
        out["holes"] = write_obj(folder / "scan_holes.obj", V, F)
    if LARGE in names:
        out[LARGE] = scan_proxy(folder, iterations=3, name="scan_large.obj")
    return {k: v for k, v in out.items() if k in names}


def run_command(path: Path, n: int, folder: Path, flags=()) -> tuple:
    """``sem-pipeline remesh path --vertices n --no-compare --no-report`` (and ``flags``) run
    from ``folder`` with this tree's package: ``(completed process, output folder, wall s, CPU
    s)``."""
    out = folder / f"{path.stem}_{n}"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(                # this tree's package
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])}
    t = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "pipeline", "remesh", str(path), "--vertices",
                          str(n), "--no-compare", "--no-report", "-o", str(out), *flags],
                         capture_output=True, text=True, cwd=folder, env=env)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return run, out, wall, cpu


HEADER = ("mesh              N  verts mean min°  <30° %    min°  <20°  unforced  folds"
          " area CV  Haus %   RMS %   wall s   CPU s")


def measures_row(label: str, n: int, vertices: int, triangles: dict, below: int, unforced,
                 distance: dict, wall: float, cpu: float) -> str:
    """One printed row: ``label`` at ``n`` requested vertices, ``vertices`` made, the
    ``triangles`` and ``distance`` measures of :func:`remesh_quality`, ``below`` faces under 20°
    (``unforced`` of them that no input corner forces, or ``"-"``), wall and CPU seconds."""
    return (f"{label:12s} {n:6d} {vertices:6d} {triangles['mean_min_angle_deg']:8.2f} "
            f"{100 * triangles['fraction_min_angle_below_30']:7.3f} "
            f"{triangles['min_angle_deg']:7.2f} {below:5d} {unforced:>9} "
            f"{distance['turned_over_faces']:6d} {triangles['area_cv']:7.3f} "
            f"{100 * distance['hausdorff_rel']:7.3f} {100 * distance['rms_rel']:7.4f} "
            f"{wall:8.2f} {cpu:7.2f}")


def remesh_row(name: str, path: Path, n: int, folder: Path) -> str:
    """One table row, ``name``'s: the command on ``path`` at ``n`` vertices (see the module
    docstring)."""
    run, out, wall, cpu = run_command(path, n, folder, FLAGS.get(name, ()))
    if run.returncode:
        return f"{name:12s} {n:6d}  failed: {run.stderr.strip().splitlines()[-1]}"
    metrics = json.loads((out / "remesh_metrics.json").read_text())
    ours, below = metrics["methods"]["sem"], metrics["remesh"]["improve"]["below_min_angle"]
    return measures_row(name, n, metrics["remesh"]["vertices"], ours["triangles"],
                        below["faces"], below["unforced_faces"], ours["distance"], wall, cpu)


def pymeshlab_row(name: str, path: Path, n: int) -> str:
    """pymeshlab's row under ``name``'s at ``n`` vertices: one isotropic remeshing call on the
    input the command remeshes (``path`` read and repaired as it does, the openings the repair
    closed open again), measured as the command measures ours (see the module docstring)."""
    from pipeline.geometry.remesh_quality import remesh_quality
    from pipeline.geometry.repair import RepairOptions, open_mesh
    from pipeline.stages.baselines import isotropic_remesh
    from pipeline.stages.load import load_stage

    flags = FLAGS.get(name, ())
    options = RepairOptions(keep_largest_component="--keep-largest-component" in flags,
                            close_holes="--close-holes" in flags)
    V, F = open_mesh(load_stage(path, options).mesh)
    b = isotropic_remesh(V, F, n, max_runs=1)
    q = remesh_quality(V, F, b.V, b.F)
    per_face = q["triangles"]["_per_face_min_angle"]
    return measures_row("  pymeshlab", n, len(b.V), q["triangles"], int((per_face < 20).sum()),
                        "-", q["distance"], b.seconds, b.cpu_seconds)


def print_rows(paths: dict, counts, compare: bool) -> None:
    """The table: per mesh of ``paths`` (name → path) and vertex count of ``counts``, our row
    and, with ``compare``, pymeshlab's under it."""
    print(HEADER, flush=True)
    for name, path in paths.items():
        for n in counts:
            print(remesh_row(name, path, n, path.parent), flush=True)
            if compare:
                print(pymeshlab_row(name, path, n), flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, nargs="+", default=[5000, 20000, 100000])
    ap.add_argument("--scans", nargs="+", choices=[*SCANS, LARGE], default=list(SCANS))
    ap.add_argument("--compare", action="store_true",
                    help="under each row, pymeshlab's isotropic remeshing of the same proxy")
    args = ap.parse_args()
    names = args.scans
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scans = make_scans(folder, names)
        for name in names:
            mesh = read_mesh(scans[name])
            print(f"{name}: {len(mesh.V)} vertices, {len(mesh.faces)} faces")
        print_rows(scans, args.vertices, args.compare)
    return 0


if __name__ == "__main__":
    sys.exit(main())
