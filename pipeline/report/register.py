"""The register stage's report: figures of a registration and ``report.html``.

* ``disks.png`` — (a) the source disk after the alignment with its landmarks, (b) the target
  disk with its landmarks, (c) before the deformation: a line from every aligned source landmark
  to its target landmark, (d) the deformed source disk (landmarks on their targets; flipped
  faces, if any, filled red).
* ``spheres.png`` (two closed meshes) — the same four panels for the spherical maps, drawn by
  Lambert's azimuthal equal-area projection about the target landmarks (:func:`equal_area_view`;
  the cap around the antipode is left out); folded faces are counted on the sphere.
* ``surfaces.png`` — source, registered (ours), target (and nricp_amberg's result with
  ``--baseline``), shaded, one camera for the target side.
* ``error_on_face.png`` (with a ground truth) — the dense error per vertex on the truth surface,
  ours and the baseline's on one colour scale, and their cumulative distributions.
* ``report.html`` — the numbers of ``metrics.json`` and the figures.

The stage passes a :class:`RegistrationView`: plain arrays and the metrics dict.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.tri import Triangulation

from ..geometry.metrics import signed_double_areas
from . import html as h
from .figure import camera_for, draw_surface, new_figure, save_png, unit_disk_axes

__all__ = ["RegistrationView", "plot_disks", "plot_surfaces", "plot_error", "write_figures",
           "write_report"]


@dataclass
class RegistrationView:
    """What the report shows of a registration. Source arrays are indexed by the repaired
    source's vertices (n), target arrays by the repaired target's; ``*_display_faces`` leave
    out the fans of holes the repair closed."""

    source_vertices: np.ndarray            # n×3
    source_faces: np.ndarray               # m×3, repaired
    source_display_faces: np.ndarray       # m'×3
    source_landmarks: np.ndarray           # k, vertex indices
    target_vertices: np.ndarray            # n_t×3
    target_faces: np.ndarray               # m_t×3
    target_display_faces: np.ndarray       # m_t'×3
    target_landmarks: np.ndarray           # k
    aligned_uv: np.ndarray                 # n×2, source disk after the alignment
    target_uv: np.ndarray                  # n_t×2
    deformed_uv: np.ndarray                # n×2
    alignment_kind: str                    # rotation | mobius
    energy: str                            # biharmonic | harmonic
    deform_ok: bool
    deform_method: str
    path_reached: float                    # share of the landmark paths the continuation made
    metrics: dict                          # the stage's metrics.json
    mapped: np.ndarray | None = None       # n×3 registered positions (None: failed)
    error: np.ndarray | None = None        # n, dense error ÷ target diagonal (NaN: no truth)
    truth_points: np.ndarray | None = None  # n×3 truth positions (mapped where none)
    truth_label: str = ""
    baseline_points: np.ndarray | None = None   # n×3 nricp_amberg result (NaN: dropped)
    baseline_error: np.ndarray | None = None    # n
    domain: str = "disk"                   # disk | sphere (the *_uv are equal-area views)
    folded: np.ndarray | None = None       # per source_faces row: folded on the sphere
    landmark_paths: np.ndarray | None = None   # k×p×2: source → target landmark paths (the
    #                                            great-circle arcs in the view; None: segments)


def equal_area_view(S: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Lambert's azimuthal equal-area projection of unit vectors ``S`` (n, 3) about ``centre``,
    halved so that the sphere minus the antipode fills the unit disk: a point at the angle ``α``
    from ``centre`` lands at radius ``sin(α/2)``. It keeps area ratios, so an equiareal sphere
    map looks as even as a disk map. (n, 3) → (n, 2)."""
    c = np.asarray(centre, dtype=np.float64) / np.linalg.norm(centre)
    e1 = np.cross(c, [1.0, 0.0, 0.0] if abs(c[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    x, y, z = S @ e1, S @ e2, np.clip(S @ c, -1.0, 1.0)
    t = np.hypot(x, y)
    scale = np.sqrt((1.0 - z) / 2.0) / np.where(t > 0, t, 1.0)
    return np.column_stack([x * scale, y * scale])


def sphere_view_faces(S: np.ndarray, F: np.ndarray, centre: np.ndarray,
                      max_angle_deg: float = 150.0) -> np.ndarray:
    """The faces of ``F`` whose corners are all within ``max_angle_deg`` of ``centre`` (near the
    antipode the equal-area view tears faces apart)."""
    c = np.asarray(centre, dtype=np.float64) / np.linalg.norm(centre)
    near = S @ c > np.cos(np.radians(max_angle_deg))
    return F[near[F].all(axis=1)]


SRC_COLOR = "tab:blue"
TGT_COLOR = "tab:red"


def _disk_axes(ax, title):
    unit_disk_axes(ax)
    ax.set_title(title, fontsize=9)


def _mesh(ax, uv, F, alpha=0.35, color="0.45"):
    lw = 0.15 if len(F) > 4000 else 0.3
    ax.triplot(Triangulation(uv[:, 0], uv[:, 1], F), color=color, lw=lw, alpha=alpha)


def plot_disks(reg: RegistrationView, path: Path) -> Path:
    ua, ut, ud = reg.aligned_uv, np.asarray(reg.target_uv), reg.deformed_uv
    ps, pt = ua[reg.source_landmarks], ut[reg.target_landmarks]
    fig = new_figure(11.0, 11.4)
    axs = fig.subplots(2, 2)
    fig.subplots_adjust(left=0.02, right=0.98, top=0.9, bottom=0.02, wspace=0.06, hspace=0.16)
    kind = reg.alignment_kind
    where = "disk" if reg.domain == "disk" else "sphere"
    _disk_axes(axs[0, 0], f"(a) source {where} after the {kind} alignment\n"
                          f"{len(reg.source_landmarks)} source landmarks (blue)")
    _mesh(axs[0, 0], ua, reg.source_faces)
    axs[0, 0].plot(ps[:, 0], ps[:, 1], "o", color=SRC_COLOR, ms=4)
    _disk_axes(axs[0, 1], f"(b) target {where}\ntarget landmarks (red)")
    _mesh(axs[0, 1], ut, reg.target_faces)
    axs[0, 1].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=4)
    lr = reg.metrics["landmark_residual"]["before"]
    _disk_axes(axs[1, 0], "(c) before the deformation: source → target landmark\n"
                          f"residual on the surface mean {lr['mean']:.2e}, max {lr['max']:.2e} "
                          f"× diagonal")
    _mesh(axs[1, 0], ut, reg.target_faces, alpha=0.12)
    paths = (np.stack([ps, pt], axis=1) if reg.landmark_paths is None
             else reg.landmark_paths)
    for line in paths:
        axs[1, 0].plot(line[:, 0], line[:, 1], "-", color="k", lw=0.8)
    axs[1, 0].plot(ps[:, 0], ps[:, 1], "o", color=SRC_COLOR, ms=3.5, label="source (aligned)")
    axs[1, 0].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=3.5, label="target")
    axs[1, 0].legend(loc="lower left", fontsize=8, frameon=False)
    flips = (signed_double_areas(ud, reg.source_faces) <= 0 if reg.folded is None
             else np.asarray(reg.folded, bool))       # a view's thin faces are not folds
    if reg.deform_ok:
        title = (f"(d) deformed source {where} ({reg.deform_method}; {reg.energy} "
                 f"{'energy' if where == 'disk' else 'kernel'})\n"
                 f"landmarks on their targets, 0 {'flipped' if where == 'disk' else 'folded'} "
                 f"faces")
    else:
        title = (f"(d) FAILED: one-step solve, {int(flips.sum())} flipped faces (red)\n"
                 f"continuation stalled at {reg.path_reached:.0%} of the landmark paths")
    _disk_axes(axs[1, 1], title)
    _mesh(axs[1, 1], ud, reg.source_faces, alpha=0.35)
    if flips.any():
        for f in reg.source_faces[flips]:
            axs[1, 1].fill(ud[f, 0], ud[f, 1], color="red", alpha=0.8)
    axs[1, 1].set_xlim(-1.05, 1.05)
    axs[1, 1].set_ylim(-1.05, 1.05)
    pd = ud[reg.source_landmarks]
    axs[1, 1].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=5, mfc="none")
    axs[1, 1].plot(pd[:, 0], pd[:, 1], ".", color=SRC_COLOR, ms=4)
    fig.suptitle("Registration on the equiareal (SEM) disks" if where == "disk" else
                 "Registration on the equiareal spheres (equal-area view about the target "
                 "landmarks; the far cap is left out)", fontsize=11)
    return save_png(fig, path)


def plot_surfaces(reg: RegistrationView, path: Path) -> Path:
    VS, VT = reg.source_vertices, reg.target_vertices
    Fs, Ft = reg.source_display_faces, reg.target_display_faces
    ls, lt = reg.source_landmarks, reg.target_landmarks
    panels = [("source", VS, Fs, ls, VS),
              ("registered (ours): source mesh\non the target surface", reg.mapped, Fs, ls,
               reg.mapped),
              ("target", VT, Ft, lt, VT)]
    if reg.baseline_points is not None:
        X = reg.baseline_points
        keep = np.isfinite(X[Fs]).all(axis=(1, 2))
        panels.append(("nricp_amberg (baseline)", np.where(np.isfinite(X), X, 0.0), Fs[keep],
                       ls, X))
    cam_s = camera_for(VS, Fs)
    cam_t = camera_for(VT, Ft, extra=[reg.mapped])
    fig = new_figure(3.6 * len(panels), 4.2)
    for k, (title, V, F, lm, P) in enumerate(panels):
        ax = fig.add_axes((k / len(panels), 0.0, 1.0 / len(panels), 0.86))
        cam = cam_s if k == 0 else cam_t
        draw_surface(ax, V, F, cam)
        q, _ = cam.project(P[lm])
        ax.plot(q[:, 0], q[:, 1], ".", color=TGT_COLOR if k else SRC_COLOR, ms=3)
        fig.text((k + 0.5) / len(panels), 0.9, title, ha="center", fontsize=9)
    return save_png(fig, path)


def plot_error(reg: RegistrationView, path: Path) -> Path:
    Fs = reg.source_display_faces
    truth = reg.truth_points
    series = [("ours", reg.error)]
    if reg.baseline_error is not None:
        series.append(("nricp_amberg", reg.baseline_error))
    vals = np.concatenate([e[np.isfinite(e)] for _, e in series])
    hi = float(np.percentile(vals, 99)) if len(vals) else 1.0
    norm = Normalize(0.0, hi if hi > 0 else 1.0)
    cam = camera_for(truth, Fs)
    n = len(series)
    fig = new_figure(3.9 * n + 5.2, 4.8)
    gs = fig.add_gridspec(1, n + 2, width_ratios=[4.0] * n + [0.14, 3.6], wspace=0.25,
                          left=0.01, right=0.97, bottom=0.14, top=0.8)
    mappable = None
    for k, (name, err) in enumerate(series):
        ax = fig.add_subplot(gs[0, k])
        e = np.where(np.isfinite(err), err, 0.0)
        mappable = draw_surface(ax, truth, Fs, cam, vertex_values=e, norm=norm, cmap="magma_r")
        fin = err[np.isfinite(err)]
        ax.set_title(f"{name}\nmean {fin.mean():.2e}, p95 {np.percentile(fin, 95):.2e}, "
                     f"max {fin.max():.2e}", fontsize=8.5)
    cb = fig.colorbar(mappable, cax=fig.add_subplot(gs[0, n]), extend="max")
    cb.set_label("|registered − truth| / target diagonal", fontsize=8)
    cb.ax.tick_params(labelsize=7)
    ax = fig.add_subplot(gs[0, n + 1])
    ax.set_box_aspect(0.9)
    for (name, err), c in zip(series, ("tab:blue", "tab:orange")):
        fin = np.sort(err[np.isfinite(err)])
        ax.plot(fin, np.linspace(0, 1, len(fin)), color=c, label=name)
    ax.set_xlabel("error / target diagonal", fontsize=8)
    ax.set_ylabel("fraction of vertices ≤ x", fontsize=8)
    ax.yaxis.set_label_position("right")
    ax.yaxis.tick_right()
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, frameon=False)
    fig.suptitle(f"Dense error on the ground truth ({reg.truth_label})", fontsize=10,
                 y=0.995)
    return save_png(fig, path)


def write_figures(folder: Path, reg: RegistrationView) -> list[Path]:
    """The figures that apply (``surfaces.png`` needs the mapped points, ``error_on_face.png``
    also a ground truth) into ``folder``."""
    folder = Path(folder)
    out = [plot_disks(reg, folder / ("disks.png" if reg.domain == "disk" else "spheres.png"))]
    if reg.mapped is not None:
        out.append(plot_surfaces(reg, folder / "surfaces.png"))
        if reg.error is not None:
            out.append(plot_error(reg, folder / "error_on_face.png"))
    return out


def _map_rows(m: dict) -> list[tuple[str, str]]:
    """The rows on the two maps and the alignment: disk (SEM, rotation or Möbius) or sphere
    (spherical SEM, rotation in SO(3))."""
    s, t = m["source"], m["target"]
    if m.get("domain") == "sphere":
        a = m["alignment"]
        return [("spherical SEM (source / target)",
                 f"face area distortion {s['sphere']['face_area_distortion']:.4f} / "
                 f"{t['sphere']['face_area_distortion']:.4f}, folded faces "
                 f"{s['sphere']['folded_faces']} / {t['sphere']['folded_faces']}"),
                ("alignment", f"rotation by {a['angle_deg']:.2f}° about "
                              f"({', '.join(f'{v:.3f}' for v in a['axis'])}), "
                              f"det = {a['det']:.12f}")]
    return [("SEM (source / target)",
             f"{s['sem']['iterations']} / {t['sem']['iterations']} iterations, "
             f"D(f) eq. 28 = {s['sem']['total_area_distortion_eq28']:.4f} / "
             f"{t['sem']['total_area_distortion_eq28']:.4f}"),
            ("alignment", f"{m['alignment']['kind']}, θ = {m['alignment']['theta_deg']:.2f}°, "
                          f"a = {m['alignment']['a'][0]:.4f} + {m['alignment']['a'][1]:.4f}i")]


def write_report(folder: Path, metrics: dict, figure_names: list[str]) -> Path:
    """``report.html`` of the register stage: the numbers of ``metrics`` (the stage's
    ``metrics.json``) and the figures ``figure_names`` (files in ``folder``)."""
    m = metrics
    lr = m["landmark_residual"]
    fmt = h.fmt
    rows = [
        ("status", m["status"]),
        ("source", f"{m['source']['file']} — {m['source']['vertices']} vertices, "
                   f"{m['source']['faces']} faces, {m['source']['holes_closed']} holes closed"),
        ("target", f"{m['target']['file']} — {m['target']['vertices']} vertices, "
                   f"{m['target']['faces']} faces, {m['target']['holes_closed']} holes closed"),
        ("landmarks", f"{m['landmarks']['count']} paired by {m['landmarks']['paired_by']}"),
        *_map_rows(m),
        ("deformation", f"{m['deformation']['energy']} "
                        f"{'kernel' if m.get('domain') == 'sphere' else 'energy'}, "
                        f"{m['deformation']['method']}, "
                        f"{m['deformation']['accepted_substeps']} sub-steps accepted, "
                        f"{m['deformation']['rejected_substeps']} rejected"),
        ("flipped faces" if m.get("domain") != "sphere" else "folded faces on the sphere",
         m["flipped_faces"]),
        ("landmark residual before deformation (mean / max, ÷ diagonal)",
         f"{fmt(lr['before']['mean'])} / {fmt(lr['before']['max'])}"),
        ("landmark residual after (max, ÷ diagonal)",
         fmt(lr["after"]["max"]) if lr["after"] else "–"),
        ("target bounding-box diagonal", f"{m['target_bbox_diagonal']:.4g}"),
        ("source vertices mapped into filled holes",
         m.get("source_vertices_mapped_into_filled_holes", "–")),
        ("time, ours (s)", f"{m['seconds']['ours_total']:.2f}"),
    ]
    body = [h.kv_table(rows)]
    de = m.get("dense_error")
    if de:
        head = ["method", "mean", "95th pct", "max", "landmark residual max", "time (s)"]
        table = [["ours (SEM + bijective deformation)", fmt(de["ours"]["mean"]),
                  fmt(de["ours"]["p95"]), fmt(de["ours"]["max"]),
                  fmt(lr["after"]["max"] if lr["after"] else None),
                  f"{m['seconds']['ours_total']:.2f}"]]
        if "nricp_amberg" in de:
            b = m["baseline"]
            table.append(["trimesh nricp_amberg", fmt(de["nricp_amberg"]["mean"]),
                          fmt(de["nricp_amberg"]["p95"]), fmt(de["nricp_amberg"]["max"]),
                          fmt(b["landmark_residual"]["max"]), f"{b['seconds']:.2f}"])
        body.append(f"<h2>Dense error against the ground truth</h2><p>Truth: "
                    f"{h.esc(de['truth'])}. Distance between the registered position of "
                    f"source vertex i and truth vertex i, relative to the target's "
                    f"bounding-box diagonal, over {de['ours']['count']} vertices.</p>"
                    + h.table(head, table))
    body.append("<h2>Figures</h2>\n" + h.figures(figure_names))
    body.append('<p class="foot">Written by sem-pipeline register; numbers from '
                "metrics.json.</p>")
    return h.write_page(Path(folder) / "report.html", "sem-pipeline registration report",
                        "\n".join(body), h1="Landmark registration on the equiareal "
                        + ("sphere" if m.get("domain") == "sphere" else "disk"))
