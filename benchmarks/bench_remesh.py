"""Uniform remeshing through the SEM map: time per step, quality beside pymeshlab, and point
location at 10^6 faces.

    python benchmarks/bench_remesh.py [--vertices 20000 100000] [--meshes camelhead_x4 ...]
                                      [--repeat 3] [--locate] [--no-remesh]
    python benchmarks/bench_remesh.py --compare [--maps converged paper 30] [--vertices 5000 ...]
                                      [--meshes choi_human_face ict_A_neutral_disk ...] [--no-cli]
    python benchmarks/bench_remesh.py --compare --closed [--vertices 5000 20000] [--meshes ...]
    python benchmarks/bench_remesh.py --compare --holes [--vertices 5000 20000] [--meshes ...]

``--compare``: per mesh and count (default: every disk mesh of ``../shared/data/meshes`` and
the ICT ``*_disk`` faces, at 5k, 20k and 100k vertices), pymeshlab's isotropic explicit
remeshing (10 iterations, target length solved for the count) and our remesh on each map of
``--maps``, in the same run and by the same evaluator: mean smallest angle, share of faces with
an angle under 30°, smallest angle, area CV, Hausdorff and RMS distance (% of the bounding-box
diagonal), one disk (``topo``: ``disk``, or ``χ=2`` for a closed genus-0 manifold; ``/N folds``
after it: N faces turned over against the input), and seconds (ours: the map + the remesh
stage; pymeshlab: its call, with its CPU seconds after the row). The row ``ours/cli`` is what
a user gets: ``sem-pipeline remesh MESH --vertices N --no-compare --no-report`` run in a fresh
interpreter, its written ``remeshed.obj`` measured, its wall seconds end to end (start,
imports, read, repair, map, remesh, measures, write) in ``s total`` and its CPU seconds (user
+ system, steadier on a shared machine) after it. ``*`` marks where ours is
at least as good (area CV: at most 0.6 × pymeshlab's; ``ours/cli`` seconds: less than
pymeshlab's call).

``--closed``: the closed genus-0 meshes of ``../shared/data/closed`` (default: all of them but
the higher-genus ones), read and repaired as the ``input`` stage does, mapped onto the sphere by
``parameterize_stage`` (``--maps paper``: the alternating-hemisphere iterations; ``converged``:
Gauss–Newton; ``auto``: the remesh command's map, a few free and hemisphere iterations; ``N``:
at most N Gauss–Newton steps) and remeshed through the sphere.

``--holes``: the ICT faces with their eye and mouth openings (``*_holes.obj``), read and
repaired with ``close_holes`` (the openings filled for the map) and remeshed with the openings
kept (the remesh's default, ``sem-pipeline remesh --close-holes``); pymeshlab remeshes, and both
are measured against, the input with its openings (:func:`pipeline.geometry.repair.open_mesh`);
``topo`` says ``disk+K`` for one disk with K holes.

Remesh table: for each mesh (parameterized once with ``SEMOptions(mode="paper")``, not timed
in the total) and each vertex count, the median over ``--repeat`` runs of every step of
:func:`pipeline.stages.remesh.remesh_stage`: sample (lattice + count solve + rim band ODT +
corner snapping), Delaunay (band ``Delaunay`` + lattice by construction), locate (grid build +
queries), lift, improve and the total; then improve's own steps
(:func:`pipeline.geometry.remesh.improve.improve_remesh`'s ``seconds``): the first flips and
relaxation, the sag refinement, the isotropic rounds (``iso``), the count correction, the
final smoothing, the pinned second refinement, the reshape steps, the sliver collapses, the
rim fans (``fans``), the fold repair (``unfold``), the minimum-angle pass (``angle``), the
moves onto far input points (``settle``), the area-evening pass (``even``), the raise above 30°
(``raise``), the star moves of the faces still below the minimum angle (``star``) and the
degenerate-face repair. The goal is
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
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", REPO.parent / "shared" / "data"))


CLOSED_GENUS0 = ("igl_bunny", "igl_arm", "igl_bumpy_cube", "igl_decimated_max", "igl_elephant")


def disk_meshes() -> list[str]:
    """Every disk mesh of the data folder: ``meshes/*.obj`` and the ICT faces' ``*_disk.obj``."""
    return sorted([p.stem for p in (data_dir() / "meshes").glob("*.obj")]
                  + [p.stem for p in (data_dir() / "faces" / "ict").glob("*_disk.obj")])


def holes_meshes() -> list[str]:
    """The ICT faces with their openings, ``*_holes.obj`` (remeshed with ``--close-holes``)."""
    return sorted(p.stem for p in (data_dir() / "faces" / "ict").glob("*_holes.obj"))


def with_holes(name: str) -> bool:
    """Whether the benchmark name is a mesh with openings, read with ``close_holes``."""
    return name.endswith("_holes")


def mesh_path(name: str) -> Path | None:
    """The file of a benchmark name (closed, disk mesh or ICT face), None for a generated one."""
    for path in (data_dir() / "closed" / f"{name}.obj", data_dir() / "meshes" / f"{name}.obj",
                 data_dir() / "faces" / "ict" / f"{name}.obj"):
        if path.exists():
            return path
    return None


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
    from pipeline.geometry.repair import RepairOptions

    path = mesh_path(name)
    return load_stage(path if path is not None else data_dir() / "meshes" / f"{name}.obj",
                      RepairOptions(close_holes=with_holes(name))).mesh


def parameterize(mesh):
    """The remesh command's own map (``mode: auto``: the disk or, for a closed mesh, the
    sphere) and its seconds."""
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.parameterize import parameterize_stage

    t = time.perf_counter()
    p = parameterize_stage(mesh, SEMOptions(mode="auto"))
    return p, time.perf_counter() - t


def parameterize_with(mesh, how: str):
    """The map for ``--compare``: ``paper`` (Algorithm 1, 10 steps), ``paperK`` (Algorithm 1,
    K steps), ``converged`` (the default converged map), ``auto`` (the remesh command's map,
    :meth:`pipeline.geometry.sem.SEMOptions.for_domain`) or an integer (converged mode, at most
    that many steps)."""
    from pipeline.geometry.sem import SEMOptions
    from pipeline.stages.parameterize import parameterize_stage

    opts = (SEMOptions(mode="paper") if how == "paper" else SEMOptions() if how == "converged"
            else SEMOptions(mode="auto") if how == "auto"
            else SEMOptions(mode="paper", max_iter=int(how[5:])) if how.startswith("paper")
            else SEMOptions(mode="converged", max_iter=int(how)))
    t = time.perf_counter()
    p = parameterize_stage(mesh, opts)
    return p, time.perf_counter() - t


COLS = (("mean min°", "mean_min_angle_deg", "high", 2), ("<30° %", "fraction_min_angle_below_30",
        "low", 3), ("min°", "min_angle_deg", "high", 2), ("area CV", "area_cv", "low", 3),
        ("Haus %", "hausdorff_rel", "low", 3), ("RMS %", "rms_rel", "low", 4))


def compile_package() -> None:
    """Write the package's bytecode (``__pycache__``, git-ignored), as an installed package
    has it after its first import: the command's timings then do not include compiling the
    sources, which a user pays once (``PYTHONDONTWRITEBYTECODE``, set on some machines, would
    otherwise make every run compile them anew: 0.07–0.1 s)."""
    import compileall

    compileall.compile_dir(str(REPO / "pipeline"), quiet=1)


def cli_remesh(path: Path, n: int, repeat: int, flags=()):
    """``sem-pipeline remesh PATH --vertices n --no-compare --no-report`` as a user runs it
    (a fresh interpreter: start, imports, read, repair, map, remesh, measure, write; the
    package's bytecode compiled, :func:`compile_package`): the mesh it wrote, its wall seconds
    and its CPU seconds (user + system; steadier than the wall time when other jobs share the
    machine), each the median of ``repeat`` runs; ``flags``: more of the command's options."""
    import resource
    import tempfile

    from pipeline.io.meshio import read_mesh

    compile_package()

    def cpu():
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    secs, cpus = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        for _ in range(repeat):
            t, c = time.perf_counter(), cpu()
            subprocess.run([sys.executable, "-m", "pipeline", "remesh", str(path), "-o", str(out),
                            "--vertices", str(n), "--no-compare", "--no-report", *flags],
                           check=True, capture_output=True)
            secs.append(time.perf_counter() - t)
            cpus.append(cpu() - c)
        mesh = read_mesh(out / "remeshed.obj")
    return mesh.V, np.asarray(mesh.faces), float(np.median(secs)), float(np.median(cpus))


def bench_compare(names, counts, maps, repeat, n_random=100_000, cli=True):
    """Side by side at each vertex count: our remesh (per map of ``maps``) and pymeshlab's
    isotropic explicit remeshing (10 iterations, target length solved for the count), measured
    by the same evaluator (:func:`pipeline.geometry.remesh_quality.remesh_quality`). Seconds:
    ours = map + remesh (median of ``repeat`` remesh runs), pymeshlab = its call (the reported
    run; its CPU seconds, all its threads, after the row). With ``cli``, also the row
    ``ours/cli``: the mesh ``sem-pipeline remesh`` writes with its defaults and the command's
    wall seconds end to end (:func:`cli_remesh`). ``*`` marks our
    value where it is at least as good as pymeshlab's; ``area CV`` needs ≤ 0.6 × pymeshlab's
    for the mark, the seconds of ``ours/cli`` less than pymeshlab's call."""
    from pipeline.geometry.remesh_quality import remesh_quality
    from pipeline.geometry.repair import open_mesh
    from pipeline.stages import baselines
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    head = (f"{'mesh':26s} {'n':>6s} {'method':>14s} {'verts':>6s} "
            + " ".join(f"{c[0]:>9s}" for c in COLS) + f" {'topo':>4s} {'s map':>6s} {'s mesh':>6s}"
            f" {'s total':>8s}")
    print(head)

    def measure(mesh, V, F):
        r = remesh_quality(*open_mesh(mesh), V, F, n_random)
        vals = {**r["triangles"], **r["distance"]}
        vals["fraction_min_angle_below_30"] *= 100
        vals["hausdorff_rel"] *= 100
        vals["rms_rel"] *= 100
        shape = ("disk" if r["is_disk"] else "χ=2" if r["is_sphere"] else
                 f"disk+{r['holes']}" if r["is_disk_with_holes"] else "NO")
        folds = r["distance"]["turned_over_faces"]
        return vals, shape if not folds else f"{shape}/{folds} folds"

    def line(name, n, method, nv, vals, disk, t_map, t_mesh, ref=None, total_mark=" ",
             tail=""):
        cells = []
        for label, key, better, dig in COLS:
            mark = " "
            if ref is not None:
                x, y = vals[key], ref[key]
                ok = (x <= 0.6 * y if key == "area_cv" else x <= y if better == "low"
                      else x >= y)
                mark = "*" if ok else " "
            cells.append(f"{vals[key]:8.{dig}f}{mark}")
        print(f"{name:26s} {n:6d} {method:>14s} {nv:6d} " + " ".join(cells)
              + f" {disk:>4s} {t_map:6.2f} {t_mesh:6.2f} {t_map + t_mesh:7.2f}{total_mark}{tail}",
              flush=True)

    for name in names:
        mesh = load(name)
        ms = {how: parameterize_with(mesh, how) for how in maps}
        for n in counts:
            b = baselines.isotropic_remesh(*open_mesh(mesh), n)
            ref, disk = measure(mesh, b.V, b.F)
            line(name, n, "pymeshlab", len(b.V), ref, disk, 0.0, b.seconds,
                 tail=f" (CPU {b.cpu_seconds:.2f} s)")
            for how, (p, t_map) in ms.items():
                dmap, flipped = p.image, p.flipped_faces
                if flipped:
                    print(f"{name:26s} {n:6d} {'ours/' + how:>14s} the map has "
                          f"{flipped} flipped faces: no remesh", flush=True)
                    continue
                secs = []
                for _ in range(repeat):
                    t = time.perf_counter()
                    r = remesh_stage(mesh, dmap, RemeshConfig(vertices=n))
                    secs.append(time.perf_counter() - t)
                vals, disk = measure(mesh, r.V, r.F)
                line(name, n, f"ours/{how}", len(r.V), vals, disk, t_map, float(np.median(secs)),
                     ref)
            path = mesh_path(name)
            if cli and path is not None:
                V, F, t_cli, cpu_cli = cli_remesh(
                    path, n, repeat, ("--close-holes",) if with_holes(name) else ())
                vals, disk = measure(mesh, V, F)
                line(name, n, "ours/cli", len(V), vals, disk, 0.0, t_cli, ref,
                     "*" if t_cli < b.seconds else " ", f" (CPU {cpu_cli:.2f} s)")


STEPS = ("sample", "delaunay", "locate", "lift", "improve", "total")
SUB = ("flips", "relax", "refine", "isotropic", "count", "smoothing", "pinned", "reshape",
       "follow", "slivers", "rim_fans", "folds", "guarantee", "settle", "even", "raise",
       "star_moves", "repair")
SUB_HEAD = ("flips", "relax", "refine", "iso", "count", "smooth", "pinned", "reshape", "follow",
            "sliver", "fans", "unfold", "angle", "settle", "even", "raise", "star", "repair")


def bench_remesh(names, counts, repeat):
    from pipeline.stages.remesh import RemeshConfig, remesh_stage

    rows = []
    for name in names:
        mesh = load(name)
        p, t_sem = parameterize(mesh)
        for n in counts:
            runs = []
            for _ in range(repeat):
                r = remesh_stage(mesh, p.image, RemeshConfig(vertices=n))
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
              + " ".join(f"{k:>6s}" for k in SUB_HEAD))
    print(f"{name:16s} {faces:8d} {n:8d} {got:8d} {t_sem:8.2f} | "
          + " ".join(f"{v:8.3f}" for v in med[:len(STEPS)]) + " | "
          + " ".join(f"{v:6.2f}" for v in med[len(STEPS):]), flush=True)


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
    ap.add_argument("--meshes", nargs="+", default=None,
                    help="default: camelhead_x4; with --compare every disk mesh, with "
                         "--closed every closed one")
    ap.add_argument("--vertices", nargs="+", type=int, default=None,
                    help="default: 20000 100000; with --compare 5000 20000 100000, with "
                         "--closed 5000 20000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--locate", action="store_true", help="also the point-location comparison")
    ap.add_argument("--no-remesh", action="store_true")
    ap.add_argument("--compare", action="store_true",
                    help="the side-by-side quality table against pymeshlab instead of the steps")
    ap.add_argument("--maps", nargs="+", default=["converged"],
                    help="with --compare: paper | paperK | converged | auto | N (converged, "
                         "at most N steps)")
    ap.add_argument("--no-cli", action="store_true",
                    help="with --compare: no ours/cli rows (the command end to end)")
    ap.add_argument("--closed", action="store_true",
                    help="the closed genus-0 meshes through the sphere map "
                         "(default meshes: all of them; default counts 5000 20000)")
    ap.add_argument("--holes", action="store_true",
                    help="the ICT faces with their openings, kept open (default counts 5000 "
                         "20000)")
    args = ap.parse_args(argv)
    # defaults by mode; a value given on the command line is kept even when it equals
    # another mode's default
    if args.closed:
        meshes, counts = list(CLOSED_GENUS0), [5000, 20000]
    elif args.holes:
        meshes, counts = holes_meshes(), [5000, 20000]
    elif args.compare:
        meshes, counts = disk_meshes(), [5000, 20000, 100000]
    else:
        meshes, counts = ["camelhead_x4"], [20000, 100000]
    args.meshes = meshes if args.meshes is None else args.meshes
    args.vertices = counts if args.vertices is None else args.vertices
    if args.compare:
        print("side by side, same evaluator; * = ours at least as good as pymeshlab "
              "(area CV: ≤ 0.6 ×); seconds: ours = SEM map + remesh_stage (median of "
              f"{args.repeat}), pymeshlab = its call\n")
        bench_compare(args.meshes, args.vertices, args.maps, args.repeat, cli=not args.no_cli)
        return
    if not args.no_remesh:
        print("remesh_stage, seconds per step (median of "
              f"{args.repeat}); the SEM map (the command's, mode auto) is not in the total\n")
        bench_remesh(args.meshes, args.vertices, args.repeat)
    if args.locate:
        bench_locate()


if __name__ == "__main__":
    main()
