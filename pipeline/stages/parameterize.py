"""Stage 2 — SEM disk parameterization of a repaired disk mesh, and its files.

Files (contract in ``shared/docs/DESIGN.md``):

* ``parameterization.npz`` — ``vertices`` n×3, ``faces`` m×3, ``uv`` n×2, ``boundary`` k,
  ``source_index`` n (input vertex of each vertex, −1 for vertices the repair added);
* ``parameterized.obj`` — the mesh with one ``vt`` per vertex (= uv);
* ``metrics.json`` — mesh and repair report, SEM status, §7.1 distortion measures, the energy
  and distortion of every iteration, time per phase;
* figures (paper Figs. 3, 4, 5, 7): ``disk_area_ratio.png``, ``area_ratio_histogram.png``,
  ``angle_histogram.png``, ``convergence.png``, ``surface_and_disk.png``;
* ``report.html`` — the metrics table and the figures (:mod:`pipeline.report.parameterize`).

A map with flipped faces is a failure: its ``metrics.json`` (status ``failed``), report and
figures are written for diagnosis, the map files are not, and :class:`ParameterizationFailed`
is raised.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry.metrics import distortion_summary
from ..geometry.repair import RepairedMesh
from ..errors import UserError
from ..geometry.sem import SEMOptions, SEMResult, stretch_energy_minimization
from ..geometry.solvers import NotPositiveDefinite
from ..io.artifacts import save_npz, staged_output, write_json
from ..io.meshio import write_obj
from .stage import Context, Stage


class ParameterizationFailed(RuntimeError):
    """SEM ended with flipped faces (exit code 1: the input is valid, the method failed)."""


@dataclass
class Parameterization:
    """A map of ``mesh`` onto its domain: the unit disk (``uv`` (n, 2), ``sphere`` None) or,
    for a closed genus-0 mesh, the unit sphere (``sphere`` (n, 3) unit vectors, ``uv`` None)."""

    mesh: RepairedMesh
    uv: np.ndarray | None
    sem: SEMResult
    options: SEMOptions
    metrics: dict = field(default_factory=dict)
    sphere: np.ndarray | None = None

    @property
    def domain(self) -> str:
        return "disk" if self.sphere is None else "sphere"

    @property
    def ok(self) -> bool:
        return self.sem.flipped_faces == 0


def parameterize_stage(mesh: RepairedMesh, options: SEMOptions | None = None,
                       progress=None) -> Parameterization:
    """Run SEM on the repaired mesh and measure the result (§7.1); a singular system (a mesh of
    a few faces) is a one-line :class:`UserError`."""
    options = options or SEMOptions()
    try:
        result = stretch_energy_minimization(mesh.V, mesh.F, mesh.boundary, options, progress)
    except NotPositiveDefinite as exc:
        interior = len(mesh.V) - len(mesh.boundary)
        raise UserError(f"SEM's linear system is singular on this mesh ({len(mesh.V)} vertices, "
                        f"{interior} interior; {exc}): a mesh this small or degenerate has no "
                        f"SEM map; pass a finer mesh") from None
    t0 = time.perf_counter()
    distortion = distortion_summary(mesh.V, mesh.F, result.uv)
    timings = dict(result.timings, metrics=time.perf_counter() - t0)
    metrics = {
        "status": "ok" if result.flipped_faces == 0 else "failed",
        "mesh": {"vertices": int(len(mesh.V)), "faces": int(len(mesh.F)),
                 "boundary_vertices": int(len(mesh.boundary)),
                 "added_vertices": int(len(mesh.added_vertices))},
        "parameterization": {"method": "SEM (Yueh et al. 2019, Algorithm 1)",
                             "mode": options.mode, "status": result.status,
                             "stop_reason": result.stop_reason, "steps": result.steps,
                             "iterations": result.iterations, "solver": result.solver,
                             "solver_stats": result.solver_stats,
                             "options": options.model_dump(), "harmonic": result.harmonic},
        "distortion": distortion,
        "history": result.history,
        "seconds": timings,
    }
    return Parameterization(mesh, result.uv, result, options, metrics)


def write_figures(p: Parameterization, folder: Path) -> list[Path]:
    """The paper's figures for this map (Figs. 3, 4, 5, 7) into ``folder``."""
    from ..report import parameterize as report

    return report.write_figures(folder, p.mesh.V, p.mesh.F, p.uv, p.sem.history)


def write_parameterization(p: Parameterization, out_dir: str | Path, extra_metrics: dict | None
                           = None, figures: bool = True) -> dict[str, Path]:
    """Write the stage's files into ``out_dir`` all-or-nothing; raise if the map failed."""
    from ..report import parameterize as report

    out_dir = Path(out_dir)
    metrics = dict(extra_metrics or {}, **p.metrics)
    written = {}
    t0 = time.perf_counter()
    with staged_output(out_dir) as tmp:
        if p.ok:
            m = p.mesh
            save_npz(tmp / "parameterization.npz", vertices=m.V, faces=m.F, uv=p.uv,
                     boundary=m.boundary, source_index=m.source_index)
            write_obj(tmp / "parameterized.obj", m.V, m.F, uv=p.uv, colors=m.colors,
                      header="SEM equiareal disk parameterization (sem-pipeline); vt = uv")
            written["npz"] = out_dir / "parameterization.npz"
            written["obj"] = out_dir / "parameterized.obj"
        figs = write_figures(p, tmp) if figures else []
        for path in figs:
            written[path.stem] = out_dir / path.name
        metrics["seconds"] = dict(metrics["seconds"], write=time.perf_counter() - t0)
        write_json(tmp / "metrics.json", metrics)
        written["metrics"] = out_dir / "metrics.json"
        report.write_report(tmp, metrics, [f.name for f in figs])
        written["report"] = out_dir / "report.html"
    if not p.ok:
        raise ParameterizationFailed(
            f"parameterization failed: {p.sem.flipped_faces} flipped faces remain after "
            f"{p.sem.iterations} iterations (status {p.sem.status}); see {out_dir / 'metrics.json'}")
    return written


def _run(ctx: Context) -> dict:
    intake = ctx.artifacts["intake"]
    return {"parameterization": parameterize_stage(intake.mesh, ctx.section("parameterize"),
                                                   ctx.progress())}


def _write(ctx: Context, folder: Path) -> dict[str, Path]:
    return write_parameterization(ctx.artifacts["parameterization"], folder,
                                  {"input": ctx.artifacts["intake"].info}, figures=ctx.figures)


def _summary(ctx: Context, files: dict) -> str:
    p = ctx.artifacts["parameterization"]
    d = p.metrics["distortion"]
    return (f"{p.metrics['mesh']['vertices']} vertices, {p.sem.iterations} iterations "
            f"({p.sem.status}), D(f) eq.28 = {d['total_area_distortion_eq28']:.5f}, "
            f"face area distortion = {d['face_area_distortion']:.5f}, "
            f"flipped faces = {d['flipped_faces']}, "
            f"{sum(p.metrics['seconds'].values()):.2f} s")


STAGE = Stage(name="parameterize", section=SEMOptions, run=_run, write=_write,
              needs=("intake",), makes=("parameterization",), uses=("report",),
              default_on=True, summary=_summary, help="SEM disk map of one mesh")
