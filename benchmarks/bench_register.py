"""Landmark registration: ours (SEM disks + bijective landmark deformation) against trimesh's
``registration.nricp_amberg`` on the ICT-FaceKit pairs, with the dense ground truth.

    python benchmarks/bench_register.py [--kinds holes disk] [--sets ibug68 named]
                                        [--variants rotation mobius harmonic] [--no-baseline]

Pairs: A_neutral → A_smile, A_neutral → B_neutral, A_neutral → B_smile_jawopen (the four ICT
faces share one connectivity, so target vertex i is the truth for source vertex i). ``holes``:
the original meshes with eye/mouth openings (closed by close_holes for our method, given as is
to nricp); ``disk``: the files with the openings fan-closed. Landmark sets: the 68 iBUG points
(paired by order) and the 16 named ones (paired by name). Errors are relative to the target's
bounding-box diagonal, over the source's input vertices. Both methods get the same meshes and
landmarks; nricp_amberg runs with its default steps. "ours s" counts both SEM maps (converged
mode, 100 iterations) plus the registration. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from pipeline.geometry.repair import RepairOptions  # noqa: E402
from pipeline.geometry.sem import SEMOptions  # noqa: E402
from pipeline.io.landmarks import pair_landmarks, read_landmarks, resolve_landmarks  # noqa: E402
from pipeline.stages.load import load_stage  # noqa: E402
from pipeline.stages.parameterize import parameterize_stage  # noqa: E402
from pipeline.stages.register import (Face, Pair, load_truth,  # noqa: E402
                                      nricp_baseline, register_maps)

TARGETS = ("A_smile", "B_neutral", "B_smile_jawopen")
SETS = {"ibug68": "ibug68", "named": None}


def data_dir() -> Path:
    return Path(os.environ.get("SEM_DATA", HERE.parent.parent / "shared" / "data"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=["holes"], choices=("holes", "disk"))
    ap.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    ap.add_argument("--variants", nargs="+", default=["rotation"],
                    choices=("rotation", "mobius", "harmonic"))
    ap.add_argument("--no-baseline", action="store_true")
    args = ap.parse_args(argv)
    folder = data_dir() / "faces" / "ict"
    if not folder.is_dir():
        print(f"ICT data not found at {folder}; set SEM_DATA", file=sys.stderr)
        return 2
    sem = SEMOptions(mode="converged", max_iter=100)
    cache = {}

    def side(name, kind):
        if (name, kind) not in cache:
            intake = load_stage(folder / f"ict_{name}_{kind}.obj", RepairOptions(close_holes=True))
            t0 = time.perf_counter()
            p = parameterize_stage(intake.mesh, sem)
            cache[name, kind] = (intake, p, time.perf_counter() - t0)
        return cache[name, kind]

    print("| pair | mesh | landmarks | method | mean | p95 | max | landmark res. max | "
          "flipped | time s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for kind in args.kinds:
        for target in TARGETS:
            si, ps, ts = side("A_neutral", kind)
            ti, pt, tt = side(target, kind)
            truth = folder / f"ict_{target}_{kind}.obj"
            for set_name in args.sets:
                lms = read_landmarks(folder / "ict_landmarks.json", SETS[set_name])
                ls, lt = pair_landmarks(lms, lms)
                pair = Pair(Face(si, resolve_landmarks(ls, si.mesh, si.info["input_vertices"])[0],
                                 "source"),
                            Face(ti, resolve_landmarks(lt, ti.mesh, ti.info["input_vertices"])[0],
                                 "target"),
                            ls.names, load_truth(truth, si), str(truth))
                label = f"A_neutral → {target} | {kind} | {set_name} ({len(ls)})"
                for variant in args.variants:
                    opts = dict(mobius=variant == "mobius",
                                energy="harmonic" if variant == "harmonic" else "biharmonic")
                    t0 = time.perf_counter()
                    reg = register_maps(pair, ps, pt, **opts)
                    sec = ts + tt + time.perf_counter() - t0
                    m = reg.metrics
                    e = m["dense_error"]["ours"]
                    name = {"rotation": "ours", "mobius": "ours (Möbius)",
                            "harmonic": "ours (harmonic)"}[variant]
                    print(f"| {label} | {name} | {e['mean']:.5f} | {e['p95']:.5f} | "
                          f"{e['max']:.5f} | {m['landmark_residual']['after']['max']:.1e} | "
                          f"{m['flipped_faces']} | {sec:.1f} |", flush=True)
                if not args.no_baseline:
                    diag = m["target_bbox_diagonal"]
                    b = nricp_baseline(pair, diag)
                    err = b["error"]
                    import numpy as np
                    fin = err[np.isfinite(err)]
                    print(f"| {label} | nricp_amberg | {fin.mean():.5f} | "
                          f"{np.percentile(fin, 95):.5f} | {fin.max():.5f} | "
                          f"{b['landmark_residual']['max']:.1e} | {b['faces_turned_over']}* | "
                          f"{b['seconds']:.1f} |", flush=True)
    if not args.no_baseline:
        print("\n*nricp: faces whose normal turned by more than 90° (it has no disk map to "
              "count flips in); ours: flipped faces of the deformed disk map.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
