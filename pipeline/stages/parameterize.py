"""Stage 2 — SEM parameterization of a repaired mesh onto its domain, and its files.

The domain (``parameterize.domain``, :func:`resolve_domain`): the unit disk for a disk mesh
(SEM, :mod:`pipeline.geometry.sem`), the unit sphere for a closed genus-0 mesh (spherical SEM,
:mod:`pipeline.geometry.sphere`); ``auto`` picks it from the repaired mesh's topology.

Files of a disk map (contract in ``shared/docs/DESIGN.md``):

* ``parameterization.npz`` — ``vertices`` n×3, ``faces`` m×3, ``uv`` n×2, ``boundary`` k,
  ``source_index`` n (input vertex of each vertex, −1 for vertices the repair added);
* ``parameterized.obj`` — the mesh with one ``vt`` per vertex (= uv);
* ``metrics.json`` — mesh and repair report, SEM status, §7.1 distortion measures, the energy
  and distortion of every iteration, time per phase;
* figures (paper Figs. 3, 4, 5, 7): ``disk_area_ratio.png``, ``area_ratio_histogram.png``,
  ``angle_histogram.png``, ``convergence.png``, ``surface_and_disk.png``;
* ``report.html`` — the metrics table and the figures (:mod:`pipeline.report.parameterize`).

Files of a spherical map:

* ``parameterization.npz`` — ``vertices`` n×3, ``faces`` m×3 (outward), ``sphere`` n×3 (unit
  vectors, every spherical triangle positively oriented) and ``source_index`` n; no ``uv``, no
  ``boundary``;
* ``parameterized.obj`` — the repaired surface (the vertex order and faces the map belongs to),
  and ``sphere.obj`` — the same faces on the unit sphere (vertex ``i`` at ``sphere[i]``), so a
  mesh viewer shows the map;
* ``metrics.json`` — as for the disk, with the measures against the geodesic triangle areas
  (:func:`pipeline.geometry.sphere_metrics.sphere_distortion_summary`), ``domain: "sphere"``
  and the kernel's own measures and start;
* figures: ``sphere_area_ratio.png``, ``area_ratio_histogram.png``, ``convergence.png``,
  ``surface_and_sphere.png``; ``report.html``.

Modes on the sphere (:func:`sphere_options`): ``converged`` runs :func:`spherical_sem` with its
defaults (Tutte start, free phase, then Gauss–Newton steps with a fold barrier until the energy
ratio is within 10⁻⁴ of its bound or stops falling; ``max_iter`` caps the Gauss–Newton
steps); ``paper`` runs only the alternating-hemisphere iterations of the published spherical
SEM, ``max_iter`` (default 10) of them, without the gradient phase: a quick map, as Algorithm 1
is on the disk. ``tol``, ``patience``, ``min_step`` and ``solver`` are passed on when given (the
section's defaults are the disk's, so ``tol``, ``patience`` and ``min_step`` only when set
explicitly), and ``free_iter``, the free phase's iterations before either, when not None (the
kernel's default: 10). ``auto``, the remesh's map, is paper mode with
``REMESH_SPHERE_STEPS`` iterations after ``REMESH_SPHERE_FREE_STEPS`` free ones
(:meth:`SEMOptions.for_domain`).

A map with flipped (folded) faces, or a disk map whose boundary image crosses itself (it wraps
part of the mesh twice with every face positive), is a failure: its ``metrics.json`` (status
``failed``), report and figures are written for diagnosis, the map files are not, and
:class:`ParameterizationFailed` is raised.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..geometry.metrics import distortion_summary
from ..geometry.repair import RepairedMesh
from ..errors import UserError
from ..geometry.sem import SEMOptions, SEMResult, stretch_energy_minimization
from ..geometry.solvers import NotPositiveDefinite
from ..io.artifacts import save_npz, staged_output, write_json
from ..io.meshio import write_obj
from .stage import Context, Stage

if TYPE_CHECKING:                  # the sphere's modules are imported when a sphere is mapped
    from ..geometry.sphere import SphereResult


class ParameterizationFailed(RuntimeError):
    """SEM ended with flipped faces or a self-crossing boundary (exit code 1: the input is
    valid, the method failed)."""


@dataclass
class Parameterization:
    """A map of ``mesh`` onto its domain: the unit disk (``uv`` (n, 2), ``sphere`` None) or,
    for a closed genus-0 mesh, the unit sphere (``sphere`` (n, 3) unit vectors, ``uv`` None)."""

    mesh: RepairedMesh
    uv: np.ndarray | None
    sem: SEMResult | SphereResult
    options: SEMOptions
    metrics: dict = field(default_factory=dict)
    sphere: np.ndarray | None = None

    @property
    def domain(self) -> str:
        return "disk" if self.sphere is None else "sphere"

    @property
    def image(self) -> np.ndarray:
        """The map itself: ``uv`` (n, 2) on the disk, ``sphere`` (n, 3) on the sphere."""
        return self.uv if self.sphere is None else self.sphere

    @property
    def flipped_faces(self) -> int:
        """Faces flipped on the disk, or folded on the sphere (``det[s0, s1, s2] ≤ 0``)."""
        if self.sphere is None:
            return self.sem.flipped_faces
        return self.sem.measures["folded_faces"]

    @property
    def boundary_self_crossings(self) -> int:
        """Pairs of boundary image edges that meet (disk only; see
        :func:`~pipeline.geometry.metrics.boundary_self_crossings`)."""
        return self.metrics.get("distortion", {}).get("boundary_self_crossings", 0)

    @property
    def ok(self) -> bool:
        """One-to-one: no flipped (folded) face and, on the disk, a simple boundary image."""
        return self.flipped_faces == 0 and self.boundary_self_crossings == 0

    @property
    def problem(self) -> str:
        """What makes the map fail, for error messages ('' when :attr:`ok`)."""
        if self.flipped_faces:
            what = "folded" if self.domain == "sphere" else "flipped"
            return f"{self.flipped_faces} {what} faces remain"
        if self.boundary_self_crossings:
            return (f"the boundary image crosses itself ({self.boundary_self_crossings} edge "
                    f"pairs meet): the map wraps part of the mesh around twice")
        return ""


def resolve_domain(domain: str, closed: bool, welded: int = 0) -> str:
    """The map's domain: ``"sphere"`` or ``"disk"`` (``domain`` is ``parameterize.domain``,
    ``closed`` whether the repaired mesh has no boundary, ``welded`` how many vertices the
    repair welded). ``auto`` follows the topology; a domain that does not fit the mesh is a
    one-line :class:`UserError` naming the fix."""
    if domain == "auto":
        return "sphere" if closed else "disk"
    if domain == "disk" and closed:
        seam = (f", or set repair.weld: false (--no-weld) to keep the seam that welding "
                f"{welded} vertices closed" if welded else "")
        raise UserError(f"parameterize.domain is 'disk' but the mesh is closed (no boundary); "
                        f"set --domain sphere (or auto) or cut the mesh open{seam}")
    if domain == "sphere" and not closed:
        raise UserError("parameterize.domain is 'sphere' but the mesh has a boundary (not "
                        "closed); set --domain disk (or auto) or pass a closed genus-0 mesh")
    return domain


def parameterize_stage(mesh: RepairedMesh, options: SEMOptions | None = None,
                       progress=None) -> Parameterization:
    """Map the repaired mesh onto its domain (:func:`resolve_domain`) and measure the result
    (§7.1); a singular system (a mesh of a few faces) is a one-line :class:`UserError`."""
    options = options or SEMOptions()
    welded = int(mesh.report.get("vertices_welded") or 0)
    domain = resolve_domain(options.domain, mesh.closed, welded)
    options = options.for_domain(domain)
    if domain == "sphere":
        return sphere_parameterization(mesh, options)
    try:
        result = stretch_energy_minimization(mesh.V, mesh.F, mesh.boundary, options, progress)
    except NotPositiveDefinite as exc:
        interior = len(mesh.V) - len(mesh.boundary)
        raise UserError(f"SEM's linear system is singular on this mesh ({len(mesh.V)} vertices, "
                        f"{interior} interior; {exc}): a mesh this small or degenerate has no "
                        f"SEM map; pass a finer mesh") from None
    t0 = time.perf_counter()
    distortion = distortion_summary(mesh.V, mesh.F, result.uv, mesh.boundary,
                                    result.surface_double_area)
    timings = dict(result.timings, metrics=time.perf_counter() - t0)
    metrics = {
        "status": "ok" if result.flipped_faces == distortion["boundary_self_crossings"] == 0
                  else "failed",
        "domain": "disk",
        "mesh": _mesh_counts(mesh),
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


def _mesh_counts(mesh: RepairedMesh) -> dict:
    return {"vertices": int(len(mesh.V)), "faces": int(len(mesh.F)),
            "boundary_vertices": int(len(mesh.boundary)),
            "added_vertices": int(len(mesh.added_vertices)), "closed": mesh.closed}


SPHERE_METHODS = {
    "hemisphere": "spherical SEM (alternating hemispheres, Yueh et al.)",
    "newton": "spherical stretch-energy minimization (Tutte start, alternating-hemisphere "
              "free phase, Gauss–Newton with a fold barrier)",
}


def sphere_options(options: SEMOptions) -> dict:
    """Keyword arguments of :func:`spherical_sem` for the ``parameterize`` section (see the
    module docstring: ``paper`` = hemisphere iterations only, ``max_iter`` default 10;
    ``converged`` = the kernel's defaults, ``max_iter`` caps the Gauss–Newton steps; explicit
    ``tol``/``patience``/``min_step`` passed, ``free_iter`` unless None)."""
    kw: dict = {"solver": options.solver}
    if options.mode == "paper":
        kw.update(method="hemisphere", max_iter=options.iterations(), gradient_iter=0,
                  cycles=1)
    elif options.max_iter is not None:
        kw["newton_iter"] = options.max_iter
    kw.update({k: getattr(options, k) for k in ("tol", "patience", "min_step")
               if k in options.model_fields_set})
    if options.free_iter is not None:
        kw["free_iter"] = options.free_iter
    return kw


def sphere_parameterization(mesh: RepairedMesh, options: SEMOptions) -> Parameterization:
    """The spherical SEM map of a closed genus-0 repaired mesh (outward faces) and its
    measures against the geodesic triangle areas."""
    from ..geometry.sphere import spherical_sem
    from ..geometry.sphere_metrics import sphere_distortion_summary

    kw = sphere_options(options)
    result = spherical_sem(mesh.V, mesh.F, **kw)
    if not np.array_equal(result.F, mesh.F):  # pragma: no cover - the repair orients outward
        raise RuntimeError("spherical SEM re-oriented the faces of a repaired mesh")
    t0 = time.perf_counter()
    distortion = sphere_distortion_summary(mesh.V, mesh.F, result.S)
    timings = dict(result.timings)
    total = timings.pop("total", sum(timings.values()))
    timings["setup"] = max(total - sum(timings.values()), 0.0)   # phases only: they add up
    timings["metrics"] = time.perf_counter() - t0
    metrics = {
        "status": "ok" if distortion["flipped_faces"] == 0 else "failed",
        "domain": "sphere",
        "mesh": _mesh_counts(mesh),
        "parameterization": {"method": SPHERE_METHODS[kw.get("method", "newton")],
                             "mode": options.mode, "status": result.status,
                             "iterations": result.iterations, "solver": options.solver,
                             "options": options.model_dump(), "kernel_options": kw,
                             "start": result.start, "sphere_measures": result.measures},
        "distortion": distortion,
        "history": result.history,
        "seconds": timings,
    }
    return Parameterization(mesh, None, result, options, metrics, sphere=result.S)


def write_figures(p: Parameterization, folder: Path) -> list[Path]:
    """The figures of this map into ``folder``: the paper's (Figs. 3, 4, 5, 7) for a disk, their
    spherical counterparts for a sphere."""
    from ..report import parameterize as report

    if p.domain == "sphere":
        return report.write_sphere_figures(folder, p.mesh.V, p.mesh.F, p.sphere, p.sem.history)
    return report.write_figures(folder, p.mesh.V, p.mesh.F, p.uv, p.sem.history)


def _write_map(p: Parameterization, tmp: Path, out_dir: Path) -> dict[str, Path]:
    """The map files (npz, OBJ) of either domain into ``tmp``; their final paths by key."""
    m = p.mesh
    if p.domain == "sphere":
        save_npz(tmp / "parameterization.npz", vertices=m.V, faces=m.F, sphere=p.sphere,
                 source_index=m.source_index)
        write_obj(tmp / "parameterized.obj", m.V, m.F, colors=m.colors,
                  header="closed genus-0 surface mapped to the unit sphere (sem-pipeline); "
                         "the map: sphere.obj, same vertex order")
        write_obj(tmp / "sphere.obj", p.sphere, m.F, colors=m.colors,
                  header="spherical SEM equiareal map (sem-pipeline): vertex i of "
                         "parameterized.obj on the unit sphere")
        names = {"npz": "parameterization.npz", "obj": "parameterized.obj",
                 "sphere": "sphere.obj"}
    else:
        save_npz(tmp / "parameterization.npz", vertices=m.V, faces=m.F, uv=p.uv,
                 boundary=m.boundary, source_index=m.source_index)
        write_obj(tmp / "parameterized.obj", m.V, m.F, uv=p.uv, colors=m.colors,
                  header="SEM equiareal disk parameterization (sem-pipeline); vt = uv")
        names = {"npz": "parameterization.npz", "obj": "parameterized.obj"}
    return {key: out_dir / name for key, name in names.items()}


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
            written.update(_write_map(p, tmp, out_dir))
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
            f"parameterization failed: {p.problem} after "
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
    return (f"{p.metrics['mesh']['vertices']} vertices on the {p.domain}, "
            f"{p.sem.iterations} iterations ({p.sem.status}), "
            f"D(f) eq.28 = {d['total_area_distortion_eq28']:.5f}, "
            f"face area distortion = {d['face_area_distortion']:.5f}, "
            f"{'folded' if p.domain == 'sphere' else 'flipped'} faces = {d['flipped_faces']}, "
            f"{sum(p.metrics['seconds'].values()):.2f} s")


STAGE = Stage(name="parameterize", section=SEMOptions, run=_run, write=_write,
              needs=("intake",), makes=("parameterization",), uses=("report",),
              default_on=True, summary=_summary,
              help="SEM equiareal map of one mesh onto the disk (open) or the sphere (closed)")
