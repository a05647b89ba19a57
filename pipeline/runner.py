"""The runner: a validated config → the stages it names (:func:`pipeline.stages.registry.plan`)
→ their folders, for ``sem-pipeline run``, every per-stage subcommand and every experiment item.
"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path
from typing import Callable

from . import __version__
from .io.artifacts import write_json
from .stages.registry import plan
from .stages.stage import Context, _log_stderr


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
    for stage in plan(config):
        t0 = time.perf_counter()
        ctx.artifacts.update(stage.run(ctx))
        folder = folders(stage.name)
        if folder is not None:
            written = stage.write(ctx, Path(folder))
            if written:
                files[stage.name] = written
        seconds[stage.name] = time.perf_counter() - t0
    return ctx, files, seconds


def run_config(config, base: Path, out_root: str | Path | None = None) -> Path:
    """``sem-pipeline run``: every stage into ``<out_root>/<run.name>/<stage>/``, then the run's
    ``index.html`` and ``manifest.json`` (config snapshot, versions, files, timings). Returns the
    run folder."""
    from .report.index import write_run_index

    run_dir = Path(out_root) if out_root else Path(config.run.out_dir)   # relative to the cwd
    run_dir = run_dir / config.run.name
    t0 = time.perf_counter()
    ctx, files, seconds = run_stages(config, base, lambda name: run_dir / name, config.run.name)
    write_json(run_dir / "manifest.json", {
        "config": config.model_dump(), "versions": versions(),
        "stages": {name: {k: str(v) for k, v in f.items()} for name, f in files.items()},
        "stage_seconds": seconds, "seconds": time.perf_counter() - t0})
    summaries = {s.name: s.summary(ctx, files.get(s.name, {})) for s in plan(config)
                 if s.summary is not None}
    write_run_index(run_dir, files, config.run.name, summaries, seconds)
    return run_dir
