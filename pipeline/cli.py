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


def _repair_options(args):
    """RepairOptions from the intake flags ``_add_intake_args`` declares."""
    from .geometry.repair import RepairOptions
    return RepairOptions(close_holes=args.close_holes,
                         keep_largest_component=args.keep_largest_component,
                         decimate_to_faces=args.decimate, weld=not args.no_weld)


def _load_reported(path, args):
    """Load and repair ``path``; every repair goes to stderr as one 'repair:' line."""
    from .stages.load import load_stage
    intake = load_stage(path, _repair_options(args))
    for line in intake.mesh.messages:
        print(f"repair: {line}", file=sys.stderr)
    return intake


def cmd_parameterize(args) -> int:
    from .geometry.sem import SEMOptions
    from .runner import Progress
    from .stages.parameterize import parameterize_stage, write_parameterization

    options = SEMOptions(mode=args.mode, max_iter=args.max_iter, tol=args.tol,
                         inversion=args.inversion, solver=args.solver)
    intake = _load_reported(args.mesh, args)
    p = parameterize_stage(intake.mesh, options, Progress(Path(args.mesh).name))
    write_parameterization(p, args.out, {"input": intake.info}, figures=not args.no_figures)
    print(f"{args.out}: {_summary(p)}")
    return 0


def cmd_remesh(args) -> int:
    from pydantic import ValidationError

    from .config import ImproveConfig, RemeshConfig, format_validation_error
    from .geometry.sem import SEMOptions
    from .runner import Progress
    from .runner_remesh import run_remesh
    from .stages.parameterize import ParameterizationFailed, parameterize_stage

    try:
        rc = RemeshConfig(vertices=args.vertices, spacing=args.spacing, pattern=args.pattern,
                          seed=args.seed, improve=None if args.no_improve else ImproveConfig(),
                          compare=not args.no_compare, report=not args.no_report,
                          landmarks=args.landmarks)
    except ValidationError as exc:
        raise UserError(format_validation_error(exc, "sem-pipeline remesh")) from None
    intake = _load_reported(args.mesh, args)
    p = parameterize_stage(intake.mesh, SEMOptions(mode=args.mode, max_iter=args.max_iter,
                                                   solver=args.solver),
                           Progress(Path(args.mesh).name))
    if not p.ok:
        raise ParameterizationFailed(f"parameterization failed: {p.sem.flipped_faces} flipped "
                                     f"faces remain; remeshing needs a bijective map")
    run_remesh(rc, intake, p, args.out, figures=not args.no_report)
    print(f"{args.out}: remeshed.obj, remesh_metrics.json"
          + ("" if args.no_report else ", report.html"))
    return 0


def cmd_run(args) -> int:
    from .config import load_config
    from .runner import run_config

    config, base = load_config(args.config)
    run_dir = run_config(config, base, args.out)
    print(f"{run_dir}: done (see {run_dir / 'manifest.json'})")
    return 0


def cmd_register(args) -> int:
    from .geometry.repair import RepairOptions
    from .geometry.sem import SEMOptions
    from .runner_register import (log_line, log_pair_messages, register_summary,
                                  sem_progress)
    from .stages.register import RegisterOptions, load_pair, register_stage, write_registration

    if args.target_landmarks is None:
        args.target_landmarks = args.source_landmarks
    repair = RepairOptions(close_holes=args.close_holes)
    pair = load_pair(args.source, args.target, args.source_landmarks, args.target_landmarks,
                     args.landmark_set, repair, args.truth)
    log_pair_messages(pair)
    options = RegisterOptions(mobius=args.mobius, energy=args.energy, baseline=args.baseline,
                              sem=SEMOptions(mode=args.mode, max_iter=args.max_iter,
                                             solver=args.solver))
    reg = register_stage(pair, options, progress=sem_progress, log=log_line)
    write_registration(reg, args.out, figures=not args.no_figures)
    print(f"{args.out}: {register_summary(reg)}")
    return 0


def cmd_morph(args) -> int:
    from .stages.morph import MorphOptions, load_morph_inputs, morph_stage, write_morph

    V0, V1, F = load_morph_inputs(args.inputs)
    m = morph_stage(V0, V1, F, MorphOptions(frames=args.frames, easing=args.easing,
                                            frame_ms=args.frame_ms, size=args.size))
    files = write_morph(m, args.out)
    print(f"{args.out}: {args.frames} frames ({args.easing}) in {files['frames']}, "
          f"animation {files['gif']}, filmstrip {files['filmstrip']}")
    return 0


def cmd_experiment(args) -> int:
    from .experiments.execute import run_experiment
    from .experiments.spec import load_experiment

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be at least 1 (got {args.workers})")
    exp = load_experiment(args.config)
    out = run_experiment(exp, args.out, workers=args.workers, scheduler=args.scheduler,
                         retry_failed=args.retry_failed)
    print(f"{out.run_dir}: {len(exp.items)} items: {len(out.ran)} ran ({out.backend}), "
          f"{len(out.skipped)} skipped, {len(out.failed)} failed; summary "
          f"{out.summary[1] if out.summary else '-'}")
    for item_id in out.failed:
        print(f"failed: {item_id}: {out.records.get(item_id, {}).get('error')}")
    return 1 if out.failed else 0


def cmd_sample(args) -> int:
    from .sample import write_sample

    paths = write_sample(args.out, n_vertices=args.vertices)
    print("\n".join(str(p) for p in paths.values()))
    return 0


def _add_intake_args(parser) -> None:
    """The load-and-repair flags shared by the commands that read one mesh."""
    parser.add_argument("--close-holes", action="store_true",
                        help="close every boundary loop but the longest (eyes, mouth)")
    parser.add_argument("--keep-largest-component", action="store_true")
    parser.add_argument("--decimate", type=int, default=None, metavar="FACES",
                        help="decimate to about this many faces first (fast-simplification)")
    parser.add_argument("--no-weld", action="store_true",
                        help="do not weld duplicate vertices")


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
    _add_intake_args(par)
    par.add_argument("--no-figures", action="store_true")
    par.set_defaults(func=cmd_parameterize)

    reg = sub.add_parser("register", help="landmark registration of SOURCE onto TARGET on "
                                          "their SEM disks")
    reg.add_argument("source", help="source face mesh")
    reg.add_argument("target", help="target face mesh")
    reg.add_argument("--source-landmarks", required=True,
                     help="JSON ({'landmarks': {name: index}} or a list), CSV or TXT "
                          "(indices or x y z points, snapped to the nearest vertex)")
    reg.add_argument("--target-landmarks", default=None,
                     help="target landmark file (default: the source's, for one file of both)")
    reg.add_argument("--landmark-set", default=None, metavar="KEY",
                     help="JSON key of the landmark set, e.g. ibug68 (default: 'landmarks')")
    reg.add_argument("-o", "--out", required=True, help="output folder")
    reg.add_argument("--truth", default=None, metavar="MESH",
                     help="ground truth with the source's connectivity: report the dense error")
    reg.add_argument("--mobius", action="store_true",
                     help="align the disks by a Möbius map (default: a rotation)")
    reg.add_argument("--energy", choices=("biharmonic", "harmonic"), default="biharmonic",
                     help="smoothness of the landmark deformation (default biharmonic)")
    reg.add_argument("--baseline", action="store_true",
                     help="also run trimesh's nricp_amberg and compare")
    reg.add_argument("--close-holes", action="store_true",
                     help="close eye/mouth openings (every boundary loop but the longest)")
    reg.add_argument("--mode", choices=("paper", "converged"), default="converged")
    reg.add_argument("--max-iter", type=int, default=None, help="SEM iteration cap")
    reg.add_argument("--solver", choices=("auto", "cholmod", "scipy"), default="auto")
    reg.add_argument("--no-figures", action="store_true")
    reg.set_defaults(func=cmd_register)

    mor = sub.add_parser("morph", help="morph a face into its registered image (frames + GIF)")
    mor.add_argument("inputs", nargs="+", metavar="INPUT",
                     help="a 'register' output folder (or its registration.npz), or SOURCE and "
                          "REGISTERED meshes with the same connectivity")
    mor.add_argument("-o", "--out", required=True, help="output folder")
    mor.add_argument("--frames", type=int, default=24, help="number of frames K (≥ 2)")
    mor.add_argument("--easing", choices=("linear", "ease-in-out", "cosine"),
                     default="ease-in-out")
    mor.add_argument("--frame-ms", type=int, default=80, help="GIF frame duration")
    mor.add_argument("--size", type=int, default=480, help="GIF frame size in pixels")
    mor.set_defaults(func=cmd_morph)

    exp = sub.add_parser("experiment", help="run a config over a dataset and a parameter sweep "
                                            "(cached, resumable; process pool or Dask)")
    exp.add_argument("config", help="experiment YAML (see configs/experiment_*.yaml)")
    exp.add_argument("--out", help="output root instead of the config's run.out_dir")
    exp.add_argument("--workers", type=int, default=None,
                     help="local worker processes (default: experiment.workers, else cores); "
                          "1 runs the items in this process")
    exp.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="run on the Dask cluster at ADDRESS (tcp://host:8786), or 'local' "
                          "for a Dask LocalCluster of --workers processes")
    exp.add_argument("--retry-failed", action="store_true",
                     help="also re-run items that failed on bad input with unchanged inputs")
    exp.set_defaults(func=cmd_experiment)

    rem = sub.add_parser("remesh", help="uniform remesh through the SEM disk map, with a "
                                        "quality report beside pymeshlab and decimation")
    rem.add_argument("mesh", help="OBJ, PLY, OFF, STL or MATLAB .mat (V/F) mesh")
    rem.add_argument("-o", "--out", required=True, help="output folder")
    rem.add_argument("--vertices", type=int, default=None, help="vertex count of the remesh")
    rem.add_argument("--spacing", type=float, default=None,
                     help="or: target edge length in the mesh's units")
    rem.add_argument("--pattern", choices=("hexagonal", "blue_noise", "concentric"),
                     default="hexagonal", help="disk sampling pattern (default hexagonal)")
    rem.add_argument("--seed", type=int, default=0, help="blue noise seed")
    rem.add_argument("--no-improve", action="store_true",
                     help="the paper's plain lift: no flips, relaxation or refinement")
    rem.add_argument("--no-compare", action="store_true",
                     help="skip the pymeshlab and decimation baselines")
    rem.add_argument("--no-report", action="store_true", help="no report.html and figures")
    rem.add_argument("--landmarks", default=None,
                     help="JSON {\"landmarks\": {name: input vertex index}} carried to the "
                          "remesh")
    rem.add_argument("--mode", choices=("paper", "converged"), default="converged",
                     help="SEM mode (default converged)")
    rem.add_argument("--max-iter", type=int, default=None, help="SEM iteration cap")
    rem.add_argument("--solver", choices=("auto", "cholmod", "scipy"), default="auto")
    _add_intake_args(rem)
    rem.set_defaults(func=cmd_remesh)

    smp = sub.add_parser("sample", help="write the embedded synthetic face meshes")
    smp.add_argument("-o", "--out", required=True)
    smp.add_argument("--vertices", type=int, default=6000)
    smp.set_defaults(func=cmd_sample)
    return parser


def main(argv=None) -> int:
    from .stages.parameterize import ParameterizationFailed
    from .stages.register import RegistrationFailed

    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return UserError.exit_code
    except (ParameterizationFailed, RegistrationFailed) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
