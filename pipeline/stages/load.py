"""Stage 1 — load and repair: a mesh file (or the embedded sample) to a clean disk mesh."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from ..geometry.repair import RepairedMesh, RepairOptions, repair_mesh
from ..io.meshio import read_mesh
from ..sample import make_face


@dataclass
class Intake:
    mesh: RepairedMesh
    info: dict = field(default_factory=dict)     # source, input counts, repair report, timings


def load_stage(path: str | Path, options: RepairOptions | None = None) -> Intake:
    """Read any supported mesh file and repair it into one disk (see geometry.repair)."""
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
    t0 = time.perf_counter()
    face = make_face(n_vertices, expression=expression, identity=identity)
    mesh = repair_mesh(face.V, face.F, None, options or RepairOptions(), name=face.name)
    return Intake(mesh, {"source": f"synthetic sample '{face.name}'",
                         "input_vertices": int(len(face.V)), "input_faces": int(len(face.F)),
                         "landmarks": face.landmarks, "repair": mesh.report,
                         "repair_messages": mesh.messages,
                         "seconds": {"generate+repair": time.perf_counter() - t0}})
