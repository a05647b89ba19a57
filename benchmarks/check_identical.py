"""Check that maps, remeshes and registrations are bit for bit those of another revision.

Runs the stable command-line contracts (``parameterize``, ``remesh``, ``register``; see
``shared/docs/DESIGN.md``) on every shared disk mesh and on an ICT face pair, and either saves
the result files (``--save DIR``) or compares them with a saved set (``--compare DIR``): every
array of every ``.npz`` must be equal element for element and every OBJ equal byte for byte.
Because it uses only the CLI, the same script runs on an older checkout::

    git worktree add /tmp/old REV && (cd /tmp/old && python setup.py build_ext --inplace -q)
    (cd /tmp/old && python /path/to/check_identical.py --save /tmp/ref)
    python benchmarks/check_identical.py --compare /tmp/ref

Prints one row per file and exits 1 on any difference.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

DATA = Path(os.environ.get("SEM_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
SEM = ["--mode", "converged", "--max-iter", "60"]


def jobs(data: Path) -> list[tuple[str, list[str], list[str]]]:
    """(name, CLI arguments before -o, result files) for every check."""
    out = []
    for mesh in sorted((data / "meshes").glob("*.obj")):
        out.append((f"parameterize/{mesh.stem}", ["parameterize", str(mesh), *SEM,
                                                   "--no-figures"],
                    ["parameterization.npz", "parameterized.obj"]))
        out.append((f"remesh/{mesh.stem}", ["remesh", str(mesh), "--vertices", "3000", *SEM,
                                             "--no-compare", "--no-report"], ["remeshed.obj"]))
    ict = data / "faces" / "ict"
    out.append(("register/ict_A_neutral-to-A_smile",
                ["register", str(ict / "ict_A_neutral_holes.obj"),
                 str(ict / "ict_A_smile_holes.obj"), "--source-landmarks",
                 str(ict / "ict_landmarks.json"), "--close-holes", *SEM, "--no-figures"],
                ["registration.npz", "registered.obj"]))
    return out


def same(a: Path, b: Path) -> bool:
    if a.suffix == ".npz":
        with np.load(a) as x, np.load(b) as y:
            return set(x.files) == set(y.files) and all(
                x[k].dtype == y[k].dtype and np.array_equal(x[k], y[k]) for k in x.files)
    return filecmp.cmp(a, b, shallow=False)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", type=Path, help="write the result files here")
    group.add_argument("--compare", type=Path, help="compare with the files saved here")
    ap.add_argument("--only", default="", help="run only the checks whose name contains this")
    args = ap.parse_args()
    work = args.save or Path(tempfile.mkdtemp(prefix="identical-"))
    differ = 0
    for name, argv, files in jobs(DATA):
        if args.only not in name:
            continue
        out = work / name
        proc = subprocess.run([sys.executable, "-m", "pipeline", *argv, "-o", str(out)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            print(f"{name}: exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:]}")
            differ += 1
            continue
        for f in files:
            if args.save:
                print(f"{name}/{f}: saved")
                continue
            ok = same(out / f, args.compare / name / f)
            differ += not ok
            print(f"{name}/{f}: {'identical' if ok else 'DIFFERENT'}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
