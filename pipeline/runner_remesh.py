"""Runner glue for the ``remesh`` config section and ``sem-pipeline remesh`` (used by
``runner.py`` and the CLI): config model → :class:`RemeshOptions` → remesh stage → report →
``<run>/remesh/`` (or the CLI's ``-o DIR``)."""

from __future__ import annotations

import sys
from pathlib import Path

from .config import RemeshConfig, resolve_path
from .stages.remesh import RemeshOptions, map_landmarks, read_landmarks, remesh_stage


def remesh_options(rc: RemeshConfig) -> RemeshOptions:
    """The stage's options from the config section; ``improve: false`` is the paper's plain
    lift (no improvement, no corner snapping)."""
    imp = rc.improve
    base = dict(vertices=rc.vertices, spacing=rc.spacing, pattern=rc.pattern,
                rim_relax=rc.rim_relax, seed=rc.seed)
    if imp is None:
        return RemeshOptions(**base, improve=False, corner_angle_deg=0.0)
    return RemeshOptions(**base, improve=True, flips=imp.flips,
                         relax_iterations=imp.relax_iterations, relax_step=imp.relax_step,
                         max_dihedral_deg=imp.max_dihedral_deg, refine_sag=imp.refine_sag,
                         refine_budget=imp.refine_budget, corner_angle_deg=imp.corner_angle_deg)


def remesh_summary(r, metrics: dict) -> str:
    sem = metrics["methods"]["sem"]
    t = sem["triangles"]
    d = sem.get("distance", {})
    return (f"{len(r.V)} vertices, {len(r.F)} faces, "
            f"{'one disk' if sem['is_disk'] else 'NOT a disk'}, "
            f"min angle {t['min_angle_deg']:.1f}°, mean smallest angle "
            f"{t['mean_min_angle_deg']:.1f}°, Hausdorff {100 * d.get('hausdorff_rel', 0):.3f} % "
            f"of the diagonal, {r.seconds['total']:.2f} s")


def run_remesh(rc: RemeshConfig, intake, parameterization, out_dir, base: Path | None = None,
               figures: bool = True, log=None) -> tuple[dict, dict]:
    """Remesh the intake's mesh through the map and write the stage's files into
    ``out_dir``. Landmarks: ``rc.landmarks`` (a JSON file, relative to ``base``) or those of
    the embedded sample. Returns ``(files, metrics)``."""
    from .stages.remesh import remesh_outputs

    log = log or (lambda line: print(line, file=sys.stderr, flush=True))
    mesh = intake.mesh
    if rc.landmarks is not None:
        path = resolve_path(rc.landmarks, base) if base is not None else Path(rc.landmarks)
        landmarks = read_landmarks(path, mesh)
    elif intake.info.get("landmarks"):
        landmarks = map_landmarks(intake.info["landmarks"], mesh, "sample landmarks")
    else:
        landmarks = {}
    r = remesh_stage(mesh, parameterization.uv, remesh_options(rc), landmarks)
    files, metrics = remesh_outputs(mesh, parameterization, r, out_dir, intake.info,
                                    compare=rc.compare, report=rc.report, figures=figures,
                                    n_random=rc.distance_samples,
                                    progress=lambda msg: log(f"remesh: {msg}"))
    log(f"remesh: {remesh_summary(r, metrics)}")
    for warning in metrics["warnings"]:
        log(f"remesh: warning: {warning}")
    return files, metrics
