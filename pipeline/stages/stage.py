"""The stage interface: what every stage module declares, and what the runner gives it.

A stage module ends with one :class:`Stage` value, ``STAGE``, listed in
:mod:`pipeline.stages.registry`. It names

* its **config section** (a pydantic model: the one options object; the stage and its kernels
  receive it, or plain values taken from it, and nothing validates it again),
* the **artifacts** it needs (made by earlier stages) and makes (for later ones),
* its **run** step (compute, no files) and its **write** step (its folder, all-or-nothing),
* the keys of its section that name **input files** (checked before anything runs, made
  absolute and hashed by content in experiments),
* optionally a **check** of its request's resources (:mod:`pipeline.limits`), run as soon as
  the artifacts it needs exist, so an impossible request fails before the long stages run.

The runner (:mod:`pipeline.runner`) walks the registry for ``sem-pipeline run``, for every
per-stage subcommand and for every experiment item; the config schema, its checks and the
subcommands' flags are derived from the same declarations.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

from pydantic import BaseModel, ConfigDict

__all__ = ["Section", "Stage", "Context", "Progress"]


class Section(BaseModel):
    """Base of every config section: unknown keys are errors (``extra="forbid"``), and so are
    NaN and infinite numbers (``allow_inf_nan=False``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def _log_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


class Progress:
    """SEM progress callback: one stderr line at most every ``every`` seconds."""

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


@dataclass
class Context:
    """What a stage's run and write steps see.

    ``config`` is the validated run config (every section, so a stage can read the shared
    ``repair`` / ``parameterize`` / ``report`` options it declares in ``Stage.uses``);
    ``base`` the folder that relative input paths use; ``artifacts`` what earlier stages made.
    """

    config: Any
    base: Path
    label: str = "run"
    log: Callable[[str], None] = _log_stderr
    artifacts: dict = field(default_factory=dict)

    def section(self, name: str):
        return getattr(self.config, name)

    def progress(self, label: str | None = None) -> Progress:
        return Progress(label or self.label)

    def path(self, value: str | None) -> Optional[Path]:
        """An input path of the config, relative to ``base`` (``None`` stays ``None``)."""
        if value is None:
            return None
        p = Path(value).expanduser()
        return p if p.is_absolute() else self.base / p

    @property
    def figures(self) -> bool:
        return self.config.report.figures


@dataclass(frozen=True)
class Stage:
    """One pipeline stage (see the module docstring).

    Attributes
    ----------
    name : str
        Its config section, its output folder ``<run>/<name>/`` and its subcommand.
    section : type[Section]
        The section's model.
    run : callable
        ``run(ctx) -> dict`` of the artifacts named in ``makes``.
    write : callable
        ``write(ctx, folder) -> dict[str, Path]`` of the files written (all-or-nothing).
    needs, makes : tuple[str, ...]
        Artifact names read from and added to ``ctx.artifacts``.
    needs_when : callable or None
        ``needs_when(section) -> bool``: whether ``needs`` apply to this section (a stage that
        can also read its inputs from files, such as ``morph``); default: always.
    uses : tuple[str, ...]
        Other sections the stage reads (``repair``, ``parameterize``).
    extra_sections : dict
        Sections the stage owns besides its own (``input`` owns ``repair``).
    default_on : bool
        The section has a default and the stage runs whenever its needs are met
        (``parameterize``); otherwise it runs only when its section is given.
    input_files : tuple[str, ...]
        Keys of the section that name input files.
    mesh_files : tuple[str, ...]
        Those of ``input_files`` that name mesh files (their suffix is checked with the files).
    positional : tuple[str, ...]
        Keys of the section given as positional arguments of the subcommands that run this
        stage (``input.mesh`` → ``MESH``).
    summary : callable or None
        ``summary(ctx, files) -> str``: the stage's one-line result (the subcommand's closing
        line, the run index's overview).
    check : callable or None
        ``check(ctx) -> None``: refuse a request that cannot fit (a one-line ``UserError``
        from :func:`pipeline.limits.check_memory`) or a bad input file the stage reads, run
        before any stage computes when ``check_needs`` is empty, else as soon as the
        artifacts it names exist. It may keep what it read in ``ctx.artifacts`` for the run
        step.
    check_needs : tuple[str, ...]
        The artifacts ``check`` reads (``intake`` for a request relative to the mesh).
    command : bool
        Whether the stage has a subcommand of its own (``input`` has none: every subcommand
        that needs a mesh reads one).
    command_defaults : dict
        Defaults of the subcommand that differ from the sections' (``{"parameterize.mode":
        "auto"}``: the remesh subcommand maps with Algorithm 1's ten steps on the disk and in
        converged mode on the sphere unless asked).
    help : str
        The subcommand's one-line help.
    """

    name: str
    section: type[BaseModel]
    run: Callable[[Context], dict]
    write: Callable[[Context, Path], dict]
    needs: tuple[str, ...] = ()
    makes: tuple[str, ...] = ()
    needs_when: Optional[Callable[[Any], bool]] = None
    uses: tuple[str, ...] = ()
    extra_sections: dict = field(default_factory=dict)
    default_on: bool = False
    input_files: tuple[str, ...] = ()
    mesh_files: tuple[str, ...] = ()
    positional: tuple[str, ...] = ()
    summary: Optional[Callable[[Context, dict], str]] = None
    check: Optional[Callable[[Context], None]] = None
    check_needs: tuple[str, ...] = ()
    command: bool = True
    command_defaults: dict = field(default_factory=dict)
    help: str = ""

    def needs_for(self, section) -> tuple[str, ...]:
        if self.needs_when is None or self.needs_when(section):
            return self.needs
        return ()
