"""Stage 3 — uniform remeshing through the SEM map (paper §8): sample → triangulate →
locate → lift → improve → write.

1. **Sample** the image polygon evenly (:mod:`pipeline.geometry.disk_sampling`): a hexagonal
   lattice (or blue noise / concentric rings) plus rim samples on the polygon, at the spacing
   that gives the requested vertex count. The map is equiareal, so even on the disk means even
   on the surface.
2. **Triangulate** the samples (Delaunay; a disk without leaf faces, CCW).
3. **Locate** every sample in the image of the input mesh (:mod:`pipeline.geometry.locate`).
4. **Lift** it by eq. (1): positions and every per-vertex attribute (colours); landmarks go to
   the nearest new vertex (the corner, nearest in 3D, of the new face that contains the
   landmark's disk position).
5. **Improve** (on by default, ``RemeshOptions.improve``; :mod:`..geometry.remesh_improve`):
   sharp input corners get a vertex (on the boundary by moving a rim sample, inside by
   snapping the nearest vertex), Delaunay flips on the lifted surface, tangential relaxation
   made on the disk, splits of edges that leave the surface (where the map squeezes a region
   into a sliver) balanced by collapses of the shortest edges so that the count is the request
   again, a last relaxation and flips. Every vertex stays exactly on the input surface and
   every face counter-clockwise on the disk. The measures before and after are both reported.
6. **Write** ``remeshed.obj`` (``v`` with colours if the input had them, ``vt`` = the new
   vertices' disk positions, so the output is parameterized too), ``remesh_metrics.json``,
   ``remeshed_landmarks.json`` when there are landmarks, and ``report.html`` with its figures
   (:mod:`pipeline.report.remesh`), all-or-nothing (:func:`remesh_outputs`).

Why improvement is on by default: the plain lift of equilateral disk triangles is skewed by
the map's angle distortion (mean smallest angle 35–37° on the shared faces, 15–25° on
hands and relief, against 49–51° for pymeshlab), and across slivers its edges leave the
surface (Hausdorff 0.6–1.8 % of the diagonal at 20k vertices). Improvement raises the mean
smallest angle to 38–48° (the 5th percentile of the faces' smallest angles to 20–37°), brings
the Hausdorff distance under 0.5 % on every shared mesh and ICT face at 20k vertices
(0.07–0.40 %; the hand 0.18 %), keeps the vertex count, and costs about 0.5–1 s at 20k and
1.5–2.5 s at 100k vertices on the face and the camel head (2.5 s at 20k and 6.5 s at 100k on
the hand and brain, where refinement adds many vertices). Turn it off
(``improve: false``, ``--no-improve``) for the paper's plain lift.
Where the map stretches much of the surface more than 10:1 (σ₁/σ₂, reported in
``remesh_metrics.json``), or the Hausdorff distance exceeds 0.5 %, the run says so.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..geometry import topology as topo
from ..geometry.disk_sampling import (PATTERNS, DiskSamples, sample_disk, snap_rim,
                                     triangulate_samples)
from ..geometry.laplacian import face_double_areas
from ..geometry.locate import PointLocator, lift
from ..geometry.metrics import corner_angles, signed_double_areas
from ..geometry.remesh_improve import RemeshState, improve_remesh
from ..geometry.repair import RepairedMesh

__all__ = ["RemeshOptions", "Remesh", "remesh_stage", "read_landmarks", "map_landmarks",
           "carry_landmarks", "boundary_corners", "interior_corners", "write_remesh",
           "compare_methods", "remesh_outputs"]


@dataclass
class RemeshOptions:
    vertices: int | None = None          # requested vertex count, or …
    spacing: float | None = None         # … target edge length in the mesh's units
    pattern: str = "hexagonal"           # hexagonal | blue_noise | concentric
    rim_relax: int = 3                   # ODT sweeps of the band near the rim (disk)
    improve: bool = True
    flips: bool = True
    relax_iterations: int = 2            # tangential relaxation steps (each followed by flips)
    relax_step: float = 0.5
    max_dihedral_deg: float = 20.0       # flips in quads flatter than this (more folded:
                                         # only towards an edge closer to the surface)
    refine_sag: float = 0.2              # split edges farther than this × spacing from the
    refine_budget: float = 0.3           # surface (at most this fraction of the vertices);
                                         # also the tolerance of count correction's collapses
    corner_angle_deg: float = 30.0       # input corners sharper than this keep a vertex
    seed: int = 0                        # blue noise

    def check(self) -> None:
        if (self.vertices is None) == (self.spacing is None):
            raise UserError("remesh: give exactly one of 'vertices' (a count) or 'spacing' "
                            "(a target edge length in the mesh's units)")
        if self.vertices is not None and not 100 <= int(self.vertices) <= 5_000_000:
            raise UserError(f"remesh: vertices = {self.vertices} is out of range; "
                            f"use 100 … 5000000")
        if self.spacing is not None and not self.spacing > 0:
            raise UserError(f"remesh: spacing = {self.spacing} must be > 0")
        if self.pattern not in PATTERNS:
            raise UserError(f"remesh: unknown pattern '{self.pattern}'; use one of "
                            f"{', '.join(PATTERNS)}")


@dataclass
class Remesh:
    """The remeshed disk and what is needed to report on it."""

    V: np.ndarray                      # n×3 lifted positions (after improvement if on)
    F: np.ndarray                      # m×3, CCW on the disk, consistently oriented
    uv: np.ndarray                     # n×2 disk positions of the new vertices
    face: np.ndarray                   # n: input face under each new vertex
    bary: np.ndarray                   # n×3: its barycentrics (eq. 1)
    colors: np.ndarray | None
    samples: DiskSamples
    lifted: tuple                      # (V, F) straight after lifting, before improvement
    landmarks: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)


def boundary_corners(V: np.ndarray, F: np.ndarray, boundary: np.ndarray, angle_deg: float
                     ) -> np.ndarray:
    """Boundary vertices where the boundary turns sharply on the surface: the angles of the
    faces at the vertex sum to less than ``180° − angle_deg`` or more than ``180° + angle_deg``
    (a flat boundary has 180°). Sharpest first."""
    if angle_deg is None or angle_deg <= 0:
        return np.zeros(0, np.int64)
    total = np.bincount(F.ravel(), corner_angles(V, F).ravel(), len(V))[boundary]
    dev = np.abs(np.degrees(total) - 180.0)
    sharp = np.flatnonzero(dev > angle_deg)
    return boundary[sharp[np.argsort(-dev[sharp])]]


def interior_corners(V: np.ndarray, F: np.ndarray, angle_deg: float) -> np.ndarray:
    """Interior vertices that are sharp points of the surface: the angles of their faces sum
    to less than ``360° − angle_deg`` (a cone tip) or more than ``360° + angle_deg`` (a saddle
    spike). Sharpest first."""
    if angle_deg is None or angle_deg <= 0:
        return np.zeros(0, np.int64)
    total = np.degrees(np.bincount(F.ravel(), corner_angles(V, F).ravel(), len(V)))
    dev = np.abs(total - 360.0)
    dev[topo.boundary_vertices_mask(F, len(V))] = 0.0
    sharp = np.flatnonzero(dev > angle_deg)
    return sharp[np.argsort(-dev[sharp])]


def _check_map(mesh: RepairedMesh, uv: np.ndarray) -> None:
    if uv.shape != (len(mesh.V), 2):
        raise UserError(f"remesh: the map has shape {uv.shape}, expected {len(mesh.V)}×2")
    flipped = int(np.count_nonzero(signed_double_areas(uv, mesh.F) <= 0))
    if flipped:
        raise UserError(f"remesh: the disk map has {flipped} flipped faces; remeshing needs a "
                        f"bijective map (parameterize with mode 'converged')")


def disk_spacing(mesh_spacing: float, V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> float:
    """A target edge length on the surface as a spacing on the disk: the map scales areas by
    ``|f(M)| / |M|`` (equiareal), so lengths by its square root on average."""
    ratio = np.abs(signed_double_areas(uv, F)).sum() / face_double_areas(V, F).sum()
    return float(mesh_spacing * np.sqrt(ratio))


def carry_landmarks(landmarks: dict, mesh: RepairedMesh, uv: np.ndarray, X: np.ndarray,
                    uv_out: np.ndarray, F_out: np.ndarray) -> dict:
    """Each landmark (an index into the repaired mesh) → the nearest new vertex: the corner,
    nearest in 3D, of the new face containing the landmark's disk position."""
    if not landmarks:
        return {}
    names = list(landmarks)
    idx = np.array([landmarks[k] for k in names], np.int64)
    face, _ = PointLocator(uv_out, F_out).locate(uv[idx])
    corners = F_out[face]                                            # (k, 3)
    d = np.linalg.norm(X[corners] - mesh.V[idx][:, None, :], axis=2)
    j = np.argmin(d, axis=1)
    out = {}
    for i, name in enumerate(names):
        out[name] = {"input_vertex": int(idx[i]), "vertex": int(corners[i, j[i]]),
                     "distance": float(d[i, j[i]])}
    return out


def _remesh_once(mesh: RepairedMesh, uv: np.ndarray, locator: PointLocator, n_vertices,
                 spacing, options: RemeshOptions) -> tuple:
    """One pass: sample → triangulate → locate → lift → improve. Returns
    ``(X, F, uv, face, bary, samples, lifted, info, seconds)``."""
    V, F, boundary = mesh.V, mesh.F, mesh.boundary
    sec = {}
    t = time.perf_counter()
    samples = sample_disk(n_vertices, spacing, options.pattern, polygon=uv[boundary],
                          relax=options.rim_relax, seed=options.seed)
    corners = boundary_corners(mesh.V, mesh.F, boundary, options.corner_angle_deg)
    snapped = snap_rim(samples, uv[corners]) if len(corners) else np.zeros(0, np.int64)
    sec["sample"] = time.perf_counter() - t
    t = time.perf_counter()
    F_out = triangulate_samples(samples)
    sec["delaunay"] = time.perf_counter() - t
    t = time.perf_counter()
    face, bary = locator.locate(samples.points)
    sec["locate"] = time.perf_counter() - t
    t = time.perf_counter()
    X = lift(V, F, face, bary)
    sec["lift"] = time.perf_counter() - t
    lifted = (X, F_out)
    t = time.perf_counter()
    uv_out = samples.points
    info = {"enabled": bool(options.improve), "rim_corners_snapped": int(len(snapped))}
    if options.improve:
        is_rim = np.zeros(len(uv_out), bool)
        is_rim[:samples.n_rim] = True
        locked = np.zeros(len(uv_out), bool)
        locked[snapped] = True
        X, F_out, uv_out, face, bary, imp = _improve(mesh, uv, locator, X, F_out, uv_out,
                                                     is_rim, locked, face, bary, samples,
                                                     options, n_vertices)
        info.update(imp)
    sec["improve"] = time.perf_counter() - t
    return X, F_out, uv_out, face, bary, samples, lifted, info, sec


def _improve(mesh, uv, locator, X, F_out, uv_out, is_rim, locked, face, bary, samples,
             options, target):
    """Isotropic improvement on the disk (:func:`..geometry.remesh_improve.improve_remesh`)
    at the sampling's edge length measured on the surface."""
    S = RemeshState(X, F_out, uv_out, is_rim, face, bary, mesh.V, mesh.F, uv, locator,
                    uv[mesh.boundary], locked)
    L = samples.spacing / np.sqrt(_area_ratio(mesh.V, mesh.F, uv))    # target length in 3D
    corners = interior_corners(mesh.V, mesh.F, options.corner_angle_deg)
    improve_remesh(S, L, options.relax_iterations, options.flips, options.max_dihedral_deg,
                   options.relax_step, options.refine_sag, options.refine_budget, target,
                   uv[corners])
    info = {"enabled": True, "target_edge_length": float(L), **S.log}
    info["seconds"] = {k: float(v) for k, v in info.get("seconds", {}).items()}
    return S.X, S.F, S.uv, S.face, S.bary, info


def _area_ratio(V, F, uv) -> float:
    """``|f(M)| / |M|``: the equiareal map's scale of areas."""
    return float(np.abs(signed_double_areas(uv, F)).sum() / face_double_areas(V, F).sum())


def remesh_stage(mesh: RepairedMesh, uv: np.ndarray, options: RemeshOptions,
                 landmarks: dict | None = None, attributes: dict | None = None) -> Remesh:
    """Remesh a repaired disk through its bijective disk map ``uv`` (see the module docstring).

    ``landmarks``: ``{name: vertex index of the repaired mesh}``. ``attributes``: extra
    per-vertex arrays to lift (colours are taken from the mesh); their lifted values are in
    ``Remesh.info['attributes']``.

    With a requested count, the improvement ends by splitting or collapsing edges until the
    count is the request again (usually exactly).
    """
    options.check()
    uv = np.asarray(uv, dtype=np.float64)
    _check_map(mesh, uv)
    V, F, boundary = mesh.V, mesh.F, mesh.boundary
    t0 = time.perf_counter()
    locator = PointLocator(uv, F, boundary)
    t_loc = time.perf_counter() - t0
    spacing = None if options.spacing is None else options.spacing * np.sqrt(_area_ratio(V, F, uv))
    X, F_out, uv_out, face, bary, samples, lifted, imp, sec = _remesh_once(
        mesh, uv, locator, options.vertices, spacing, options)
    sec["locate"] += t_loc
    t = time.perf_counter()
    colors = lift(mesh.colors, F, face, bary) if mesh.colors is not None else None
    lifted_attrs = {k: lift(v, F, face, bary) for k, v in (attributes or {}).items()}
    lms = carry_landmarks(landmarks or {}, mesh, uv, X, uv_out, F_out)
    sec["attributes"] = time.perf_counter() - t
    ratio = _area_ratio(V, F, uv)
    info = {
        "requested_vertices": options.vertices,
        "requested_spacing": options.spacing,
        "pattern": samples.pattern,
        "vertices": int(len(X)),
        "samples": int(len(samples.points)),
        "rim_samples": int(samples.n_rim),
        "spacing_disk": samples.spacing,
        "spacing_mesh_units": samples.spacing / np.sqrt(ratio),
        "count_evaluations": samples.iterations,
        "improve": imp,
        "attributes": lifted_attrs,
    }
    sec["total"] = sum(sec.values())
    return Remesh(X, F_out, uv_out, face, bary, colors, samples, lifted, lms, info, sec)


def read_landmarks(path: str | Path, mesh: RepairedMesh) -> dict:
    """Landmarks from a JSON file: ``{"landmarks": {name: index}}`` or ``{name: index}``,
    0-based indices of the *input file's* vertices; mapped to the repaired mesh through
    ``source_index`` (a landmark whose vertex the repair removed is an error)."""
    import json

    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"landmarks file '{path}' not found") from None
    except (OSError, ValueError) as exc:
        raise UserError(f"landmarks file '{path}' is not valid JSON ({exc}); "
                        f"expected {{\"landmarks\": {{name: vertex index}}}}") from None
    if isinstance(data, dict) and isinstance(data.get("landmarks"), dict):
        data = data["landmarks"]
    if not isinstance(data, dict) or not data or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in data.values()):
        raise UserError(f"landmarks file '{path}': expected {{\"landmarks\": {{name: vertex "
                        f"index}}}} with integer (0-based) vertex indices")
    return map_landmarks(data, mesh, str(path))


def map_landmarks(landmarks: dict, mesh: RepairedMesh, where: str = "landmarks") -> dict:
    """Input-file vertex indices → repaired-mesh vertex indices (via ``source_index``)."""
    src = mesh.source_index
    lookup = np.full(int(src.max()) + 1 if len(src) else 0, -1, np.int64)
    ok = src >= 0
    lookup[src[ok]] = np.flatnonzero(ok)
    out = {}
    for name, i in landmarks.items():
        i = int(i)
        if i < 0 or i >= len(lookup) or lookup[i] < 0:
            raise UserError(f"{where}: landmark '{name}' = vertex {i} is not a vertex of the "
                            f"repaired mesh (out of range or removed by the repair)")
        out[str(name)] = int(lookup[i])
    return out


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
        write_obj(tmp / "remeshed.obj", r.V, r.F, uv=r.uv, colors=r.colors,
                  header=[f"SEM uniform remesh (sem-pipeline): {len(r.V)} vertices, "
                          f"{len(r.F)} faces, pattern {r.info['pattern']}",
                          "vt = the vertex's position on the disk (its parameterization)"
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
                    compare: bool = True, n_random: int = 200_000, seed: int = 0,
                    progress=None) -> dict[str, Method]:
    """Measure the input, our lifted and improved remeshes and (``compare``) the baselines."""
    from ..geometry.remesh_quality import remesh_quality
    from ..report.remesh import Method
    from . import baselines

    def say(msg):
        if progress:
            progress(msg)

    out: dict[str, Method] = {}
    out["input"] = Method("input", V_in, F_in, None,
                          remesh_quality(V_in, F_in, V_in, F_in, distance=False))
    Xl, Fl = remesh.lifted
    say("measuring the lifted remesh")
    out["sem_lifted"] = Method("sem_lifted", Xl, Fl, remesh.seconds["sample"]
                               + remesh.seconds["delaunay"] + remesh.seconds["locate"]
                               + remesh.seconds["lift"],
                               remesh_quality(V_in, F_in, Xl, Fl, n_random, seed))
    say("measuring the improved remesh")
    out["sem"] = Method("sem", remesh.V, remesh.F, remesh.seconds["total"],
                        remesh_quality(V_in, F_in, remesh.V, remesh.F, n_random, seed))
    if not compare:
        return out
    if baselines.pymeshlab_available():
        say("pymeshlab isotropic explicit remeshing (solving for the target length)")
        b = baselines.isotropic_remesh(V_in, F_in, target)
        out["pymeshlab_isotropic"] = Method(
            "pymeshlab_isotropic", b.V, b.F, b.seconds,
            remesh_quality(V_in, F_in, b.V, b.F, n_random, seed),
            extra={"runs": b.runs, "parameters": b.parameter,
                   "seconds_all_runs": b.seconds_all_runs})
    else:
        out["pymeshlab_isotropic"] = Method("pymeshlab_isotropic", None, None,
                                            note="pymeshlab is not installed "
                                                 "(pip install pymeshlab)")
    say("fast-simplification decimation")
    b = baselines.decimate(V_in, F_in, target)
    if b is None:
        out["fast_simplification"] = Method(
            "fast_simplification", None, None,
            note=f"not applicable: decimation only removes vertices and the input has "
                 f"{len(V_in)} ≤ {target}")
    else:
        out["fast_simplification"] = Method(
            "fast_simplification", b.V, b.F, b.seconds,
            remesh_quality(V_in, F_in, b.V, b.F, n_random, seed),
            extra={"runs": b.runs, "parameters": b.parameter,
                   "seconds_all_runs": b.seconds_all_runs})
    return out




def remesh_outputs(mesh, parameterization, remesh, out_dir, input_info: dict | None = None,
                   compare: bool = True, report: bool = True, figures: bool = True,
                   n_random: int = 200_000, progress=None):
    """Measure, compare and write everything of the remesh stage into ``out_dir``; returns
    ``(files, metrics)``."""
    from ..geometry.remesh_quality import bounding_box_diagonal
    from ..report.remesh import (LABELS, comparison_table, plain_metrics, remesh_warnings,
                                 verdicts, write_report)

    t0 = time.perf_counter()
    target = remesh.info.get("requested_vertices") or len(remesh.V)
    methods = compare_methods(mesh.V, mesh.F, remesh, target, compare, n_random,
                              progress=progress)
    t_measure = time.perf_counter() - t0
    pm = parameterization.metrics
    rows = comparison_table(methods)
    metrics = {
        "input": dict(input_info or {}, vertices=int(len(mesh.V)), faces=int(len(mesh.F)),
                      bbox_diagonal=bounding_box_diagonal(mesh.V)),
        "parameterization": {"mode": pm["parameterization"]["mode"],
                             "iterations": pm["parameterization"]["iterations"],
                             "status": pm["parameterization"]["status"],
                             "distortion": pm["distortion"],
                             "seconds": float(sum(pm["seconds"].values()))},
        "remesh": {k: v for k, v in remesh.info.items() if k != "attributes"},
        "landmarks": remesh.landmarks,
        "methods": {k: {"label": LABELS[k], "available": m.ok, "note": m.note,
                        "seconds": m.seconds, **plain_metrics(m.quality),
                        **({"baseline": m.extra} if m.extra else {})}
                    for k, m in methods.items()},
        "table": [{k: v for k, v in r.items() if k not in ("digits", "pct")} for r in rows],
        "seconds": dict(remesh.seconds, measure=t_measure),
    }
    metrics["warnings"] = remesh_warnings(pm["distortion"], metrics["methods"])
    metrics["summary"] = {f"vs_{k}": {"ours_better": b, "ours_worse": w}
                          for k, (b, w) in verdicts(rows, methods).items()}
    meta = {"name": Path(str((input_info or {}).get("source", "mesh"))).stem,
            "source": (input_info or {}).get("source", ""), "target": target,
            "parameterization": metrics["parameterization"],
            "parameterization_seconds": metrics["parameterization"]["seconds"],
            "angular_distortion_deg": pm["distortion"]["angular_distortion_mean_deg"],
            "distortion": pm["distortion"], "warnings": metrics["warnings"],
            "remesh": metrics["remesh"]}
    writer = ((lambda tmp: write_report(tmp, methods, remesh.uv, remesh.F, meta, figures))
              if report else None)
    files = write_remesh(remesh, out_dir, metrics, writer)
    return files, metrics
