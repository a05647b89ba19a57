"""Stage 3 — uniform remeshing through the SEM map (paper §8): the repaired mesh and its
bijective disk map (or, for a closed genus-0 mesh, sphere map) in, a remesh of the requested
size out.

The algorithm — sample → triangulate → locate → lift → improve, landmarks to the nearest new
vertex — is :func:`pipeline.geometry.remesh.uniform_remesh` on the disk and
:func:`pipeline.geometry.remesh.sphere.sphere_remesh` on the sphere (the stage dispatches on the
map's domain). This stage checks the options and the map, lifts the per-vertex attributes
(colours and any given), and writes ``remeshed.obj`` (``v`` with colours if the input had
them; on the disk ``vt`` = the new vertices' disk positions, so the output is parameterized
too; on the sphere no ``vt``, a texture coordinate being 2D — the remesh is closed, genus 0),
``remesh_metrics.json``,
``remeshed_landmarks.json`` when there are landmarks, and ``report.html`` with its figures
(:mod:`pipeline.report.remesh`), all-or-nothing (:func:`remesh_outputs`).

Improvement is on by default: the plain lift of equilateral disk triangles is skewed by the
map's angle distortion, and across the slivers the map squeezes long protrusions into, its
edges leave the surface; the improvement pass fixes both while keeping the vertex count. Turn
it off (``improve: false``, ``--no-improve``) for the paper's plain lift.

Where the intake closed holes (``close_holes``: eyes, mouth), the remesh keeps them open
(``keep_holes``, with the improvement pass; :mod:`pipeline.geometry.remesh.holes`), and the
measures and baselines take the input with its holes open (:func:`..geometry.repair.open_mesh`);
``keep_holes: false`` (``--cover-holes``) covers them with the fans' surface, with a warning.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..errors import UserError
from ..geometry.locate import lift
from ..geometry.metrics import boundary_self_crossings, signed_double_areas
from ..geometry.remesh import PATTERNS, DiskSamples, uniform_remesh
from ..geometry.remesh.features import FOLD_BACK_DEG
from ..geometry.remesh_quality import DISTANCE_SAMPLES
from ..geometry.repair import RepairedMesh, open_mesh
from .stage import Context, Section, Stage

__all__ = ["RemeshConfig", "ImproveConfig", "Remesh", "remesh_stage", "read_landmarks",
           "write_remesh", "compare_methods", "remesh_outputs"]


class ImproveConfig(Section):
    """Quality pass after lifting; ``improve: false`` turns it off (the paper's plain lift),
    ``improve: true`` means these defaults."""

    flips: bool = True                       # Delaunay flips on the lifted surface
    relax_iterations: int = Field(2, ge=0, le=50)     # tangential relaxation steps
    relax_step: float = Field(1.0, gt=0.0, le=1.0)
    max_dihedral_deg: float = Field(20.0, ge=0.0, le=90.0)   # flip only flatter quads
    refine_sag: float = Field(0.2, ge=0.0)   # split edges farther than this × spacing from
    refine_budget: float = Field(0.3, ge=0.0, le=1.0)   # the surface (≤ this × vertices)
    corner_angle_deg: float = Field(30.0, ge=0.0)   # keep input corners sharper than this (at L)
    isotropic_iterations: int = Field(4, ge=0, le=50)   # split/collapse/flip/relax rounds
    final_relax_iterations: int = Field(6, ge=0, le=50)   # relax + flips after the count
    pinned_relax_iterations: int = Field(2, ge=0, le=50)  # after the second sag refinement
    min_angle_deg: float = Field(20.0, ge=0.0, le=40.0)   # the last pass's minimum angle
    follow_input: float = Field(0.25, ge=0.0)   # a vertex on input points (vertices, edge and
                                                # face middles) farther than this × spacing
                                                # from the remesh, 0.8 × this where a disk's
                                                # input has fewer vertices than asked (0: none)
    feature_angle_deg: float = Field(FOLD_BACK_DEG, ge=0.0, le=180.0)   # vertices and edges
                                                # kept along input edges folded more than this
                                                # (0: none; disk maps only)
    fit_surface: bool = True                    # vertices offset along their normals to
                                                # the least-squares fit of the input (at most
                                                # 0.1 × spacing); false: every vertex on it


MIN_VERTICES = 100          # fewer cannot cover a disk with a lattice and its rim


class RemeshConfig(Section):
    """Uniform remeshing through the SEM map (``configs/remesh.yaml``). Give ``vertices`` or
    ``spacing`` (target edge length in the mesh's units)."""

    vertices: Optional[int] = Field(None, ge=MIN_VERTICES, le=5_000_000,
                                    description="vertex count of the remesh")
    spacing: Optional[float] = Field(None, gt=0.0, description="or: target edge length in the "
                                                               "mesh's units")
    pattern: Literal[PATTERNS] = Field(
        "jittered", description="sampling pattern (on the sphere: jittered or hexagonal, the "
                                "Fibonacci lattice with or without seeded offsets)")
    rim_relax: int = Field(3, ge=0, le=50, description="ODT sweeps of the lattice band along "
                                                       "the rim")
    seed: int = Field(0, description="jittered and blue noise seed")
    improve: Optional[ImproveConfig] = Field(
        ImproveConfig(), description="the quality pass (off: the paper's plain lift)",
        json_schema_extra={"nested_flags": True})          # --min-angle-deg, --no-flips, ...
    compare: bool = Field(True, description="measure the plain lift, pymeshlab and decimation "
                                            "at the same vertex count beside ours")
    report: bool = Field(True, description="report.html and figures")
    landmarks: Optional[str] = Field(
        None, description="landmark file carried to the remesh (as register's: JSON, CSV or "
                          "TXT; 0-based input vertex indices or x y z points)")
    landmark_set: Optional[str] = Field(
        None, description="JSON key of the landmark set, e.g. ibug68 (default 'landmarks')")
    exact_landmarks: bool = Field(
        False, description="a locked remesh vertex exactly on each interior landmark (else the "
                           "nearest vertex; the triangles around a locked one pay for it)")
    keep_holes: bool = Field(
        True, description="the holes the intake's close_holes filled stay open, their rims "
                          "followed (with the improvement pass); --cover-holes: the fans' "
                          "surface covers them instead",
        json_schema_extra={"flag": "--cover-holes"})
    distance_samples: int = Field(DISTANCE_SAMPLES, ge=1000,
                                  description="random samples per surface for the distances")

    @field_validator("improve", mode="before")
    @classmethod
    def _improve_flag(cls, v):
        if v is True:
            return {}
        if v is False:
            return None
        return v

    @model_validator(mode="after")
    def _count_or_spacing(self):
        if (self.vertices is None) == (self.spacing is None):
            raise ValueError("give exactly one of 'vertices' (a count) or 'spacing' (a target "
                             "edge length in the mesh's units)")
        if self.landmark_set is not None and self.landmarks is None:
            raise ValueError(f"landmark_set '{self.landmark_set}' names a set in a landmarks "
                             f"file, but no landmarks file is given; give one (--landmarks) "
                             f"or drop the set")
        return self


@dataclass
class Remesh:
    """The remeshed disk and what is needed to report on it."""

    V: np.ndarray                      # n×3 lifted positions (after improvement if on)
    F: np.ndarray                      # m×3, CCW in the domain, consistently oriented
    uv: np.ndarray                     # n×2 disk (or n×3 sphere) positions of the new vertices
    face: np.ndarray                   # n: input face under each new vertex
    bary: np.ndarray                   # n×3: its barycentrics (eq. 1)
    colors: np.ndarray | None
    samples: DiskSamples
    lifted: tuple                      # (V, F) straight after lifting, before improvement
    landmarks: dict = field(default_factory=dict)  # {name: {input_vertex (of the input file;
    #                                      −1: added by the repair), vertex, distance}}
    info: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)   # remesh_metrics.json, once written
    facts: dict = field(default_factory=dict)     # mesh_facts of (V, F), as checked
    input_distance: object = None      # the input's MeshDistance, if the remesher built one


def _check_map(mesh: RepairedMesh, uv: np.ndarray) -> None:
    if uv.ndim != 2 or uv.shape[0] != len(mesh.V) or uv.shape[1] not in (2, 3):
        raise UserError(f"remesh: the map has shape {uv.shape}, expected {len(mesh.V)}×2 (a "
                        f"disk) or {len(mesh.V)}×3 (a sphere)")
    if uv.shape[1] == 2:
        flipped = int(np.count_nonzero(signed_double_areas(uv, mesh.F) <= 0))
    else:
        from ..geometry.sphere import folded_faces

        flipped = folded_faces(uv, _outward(mesh.F, uv))
    if flipped:
        raise UserError(f"remesh: the {'disk' if uv.shape[1] == 2 else 'sphere'} map has "
                        f"{flipped} flipped faces; remeshing needs a bijective map "
                        f"(parameterize with mode 'converged')")
    if uv.shape[1] == 2 and (crossings := boundary_self_crossings(uv, mesh.boundary)):
        raise UserError(f"remesh: the disk map's boundary image crosses itself ({crossings} "
                        f"edge pairs meet), so it wraps part of the mesh twice; remeshing needs "
                        f"a bijective map (parameterize with mode 'converged')")


def _check_sphere_pattern(pattern: str) -> None:
    """Refuse a sampling pattern that has no sphere version (a closed mesh's remesh samples
    the sphere, :data:`..geometry.remesh.sphere.SPHERE_PATTERNS`)."""
    from ..geometry.remesh.sphere import SPHERE_PATTERNS

    if pattern not in SPHERE_PATTERNS:
        raise UserError(f"remesh: pattern '{pattern}' has no sphere version (the mesh is "
                        f"closed); use one of {', '.join(SPHERE_PATTERNS)}")


def _outward(F: np.ndarray, S: np.ndarray) -> np.ndarray:
    """The faces ``F`` ordered so that the sphere map ``S`` (n×3) turns them outward
    (``det[s0, s1, s2] > 0``): reversed when most of them are inward (a mesh oriented
    inward)."""
    from ..geometry.sphere import triple_products

    inward = np.count_nonzero(triple_products(S, F) < 0) > len(F) / 2
    return np.ascontiguousarray(F[:, ::-1]) if inward else F


def remesh_stage(mesh: RepairedMesh, uv: np.ndarray, options: RemeshConfig,
                 landmarks: dict | None = None, attributes: dict | None = None) -> Remesh:
    """Remesh a repaired disk through its bijective disk map ``uv`` (n×2), or a closed genus-0
    mesh through its bijective sphere map (``uv`` n×3 unit vectors; see the module docstring).

    ``landmarks``: ``{name: vertex index of the repaired mesh}``. ``attributes``: extra
    per-vertex arrays to lift (colours are taken from the mesh); their lifted values are in
    ``Remesh.info['attributes']``.

    With a requested count, the improvement ends by splitting or collapsing edges until the
    count is the request again (usually exactly).
    """
    uv = np.asarray(uv, dtype=np.float64)
    _check_map(mesh, uv)
    # improve: null is the paper's plain lift: no improvement and no corner snapping
    imp = options.improve or ImproveConfig(corner_angle_deg=0.0)
    F = mesh.F
    if uv.shape[1] == 3:
        from ..geometry.remesh.sphere import sphere_remesh

        _check_sphere_pattern(options.pattern)
        F = _outward(mesh.F, uv)
        r = sphere_remesh(mesh.V, F, uv, vertices=options.vertices, spacing=options.spacing,
                          improve=options.improve is not None, landmarks=landmarks,
                          exact_landmarks=options.exact_landmarks,
                          pattern=options.pattern, seed=options.seed, **imp.model_dump())
    else:
        holes = keeps_holes(mesh, options)
        r = uniform_remesh(mesh.V, mesh.F, uv, mesh.boundary, vertices=options.vertices,
                           spacing=options.spacing, pattern=options.pattern,
                           rim_relax=options.rim_relax, seed=options.seed,
                           improve=options.improve is not None, landmarks=landmarks,
                           exact_landmarks=options.exact_landmarks, **imp.model_dump(),
                           **({"hole_loops": mesh.hole_loops(), "fans": mesh.fan_faces()}
                              if holes else {}))
    t = time.perf_counter()
    colors = lift(mesh.colors, F, r.face, r.bary) if mesh.colors is not None else None
    lifted_attrs = {k: lift(v, F, r.face, r.bary) for k, v in (attributes or {}).items()}
    sec = dict(r.seconds, attributes=time.perf_counter() - t)
    sec["total"] = sum(sec.values())
    info = {"requested_vertices": options.vertices, "requested_spacing": options.spacing,
            **r.info, "attributes": lifted_attrs}
    return Remesh(r.V, r.F, r.uv, r.face, r.bary, colors, r.samples, r.lifted,
                  _input_file_vertices(r.landmarks, mesh.source_index), info, sec,
                  facts=r.facts, input_distance=r.input_distance)


def lifted_note(info: dict) -> str:
    """The plain lift's note where the remesh kept holes open (``info["holes_kept"]``)."""
    if not info.get("holes_kept"):
        return ""
    return ("its faces whose disk centroid lies in a hole kept open are left out; with no "
            "vertices on the holes' loops, its hole rims run along its own edges, across "
            "the input's")


def keeps_holes(mesh: RepairedMesh, options: RemeshConfig) -> bool:
    """Whether the remesh of ``mesh`` keeps the holes its repair closed open: there are some,
    ``keep_holes`` is on and so is the improvement pass (which places their rims)."""
    return bool(mesh.closed_holes) and options.keep_holes and options.improve is not None


def _input_file_vertices(carried: dict, source_index: np.ndarray) -> dict:
    """The carried landmarks (:func:`pipeline.geometry.remesh.landmarks.carry_landmarks`, whose
    ``input_vertex`` is a vertex of the repaired mesh) with ``input_vertex`` the input file's
    vertex instead (``source_index``; −1 for a vertex the repair added)."""
    return {name: dict(d, input_vertex=int(source_index[d["input_vertex"]]))
            for name, d in carried.items()}


def read_landmarks(path: str | Path, mesh: RepairedMesh, n_input: int,
                   landmark_set: str | None = None) -> tuple[dict, list[str]]:
    """The landmarks of a landmark file on the repaired mesh.

    Any file :func:`pipeline.io.landmarks.read_landmarks` reads (JSON, CSV or TXT; 0-based
    vertex indices of the *input file*, or 3D points snapped to the nearest vertex), mapped
    through ``source_index`` (:func:`pipeline.io.landmarks.repaired_indices`: an index out of
    range or a vertex the repair removed is an error). Unlike a registration's, a remesh's
    landmarks may lie on the rim or share a vertex.

    Parameters
    ----------
    path : str or Path
    mesh : RepairedMesh
    n_input : int
        The input file's vertex count.
    landmark_set : str, optional
        The JSON key of the set (short names: :data:`pipeline.io.landmarks.KEY_ALIASES`);
        by default the ``"landmarks"`` entry, or the whole file where it has none.

    Returns
    -------
    landmarks : dict
        ``{name: vertex index of the repaired mesh}``, in the file's order; an unnamed set's
        names are its positions (``"0"``, ``"1"``, …).
    messages : list of str
        A line on the snapping when there are point landmarks.
    """
    from ..io.landmarks import read_landmarks as read_file

    return _on_repaired(read_file(path, landmark_set), mesh, n_input,
                        f"landmarks file '{path}'")


def _on_repaired(lms, mesh: RepairedMesh, n_input: int, label: str) -> tuple[dict, list[str]]:
    """``{name: repaired vertex}`` of a :class:`~pipeline.io.landmarks.LandmarkSet`, and the
    report lines of :func:`~pipeline.io.landmarks.repaired_indices`."""
    from ..io.landmarks import repaired_indices

    idx, messages = repaired_indices(lms, mesh, n_input, label)
    names = lms.names or [str(k) for k in range(len(lms))]
    return dict(zip(names, idx.tolist())), messages


def write_remesh(r: Remesh, out_dir: str | Path, metrics: dict, report=None) -> dict[str, Path]:
    """Write ``remeshed.obj``, ``remesh_metrics.json``, ``remeshed_landmarks.json`` (when there
    are landmarks) and, when ``report`` is a callable ``report(tmp_folder) -> [paths]``, the
    report with its figures; all-or-nothing."""
    from ..io.artifacts import staged_output, write_json
    from ..io.meshio import write_obj

    out_dir = Path(out_dir)
    written = {}
    with staged_output(out_dir) as tmp:
        facts = metrics.get("methods", {}).get("sem", {}).get("facts", {})
        sphere = r.uv.shape[1] == 3
        write_obj(tmp / "remeshed.obj", r.V, r.F, uv=None if sphere else r.uv, colors=r.colors,
                  header=[f"SEM uniform remesh (sem-pipeline): {len(r.V)} vertices, "
                          f"{len(r.F)} faces, pattern {r.info['pattern']}",
                          ("closed genus-0 remesh through the sphere map; no vt (a texture "
                           "coordinate is 2D)" if sphere else
                           "vt = the vertex's position on the disk (its parameterization)")
                          + (f"; Euler characteristic {facts['euler_characteristic']}"
                             if facts else "")])
        written["obj"] = out_dir / "remeshed.obj"
        if r.landmarks:
            write_json(tmp / "remeshed_landmarks.json",
                       {"source": "sem-pipeline remesh: input landmarks carried to the nearest "
                                  "new vertex (0-based indices into remeshed.obj)",
                        "landmarks": {k: v["vertex"] for k, v in r.landmarks.items()},
                        "details": r.landmarks})
            written["landmarks"] = out_dir / "remeshed_landmarks.json"
        if report is not None:
            for p in report(tmp):
                written[Path(p).stem] = out_dir / Path(p).relative_to(tmp)
        write_json(tmp / "remesh_metrics.json", metrics)
        written["metrics"] = out_dir / "remesh_metrics.json"
    return written


# ------------------------------------------------------------------ measure, compare, write


def compare_methods(V_in: np.ndarray, F_in: np.ndarray, remesh, target: int,
                    compare: bool = True, n_random: int = DISTANCE_SAMPLES, seed: int = 0,
                    progress=None) -> dict[str, Method]:
    """Measure the input and our remesh, and with ``compare`` the columns it is compared
    with: the plain lift before improvement (paper §8) and the baselines."""
    from ..geometry.remesh_quality import SampledSurface, remesh_quality
    from ..geometry.topology import kept_edge_groups
    from ..report.remesh import Method

    def say(msg):
        if progress:
            progress(msg)

    with kept_edge_groups():               # the input's edges, grouped once for both
        reference = SampledSurface(V_in, F_in, n_random, seed,      # one for every method
                                   distance=tree_of(remesh.input_distance, V_in, F_in))
        measured_input = remesh_quality(V_in, F_in, V_in, F_in, distance=False,
                                        double_area=reference.double_area)

    def quality(V, F, facts=None):
        return remesh_quality(V_in, F_in, V, F, n_random, seed, reference=reference,
                              facts=facts)

    out: dict[str, Method] = {}
    out["input"] = Method("input", V_in, F_in, None, measured_input)
    if compare:
        Xl, Fl = remesh.lifted
        say("measuring the lifted remesh")
        out["sem_lifted"] = Method("sem_lifted", Xl, Fl, remesh.seconds["sample"]
                                   + remesh.seconds["delaunay"] + remesh.seconds["locate"]
                                   + remesh.seconds["lift"],
                                   quality(Xl, Fl), lifted_note(remesh.info))
    say("measuring the improved remesh")
    out["sem"] = Method("sem", remesh.V, remesh.F, remesh.seconds["total"],
                        quality(remesh.V, remesh.F, remesh.facts or None))
    if not compare:
        return out
    from . import baselines

    def baseline(key: str, make) -> Method:
        """The column of a baseline, or an empty one saying why it failed: a third-party
        library's failure on an input costs its column, not the remesh."""
        try:
            b = make()
        except Exception as exc:  # noqa: BLE001 - any failure of the library
            return Method(key, None, None, note=f"failed on this input: {type(exc).__name__}: "
                                                f"{str(exc).splitlines()[0] if str(exc) else ''}")
        if b is None:
            return Method(key, None, None,
                          note=f"not applicable: decimation only removes vertices and the "
                               f"input has {len(V_in)} ≤ {target}")
        return Method(key, b.V, b.F, b.seconds, quality(b.V, b.F),
                      extra={"runs": b.runs, "parameters": b.parameter,
                             "seconds_all_runs": b.seconds_all_runs})

    if baselines.pymeshlab_available():
        say("pymeshlab isotropic explicit remeshing (solving for the target length)")
        out["pymeshlab_isotropic"] = baseline(
            "pymeshlab_isotropic", lambda: baselines.isotropic_remesh(V_in, F_in, target))
    else:
        out["pymeshlab_isotropic"] = Method("pymeshlab_isotropic", None, None,
                                            note="pymeshlab is not installed "
                                                 "(pip install pymeshlab)")
    say("fast-simplification decimation")
    out["fast_simplification"] = baseline(
        "fast_simplification", lambda: baselines.decimate(V_in, F_in, target))
    return out


def tree_of(distance, V: np.ndarray, F: np.ndarray):
    """``distance`` (a :class:`..geometry.remesh_quality.MeshDistance`, or None) if it was
    built on the mesh ``(V, F)`` (n, 3), (m, 3) itself — the same vertices and the same faces
    in the same order and orientation, so that it answers as one built here — else None."""
    if distance is None or not (np.array_equal(distance.V, V) and np.array_equal(distance.F, F)):
        return None
    return distance


def remesh_outputs(mesh, parameterization, remesh, out_dir, input_info: dict | None = None,
                   compare: bool = True, report: bool = True, figures: bool = True,
                   n_random: int = DISTANCE_SAMPLES, progress=None):
    """Measure, compare and write everything of the remesh stage into ``out_dir``; returns
    ``(files, metrics)``."""
    from ..geometry.remesh_quality import bounding_box_diagonal
    from ..report.remesh import (LABELS, comparison_table, plain_metrics, remesh_warnings,
                                 verdicts, write_report)

    t0 = time.perf_counter()
    target = remesh.info.get("requested_vertices") or len(remesh.V)
    kept = remesh.info.get("holes_kept", 0)
    covered = remesh.info.get("improve", {}).get("holes_covered_index", [])
    V_in, F_in = open_mesh(mesh, covered) if kept else (mesh.V, mesh.F)
    methods = compare_methods(V_in, F_in, remesh, target, compare, n_random,
                              progress=progress)
    t_measure = time.perf_counter() - t0
    pm = parameterization.metrics
    rows = comparison_table(methods)
    metrics = {
        "input": dict(input_info or {}, vertices=int(len(V_in)), faces=int(len(F_in)),
                      bbox_diagonal=bounding_box_diagonal(V_in)),
        "parameterization": {"domain": "sphere" if remesh.uv.shape[1] == 3 else "disk",
                             "mode": pm["parameterization"].get("mode"),
                             "iterations": pm["parameterization"].get("iterations"),
                             "status": pm["parameterization"].get("status"),
                             "distortion": pm.get("distortion", {}),
                             "seconds": float(sum(pm.get("seconds", {}).values()))},
        "remesh": {k: v for k, v in remesh.info.items() if k != "attributes"},
        "landmarks": remesh.landmarks,
        "methods": {k: {"label": LABELS[k], "available": m.ok, "note": m.note,
                        "seconds": m.seconds, **plain_metrics(m.quality),
                        **({"baseline": m.extra} if m.extra else {})}
                    for k, m in methods.items()},
        "table": [{k: v for k, v in r.items() if k not in ("digits", "pct")} for r in rows],
        "seconds": dict(remesh.seconds, measure=t_measure),
    }
    metrics["warnings"] = remesh_warnings(
        pm.get("distortion", {}), metrics["methods"],
        remesh.info.get("improve", {}).get("below_min_angle"),
        {"requested": remesh.info.get("requested_vertices"), "vertices": int(len(remesh.V)),
         "rim": remesh.info.get("rim_samples")},
        remesh.info.get("improve", {}).get("trials_cut", 0),
        0 if kept else (input_info or {}).get("repair", {}).get("holes_closed", 0),
        remesh.info.get("improve", {}).get("holes_covered") if kept else None)
    metrics["summary"] = {f"vs_{k}": {"ours_better": b, "ours_worse": w}
                          for k, (b, w) in verdicts(rows, methods).items()}
    meta = {"name": Path(str((input_info or {}).get("source", "mesh"))).stem,
            "source": (input_info or {}).get("source", ""), "target": target,
            "repairs": (input_info or {}).get("repair_messages", []),
            "parameterization": metrics["parameterization"],
            "parameterization_seconds": metrics["parameterization"]["seconds"],
            "angular_distortion_deg": pm.get("distortion", {}).get(
                "angular_distortion_mean_deg", float("nan")),
            "domain": metrics["parameterization"]["domain"],
            "distortion": pm.get("distortion", {}), "warnings": metrics["warnings"],
            "remesh": metrics["remesh"], "landmarks": remesh.landmarks}
    writer = ((lambda tmp: write_report(tmp, methods, remesh.uv, remesh.F, meta, figures))
              if report else None)
    files = write_remesh(remesh, out_dir, metrics, writer)
    return files, metrics


# ----------------------------------------------------------------------------- the stage


def _run(ctx: Context) -> dict:
    from .parameterize import ParameterizationFailed

    rc, intake, p = ctx.section("remesh"), ctx.artifacts["intake"], \
        ctx.artifacts["parameterization"]
    if not p.ok:
        raise ParameterizationFailed(f"parameterization failed: {p.problem}; remeshing needs "
                                     f"a bijective map")
    return {"remesh": remesh_stage(intake.mesh, p.image, rc, ctx.artifacts.pop(LANDMARKS))}


#: the artifact under which the stage check keeps the landmarks it read for the run step
LANDMARKS = "remesh.landmarks"


def _landmarks(ctx: Context) -> dict:
    """The landmarks to carry, ``{name: vertex index of the repaired mesh}``: those of the
    ``landmarks`` file (its snapping reported), else those of the sample face, else none."""
    from ..io.landmarks import landmarks_from_dict

    rc, intake = ctx.section("remesh"), ctx.artifacts["intake"]
    n_input = intake.info["input_vertices"]
    if rc.landmarks is not None:
        landmarks, messages = read_landmarks(ctx.path(rc.landmarks), intake.mesh, n_input,
                                             rc.landmark_set)
    elif intake.info.get("landmarks"):
        sample = landmarks_from_dict({"landmarks": intake.info["landmarks"]}, "sample landmarks")
        landmarks, messages = _on_repaired(sample, intake.mesh, n_input, "sample landmarks")
    else:
        return {}
    for line in messages:
        ctx.log(f"remesh: {line}")
    return landmarks


# Peak memory per remeshed vertex (lattice, triangulation, lift, improvement, measures and
# report; measured ≈ 2.5 KiB on the sample face, with margin).
BYTES_PER_VERTEX = 4096


def expected_vertices(rc: RemeshConfig, surface_area: float) -> float:
    """The remesh's vertex count: the requested one, or for a spacing ``h`` the count of an
    equilateral lattice on the surface, ``area / (√3/2 · h²)``."""
    if rc.vertices is not None:
        return float(rc.vertices)
    return surface_area / (np.sqrt(3) / 2 * rc.spacing ** 2)


def _check(ctx: Context) -> None:
    """Refuse a bad landmarks file, a spacing that gives too few vertices, a request that
    needs more memory than the limit (:mod:`pipeline.limits`) and, for a closed mesh, a
    pattern with no sphere version, before the map is computed; the run step uses the
    landmarks read here."""
    from ..geometry.laplacian import face_double_areas
    from ..limits import check_memory

    ctx.artifacts[LANDMARKS] = _landmarks(ctx)
    rc, mesh = ctx.section("remesh"), ctx.artifacts["intake"].mesh
    if len(mesh.boundary) == 0:                  # closed: remeshed on the sphere
        _check_sphere_pattern(rc.pattern)
    area = float(face_double_areas(mesh.V, mesh.F).sum() / 2)
    n = expected_vertices(rc, area)
    if rc.spacing is not None:
        if n < MIN_VERTICES:
            most = np.sqrt(area / (np.sqrt(3) / 2 * MIN_VERTICES))
            raise UserError(f"remesh: spacing {rc.spacing:g} gives about {n:.3g} vertices on this "
                            f"mesh (area {area:.4g}); the remesh needs at least {MIN_VERTICES}: "
                            f"give a spacing of at most {most:.3g} (or --vertices)")
        what = f"remesh: spacing {rc.spacing:g} gives about {n:.3g} vertices, which"
        fix = "give a larger spacing (or --vertices)"
    else:
        what, fix = f"remesh: {rc.vertices} vertices", "ask for fewer vertices"
    check_memory(n * BYTES_PER_VERTEX, what, fix)


def _write(ctx: Context, folder: Path) -> dict[str, Path]:
    rc, r = ctx.section("remesh"), ctx.artifacts["remesh"]
    files, metrics = remesh_outputs(ctx.artifacts["intake"].mesh,
                                    ctx.artifacts["parameterization"], r, folder,
                                    ctx.artifacts["intake"].info, compare=rc.compare,
                                    report=rc.report, figures=ctx.figures,
                                    n_random=rc.distance_samples,
                                    progress=lambda msg: ctx.log(f"remesh: {msg}"))
    r.metrics = metrics
    ctx.log(f"remesh: {_summary(ctx, files)}")
    for warning in metrics["warnings"]:
        ctx.log(f"remesh: warning: {warning}")
    return files


def _summary(ctx: Context, files: dict) -> str:
    r = ctx.artifacts["remesh"]
    sem = r.metrics["methods"]["sem"]
    t = sem["triangles"]
    d = sem.get("distance", {})
    shape = (("closed genus 0" if sem.get("is_sphere") else "NOT closed genus 0")
             if r.uv.shape[1] == 3 else disk_shape_words(sem, r.info.get("holes_kept", 0)))
    covered = len(r.info.get("improve", {}).get("holes_covered", []))
    shape += f" ({covered} more covered: see the warnings)" if covered else ""
    return (f"{len(r.V)} vertices, {len(r.F)} faces, {shape}, "
            f"min angle {t['min_angle_deg']:.1f}°, mean smallest angle "
            f"{t['mean_min_angle_deg']:.1f}°, Hausdorff {100 * d.get('hausdorff_rel', 0):.3f} % "
            f"of the diagonal, {r.seconds['total']:.2f} s")


def disk_shape_words(sem: dict, holes: int) -> str:
    """What the summary line says of a disk remesh's topology (``sem``: its measures, with
    ``holes`` the input's holes it kept): ``one disk``, ``one disk with k holes, as the
    input`` or ``NOT …``."""
    if not holes:
        return "one disk" if sem["is_disk"] else "NOT a disk"
    words = f"one disk with {holes} {'hole' if holes == 1 else 'holes'}"
    return f"{words}, as the input" if sem.get("holes") == holes and \
        sem.get("is_disk_with_holes") else f"NOT {words}"


STAGE = Stage(name="remesh", section=RemeshConfig, run=_run, write=_write,
              needs=("intake", "parameterization"), makes=("remesh",), uses=("report",),
              input_files=("landmarks",),
              summary=_summary, check=_check, check_needs=("intake",),
              command_defaults={"parameterize.mode": "auto"},
              help="uniform remesh through the SEM disk map, with a quality report beside "
                   "pymeshlab and decimation")
