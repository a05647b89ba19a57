"""The remesh report's figures (:mod:`.remesh` writes the page): every mesh rendered the same
way, the smallest-angle and valence distributions of all methods, and our remesh on its domain.
Kept apart from the tables so that a run without a report never imports matplotlib."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import PolyCollection

from ..geometry.remesh_quality import point_mesh_distance
from .figure import camera_for, draw_surface, new_figure, save_png
from .remesh_methods import COLORS, LABELS, Method

DPI = 110


def _figure(width: float, height: float):
    return new_figure(width, height, dpi=DPI, layout="constrained")



MESH_COLOR = (0.78, 0.80, 0.84)        # a light blue-grey for every mesh in the renders


def _windows(view, methods: dict[str, Method], V_in, F_in):
    """Two zoom windows (about 14 of our edge lengths wide): the middle of the surface and the
    place where our remesh is farthest from the input."""
    sem = methods["sem"]
    P, depth = view.project(V_in)
    lo, hi = P.min(axis=0), P.max(axis=0)
    edge = sem.quality["triangles"]["mean_edge_length"]
    half = 7.0 * edge
    # middle: the input vertex nearest the centre of the view that faces the viewer
    centre = 0.5 * (lo + hi)
    front = np.argsort(np.linalg.norm(P - centre, axis=1))[:50]
    c1 = P[front[np.argmax(depth[front])]]
    C = sem.V[sem.F].mean(axis=1)
    d, _ = point_mesh_distance(C, V_in, F_in)
    worst = C[np.argmax(d)]
    c2, _ = view.project(worst[None])
    wins = []
    for c in (c1, c2[0]):
        wins.append(((c[0] - half, c[0] + half), (c[1] - half, c[1] + half)))
    return wins, float(d.max())


def plot_renders(path: Path, methods: dict[str, Method], V_in, F_in) -> Path:
    keys = [k for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic",
                        "fast_simplification") if methods.get(k) and methods[k].ok]
    view = camera_for(V_in, F_in, margin=0.02)
    wins, _ = _windows(view, methods, V_in, F_in)
    fig = _figure(3.0 * len(keys), 9.2)
    axs = fig.subplots(3, len(keys), squeeze=False)
    for j, k in enumerate(keys):
        m = methods[k]
        draw_surface(axs[0, j], m.V, m.F, view, shading="flat", color=MESH_COLOR)
        axs[0, j].set_title(f"{LABELS[k]}\n{len(m.V)} vertices, {len(m.F)} faces", fontsize=8)
        for i, w in enumerate(wins):
            draw_surface(axs[1 + i, j], m.V, m.F, view, shading="flat", color=MESH_COLOR,
                         window=w, edges=True)
            for (x0, x1), (y0, y1) in [w]:
                axs[0, j].plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0],
                               color=("tab:red" if i else "tab:purple"), lw=0.8)
    axs[1, 0].set_ylabel("zoom: middle (purple box)", fontsize=8)
    axs[2, 0].set_ylabel("zoom: where ours is farthest\nfrom the input (red box)", fontsize=8)
    fig.suptitle("Same orthographic view for every mesh (flat shading; darker = back faces)",
                 fontsize=9)
    return save_png(fig, path, DPI)


def plot_min_angles(path: Path, methods: dict[str, Method]) -> Path:
    fig = _figure(6.4, 4.0)
    ax = fig.add_subplot()
    bins = np.linspace(0, 60, 61)
    for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic", "fast_simplification"):
        m = methods.get(k)
        if not m or not m.ok:
            continue
        mn = m.quality["triangles"]["_per_face_min_angle"]
        w = np.full(len(mn), 100.0 / len(mn))
        ax.hist(mn, bins=bins, weights=w, histtype="step", lw=1.6 if k == "sem" else 1.1,
                color=COLORS[k], label=f"{LABELS[k]} (mean {mn.mean():.1f}°)",
                ls="--" if k in ("input", "sem_lifted") else "-")
    ax.axvline(30, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("smallest angle of a face (degrees; 60° = equilateral)")
    ax.set_ylabel("faces (%) per 1° bin")
    ax.legend(fontsize=7, loc="upper left")
    ax.set_xlim(0, 60)
    return save_png(fig, path, DPI)


def plot_valence(path: Path, methods: dict[str, Method]) -> Path:
    fig = _figure(6.4, 3.6)
    ax = fig.add_subplot()
    keys = [k for k in ("input", "sem_lifted", "sem", "pymeshlab_isotropic",
                        "fast_simplification") if methods.get(k) and methods[k].ok]
    vals = np.arange(3, 11)
    width = 0.8 / len(keys)
    for i, k in enumerate(keys):
        h = methods[k].quality["valence"]["interior_histogram"]
        tot = sum(h.values())
        y = [100.0 * (h.get(str(v), 0) if v < 10 else
                      sum(c for k2, c in h.items() if int(k2) >= 10)) / tot for v in vals]
        ax.bar(vals - 0.4 + (i + 0.5) * width, y, width, color=COLORS[k], label=LABELS[k])
    ax.set_xticks(vals)
    ax.set_xticklabels([str(v) if v < 10 else "10+" for v in vals])
    ax.set_xlabel("valence of interior vertices (6 = regular)")
    ax.set_ylabel("interior vertices (%)")
    ax.legend(fontsize=7)
    return save_png(fig, path, DPI)


def plot_disk(path: Path, uv: np.ndarray, F: np.ndarray, methods: dict[str, Method]) -> Path:
    """Our remesh (disk positions ``uv`` n×2, faces ``F`` m×3) on the disk, faces coloured by
    their smallest angle on the surface; the whole disk and a zoom at the rim."""
    fig = _figure(11.0, 5.2)
    axs = fig.subplots(1, 2)
    mn = methods["sem"].quality["triangles"]["_per_face_min_angle"]
    for ax, zoom in zip(axs, (False, True)):
        pc = PolyCollection(uv[F], array=mn, cmap="RdYlGn", clim=(0, 60),
                            edgecolors="k" if zoom else "none",
                            linewidths=0.2 if zoom else 0, rasterized=True)
        ax.add_collection(pc)
        ax.set_aspect("equal")
        if zoom:
            ax.set_xlim(0.70, 1.01)
            ax.set_ylim(-0.155, 0.155)
            ax.set_title("zoom at the rim (right edge of the disk)", fontsize=9)
        else:
            ax.set_xlim(-1.02, 1.02)
            ax.set_ylim(-1.02, 1.02)
            ax.set_title("the whole disk", fontsize=9)
    cb = fig.colorbar(pc, ax=list(axs), shrink=0.85)
    cb.set_label("smallest angle of the face on the surface (°)")
    fig.suptitle("Our remesh on the disk: faces coloured by their smallest angle on the surface "
                 "(red: skewed by the map's angle distortion)", fontsize=9)
    return save_png(fig, path, DPI)


def plot_sphere(path: Path, P: np.ndarray, F: np.ndarray, methods: dict[str, Method]) -> Path:
    """Our remesh on the sphere (positions ``P`` n×3 unit vectors, faces ``F`` m×3), faces
    coloured by their smallest angle on the surface: the hemispheres z ≥ 0 and z ≤ 0, each seen
    from outside along the z axis (orthographic), only the faces turned towards the viewer."""
    fig = _figure(11.0, 5.2)
    axs = fig.subplots(1, 2)
    mn = methods["sem"].quality["triangles"]["_per_face_min_angle"]
    for ax, side in zip(axs, (1.0, -1.0)):
        T = P[F]                                                      # (m, 3, 3)
        facing = side * T[:, :, 2].mean(axis=1) > 0
        xy = T[facing][:, :, :2] * np.array([side, 1.0])             # seen from outside
        pc = PolyCollection(xy, array=mn[facing], cmap="RdYlGn", clim=(0, 60),
                            edgecolors="k", linewidths=0.1, rasterized=True)
        ax.add_collection(pc)
        ax.set_aspect("equal")
        ax.set_xlim(-1.02, 1.02)
        ax.set_ylim(-1.02, 1.02)
        ax.set_axis_off()
        ax.set_title(f"the {'northern' if side > 0 else 'southern'} hemisphere "
                     f"(z {'≥' if side > 0 else '≤'} 0), seen from outside", fontsize=9)
    cb = fig.colorbar(pc, ax=list(axs), shrink=0.85)
    cb.set_label("smallest angle of the face on the surface (°)")
    fig.suptitle("Our remesh on the sphere: faces coloured by their smallest angle on the "
                 "surface (red: skewed by the map's angle distortion)", fontsize=9)
    return save_png(fig, path, DPI)
