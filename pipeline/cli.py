"""Command line: ``sem-pipeline run CONFIG.yaml`` and ``sem-pipeline parameterize MESH -o DIR``.

Thin by design: it parses arguments, builds the same option objects the YAML runner builds and
calls the stages. Bad input or configuration → one line on stderr, exit code 2; a map that
failed (flipped faces remain) → one line, exit code 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import __version__
from .errors import UserError


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):  # argparse's default prints the whole usage block
        raise UserError(f"{message}; see '{self.prog} --help'")


def _summary(p) -> str:
    d = p.metrics["distortion"]
    return (f"{p.metrics['mesh']['vertices']} vertices, {p.sem.iterations} iterations "
            f"({p.sem.status}), D(f) eq.28 = {d['total_area_distortion_eq28']:.5f}, "
            f"face area distortion = {d['face_area_distortion']:.5f}, "
            f"flipped faces = {d['flipped_faces']}, "
            f"{sum(p.metrics['seconds'].values()):.2f} s")


def cmd_parameterize(args) -> int:
    from .geometry.repair import RepairOptions
    from .geometry.sem import SEMOptions
    from .runner import Progress
    from .stages.load import load_stage
    from .stages.parameterize import parameterize_stage, write_parameterization

    repair = RepairOptions(close_holes=args.close_holes,
                           keep_largest_component=args.keep_largest_component,
                           decimate_to_faces=args.decimate, weld=not args.no_weld)
    options = SEMOptions(mode=args.mode, max_iter=args.max_iter, tol=args.tol,
                         inversion=args.inversion, solver=args.solver)
    intake = load_stage(args.mesh, repair)
    for line in intake.mesh.messages:
        print(f"repair: {line}", file=sys.stderr)
    p = parameterize_stage(intake.mesh, options, Progress(Path(args.mesh).name))
    write_parameterization(p, args.out, {"input": intake.info}, figures=not args.no_figures)
    print(f"{args.out}: {_summary(p)}")
    return 0


def cmd_run(args) -> int:
    from .config import load_config
    from .runner import run_config

    config, base = load_config(args.config)
    run_dir = run_config(config, base, args.out)
    print(f"{run_dir}: done (see {run_dir / 'manifest.json'})")
    return 0


def cmd_sample(args) -> int:
    from .sample import write_sample

    paths = write_sample(args.out, n_vertices=args.vertices)
    print("\n".join(str(p) for p in paths.values()))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(prog="sem-pipeline", description=(
        "Equiareal disk parameterizations by Stretch Energy Minimization, and the stages "
        "built on them."))
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)

    run = sub.add_parser("run", help="run the stages a YAML config names")
    run.add_argument("config", help="YAML config (see configs/)")
    run.add_argument("--out", help="output root instead of the config's run.out_dir")
    run.set_defaults(func=cmd_run)

    par = sub.add_parser("parameterize", help="SEM disk map of one mesh")
    par.add_argument("mesh", help="OBJ, PLY, OFF, STL or MATLAB .mat (V/F) mesh")
    par.add_argument("-o", "--out", required=True, help="output folder")
    par.add_argument("--mode", choices=("paper", "converged"), default="converged",
                     help="paper: Algorithm 1, ≤10 iterations; converged (default): iterate "
                          "until the energy stops decreasing")
    par.add_argument("--max-iter", type=int, default=None,
                     help="iteration cap (default 10 paper, 1000 converged)")
    par.add_argument("--tol", type=float, default=1e-7,
                     help="converged mode: relative energy decrease counted as none")
    par.add_argument("--inversion", action="store_true", help="Remark 2's inversion (off)")
    par.add_argument("--solver", choices=("auto", "cholmod", "scipy"), default="auto")
    par.add_argument("--close-holes", action="store_true",
                     help="close every boundary loop but the longest (eyes, mouth)")
    par.add_argument("--keep-largest-component", action="store_true")
    par.add_argument("--decimate", type=int, default=None, metavar="FACES",
                     help="decimate to about this many faces first (fast-simplification)")
    par.add_argument("--no-weld", action="store_true", help="do not weld duplicate vertices")
    par.add_argument("--no-figures", action="store_true")
    par.set_defaults(func=cmd_parameterize)

    smp = sub.add_parser("sample", help="write the embedded synthetic face meshes")
    smp.add_argument("-o", "--out", required=True)
    smp.add_argument("--vertices", type=int, default=6000)
    smp.set_defaults(func=cmd_sample)
    return parser


def main(argv=None) -> int:
    from .stages.parameterize import ParameterizationFailed

    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return UserError.exit_code
    except ParameterizationFailed as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
