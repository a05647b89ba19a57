"""Stage — landmark registration of a source face onto a target face through their SEM disks,
or of two closed genus-0 meshes through their spherical maps.

Steps (kernels in :mod:`pipeline.geometry.register`): read and repair both meshes (holes closed
by ``close_holes`` are tracked), read and pair the landmarks (:mod:`pipeline.io.landmarks`),
SEM-parameterize both faces (:mod:`pipeline.stages.parameterize`), align the source disk to the
target landmarks (rotation, or disk Möbius map), deform it so every landmark lands exactly on
its partner without flipping a face, and lift every source vertex onto the target surface
through the target's inverse map (eq. 1). Optionally the dense error against a ground truth with
the source's connectivity, and trimesh's ``nricp_amberg`` on the same pair as a baseline.

Two closed meshes (``Parameterization.domain == "sphere"``) go through
:func:`register_spheres` instead (kernels in :mod:`pipeline.geometry.register_sphere`): a
rotation in SO(3), a landmark-exact deformation of the sphere with no folded face, and the lift
through the target's inverse spherical map; a closed and an open mesh are refused (one line,
exit 2). The files are the same, with the sphere's arrays in place of the disk's (below).

Files (contract in ``shared/docs/DESIGN.md``):

* ``registration.npz`` — ``mapped_points`` n×3 (image of every source vertex on the target
  surface), ``target_face`` n, ``target_barycentric`` n×3 (``mapped_points[i] = Σ_c
  target_barycentric[i, c] · target_vertices[target_faces[target_face[i], c]]``); and for
  re-use: ``source_vertices``, ``source_faces`` (the source connectivity as written in
  ``registered.obj``), ``source_index``, ``source_landmarks``, ``target_landmarks``,
  ``source_uv``, ``target_uv``, ``aligned_uv``, ``deformed_uv`` (on the sphere:
  ``source_sphere``, ``target_sphere``, ``aligned_sphere``, ``deformed_sphere`` n×3 and
  ``rotation`` 3×3; :func:`map_arrays`), ``target_vertices``, ``target_faces``. Vertex ``i``
  is vertex ``i`` of the *repaired* source mesh; ``source_index[i]`` is its index in the input
  file (−1 for a vertex the repair added).
* ``registered.obj`` — the source connectivity on the target geometry. Faces of holes the
  repair closed (fans to a centre vertex) are left out, so the holes stay open as in the input.
* ``metrics.json``, ``report.html`` and figures (``disks.png`` — ``spheres.png`` on the sphere,
  ``surfaces.png``, ``error_on_face.png`` with a ground truth), built by
  :mod:`pipeline.report.register`.

A registration that leaves flipped faces is a failure: ``metrics.json``, the report and its
figures are written for diagnosis, the map files are not, and :class:`RegistrationFailed` is
raised (exit code 1).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Optional

import numpy as np
from pydantic import Field, model_validator

from ..errors import UserError
from ..geometry.repair import RepairOptions, display_faces, used_vertices_only
from ..geometry.sem import SEMOptions
from ..io.artifacts import save_npz, staged_output, write_json
from ..io.meshio import read_mesh, write_obj
from .load import Intake, load_stage, sample_stage
from .parameterize import ParameterizationFailed, parameterize_stage
from .stage import Context, Section, Stage

if TYPE_CHECKING:
    from ..io.landmarks import LandmarkSet


class RegistrationFailed(RuntimeError):
    """Faces remain flipped after the deformation (exit code 1: valid input, method failed)."""


class RegisterConfig(Section):
    """Landmark registration of a source face onto a target face; the stage's options.

    Either ``sample: true`` (the embedded synthetic face, neutral → ``sample_expression``; the
    target is also the ground truth) or the files (paths relative to the config's folder). The
    meshes go through the ``repair`` section and the ``parameterize`` section's SEM options.
    """

    sample: bool = Field(False, description="the embedded synthetic face, neutral → expression")
    sample_vertices: int = Field(3000, ge=300, le=200_000)
    sample_expression: Literal["smile", "jawopen"] = "smile"
    source: Optional[str] = Field(None, description="source face mesh")
    target: Optional[str] = Field(None, description="target face mesh")
    source_landmarks: Optional[str] = Field(
        None, description="JSON ({'landmarks': {name: index}} or a list), CSV or TXT (indices or "
                          "x y z points, snapped to the nearest vertex)")
    target_landmarks: Optional[str] = Field(
        None, description="target landmark file (default: the source's, one file for both)")
    landmark_set: Optional[str] = Field(
        None, description="JSON key of the landmark set, e.g. ibug68 (default 'landmarks')")
    truth: Optional[str] = Field(
        None, description="ground truth with the source's connectivity: report the dense error")
    mobius: bool = Field(False, description="align the disks by a Möbius map (default: a "
                                            "rotation)")
    energy: Literal["biharmonic", "harmonic"] = Field(
        "biharmonic", description="smoothness of the landmark deformation")
    baseline: bool = Field(False, description="also run trimesh's nricp_amberg and compare")

    @model_validator(mode="after")
    def _inputs(self):
        files = (self.source, self.target, self.source_landmarks)
        if self.sample and any(f is not None for f in files + (self.truth,)):
            raise ValueError("give either 'sample: true' or the files (source, target, "
                             "source_landmarks), not both")
        if not self.sample and any(f is None for f in files):
            raise ValueError("give 'source', 'target' and 'source_landmarks' (and "
                             "'target_landmarks' if they differ), or 'sample: true'")
        return self


@dataclass
class Face:
    """One side of the pair: the repaired mesh, its landmark vertices (repaired indices)."""

    intake: Intake
    landmarks: np.ndarray
    label: str

    @property
    def mesh(self):
        return self.intake.mesh


@dataclass
class Pair:
    """The two faces a registration maps between, with their landmarks paired, the dense
    ground truth when there is one, and the pairing's messages."""

    source: Face
    target: Face
    names: list[str] | None              # landmark names in pairing order (None: by order)
    truth: np.ndarray | None = None      # ground-truth positions of the source's input vertices
    truth_label: str = ""
    messages: list[str] = field(default_factory=list)


# ----------------------------------------------------------------------------------- inputs


def _side(intake: Intake, lms: LandmarkSet, label: str, messages: list) -> Face:
    from ..io.landmarks import resolve_landmarks

    idx, msgs = resolve_landmarks(lms, intake.mesh, intake.info["input_vertices"],
                                  f"{label} landmarks")
    messages.extend(msgs)
    return Face(intake, idx, label)


def load_truth(path, source: Intake) -> np.ndarray:
    """Ground-truth vertex positions that share the source's connectivity (vertex i ↔ i)."""
    raw = read_mesh(path)
    n, m = source.info["input_vertices"], source.info["input_faces"]
    if len(raw.V) != n or raw.n_faces != m:
        raise UserError(f"truth mesh '{path}' has {len(raw.V)} vertices and {raw.n_faces} faces "
                        f"but the source has {n} and {m}; the truth must share the source's "
                        f"connectivity (vertex i corresponds to source vertex i)")
    return np.asarray(raw.V, dtype=np.float64)


def load_pair(source, target, source_landmarks, target_landmarks=None,
              landmark_set: str | None = None, repair: RepairOptions | None = None,
              truth=None) -> Pair:
    """Read, repair and pair two faces and their landmark files (``target_landmarks``
    defaults to ``source_landmarks``: one file that holds the landmarks of both, as ICT's)."""
    from ..io.landmarks import pair_landmarks, read_landmarks

    messages: list[str] = []
    src = load_stage(source, repair)
    tgt = load_stage(target, repair)
    ls = read_landmarks(source_landmarks, landmark_set)
    lt = read_landmarks(target_landmarks or source_landmarks, landmark_set)
    ls, lt = pair_landmarks(ls, lt)
    if len(ls) < 3:
        raise UserError(f"only {len(ls)} landmarks; give at least 3 (the alignment and the "
                        f"deformation need them)")
    pair = Pair(_side(src, ls, "source", messages), _side(tgt, lt, "target", messages),
                ls.names if ls.names and lt.names else None, messages=messages)
    pair.messages[:0] = [f"{len(ls)} landmarks paired by "
                         f"{'name' if pair.names else 'order'}"]
    if truth is not None:
        pair.truth, pair.truth_label = load_truth(truth, src), str(truth)
    return pair


def sample_pair(n_vertices: int = 3000, expression: str = "smile",
                repair: RepairOptions | None = None) -> Pair:
    """The embedded synthetic face: neutral → ``expression`` (same connectivity, same
    landmarks), so the target is also the dense ground truth."""
    from ..io.landmarks import landmarks_from_dict

    src = sample_stage(n_vertices, "neutral", options=repair)
    tgt = sample_stage(n_vertices, expression, options=repair)
    lms = landmarks_from_dict({"landmarks": src.info["landmarks"]}, "sample landmarks")
    messages: list[str] = []
    pair = Pair(_side(src, lms, "source", messages), _side(tgt, lms, "target", messages),
                lms.names, messages=messages)
    pair.truth = _input_order(tgt)
    pair.truth_label = f"synthetic {expression} face (same connectivity)"
    pair.messages.insert(0, f"{len(lms)} landmarks paired by name")
    return pair


def _input_order(intake: Intake) -> np.ndarray:
    """Positions of the input vertices (NaN where the repair removed one)."""
    m = intake.mesh
    out = np.full((intake.info["input_vertices"], 3), np.nan)
    ok = m.source_index >= 0
    out[m.source_index[ok]] = m.V[ok]
    return out


# ----------------------------------------------------------------------------- the method


@dataclass
class Registration:
    """The ``registration`` artifact: the pair, both maps, the alignment and the deformation,
    the source's vertices mapped onto the target (``mapped`` (n, 3), with their target
    ``face`` (n,) and ``bary`` (n, 3)), their ``error`` (n,), the baseline and the metrics."""

    pair: Pair
    energy: str                               # the deformation's smoothness
    uv_source: np.ndarray                     # source map: disk n×2, or sphere n×3
    uv_target: np.ndarray                     # target map: disk n_t×2, or sphere n_t×3
    alignment: object                         # Alignment (disk) | SphereAlignment
    deform: object                            # DeformResult (disk) | SphereDeformResult
    domain: str = "disk"
    mapped: np.ndarray | None = None
    face: np.ndarray | None = None
    bary: np.ndarray | None = None
    error: np.ndarray | None = None           # per source vertex / diagonal (NaN: no truth)
    baseline: dict | None = None
    metrics: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.deform.flipped_faces == 0


def _parameterize(face: Face, opts: SEMOptions, progress):
    p = parameterize_stage(face.mesh, opts, progress(face.label) if progress else None)
    if not p.ok:
        raise ParameterizationFailed(
            f"{face.label} parameterization failed: {p.problem} "
            f"(status {p.sem.status}); the registration needs fold-free {p.domain} maps")
    return p


def check_same_domain(pair: Pair) -> None:
    """Both meshes closed (sphere) or both with a boundary (disk); else a one-line UserError."""
    kinds = ["closed (sphere)" if f.mesh.closed else "open (disk)" for f in (pair.source,
                                                                             pair.target)]
    if kinds[0] != kinds[1]:
        raise UserError(f"source is {kinds[0]} but target is {kinds[1]}; register needs two "
                        f"closed meshes or two meshes with a boundary")


def _truth_at_source(pair: Pair) -> tuple[np.ndarray, np.ndarray]:
    """The source vertices with a finite ground-truth position (k indices) and those
    positions (k×3)."""
    src = pair.source.mesh.source_index
    ok = (src >= 0) & (src < len(pair.truth))
    T = pair.truth[src[ok]]
    good = np.isfinite(T).all(axis=1)
    return np.flatnonzero(ok)[good], T[good]


def _dense_error(points: np.ndarray, pair: Pair, diag: float) -> np.ndarray | None:
    """Per source vertex ``|points_i − truth_{source_index(i)}| / diag`` (NaN where no truth)."""
    if pair.truth is None:
        return None
    err = np.full(len(points), np.nan)
    idx, T = _truth_at_source(pair)
    err[idx] = np.linalg.norm(points[idx] - T, axis=1) / diag
    return err


def _finite_summary(err: np.ndarray | None) -> dict | None:
    if err is None:
        return None
    from ..geometry.register import error_summary

    return error_summary(err[np.isfinite(err)], 1.0)


def register_stage(pair: Pair, options: RegisterConfig, sem: SEMOptions | None = None,
                   progress=None, log=None) -> Registration:
    """Register ``pair.source`` onto ``pair.target`` (module docstring): SEM maps of both, then
    :func:`register_maps`. Raises ``ParameterizationFailed`` if a SEM map folds; never raises for
    flipped faces of the deformation — check :attr:`Registration.ok`."""
    opt, sem = options, sem or SEMOptions()
    say = log or (lambda s: None)
    check_same_domain(pair)
    t0 = time.perf_counter()
    ps = _parameterize(pair.source, sem, progress)
    t1 = time.perf_counter()
    pt = _parameterize(pair.target, sem, progress)
    t2 = time.perf_counter()
    say(f"SEM: source {ps.sem.iterations} iterations ({ps.sem.status}), target "
        f"{pt.sem.iterations} iterations ({pt.sem.status})")
    if ps.domain == "sphere" and (opt.mobius or opt.energy != "biharmonic"):
        say("on the sphere the alignment is a rotation and the deformation a smooth kernel "
            "continuation: 'mobius' and 'energy' do not apply")
    return register_maps(pair, ps, pt, mobius=opt.mobius, energy=opt.energy,
                         baseline=opt.baseline, log=log,
                         seconds={"parameterize_source": t1 - t0, "parameterize_target": t2 - t1})


def register_maps(pair: Pair, ps, pt, *, mobius: bool = False, energy: str = "biharmonic",
                  baseline: bool = False, log=None, seconds: dict | None = None) -> Registration:
    """Register with given SEM parameterizations ``ps`` (source) and ``pt`` (target) of
    ``pair``'s repaired meshes (:class:`~pipeline.stages.parameterize.Parameterization`).

    ``mobius``, ``energy`` and ``baseline`` are the :class:`RegisterConfig` keys of the same
    names: the alignment (disk Möbius map or rotation), the deformation's smoothness, and
    whether trimesh's ``nricp_amberg`` runs on the same pair for comparison.
    """
    from ..geometry.register import (DeformOptions, align, as_complex, compose_with_inverse,
                                     deform_to_landmarks)

    say = log or (lambda s: None)
    S, T = pair.source, pair.target
    if ps.domain != pt.domain:
        raise UserError(f"source map is a {ps.domain} but target map a {pt.domain}; register "
                        f"needs two closed meshes or two meshes with a boundary")
    if ps.domain == "sphere":
        return register_spheres(pair, ps, pt, baseline=baseline, log=log, seconds=seconds)
    if len(ps.uv) != len(S.mesh.V) or len(pt.uv) != len(T.mesh.V):
        raise ValueError("the parameterizations do not belong to the pair's meshes")
    seconds = dict(seconds or {})
    t0 = time.perf_counter()
    zt_lm = as_complex(pt.uv)[T.landmarks]
    al = align(ps.uv, S.landmarks, zt_lm, use_mobius=mobius)
    seconds["align"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    dopt = DeformOptions(energy=energy)
    de = deform_to_landmarks(S.mesh.F, al.z, S.mesh.boundary, S.landmarks, zt_lm, dopt)
    seconds["deform"] = time.perf_counter() - t0
    say(f"deformation: {de.method}, {de.substeps} sub-steps accepted, {de.rejected_substeps} "
        f"rejected, {de.flipped_faces} flipped faces")

    reg = Registration(pair, energy, ps.uv, pt.uv, al, de)
    VT, FT = T.mesh.V, T.mesh.F
    diag = float(np.linalg.norm(VT.max(axis=0) - VT.min(axis=0)))

    # landmark residuals: before = after the alignment only; after = after the deformation
    t0 = time.perf_counter()
    before, _, _ = compose_with_inverse(al.z[S.landmarks], VT, FT, pt.uv, T.mesh.boundary)
    res_before = np.linalg.norm(before - VT[T.landmarks], axis=1) / diag
    located, _, _ = compose_with_inverse(de.z[S.landmarks], VT, FT, pt.uv, T.mesh.boundary)
    res_located = np.linalg.norm(located - VT[T.landmarks], axis=1) / diag
    seconds["landmark_residuals"] = time.perf_counter() - t0

    metrics = {
        "status": "ok" if reg.ok else "failed",
        "method": ("SEM disk maps (Yueh et al. 2019) + landmark alignment + bijective "
                   "landmark-constrained deformation + inverse map (eq. 1)"),
        "source": _side_metrics(S, ps), "target": _side_metrics(T, pt),
        "landmarks": {"count": int(len(S.landmarks)),
                      "paired_by": "name" if pair.names else "order",
                      "names": pair.names, "messages": pair.messages},
        "target_bbox_diagonal": diag,
        "alignment": al.as_dict(),
        "deformation": {"energy": energy, **de.as_dict()},
        "flipped_faces": int(de.flipped_faces),
        "landmark_residual": {
            "relative_to": "target bounding-box diagonal",
            "before": {"mean": float(res_before.mean()), "max": float(res_before.max()),
                       "per_landmark": res_before.tolist(),
                       "disk_max": float(np.abs(al.z[S.landmarks] - zt_lm).max())},
            "after": None,
            "after_located_max": float(res_located.max()),
        },
    }
    if reg.ok:
        t0 = time.perf_counter()
        mapped, face, bary = compose_with_inverse(de.z, VT, FT, pt.uv, T.mesh.boundary,
                                                  S.landmarks, T.landmarks)
        seconds["lift"] = time.perf_counter() - t0
        reg.mapped, reg.face, reg.bary = mapped, face, bary
        res_after = np.linalg.norm(mapped[S.landmarks] - VT[T.landmarks], axis=1) / diag
        metrics["landmark_residual"]["after"] = {
            "mean": float(res_after.mean()), "max": float(res_after.max()),
            "disk_max": float(np.abs(de.z[S.landmarks] - zt_lm).max())}
        centres = [h["centre_vertex"] for h in T.mesh.closed_holes]
        in_fans = np.isin(FT[face], centres).any(axis=1) & (S.mesh.source_index >= 0)
        metrics["source_vertices_mapped_into_filled_holes"] = int(in_fans.sum())
        reg.error = _dense_error(mapped, pair, diag)
        metrics["dense_error"] = None if reg.error is None else {
            "truth": pair.truth_label, "relative_to": "target bounding-box diagonal",
            "ours": _finite_summary(reg.error)}
    return _finish(reg, metrics, seconds, diag, baseline, say)


def _finish(reg: Registration, metrics: dict, seconds: dict, diag: float, baseline: bool,
            say) -> Registration:
    """The optional nricp baseline, the times, and ``reg.metrics`` (both domains)."""
    if baseline:
        say("baseline: trimesh.registration.nricp_amberg …")
        reg.baseline = nricp_baseline(reg.pair, diag)
        seconds["baseline_nricp_amberg"] = reg.baseline["seconds"]
        metrics["baseline"] = {k: v for k, v in reg.baseline.items() if k not in ("points",
                                                                                  "error")}
        if reg.baseline.get("error") is not None and metrics.get("dense_error"):
            metrics["dense_error"]["nricp_amberg"] = _finite_summary(reg.baseline["error"])
    ours = sum(v for k, v in seconds.items() if k not in ("baseline_nricp_amberg",
                                                            "landmark_residuals"))
    seconds["ours_total"] = ours
    metrics["seconds"] = seconds
    reg.metrics = metrics
    return reg


def register_spheres(pair: Pair, ps, pt, *, baseline: bool = False, log=None,
                     seconds: dict | None = None) -> Registration:
    """:func:`register_maps` for two closed meshes with spherical maps (``p.sphere``):
    rotation, landmark-exact deformation of the sphere, lift through the target's inverse map
    (:mod:`pipeline.geometry.register_sphere`). Residuals: ``before`` after the rotation only,
    ``after`` with the landmarks set on their target vertices, ``after_located_max`` without."""
    from ..geometry.register_sphere import (align_sphere, compose_with_inverse_sphere,
                                            deform_sphere_to_landmarks, sphere_faces)

    say = log or (lambda s: None)
    S, T = pair.source, pair.target
    if len(ps.sphere) != len(S.mesh.V) or len(pt.sphere) != len(T.mesh.V):
        raise ValueError("the parameterizations do not belong to the pair's meshes")
    seconds = dict(seconds or {})
    Fs = sphere_faces(ps.sphere, S.mesh.F)
    VT, FT = T.mesh.V, sphere_faces(pt.sphere, T.mesh.F)
    targets = pt.sphere[T.landmarks]
    t0 = time.perf_counter()
    al = align_sphere(ps.sphere, S.landmarks, targets)
    seconds["align"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    de = deform_sphere_to_landmarks(Fs, al.S, S.landmarks, targets)
    seconds["deform"] = time.perf_counter() - t0
    say(f"deformation: {de.method}, {de.substeps} sub-steps accepted, {de.rejected_substeps} "
        f"rejected, {de.flipped_faces} folded faces")
    if de.method == "infeasible":
        say(f"deformation: {de.landmark_faces_reversed} faces whose corners are all landmarks "
            f"are reversed by the target landmarks: no fold-free map places them")
    reg = Registration(pair, "wendland", ps.sphere, pt.sphere, al, de, domain="sphere")
    diag = float(np.linalg.norm(VT.max(axis=0) - VT.min(axis=0)))
    t0 = time.perf_counter()
    before, _, _ = compose_with_inverse_sphere(al.S[S.landmarks], VT, FT, pt.sphere)
    located, _, _ = compose_with_inverse_sphere(de.S[S.landmarks], VT, FT, pt.sphere)
    res_before = np.linalg.norm(before - VT[T.landmarks], axis=1) / diag
    res_located = np.linalg.norm(located - VT[T.landmarks], axis=1) / diag
    seconds["landmark_residuals"] = time.perf_counter() - t0
    metrics = {
        "status": "ok" if reg.ok else "failed", "domain": "sphere",
        "method": ("spherical SEM maps + rotation (Kabsch) + landmark-exact smooth deformation "
                   "of the sphere (Wendland kernel, continuation) + inverse map (eq. 1)"),
        "source": _sphere_side_metrics(S, ps, Fs), "target": _sphere_side_metrics(T, pt, FT),
        "landmarks": {"count": int(len(S.landmarks)),
                      "paired_by": "name" if pair.names else "order",
                      "names": pair.names, "messages": pair.messages},
        "target_bbox_diagonal": diag,
        "alignment": al.as_dict(),
        "deformation": {"energy": "wendland", **de.as_dict()},
        "flipped_faces": int(de.flipped_faces),
        "landmark_residual": {
            "relative_to": "target bounding-box diagonal",
            "before": {"mean": float(res_before.mean()), "max": float(res_before.max()),
                       "per_landmark": res_before.tolist(),
                       "sphere_max": float(np.linalg.norm(al.S[S.landmarks] - targets,
                                                          axis=1).max())},
            "after": None,
            "after_located_max": float(res_located.max()),
        },
    }
    if reg.ok:
        t0 = time.perf_counter()
        mapped, face, bary = compose_with_inverse_sphere(de.S, VT, FT, pt.sphere, S.landmarks,
                                                         T.landmarks)
        seconds["lift"] = time.perf_counter() - t0
        reg.mapped, reg.face, reg.bary = mapped, face, bary
        res_after = np.linalg.norm(mapped[S.landmarks] - VT[T.landmarks], axis=1) / diag
        metrics["landmark_residual"]["after"] = {
            "mean": float(res_after.mean()), "max": float(res_after.max()),
            "sphere_max": float(np.linalg.norm(de.S[S.landmarks] - targets, axis=1).max())}
        reg.error = _dense_error(mapped, pair, diag)
        metrics["dense_error"] = None if reg.error is None else {
            "truth": pair.truth_label, "relative_to": "target bounding-box diagonal",
            "ours": _finite_summary(reg.error)}
    return _finish(reg, metrics, seconds, diag, baseline, say)


def _sphere_side_metrics(face: Face, p, F_sphere: np.ndarray) -> dict:
    """One side's mesh and spherical map measures (:func:`pipeline.geometry.sphere.
    sphere_measures`)."""
    from ..geometry.sphere import sphere_measures

    m = face.mesh
    return {"file": face.intake.info.get("source"), "vertices": int(len(m.V)),
            "faces": int(len(m.F)), "input_vertices": face.intake.info["input_vertices"],
            "holes_closed": 0, "added_vertices": int(len(m.added_vertices)),
            "repair_messages": m.messages,
            "sphere": {"iterations": getattr(p.sem, "iterations", None),
                       "status": getattr(p.sem, "status", None),
                       **sphere_measures(m.V, F_sphere, p.sphere)}}


def _side_metrics(face: Face, p) -> dict:
    m = face.mesh
    return {"file": face.intake.info.get("source"), "vertices": int(len(m.V)),
            "faces": int(len(m.F)), "input_vertices": face.intake.info["input_vertices"],
            "holes_closed": len(m.closed_holes), "added_vertices": int(len(m.added_vertices)),
            "repair_messages": m.messages,
            "sem": {"mode": p.options.mode, "iterations": p.sem.iterations,
                    "status": p.sem.status, "flipped_faces": p.flipped_faces,
                    "energy_ratio": p.sem.history[-1]["energy_ratio"] if p.sem.history else None,
                    "total_area_distortion_eq28":
                        p.metrics["distortion"]["total_area_distortion_eq28"]}}


# --------------------------------------------------------------------------------- baseline


def nricp_baseline(pair: Pair, diag: float) -> dict:
    """trimesh's ``registration.nricp_amberg`` (Amberg et al. 2007) on the same pair with the
    same landmarks (source vertex indices → target landmark positions), its default steps.

    Both meshes are given as in the input: the fans of holes the repair closed are left out
    (vertices they alone used are dropped for nricp and get NaN)."""
    import trimesh
    from trimesh.registration import nricp_amberg

    S, T = pair.source.mesh, pair.target.mesh

    def compact(mesh):
        V, F, new = used_vertices_only(mesh.V, display_faces(mesh))
        return trimesh.Trimesh(V, F, process=False), np.flatnonzero(new >= 0), new

    src, used_s, new_s = compact(S)
    tgt, _, new_t = compact(T)
    ls, lt = new_s[pair.source.landmarks], new_t[pair.target.landmarks]
    t0 = time.perf_counter()
    X = nricp_amberg(src, tgt, source_landmarks=ls, target_positions=tgt.vertices[lt])
    seconds = time.perf_counter() - t0
    points = np.full((len(S.V), 3), np.nan)
    points[used_s] = X
    res = np.linalg.norm(points[pair.source.landmarks] - T.V[pair.target.landmarks],
                         axis=1) / diag
    flipped = _normal_flips(S.V, points, display_faces(S))
    return {"method": "trimesh.registration.nricp_amberg (default steps)",
            "trimesh": trimesh.__version__, "seconds": seconds, "points": points,
            "landmark_residual": {"mean": float(res.mean()), "max": float(res.max())},
            "faces_turned_over": flipped,
            "error": _dense_error(points, pair, diag)}


def _normal_flips(V0: np.ndarray, V1: np.ndarray, F: np.ndarray) -> int:
    """Faces whose normal turned by more than 90° between ``V0`` and ``V1`` (a fold indicator
    for a surface-to-surface map; nricp gives no bijectivity guarantee)."""
    def normals(V):
        return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n1 = normals(V1)
    ok = np.isfinite(n1).all(axis=1)
    return int(np.count_nonzero((np.einsum("ij,ij->i", normals(V0)[ok], n1[ok]) <= 0)))


# ------------------------------------------------------------------------------------ files


def write_registration(reg: Registration, out_dir, figures: bool = True) -> dict[str, Path]:
    """Write the stage's files all-or-nothing; raise :class:`RegistrationFailed` if faces
    remain flipped (the metrics, report and figures are still written)."""
    from ..report import register as report

    out_dir = Path(out_dir)
    written: dict[str, Path] = {}
    S, T = reg.pair.source.mesh, reg.pair.target.mesh
    t0 = time.perf_counter()
    with staged_output(out_dir) as tmp:
        figs = report.write_figures(tmp, report_view(reg)) if figures else []
        if reg.ok:
            Fd = display_faces(S)
            save_npz(
                tmp / "registration.npz", mapped_points=reg.mapped, target_face=reg.face,
                target_barycentric=reg.bary, source_vertices=S.V, source_faces=Fd,
                source_index=S.source_index, source_landmarks=reg.pair.source.landmarks,
                target_landmarks=reg.pair.target.landmarks, target_vertices=T.V,
                target_faces=T.F, **map_arrays(reg))
            write_obj(tmp / "registered.obj", reg.mapped, Fd,
                      header=["sem-pipeline register: source connectivity on the target "
                              "surface", f"source: {reg.pair.source.intake.info.get('source')}",
                              f"target: {reg.pair.target.intake.info.get('source')}"])
            written["npz"] = out_dir / "registration.npz"
            written["obj"] = out_dir / "registered.obj"
        reg.metrics["seconds"]["write"] = time.perf_counter() - t0
        write_json(tmp / "metrics.json", reg.metrics)
        report.write_report(tmp, reg.metrics, [p.name for p in figs])
        written["metrics"] = out_dir / "metrics.json"
        written["report"] = out_dir / "report.html"
        for p in figs:
            written[p.stem] = out_dir / p.name
    if not reg.ok:
        raise RegistrationFailed(
            f"registration failed: {reg.deform.flipped_faces} flipped faces remain after the "
            f"landmark deformation ({reg.deform.method}); see {out_dir / 'metrics.json'}")
    return written


def map_arrays(reg: Registration) -> dict[str, np.ndarray]:
    """The domain arrays of ``registration.npz``: ``source_uv``, ``target_uv``, ``aligned_uv``,
    ``deformed_uv`` (disk, n×2), or ``source_sphere``, ``target_sphere``, ``aligned_sphere``,
    ``deformed_sphere`` (n×3 unit vectors) and ``rotation`` (3×3) on the sphere."""
    from ..geometry.register import as_uv

    if reg.domain == "sphere":
        return {"source_sphere": reg.uv_source, "target_sphere": reg.uv_target,
                "aligned_sphere": reg.alignment.S, "deformed_sphere": reg.deform.S,
                "rotation": reg.alignment.R}
    return {"source_uv": reg.uv_source, "target_uv": reg.uv_target,
            "aligned_uv": as_uv(reg.alignment.z), "deformed_uv": as_uv(reg.deform.z)}


def report_view(reg: Registration):
    """The plain arrays and metrics the report shows
    (:class:`pipeline.report.register.RegistrationView`)."""
    from ..report.register import RegistrationView

    S, T = reg.pair.source, reg.pair.target
    truth = None
    if reg.mapped is not None and reg.pair.truth is not None:
        truth = np.array(reg.mapped)
        idx, known = _truth_at_source(reg.pair)
        truth[idx] = known
    base = reg.baseline or {}
    views = _domain_views(reg)
    return RegistrationView(
        source_vertices=S.mesh.V, source_display_faces=display_faces(S.mesh),
        source_landmarks=S.landmarks, target_vertices=T.mesh.V,
        target_display_faces=display_faces(T.mesh), target_landmarks=T.landmarks,
        alignment_kind=reg.alignment.kind, energy=reg.energy, deform_ok=bool(reg.deform.ok),
        deform_method=reg.deform.method, path_reached=float(reg.deform.path_reached),
        metrics=reg.metrics, mapped=reg.mapped, error=reg.error, truth_points=truth,
        truth_label=reg.pair.truth_label, baseline_points=base.get("points"),
        baseline_error=base.get("error"), domain=reg.domain, **views)


def _domain_views(reg: Registration) -> dict:
    """The report's planar views of the maps: the disks themselves, or the spheres by the
    equal-area view about the target landmarks (far cap left out)."""
    from ..geometry.register import as_uv

    S, T = reg.pair.source.mesh, reg.pair.target.mesh
    if reg.domain == "disk":
        return {"source_faces": S.F, "target_faces": T.F, "aligned_uv": as_uv(reg.alignment.z),
                "target_uv": np.asarray(reg.uv_target), "deformed_uv": as_uv(reg.deform.z)}
    from ..report.register import equal_area_view, sphere_view_faces

    c = reg.uv_target[reg.pair.target.landmarks].mean(axis=0)
    c = c if np.linalg.norm(c) > 1e-9 else reg.uv_target[reg.pair.target.landmarks[0]]
    from ..geometry.register_sphere import slerp, sphere_faces
    from ..geometry.sphere import triple_products

    a, b = reg.alignment.S[reg.pair.source.landmarks], reg.uv_target[reg.pair.target.landmarks]
    arcs = np.stack([equal_area_view(slerp(a, b, t), c) for t in np.linspace(0, 1, 33)], axis=1)
    Fs = sphere_view_faces(reg.deform.S, sphere_faces(reg.uv_source, S.F), c)
    return {"source_faces": Fs, "folded": triple_products(reg.deform.S, Fs) <= 0,
            "landmark_paths": arcs,
            "target_faces": sphere_view_faces(reg.uv_target, sphere_faces(reg.uv_target, T.F),
                                              c),
            "aligned_uv": equal_area_view(reg.alignment.S, c),
            "target_uv": equal_area_view(reg.uv_target, c),
            "deformed_uv": equal_area_view(reg.deform.S, c)}


# ----------------------------------------------------------------------------- the stage


def _pair(ctx: Context) -> Pair:
    rc, repair = ctx.section("register"), ctx.section("repair")
    if rc.sample:
        pair = sample_pair(rc.sample_vertices, rc.sample_expression, repair)
    else:
        def p(v):
            return None if v is None else Path(os.path.realpath(ctx.path(v)))
        pair = load_pair(p(rc.source), p(rc.target), p(rc.source_landmarks),
                         p(rc.target_landmarks), rc.landmark_set, repair, p(rc.truth))
    for face in (pair.source, pair.target):
        for line in face.mesh.messages:
            ctx.log(f"repair ({face.label}): {line}")
    for line in pair.messages:
        ctx.log(f"landmarks: {line}")
    return pair


#: the artifact under which the stage check keeps the pair it read for the run step
PAIR = "register.pair"


def _check(ctx: Context) -> None:
    """Read the two faces and pair their landmarks before any stage computes, so a bad
    landmark file is refused before a map of the run is computed; the run step uses the
    pair read here."""
    ctx.artifacts[PAIR] = _pair(ctx)


def _run(ctx: Context) -> dict:
    reg = register_stage(ctx.artifacts.pop(PAIR), ctx.section("register"),
                         ctx.section("parameterize"), progress=ctx.progress, log=ctx.log)
    ctx.log(f"register: {register_summary(reg)}")
    return {"registration": reg}


def _write(ctx: Context, folder: Path) -> dict[str, Path]:
    return write_registration(ctx.artifacts["registration"], folder, figures=ctx.figures)


def register_summary(reg: Registration) -> str:
    """One line: landmark count, deformation, flips, residuals, dense errors, time."""
    m = reg.metrics
    lr = m["landmark_residual"]
    parts = [f"{m['landmarks']['count']} landmarks",
             f"deformation {m['deformation']['method']}",
             f"flipped faces = {m['flipped_faces']}",
             f"landmark residual before {lr['before']['max']:.2e}"
             + (f", after {lr['after']['max']:.2e}" if lr["after"] else "")
             + " (max, × target diagonal)"]
    de = m.get("dense_error")
    if de:
        parts.append(f"dense error mean {de['ours']['mean']:.2e}, p95 {de['ours']['p95']:.2e}, "
                     f"max {de['ours']['max']:.2e}")
        if "nricp_amberg" in de:
            b = de["nricp_amberg"]
            parts.append(f"nricp_amberg mean {b['mean']:.2e}, p95 {b['p95']:.2e}, "
                         f"max {b['max']:.2e}")
    parts.append(f"{m['seconds']['ours_total']:.2f} s")
    return ", ".join(parts)


STAGE = Stage(name="register", section=RegisterConfig, run=_run, write=_write,
              makes=("registration",), uses=("repair", "parameterize", "report"),
              input_files=("source", "target", "source_landmarks", "target_landmarks", "truth"),
              mesh_files=("source", "target", "truth"),
              positional=("source", "target"),
              summary=lambda ctx, files: register_summary(ctx.artifacts["registration"]),
              check=_check,
              help="landmark registration of SOURCE onto TARGET on their SEM disks")
