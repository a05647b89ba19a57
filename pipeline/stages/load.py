"""Stage ``input`` — load and repair: a mesh file (or the embedded sample) to a clean disk mesh,
or to a clean closed genus-0 mesh (``RepairedMesh.closed``; parameterized onto the sphere).

Config: the ``input`` section (a mesh file, or the embedded synthetic face) and the ``repair``
section (:class:`~pipeline.geometry.repair.RepairOptions`). Makes the ``intake`` artifact.
Writes ``input/`` only for the embedded sample (its OBJs and landmarks, so the run is
reproducible outside the pipeline).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Optional

from pydantic import Field, model_validator

from ..geometry.repair import RepairedMesh, RepairOptions, repair_mesh
from ..io.artifacts import staged_output
from ..io.meshio import read_mesh
from .stage import Context, Section, Stage


class SampleInput(Section):
    vertices: int = Field(6000, ge=300, le=1_000_000)
    expression: Literal["neutral", "smile", "jawopen"] = "neutral"
    identity: int = 0


class InputConfig(Section):
    """Exactly one of ``mesh`` (a file, relative to the config's folder) or ``sample``."""

    mesh: Optional[str] = Field(None, description="OBJ, PLY, OFF, STL or MATLAB .mat (V/F) mesh")
    sample: Optional[SampleInput] = None

    @model_validator(mode="after")
    def _one_source(self):
        if (self.mesh is None) == (self.sample is None):
            raise ValueError("give exactly one of 'mesh' (a file) or 'sample' (the embedded face)")
        return self


@dataclass
class Intake:
    """The ``intake`` artifact: the repaired ``mesh`` and ``info`` on where it came from."""

    mesh: RepairedMesh
    info: dict = field(default_factory=dict)     # source, input counts, repair report, timings


def load_stage(path: str | Path, options: RepairOptions | None = None) -> Intake:
    """Read any supported mesh file and repair it into one disk or one closed genus-0 surface
    (see geometry.repair)."""
    t0 = time.perf_counter()
    raw = read_mesh(path)
    t1 = time.perf_counter()
    mesh = repair_mesh(raw.V, raw.faces, raw.colors, options or RepairOptions(),
                       name=Path(path).name)
    t2 = time.perf_counter()
    return Intake(mesh, {"source": str(path), "input_vertices": int(len(raw.V)),
                         "input_faces": int(raw.n_faces), "repair": mesh.report,
                         "repair_messages": mesh.messages,
                         "seconds": {"read": t1 - t0, "repair": t2 - t1}})


def sample_stage(n_vertices: int = 6000, expression: str = "neutral", identity: int = 0,
                 options: RepairOptions | None = None) -> Intake:
    """The embedded synthetic face (``pipeline.sample``), through the same repair checks."""
    from ..sample import make_face          # (scipy.interpolate: only a sample run needs it)

    t0 = time.perf_counter()
    face = make_face(n_vertices, expression=expression, identity=identity)
    mesh = repair_mesh(face.V, face.F, None, options or RepairOptions(), name=face.name)
    return Intake(mesh, {"source": f"synthetic sample '{face.name}'",
                         "input_vertices": int(len(face.V)), "input_faces": int(len(face.F)),
                         "landmarks": face.landmarks, "repair": mesh.report,
                         "repair_messages": mesh.messages,
                         "seconds": {"generate+repair": time.perf_counter() - t0}})


def _run(ctx: Context) -> dict:
    section, repair = ctx.section("input"), ctx.section("repair")
    if section.sample is not None:
        s = section.sample
        intake = sample_stage(s.vertices, s.expression, s.identity, repair)
    else:
        intake = load_stage(ctx.path(section.mesh), repair)
    for line in intake.mesh.messages:
        ctx.log(f"repair: {line}")
    return {"intake": intake}


def _write(ctx: Context, folder: Path) -> dict[str, Path]:
    from ..sample import write_sample

    sample = ctx.section("input").sample
    if sample is None:
        return {}
    with staged_output(folder) as tmp:
        names = write_sample(tmp, n_vertices=sample.vertices)
    return {key: folder / Path(p).name for key, p in names.items()}


def _summary(ctx: Context, files: dict) -> str:
    intake = ctx.artifacts["intake"]
    m = intake.mesh
    return (f"{intake.info['source']}: {len(m.V)} vertices, {len(m.F)} faces after repair"
            + (f" ({len(m.messages)} repairs, see metrics)" if m.messages else ""))


STAGE = Stage(name="input", section=InputConfig, run=_run, write=_write, makes=("intake",),
              extra_sections={"repair": RepairOptions}, input_files=("mesh",),
              mesh_files=("mesh",),
              positional=("mesh",), summary=_summary, command=False)
