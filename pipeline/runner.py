"""The runner: a validated config → the stages it names (:func:`pipeline.stages.registry.plan`)
→ their folders, for ``sem-pipeline run``, every per-stage subcommand and every experiment item.

``run`` and the subcommands write through :func:`pipeline.io.outputs.output_folder`: the output
folder is checked before any stage computes (location, free space, inputs inside it), locked
for the run, built beside and swapped in whole when the run ends, so it always holds one
complete run. A run whose method failed (exit code 1) is complete too: its diagnosis replaces
the previous result; bad input, a full disk or an interruption leave the previous result.
An experiment item is written by :func:`write_run` into its own staging folder.
"""

from __future__ import annotations

import platform
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from . import __version__
from .io.artifacts import write_json
from .io.outputs import output_folder
from .geometry.remesh import RemeshFailed
from .stages.parameterize import ParameterizationFailed
from .stages.register import RegistrationFailed
from .stages.registry import plan
from .stages.stage import Context, _log_stderr

# A method that failed on valid input writes its diagnosis: the run's complete result.
METHOD_FAILURES = (ParameterizationFailed, RemeshFailed, RegistrationFailed)


#: the packages whose versions a run records: import name → distribution name
VERSIONED = {"numpy": "numpy", "scipy": "scipy", "trimesh": "trimesh", "sksparse": "scikit-sparse",
             "pydantic": "pydantic", "yaml": "PyYAML", "matplotlib": "matplotlib"}


def versions() -> dict:
    """The versions of Python, sem-pipeline and :data:`VERSIONED` (absent ones left out), read
    from the installed distributions' metadata: a run that draws no figure never imports
    matplotlib just to name its version."""
    from importlib import metadata

    out = {"sem-pipeline": __version__, "python": platform.python_version()}
    for name, dist in VERSIONED.items():
        module = sys.modules.get(name)
        if module is not None and hasattr(module, "__version__"):
            out[name] = module.__version__
            continue
        try:
            out[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    return out


def run_stages(config, base: Path, folders: Callable[[str], Path | None], label: str = "run",
               log: Callable[[str], None] = _log_stderr) -> tuple[Context, dict, dict]:
    """Run every stage of ``config`` in order; write stage ``s`` into ``folders(s.name)``
    (``None``: not written). Returns ``(context, {stage: {key: path}}, {stage: seconds})``.

    A stage's write step runs right after its run step, so a failing stage (a folded map, an
    exit code 1) leaves the files of the stages before it and its own diagnosis.
    """
    ctx = Context(config, Path(base), label, log)
    files: dict[str, dict] = {}
    seconds: dict[str, float] = {}
    stages = plan(config)
    pending = [s for s in stages if s.check is not None]
    _run_checks(ctx, pending)
    for stage in stages:
        t0 = time.perf_counter()
        ctx.artifacts.update(stage.run(ctx))
        _run_checks(ctx, pending)
        folder = folders(stage.name)
        if folder is not None:
            written = stage.write(ctx, Path(folder))
            if written:
                files[stage.name] = written
        seconds[stage.name] = time.perf_counter() - t0
    return ctx, files, seconds


def _run_checks(ctx: Context, pending: list) -> None:
    """Run (and drop from ``pending``) the stage checks whose artifacts exist now."""
    for stage in list(pending):
        if all(a in ctx.artifacts for a in stage.check_needs):
            stage.check(ctx)
            pending.remove(stage)


def input_paths(config, base: Path) -> list[Path]:
    """Every file or folder the stages of ``config`` read: the values of their input-file and
    positional keys (a positional key may hold a list)."""
    ctx = Context(config, Path(base))
    out = []
    for stage in plan(config):
        section = ctx.section(stage.name)
        for key in dict.fromkeys(stage.input_files + stage.positional):
            value = getattr(section, key)
            for v in value if isinstance(value, list) else [value]:
                if v is not None:
                    out.append(ctx.path(v))
    return out


def space_needed(inputs: list[Path], n_stages: int) -> int:
    """A lower bound of the outputs' size: twice the inputs' bytes (meshes written again with
    their maps) and 1 MiB of reports per stage."""
    total = 0
    for p in inputs:
        try:
            files = [p] if p.is_file() else [q for q in p.iterdir() if q.is_file()]
            total += sum(q.stat().st_size for q in files)
        except OSError:
            continue
    return 2 * total + n_stages * (1 << 20)


def _moved(files: dict, build: Path, shown: Path) -> dict:
    """The paths of ``files`` (written below ``build``) as they are after the swap."""
    return {k: Path(shown) / Path(v).relative_to(build) for k, v in files.items()}


@contextmanager
def _output(config, base: Path, out: str | Path, command: str, flag: str, extra_inputs=()):
    """:func:`~pipeline.io.outputs.output_folder` for a run of ``config`` into ``out``; a method
    failure's message names ``out``, not the build folder."""
    inputs = input_paths(config, base) + list(extra_inputs)
    build = None
    try:
        with output_folder(out, space_needed(inputs, len(plan(config))), inputs, command,
                           flag, keep_on=METHOD_FAILURES) as build:
            yield build
    except METHOD_FAILURES as exc:
        if build is None:
            raise
        raise type(exc)(str(exc).replace(str(build), str(out))) from None


def run_command(config, stage_name: str, out: str | Path, label: str) -> tuple[Context, dict]:
    """A stage's subcommand: the stages of ``config`` (inputs relative to the working
    directory), only ``stage_name`` written, into ``out`` as a whole. Returns the context and
    the stage's files."""
    base = Path.cwd()
    with _output(config, base, out, stage_name, "-o") as build:
        ctx, files, _ = run_stages(config, base,
                                   lambda name: build if name == stage_name else None, label)
    return ctx, _moved(files.get(stage_name, {}), build, Path(out))


def run_config(config, base: Path, out_root: str | Path | None = None,
               config_file: str | Path | None = None) -> Path:
    """``sem-pipeline run``: the run folder ``<out_root>/<run.name>/`` (default root:
    ``run.out_dir``, relative to the working directory) written as a whole by
    :func:`write_run`. ``config_file`` is an input too (it must not be inside the run folder).
    Returns the run folder."""
    root = Path(config.run.out_dir) if out_root is None else Path(out_root)
    run_dir = root / config.run.name
    extra = [Path(config_file)] if config_file else []
    with _output(config, base, run_dir, "run", "run folder", extra) as build:
        write_run(config, base, build, shown=run_dir)
    return run_dir


def write_run(config, base: Path, run_dir: Path, shown: Path | None = None) -> None:
    """Every stage into ``<run_dir>/<stage>/``, then the run's ``index.html`` and
    ``manifest.json`` (config snapshot, versions, files as they are named at ``shown``,
    default ``run_dir``, timings)."""
    from .report.index import write_run_index

    t0 = time.perf_counter()
    ctx, files, seconds = run_stages(config, base, lambda name: run_dir / name, config.run.name)
    named = {name: _moved(f, run_dir, shown or run_dir) for name, f in files.items()}
    write_json(run_dir / "manifest.json", {
        "config": config.model_dump(), "versions": versions(),
        "stages": {name: {k: str(v) for k, v in f.items()} for name, f in named.items()},
        "stage_seconds": seconds, "seconds": time.perf_counter() - t0})
    summaries = {s.name: s.summary(ctx, files.get(s.name, {})) for s in plan(config)
                 if s.summary is not None}
    write_run_index(run_dir, files, config.run.name, summaries, seconds)
