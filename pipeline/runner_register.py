"""Runner glue for the ``register`` and ``morph`` config sections (used by ``runner.py`` and the
CLI): config models → stage options → stages → ``<run>/register/`` and ``<run>/morph/``."""

from __future__ import annotations

import sys
from pathlib import Path

from .config import Config, MorphConfig, RegisterConfig, resolve_path
from .geometry.repair import RepairOptions
from .geometry.sem import SEMOptions
from .stages.morph import MorphOptions, morph_stage, write_morph
from .stages.register import (Registration, RegisterOptions, display_faces, load_pair,
                              register_stage, sample_pair, write_registration)


def log_line(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def log_pair_messages(pair) -> None:
    """Every repair of either face and every landmark note, one stderr line each."""
    for face in (pair.source, pair.target):
        for line in face.mesh.messages:
            log_line(f"repair ({face.label}): {line}")
    for line in pair.messages:
        log_line(f"landmarks: {line}")


def sem_progress(label):
    from .runner import Progress
    return Progress(label)


def register_summary(reg: Registration) -> str:
    m = reg.metrics
    lr = m["landmark_residual"]
    parts = [f"{m['landmarks']['count']} landmarks",
             f"deformation {m['deformation']['method']}",
             f"flipped faces = {m['flipped_faces']}",
             f"landmark residual before {lr['before']['max']:.2e}"
             + (f", after {lr['after']['max']:.2e}" if lr["after"] else "")
             + " (max, × target diagonal)"]
    de = m.get("dense_error")
    if de:
        parts.append(f"dense error mean {de['ours']['mean']:.2e}, p95 {de['ours']['p95']:.2e}, "
                     f"max {de['ours']['max']:.2e}")
        if "nricp_amberg" in de:
            b = de["nricp_amberg"]
            parts.append(f"nricp_amberg mean {b['mean']:.2e}, p95 {b['p95']:.2e}, "
                         f"max {b['max']:.2e}")
    parts.append(f"{m['seconds']['ours_total']:.2f} s")
    return ", ".join(parts)


def register_from_config(rc: RegisterConfig, base: Path, repair: RepairOptions,
                         sem: SEMOptions) -> Registration:
    if rc.sample:
        pair = sample_pair(rc.sample_vertices, rc.sample_expression, repair)
    else:
        def p(v):
            return None if v is None else resolve_path(v, base).resolve()
        pair = load_pair(p(rc.source), p(rc.target), p(rc.source_landmarks),
                         p(rc.target_landmarks), rc.landmark_set, repair, p(rc.truth))
    log_pair_messages(pair)
    options = RegisterOptions(mobius=rc.mobius, energy=rc.energy, baseline=rc.baseline,
                              sem=sem)
    return register_stage(pair, options, progress=sem_progress, log=log_line)


def morph_options(mc: MorphConfig) -> MorphOptions:
    return MorphOptions(frames=mc.frames, easing=mc.easing, frame_ms=mc.frame_ms, size=mc.size)


def run_morph(reg: Registration, options: MorphOptions, out_dir: Path) -> dict:
    S = reg.pair.source.mesh
    m = morph_stage(S.V, reg.mapped, display_faces(S), options)
    return write_morph(m, out_dir)


def run_register_and_morph(config: Config, base: Path, run_dir: Path) -> dict:
    from .runner import repair_options, sem_options

    reg = register_from_config(config.register, base, repair_options(config),
                               sem_options(config))
    files = write_registration(reg, run_dir / "register", figures=config.report.figures)
    log_line(f"register: {register_summary(reg)}")
    stages = {"register": {k: str(v) for k, v in files.items()}}
    if config.morph is not None:
        files = run_morph(reg, morph_options(config.morph), run_dir / "morph")
        stages["morph"] = {k: str(v) for k, v in files.items()}
    return stages
