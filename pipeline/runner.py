"""Runner: a validated config → the stages it names → ``<out_dir>/<run name>/`` with a manifest."""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

from . import __version__
from .config import Config, resolve_path
from .geometry.repair import RepairOptions
from .geometry.sem import SEMOptions
from .io.artifacts import staged_output, write_json
from .sample import write_sample
from .stages.load import load_stage, sample_stage
from .stages.parameterize import parameterize_stage, write_parameterization


def versions() -> dict:
    out = {"sem-pipeline": __version__, "python": platform.python_version()}
    for name in ("numpy", "scipy", "trimesh", "sksparse", "pydantic", "yaml", "matplotlib"):
        module = sys.modules.get(name)
        if module is None:
            try:
                module = __import__(name)
            except ImportError:
                continue
        out[name] = getattr(module, "__version__", "?")
    return out


def repair_options(config: Config) -> RepairOptions:
    return RepairOptions(**config.repair.model_dump())


def sem_options(config: Config) -> SEMOptions:
    return SEMOptions(**config.parameterize.model_dump())


class Progress:
    """One line on stderr at most every ``every`` seconds while SEM iterates."""

    def __init__(self, label: str, every: float = 2.0, stream=None):
        # sys.stderr looked up now, not at import: an experiment item's log captures it.
        stream = sys.stderr if stream is None else stream
        self.label, self.every, self.stream, self.last = label, every, stream, 0.0

    def __call__(self, entry: dict) -> None:
        now = time.perf_counter()
        if now - self.last >= self.every:
            self.last = now
            print(f"{self.label}: iteration {entry['iteration']:4d} ({entry['phase']}), "
                  f"E_S/bound − 1 = {entry['energy_ratio'] - 1:.3e}, "
                  f"D(f) = {entry['total_area_distortion_eq28']:.5f}, "
                  f"flipped = {entry['flipped_faces']}", file=self.stream, flush=True)


def run_config(config: Config, base: Path, out_root: str | Path | None = None) -> Path:
    """Run every stage the config configures; returns the run folder."""
    run_dir = Path(out_root) if out_root else Path(config.run.out_dir)   # relative to the cwd
    run_dir = run_dir / config.run.name
    t0 = time.perf_counter()
    stages = {}
    if config.input is not None:
        if config.input.sample is not None:
            s = config.input.sample
            intake = sample_stage(s.vertices, s.expression, s.identity, repair_options(config))
            with staged_output(run_dir / "input") as tmp:
                write_sample(tmp, n_vertices=s.vertices)
        else:
            intake = load_stage(resolve_path(config.input.mesh, base), repair_options(config))
        for line in intake.mesh.messages:
            print(f"repair: {line}", file=sys.stderr)
        p = parameterize_stage(intake.mesh, sem_options(config), Progress(config.run.name))
        files = write_parameterization(p, run_dir / "parameterize", {"input": intake.info},
                                       figures=config.report.figures)
        stages["parameterize"] = {k: str(v) for k, v in files.items()}
        if config.remesh is not None:
            from .runner_remesh import run_remesh
            files, _ = run_remesh(config.remesh, intake, p, run_dir / "remesh", base,
                                  figures=config.report.figures)
            stages["remesh"] = {k: str(v) for k, v in files.items()}
    if config.register is not None:
        from .runner_register import run_register_and_morph
        stages.update(run_register_and_morph(config, base, run_dir))
    write_json(run_dir / "manifest.json", {
        "config": config.model_dump(), "versions": versions(),
        "stages": stages,
        "seconds": time.perf_counter() - t0})
    return run_dir
