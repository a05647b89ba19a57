"""Figures of a registration (written by :func:`pipeline.stages.register.write_registration`).

* ``disks.png`` — (a) the source disk after the alignment with its landmarks, (b) the target
  disk with its landmarks, (c) before the deformation: a line from every aligned source landmark
  to its target landmark, (d) the deformed source disk (landmarks on their targets; flipped
  faces, if any, filled red).
* ``surfaces.png`` — source, registered (ours), target (and nricp_amberg's result with
  ``--baseline``), shaded, one camera.
* ``error_on_face.png`` (with a ground truth) — the dense error per vertex on the truth surface,
  ours and the baseline's on one colour scale, and their cumulative distributions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.tri import Triangulation

from ..geometry.metrics import signed_double_areas
from ..geometry.register import as_uv
from .render import camera_for, draw_surface, new_figure, save_figure

SRC_COLOR = "tab:blue"
TGT_COLOR = "tab:red"


def _disk_axes(ax, title):
    t = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(t), np.sin(t), color="0.6", lw=0.6)
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=9)


def _mesh(ax, uv, F, alpha=0.35, color="0.45"):
    lw = 0.15 if len(F) > 4000 else 0.3
    ax.triplot(Triangulation(uv[:, 0], uv[:, 1], F), color=color, lw=lw, alpha=alpha)


def plot_disks(reg, path: Path) -> Path:
    S, T = reg.pair.source, reg.pair.target
    ua, ut, ud = as_uv(reg.alignment.z), np.asarray(reg.uv_target), as_uv(reg.deform.z)
    ps, pt = ua[S.landmarks], ut[T.landmarks]
    fig = new_figure(11.0, 11.4)
    axs = fig.subplots(2, 2)
    fig.subplots_adjust(left=0.02, right=0.98, top=0.9, bottom=0.02, wspace=0.06, hspace=0.16)
    kind = reg.alignment.kind
    _disk_axes(axs[0, 0], f"(a) source disk after the {kind} alignment\n"
                          f"{len(S.landmarks)} source landmarks (blue)")
    _mesh(axs[0, 0], ua, S.mesh.F)
    axs[0, 0].plot(ps[:, 0], ps[:, 1], "o", color=SRC_COLOR, ms=4)
    _disk_axes(axs[0, 1], "(b) target disk\ntarget landmarks (red)")
    _mesh(axs[0, 1], ut, T.mesh.F)
    axs[0, 1].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=4)
    lr = reg.metrics["landmark_residual"]["before"]
    _disk_axes(axs[1, 0], "(c) before the deformation: source → target landmark\n"
                          f"residual on the surface mean {lr['mean']:.2e}, max {lr['max']:.2e} "
                          f"× diagonal")
    _mesh(axs[1, 0], ut, T.mesh.F, alpha=0.12)
    for a, b in zip(ps, pt):
        axs[1, 0].plot([a[0], b[0]], [a[1], b[1]], "-", color="k", lw=0.8)
    axs[1, 0].plot(ps[:, 0], ps[:, 1], "o", color=SRC_COLOR, ms=3.5, label="source (aligned)")
    axs[1, 0].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=3.5, label="target")
    axs[1, 0].legend(loc="lower left", fontsize=8, frameon=False)
    flips = signed_double_areas(ud, S.mesh.F) <= 0
    de = reg.deform
    if de.ok:
        title = (f"(d) deformed source disk ({de.method}; {reg.energy} energy)\n"
                 f"landmarks on their targets, 0 flipped faces")
    else:
        title = (f"(d) FAILED: one-step solve, {int(flips.sum())} flipped faces (red)\n"
                 f"continuation stalled at {de.path_reached:.0%} of the landmark paths")
    _disk_axes(axs[1, 1], title)
    _mesh(axs[1, 1], ud, S.mesh.F, alpha=0.35)
    if flips.any():
        for f in S.mesh.F[flips]:
            axs[1, 1].fill(ud[f, 0], ud[f, 1], color="red", alpha=0.8)
    axs[1, 1].set_xlim(-1.05, 1.05)
    axs[1, 1].set_ylim(-1.05, 1.05)
    pd = ud[S.landmarks]
    axs[1, 1].plot(pt[:, 0], pt[:, 1], "o", color=TGT_COLOR, ms=5, mfc="none")
    axs[1, 1].plot(pd[:, 0], pd[:, 1], ".", color=SRC_COLOR, ms=4)
    fig.suptitle("Registration on the equiareal (SEM) disks", fontsize=11)
    return save_figure(fig, path)


def plot_surfaces(reg, path: Path) -> Path:
    from .register import display_faces

    S, T = reg.pair.source.mesh, reg.pair.target.mesh
    Fs, Ft = display_faces(S), display_faces(T)
    panels = [("source", S.V, Fs, reg.pair.source.landmarks, S.V),
              ("registered (ours): source mesh\non the target surface", reg.mapped, Fs,
               reg.pair.source.landmarks, reg.mapped),
              ("target", T.V, Ft, reg.pair.target.landmarks, T.V)]
    if reg.baseline is not None:
        X = reg.baseline["points"]
        keep = np.isfinite(X[Fs]).all(axis=(1, 2))
        panels.append(("nricp_amberg (baseline)", np.where(np.isfinite(X), X, 0.0), Fs[keep],
                       reg.pair.source.landmarks, X))
    cam_s = camera_for(S.V, Fs)
    cam_t = camera_for(T.V, Ft, extra=[reg.mapped])
    fig = new_figure(3.6 * len(panels), 4.2)
    for k, (title, V, F, lm, P) in enumerate(panels):
        ax = fig.add_axes((k / len(panels), 0.0, 1.0 / len(panels), 0.86))
        cam = cam_s if k == 0 else cam_t
        draw_surface(ax, V, F, cam)
        q, _ = cam.project(P[lm])
        ax.plot(q[:, 0], q[:, 1], ".", color=TGT_COLOR if k else SRC_COLOR, ms=3)
        fig.text((k + 0.5) / len(panels), 0.9, title, ha="center", fontsize=9)
    return save_figure(fig, path)


def plot_error(reg, path: Path) -> Path:
    from .register import display_faces

    S = reg.pair.source.mesh
    Fs = display_faces(S)
    truth = np.array(reg.mapped)
    ok = (S.source_index >= 0) & (S.source_index < len(reg.pair.truth))
    tv = reg.pair.truth[S.source_index[ok]]
    good = np.isfinite(tv).all(axis=1)
    truth[np.flatnonzero(ok)[good]] = tv[good]
    series = [("ours", reg.error)]
    if reg.baseline is not None and reg.baseline.get("error") is not None:
        series.append(("nricp_amberg", reg.baseline["error"]))
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
    fig.suptitle(f"Dense error on the ground truth ({reg.pair.truth_label})", fontsize=10,
                 y=0.995)
    return save_figure(fig, path)


def write_all(reg, folder: Path) -> list[Path]:
    out = [plot_disks(reg, folder / "disks.png")]
    if reg.mapped is not None:
        out.append(plot_surfaces(reg, folder / "surfaces.png"))
        if reg.error is not None:
            out.append(plot_error(reg, folder / "error_on_face.png"))
    return out
