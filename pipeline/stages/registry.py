"""The stages in pipeline order, and which of them a config runs.

Adding a stage: write its module (config section model, run and write steps, ``STAGE``), add
it to :data:`STAGES` below, and document its keys in ``configs/<stage>.yaml``. The config
schema, the stage checks, the input-file keys and the subcommand's flags follow from here.
"""

from __future__ import annotations

from . import load, morph, parameterize, register, remesh
from .stage import Stage

STAGES: tuple[Stage, ...] = (load.STAGE, parameterize.STAGE, remesh.STAGE, register.STAGE,
                             morph.STAGE)


def stage(name: str) -> Stage:
    return next(s for s in STAGES if s.name == name)


def input_file_keys(stages: tuple[Stage, ...] = STAGES) -> tuple[str, ...]:
    """Every dotted config key that names an input file (``input.mesh``, ``register.source``…)."""
    return tuple(f"{s.name}.{k}" for s in stages for k in s.input_files)


def mesh_file_keys(stages: tuple[Stage, ...] = STAGES) -> tuple[str, ...]:
    """The dotted config keys that name a mesh file (``input.mesh``, ``register.source``…)."""
    return tuple(f"{s.name}.{k}" for s in stages for k in s.mesh_files)


def _a(name: str) -> str:
    return f"an '{name}'" if name[0] in "aeiou" else f"a '{name}'"


def maker(artifact: str, stages: tuple[Stage, ...] = STAGES) -> Stage:
    """The stage that makes ``artifact``."""
    return next(s for s in stages if artifact in s.makes)


def plan(config, stages: tuple[Stage, ...] = STAGES) -> list[Stage]:
    """The stages ``config`` runs, in order.

    A stage runs when its section is given (or has a default, ``default_on``) and every artifact
    it needs is made by a stage before it that runs. A given section whose needs are not met is
    an error naming the section to add; so is a config in which no stage runs.

    Raises
    ------
    ValueError
        With a one-line message naming the missing section.
    """
    made: set[str] = set()
    running: list[Stage] = []
    for s in stages:
        section = getattr(config, s.name)
        if section is None:
            continue
        missing = [n for n in s.needs_for(section) if n not in made]
        if not missing:
            running.append(s)
            made.update(s.makes)
        elif not s.default_on:
            root = _root_section(config, missing[0], stages)
            raise ValueError(f"'{s.name}' needs {_a(root)} section (for its {missing[0]})")
    if not any(not s.default_on for s in running):
        starts = [s.name for s in stages if not s.needs and not s.default_on]
        raise ValueError("give " + " or ".join(_a(n) for n in starts) + " section "
                         "(a stage that reads its own input)")
    return running


def _root_section(config, artifact: str, stages) -> str:
    """The section to add so that ``artifact`` gets made (through default-on stages)."""
    made_by = maker(artifact, stages)
    section = getattr(config, made_by.name)
    if section is not None and made_by.default_on:
        for need in made_by.needs_for(section):
            return _root_section(config, need, stages)
    return made_by.name
