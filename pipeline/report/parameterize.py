"""The parameterize stage's report: the paper's figures of a disk map (Figs. 3, 4, 5 and 7, plus
a surface/disk view), their counterparts for a spherical map (the sphere from two sides and the
surface beside it, coloured by the local area ratio; the ratio histogram; the convergence of the
energy ratio), and ``report.html`` with the metrics table and the figures.

Every ``plot_*`` function is pure: arrays in, one PNG file out, the :class:`~pathlib.Path`
returned; parent folders are created and the file is written atomically
(:func:`.figure.save_png`), so a reader never sees a half-written PNG. Nothing is left open in
pyplot (``plt.get_fignums()`` stays empty) and the functions are safe to call from threads.

Every figure has a fixed pixel size, ``FIGURE_SIZES[name]`` inches × :data:`DPI` (no tight
bounding box; text is kept inside by the constrained layout engine).

Colour conventions
------------------
The local area ratio ``R(v)`` of eq. (29) is shown as ``log2 R(v)`` with a diverging colormap
centred at 0 (``R = 1``, equiareal): red where the surface area around ``v`` is *compressed* on
the disk (``R > 1``), blue where it is *stretched* (``R < 1``). ``log2`` makes a factor of 2 too
large and 2 too small equally strong; near 1 it is ``(R − 1)/ln 2``, so small deviations read
linearly. The colour limits are symmetric and robust (99th percentile of ``|log2 R|``), so the
few outliers (usually near the boundary or at creases) saturate instead of washing out the
structure; the colorbar ticks are labelled with ``R`` itself and its arrows say that values go
beyond the limits, and the figure states how many vertices do.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FixedLocator, MaxNLocator
from matplotlib.tri import Triangulation

from dataclasses import replace

from ..geometry.metrics import angular_distortion, local_area_ratios
from ..geometry.sphere_metrics import sphere_local_area_ratios
from . import html as h
from .figure import Camera, camera_for, draw_surface, new_figure, save_png, unit_disk_axes

__all__ = [
    "DPI",
    "FIGURE_SIZES",
    "plot_disk_area_ratio",
    "plot_area_ratio_histogram",
    "plot_convergence",
    "plot_surface_and_disk",
    "plot_angle_histogram",
    "log2_ratio_limit",
    "write_figures",
    "plot_sphere_area_ratio",
    "plot_surface_and_sphere",
    "plot_sphere_convergence",
    "sphere_display_rotation",
    "write_sphere_figures",
    "write_report",
]

DPI = 150
FIGURE_SIZES = {                       # inches; pixels = inches × DPI
    "disk_area_ratio": (6.4, 5.6),
    "area_ratio_histogram": (6.4, 4.4),
    "convergence": (7.2, 6.0),
    "surface_and_disk": (11.0, 5.4),
    "angle_histogram": (6.4, 4.4),
    "sphere_area_ratio": (11.0, 5.6),
    "surface_and_sphere": (11.0, 5.6),
    "sphere_convergence": (7.2, 5.0),
}

EDGE_FACE_LIMIT = 5000                 # draw mesh edges only up to this many faces
ROBUST_PERCENTILE = 99.0               # colour limit: this percentile of |log2 R|
MIN_LOG2_LIMIT = 1e-4                  # colour limit floor (|log2 R| of an exact map is ~0)
RATIO_CMAP = "RdBu_r"
PHASE_STYLE = {                        # history 'phase' -> (colour, marker, legend text)
    "harmonic": ("black", "s", "harmonic start"),
    "sem": ("tab:blue", "o", "SEM step (eq. 19–22)"),
    "gradient": ("tab:orange", "^", "preconditioned gradient step"),
}
SPHERE_PHASE_STYLE = {                 # spherical SEM history kind -> (colour, marker, legend)
    "start": ("black", "s", "Tutte + stereographic start"),
    "free+unfold": ("tab:purple", "D", "free half steps + unfolding"),
    "hemisphere": ("tab:blue", "o", "hemisphere iteration (eq. 22 per pole)"),
    "gradient": ("tab:orange", "^", "gradient phase (its last step)"),
    "newton": ("tab:green", "o", "Gauss–Newton step (fold barrier)"),
    "continuation": ("tab:olive", "v", "area continuation (end of each stage)"),
}


# ------------------------------------------------------------------------------------ helpers


def _new_figure(name: str):
    return new_figure(*FIGURE_SIZES[name], dpi=DPI, layout="constrained")



def _as_arrays(uv, F):
    uv = np.asarray(uv, dtype=np.float64)[:, :2]
    F = np.asarray(F, dtype=np.int64)
    return uv, F


def _finite_log2(ratio: np.ndarray, limit: float) -> np.ndarray:
    """``log2 R`` with non-finite values replaced so that drawing never fails: ``R = ∞`` (image
    area 0) and ``R = 0`` saturate at ``±limit``, NaN is drawn as 0 (it is counted separately)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.log2(np.asarray(ratio, dtype=np.float64))
    x = np.where(np.isnan(x), 0.0, x)
    return np.clip(x, -limit * 4, limit * 4)


def log2_ratio_limit(ratio: np.ndarray, percentile: float = ROBUST_PERCENTILE) -> float:
    """Symmetric robust colour limit for ``log2 R``: the ``percentile`` of ``|log2 R|`` over the
    finite positive ratios (at least :data:`MIN_LOG2_LIMIT`)."""
    r = np.asarray(ratio, dtype=np.float64)
    r = r[np.isfinite(r) & (r > 0)]
    if len(r) == 0:
        return 1.0
    return float(max(np.percentile(np.abs(np.log2(r)), percentile), MIN_LOG2_LIMIT))


def _tick_labels(ticks) -> list[str]:
    """Shortest fixed-point labels (1–6 decimals) that show every tick value exactly."""
    ticks = np.asarray(ticks, dtype=np.float64)
    scale = max(float(np.max(np.abs(ticks))), 1e-300) if len(ticks) else 1.0
    for d in range(1, 7):
        if np.all(np.abs(np.round(ticks, d) - ticks) <= 1e-9 * scale):
            break
    return [f"{t:.{d}f}" for t in ticks]


def _ratio_colorbar(fig, mappable, ax, limit: float, label: str, **kwargs):
    """Colorbar of ``log2 R`` on ``[−limit, limit]`` whose ticks are labelled with ``R``."""
    cb = fig.colorbar(mappable, ax=ax, extend="both", **kwargs)
    lo, hi = 2.0 ** -limit, 2.0 ** limit
    ticks = MaxNLocator(nbins=7, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
    ticks = ticks[(ticks >= lo) & (ticks <= hi) & (ticks > 0)]
    if len(ticks) < 3:
        ticks = np.array([lo, 1.0, hi])
    cb.set_ticks(FixedLocator(np.log2(ticks)))
    cb.set_ticklabels(_tick_labels(ticks))
    cb.set_label(label)
    return cb


def _outside_note(ratio: np.ndarray, limit: float) -> str:
    r = np.asarray(ratio, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.log2(r)
    above = int(np.count_nonzero(x > limit))
    below = int(np.count_nonzero(x < -limit))
    nan = int(np.count_nonzero(np.isnan(x)))
    n = max(len(r), 1)
    note = (f"colour range R ∈ [{2.0 ** -limit:.4g}, {2.0 ** limit:.4g}] (|log₂R| {ROBUST_PERCENTILE:g}th "
            f"pct.); saturated: {below} below, {above} above ({100.0 * (below + above) / n:.2g} %)")
    finite = r[np.isfinite(r)]
    if len(finite):
        note += f"; R from {finite.min():.4g} to {finite.max():.4g}"
    if nan:
        note += f"; {nan} undefined (drawn as 1)"
    return note


def _draw_disk(ax, uv, F, values, norm, cmap, *, edges: bool):
    """Gouraud-shaded disk image of per-vertex ``values``, unit circle, equal aspect, no ticks."""
    tri = Triangulation(uv[:, 0], uv[:, 1], F)
    mappable = ax.tripcolor(tri, values, shading="gouraud", cmap=cmap, norm=norm, rasterized=True)
    if edges:
        ax.triplot(tri, color="k", lw=0.15, alpha=0.35, rasterized=True)
    pad = 1.04 * max(1.0, float(np.max(np.abs(uv))) if len(uv) else 1.0)
    unit_disk_axes(ax, pad, circle_color="k", circle_lw=0.8, spines=False)
    return mappable


def _mesh_label(n_vertices: int, n_faces: int) -> str:
    return f"{n_vertices:,} vertices, {n_faces:,} faces"


# ----------------------------------------------------------------------- 1. disk, Fig. 3 style


def plot_disk_area_ratio(uv, F, ratio_per_vertex, path, title=None) -> Path:
    """The disk image of the mesh coloured by the local area ratio ``R(v)`` of eq. (29).

    Gouraud-shaded ``log2 R(v)`` on a diverging colormap centred at ``R = 1`` with robust
    symmetric limits (see the module docstring), the unit circle, equal aspect, no ticks; mesh
    edges are drawn thinly up to :data:`EDGE_FACE_LIMIT` faces. Rasterized, so 10⁶ faces are fine.
    """
    uv, F = _as_arrays(uv, F)
    R = np.asarray(ratio_per_vertex, dtype=np.float64)
    limit = log2_ratio_limit(R)
    fig = _new_figure("disk_area_ratio")
    ax = fig.add_subplot()
    m = _draw_disk(ax, uv, F, _finite_log2(R, limit), Normalize(-limit, limit), RATIO_CMAP,
                   edges=len(F) <= EDGE_FACE_LIMIT)
    _ratio_colorbar(fig, m, ax, limit,
                    "local area ratio R(v), eq. (29) — log₂ colour scale\n"
                    "red: compressed on the disk (R > 1), blue: stretched (R < 1)",
                    shrink=0.9)
    finite = R[np.isfinite(R)]
    stats = (f"mean {finite.mean():.5f}, SD {finite.std():.2e}" if len(finite) else "no finite R")
    ax.set_title(f"{title or 'Disk image: local area ratio'}\n"
                 f"{_mesh_label(len(uv), len(F))}; R: {stats}", fontsize=10)
    fig.text(0.01, 0.005, _outside_note(R, limit), fontsize=6.5, color="0.3", ha="left",
             va="bottom")
    fig.get_layout_engine().set(rect=(0, 0.03, 1, 0.97))
    return save_png(fig, path, DPI)


# -------------------------------------------------------------------- 2. histogram, Fig. 4


def _histogram(ax, x, lo, hi, color):
    n = len(x)
    bins = int(np.clip(np.sqrt(max(n, 1)) * 1.5, 20, 120))
    inside = x[(x >= lo) & (x <= hi)]
    ax.hist(inside, bins=bins, range=(lo, hi), color=color, edgecolor="white", linewidth=0.3)
    ax.set_xlim(lo, hi)
    ax.set_ylabel("count")
    ax.grid(axis="y", alpha=0.3)


def plot_area_ratio_histogram(ratio_per_vertex, path, title=None) -> Path:
    """Histogram of the local area ratios ``R(v)`` (eq. 29) on their 0.5–99.5 percentile range
    (widened to contain 1), with mean and SD over all finite values in the legend, a line at the
    ideal ``R = 1`` and the number of values outside the shown range."""
    R = np.asarray(ratio_per_vertex, dtype=np.float64).ravel()
    finite = R[np.isfinite(R)]
    fig = _new_figure("area_ratio_histogram")
    ax = fig.add_subplot()
    if len(finite):
        lo, hi = np.percentile(finite, [0.5, 99.5])
        lo, hi = min(lo, 1.0), max(hi, 1.0)
        if hi - lo < 1e-9:
            lo, hi = lo - 1e-3, hi + 1e-3
        pad = 0.02 * (hi - lo)
        lo, hi = lo - pad, hi + pad
        _histogram(ax, finite, lo, hi, "tab:blue")
        mean, sd = finite.mean(), finite.std()
        d = int(np.clip(np.ceil(-np.log10(sd)) + 1, 3, 8)) if sd > 0 else 3
        below, above = int(np.sum(finite < lo)), int(np.sum(finite > hi))
        handles = [
            Patch(color="tab:blue", label=f"R(v), {len(finite):,} vertices"),
            Line2D([], [], color="k", ls="--", label="R = 1 (equiareal)"),
            Line2D([], [], color="tab:red", label=f"mean = {mean:.{d}f}"),
            Patch(color="tab:red", alpha=0.12, label=f"mean ± SD, SD = {sd:.2e}"),
        ]
        ax.axvspan(max(mean - sd, lo), min(mean + sd, hi), color="tab:red", alpha=0.12, lw=0,
                   zorder=0)
        ax.axvline(1.0, color="k", ls="--", lw=1)
        if lo <= mean <= hi:
            ax.axvline(mean, color="tab:red", lw=1)
        ax.legend(handles=handles, fontsize=8, loc="upper right")
        note = (f"shown: 0.5–99.5 percentile range; outside it: {below:,} below, {above:,} above\n"
                f"all R from {finite.min():.4g} to {finite.max():.4g}")
        if len(finite) < len(R):
            note += f"; {len(R) - len(finite):,} non-finite R left out"
        ax.set_xlabel("local area ratio R(v), eq. (29)\n" + note, fontsize=9)
        ax.xaxis.label.set_linespacing(1.6)
        ax.ticklabel_format(axis="x", useOffset=False)
    else:
        ax.text(0.5, 0.5, "no finite area ratio", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_title(title or "Local area ratios", fontsize=11)
    return save_png(fig, path, DPI)


# --------------------------------------------------------------------- 5. angles, Fig. 5


def plot_angle_histogram(angular_distortion_deg, path, title=None) -> Path:
    """Histogram of the angular distortion ``|angle on M − angle on the disk|`` (degrees, one value
    per corner) up to its 99.5th percentile, with mean, SD and median in the legend."""
    a = np.asarray(angular_distortion_deg, dtype=np.float64).ravel()
    a = a[np.isfinite(a)]
    fig = _new_figure("angle_histogram")
    ax = fig.add_subplot()
    if len(a):
        hi = float(np.percentile(a, 99.5))
        hi = hi if hi > 0 else max(float(a.max()), 1.0)
        hi *= 1.02
        _histogram(ax, a, 0.0, hi, "tab:green")
        mean, sd, med = a.mean(), a.std(), np.median(a)
        handles = [
            Patch(color="tab:green", label=f"{len(a):,} corners"),
            Line2D([], [], color="tab:red", label=f"mean = {mean:.2f}°, SD = {sd:.2f}°"),
            Line2D([], [], color="k", ls=":", label=f"median = {med:.2f}°"),
        ]
        if mean <= hi:
            ax.axvline(mean, color="tab:red", lw=1)
        ax.axvline(med, color="k", ls=":", lw=1)
        ax.legend(handles=handles, fontsize=8, loc="upper right")
        above = int(np.sum(a > hi))
        ax.set_xlabel("angular distortion |angle on M − angle on the disk| (degrees)\n"
                      f"shown up to the 99.5th percentile; {above:,} corners above it\n"
                      f"(max {a.max():.1f}°)", fontsize=9)
        ax.xaxis.label.set_linespacing(1.6)
    else:
        ax.text(0.5, 0.5, "no angles", ha="center", va="center", transform=ax.transAxes)
    ax.set_title(title or "Angular distortion", fontsize=11)
    return save_png(fig, path, DPI)


# ----------------------------------------------------------------- 3. convergence, Fig. 7


def _phase_a_end(history) -> int | None:
    """Index of the last entry of the plain-SEM phase A: the last 'sem' entry before the first
    'gradient' one (None if no gradient step was taken, i.e. no phase B is visible)."""
    phases = [h.get("phase") for h in history]
    if "gradient" not in phases:
        return None
    first = phases.index("gradient")
    return first - 1


def _positive(x, floor=1e-16):
    x = np.asarray(x, dtype=np.float64)
    return np.where(np.isfinite(x), np.maximum(x, floor), np.nan)


def plot_convergence(history, path, title=None) -> Path:
    """Convergence of SEM (Fig. 7): per accepted iterate, the excess energy ratio
    ``E_S/(|f(M)|²/|M|) − 1`` (top, log scale) and the total area distortion of eq. (28) with the
    face-based area distortion (bottom, log scale). Markers are coloured by step kind (harmonic
    start, SEM step, gradient step); the plain SEM phase and the monotone descent phase are
    shaded; flipped faces, if any, get a third panel."""
    hist = list(history)
    it = np.array([h.get("iteration", i) for i, h in enumerate(hist)], dtype=np.float64)
    phase = np.array([str(h.get("phase", "sem")) for h in hist], dtype=object)
    ratio = np.array([h.get("energy_ratio", np.nan) for h in hist], dtype=np.float64)
    d28 = np.array([h.get("total_area_distortion_eq28", np.nan) for h in hist], dtype=np.float64)
    dface = np.array([h.get("face_area_distortion", np.nan) for h in hist], dtype=np.float64)
    flips = np.array([h.get("flipped_faces", 0) or 0 for h in hist], dtype=np.float64)
    seconds = [h.get("seconds") for h in hist]
    any_flips = bool(np.any(flips > 0))

    fig = _new_figure("convergence")
    heights = [3, 3, 1.4] if any_flips else [3, 3]
    axes = fig.subplots(len(heights), 1, sharex=True, gridspec_kw={"height_ratios": heights})
    ax_e, ax_d = axes[0], axes[1]

    if len(hist) == 0:
        ax_e.text(0.5, 0.5, "empty history", ha="center", va="center", transform=ax_e.transAxes)
    else:
        end_a = _phase_a_end(hist)
        x_lo, x_hi = it.min() - 0.5, it.max() + 0.5
        for ax in axes:
            if end_a is not None:
                split = 0.5 * (it[end_a] + it[end_a + 1])
                ax.axvspan(x_lo, split, color="tab:blue", alpha=0.06, lw=0)
                ax.axvspan(split, x_hi, color="tab:orange", alpha=0.07, lw=0)
                ax.axvline(split, color="0.4", lw=0.8, ls="--")
            ax.grid(alpha=0.3, which="major")
            ax.set_xlim(x_lo, x_hi)
        ms = 3.0 if len(hist) <= 400 else 1.5

        excess = _positive(ratio - 1.0)
        ax_e.plot(it, excess, color="0.5", lw=0.8, zorder=1)
        for name in dict.fromkeys(phase):
            sel = phase == name
            colour, marker, label = PHASE_STYLE.get(name, ("tab:gray", "o", name))
            ax_e.plot(it[sel], excess[sel], ls="none", marker=marker, ms=ms, color=colour,
                      label=label, zorder=2)
        ax_e.set_yscale("log")
        ax_e.set_ylabel("E_S / (|f(M)|²/|M|) − 1")
        ax_e.set_title("energy ratio − 1 (0 iff equiareal)", fontsize=9, loc="left")
        if end_a is not None:
            ax_e.text(0.5 * (x_lo + split), 1.0, "phase A: plain SEM", transform=ax_e.get_xaxis_transform(),
                      ha="center", va="bottom", fontsize=7, color="tab:blue", clip_on=False)
            ax_e.text(0.5 * (split + x_hi), 1.0, "phase B: monotone descent",
                      transform=ax_e.get_xaxis_transform(), ha="center", va="bottom",
                      fontsize=7, color="tab:orange", clip_on=False)
            ax_e.set_title("")
            ax_e.set_title("energy ratio − 1 (0 iff equiareal)", fontsize=9, loc="left", pad=12)
        ax_e.legend(fontsize=7, loc="upper right", markerscale=1.5)

        ax_d.plot(it, _positive(d28), color="tab:purple", lw=1.0, marker=".", ms=ms,
                  label="total area distortion D(f), eq. (28)")
        ax_d.plot(it, _positive(dface), color="tab:green", lw=1.0, marker=".", ms=ms,
                  label="face-based: Σ_τ | |τ|/|M| − |f(τ)|/|f(M)| |")
        ax_d.set_yscale("log")
        ax_d.set_ylabel("area distortion")
        ax_d.legend(fontsize=7, loc="upper right")
        summary = (f"final: ratio − 1 = {excess[-1]:.2e}, D = {d28[-1]:.2e}, "
                   f"face-based = {dface[-1]:.2e}")
        ax_d.set_title(summary, fontsize=8, loc="left")

        if any_flips:
            ax_f = axes[2]
            ax_f.bar(it, flips, width=0.8, color="tab:red")
            ax_f.set_ylabel("flipped\nfaces", fontsize=8)
            ax_f.set_ylim(0, max(1.0, flips.max()) * 1.15)
        axes[-1].set_xlabel("iteration")

    total = seconds[-1] if seconds and seconds[-1] is not None else None
    sub = f"{len(hist)} recorded iterates"
    if len(hist):
        sub += f", last iteration {int(it.max())}"
    if total is not None:
        sub += f", {float(total):.2f} s"
    if any_flips:
        sub += f", flipped faces: {int(flips[-1])} at the end (max {int(flips.max())})"
    elif len(hist):
        sub += ", no flipped faces"
    fig.suptitle(f"{title or 'SEM convergence'}\n{sub}", fontsize=10)
    return save_png(fig, path, DPI)


# ------------------------------------------------------------- 4. surface next to its disk


def _align_rotation(P, uv):
    """Rotation (2×2, det +1) that best maps the centred points ``P`` onto ``uv`` (Procrustes)."""
    A = (P - P.mean(axis=0)).T @ (uv - uv.mean(axis=0))
    U, _, Wt = np.linalg.svd(A)
    R = U @ Wt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Wt
    return R


def plot_surface_and_disk(V, F, uv, values, path, title=None, *, value_label=None) -> Path:
    """The surface (left) and its disk image (right) coloured by the same per-vertex ``values``.

    The surface is drawn by the report camera (:func:`.figure.camera_for`: orthographic onto its
    best-fit plane, from the side its normals point to), turned in the plane to best match the
    disk (so corresponding regions sit in the same place), Gouraud-shaded times the colour.
    ``values`` is per vertex. Without ``value_label``, positive values with a median in
    (0.5, 2) are taken to be the local area ratio ``R(v)`` and drawn as ``log2 R`` exactly like
    :func:`plot_disk_area_ratio`; any other values, or any values given with a ``value_label``
    (the colorbar label), are drawn on viridis with robust 1–99 percentile limits.
    """
    V = np.asarray(V, dtype=np.float64)
    uv, F = _as_arrays(uv, F)
    vals = np.asarray(values, dtype=np.float64).ravel()
    finite = vals[np.isfinite(vals)]
    is_ratio = (len(finite) > 0 and np.all(finite > 0)
                and 0.5 < float(np.median(finite)) < 2.0 and value_label is None)
    if is_ratio:
        limit = log2_ratio_limit(vals)
        draw = _finite_log2(vals, limit)
        norm, cmap = Normalize(-limit, limit), RATIO_CMAP
    else:
        if len(finite):
            lo, hi = np.percentile(finite, [1.0, 99.0])
        else:
            lo, hi = 0.0, 1.0
        if hi <= lo:
            lo, hi = lo - 0.5, hi + 0.5
        fill = 0.5 * (lo + hi)
        draw = np.where(np.isfinite(vals), vals, fill)
        norm, cmap = Normalize(lo, hi), "viridis"

    cam = camera_for(V, F)
    cam = cam.rotated(_align_rotation(cam.project(V)[0], uv)).fitted([V], 0.03)

    fig = _new_figure("surface_and_disk")
    ax_s, ax_d = fig.subplots(1, 2)
    draw_surface(ax_s, V, F, cam, vertex_values=draw, norm=norm, cmap=cmap)
    ax_s.set_title("surface M (orthographic view on its best-fit plane,\n"
                   "rotated to match the disk; shaded)", fontsize=9)

    m = _draw_disk(ax_d, uv, F, draw, norm, cmap, edges=len(F) <= EDGE_FACE_LIMIT)
    ax_d.set_title("disk image f(M)", fontsize=9)
    if is_ratio:
        _ratio_colorbar(fig, m, [ax_s, ax_d], limit,
                        "local area ratio R(v), eq. (29), log₂ colour scale\n"
                        "red: compressed on the disk, blue: stretched",
                        shrink=0.85, pad=0.02)
    else:
        cb = fig.colorbar(m, ax=[ax_s, ax_d], extend="both", shrink=0.85, pad=0.02)
        cb.set_label(value_label or "value per vertex (1–99 percentile colour range)")
    fig.suptitle(f"{title or 'Surface and its disk parameterization'}\n"
                 f"{_mesh_label(len(V), len(F))}", fontsize=10)
    return save_png(fig, path, DPI)


# ------------------------------------------------------------------------- the stage's files


def write_figures(folder: Path, V, F, uv, history) -> list[Path]:
    """The paper's figures of the map ``uv`` (n×2) of ``V`` (n×3), ``F`` (m×3) with its SEM
    ``history`` (one dict per iterate) into ``folder``."""
    folder = Path(folder)
    R = local_area_ratios(V, F, uv)
    return [
        plot_disk_area_ratio(uv, F, R, folder / "disk_area_ratio.png"),
        plot_area_ratio_histogram(R, folder / "area_ratio_histogram.png"),
        plot_angle_histogram(angular_distortion(V, F, uv).ravel(),
                             folder / "angle_histogram.png"),
        plot_convergence(history, folder / "convergence.png"),
        plot_surface_and_disk(V, F, uv, R, folder / "surface_and_disk.png"),
    ]


# ------------------------------------------------------------------------- spherical maps


def sphere_display_rotation(V: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Rotation ``R`` (3, 3, det +1) that best turns the map ``S`` (n, 3) towards the surface's
    directions from its centroid, ``min Σ |R s_i − p_i|²`` with ``p_i`` the unit vectors of
    ``V − mean(V)`` (Kabsch), so that ``S @ R.T`` seen by the surface's camera shows the same
    regions where the surface shows them. Display only: the colours are per vertex."""
    P = np.asarray(V, np.float64) - np.mean(V, axis=0)
    P /= np.maximum(np.linalg.norm(P, axis=1, keepdims=True), 1e-300)
    U, _, Wt = np.linalg.svd(P.T @ np.asarray(S, np.float64))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Wt)) or 1.0])
    return U @ D @ Wt


def _sphere_cameras(V, F, S_view) -> tuple[Camera, Camera, Camera]:
    """The surface's camera (:func:`.figure.camera_for`), the same view of the unit sphere
    ``S_view`` (front) and the view from the opposite side (back; ``rotated`` by the identity
    recomputes the head light for the turned frame)."""
    cam = camera_for(V, F)
    front = replace(cam, centre=np.zeros(3)).fitted([S_view], 0.03)
    back = replace(front, right=-front.right, toward=-front.toward).rotated(np.eye(2))
    return cam, front, back


def _ratio_panels(name, panels, R, title):
    """A figure of ``panels`` (``(V (n, 3), F, camera, subtitle)``) all coloured by the local
    area ratio ``R`` (n,) as ``log2 R`` on the diverging scale of :func:`plot_disk_area_ratio`,
    with one colorbar, the title and the saturation note."""
    R = np.asarray(R, dtype=np.float64)
    limit = log2_ratio_limit(R)
    draw, norm = _finite_log2(R, limit), Normalize(-limit, limit)
    fig = _new_figure(name)
    axes = fig.subplots(1, len(panels))
    for ax, (P, F, cam, sub) in zip(axes, panels):
        m = draw_surface(ax, P, F, cam, vertex_values=draw, norm=norm, cmap=RATIO_CMAP)
        ax.set_title(sub, fontsize=9)
    _ratio_colorbar(fig, m, list(axes), limit,
                    "local area ratio R(v), eq. (29), log₂ colour scale\n"
                    "red: compressed on the sphere, blue: stretched",
                    shrink=0.85, pad=0.02)
    finite = R[np.isfinite(R)]
    stats = (f"mean {finite.mean():.5f}, SD {finite.std():.2e}" if len(finite) else "no finite R")
    F0 = panels[0][1]
    fig.suptitle(f"{title}\n{_mesh_label(len(R), len(F0))}; R: {stats}", fontsize=10)
    fig.text(0.01, 0.005, _outside_note(R, limit), fontsize=6.5, color="0.3", ha="left",
             va="bottom")
    fig.get_layout_engine().set(rect=(0, 0.03, 1, 0.97))
    return fig


def plot_sphere_area_ratio(V, F, S, ratio_per_vertex, path, title=None) -> Path:
    """The spherical image ``S`` (n, 3) of the surface ``V`` (n, 3), ``F`` (m, 3) from two
    opposite sides, coloured by the local area ratio ``R(v)`` of eq. (29) (the colours and
    limits of :func:`plot_disk_area_ratio`). The sphere is turned by
    :func:`sphere_display_rotation` and seen along the surface camera's axis (front) and
    against it (back)."""
    V, S = np.asarray(V, np.float64), np.asarray(S, np.float64)
    F = np.asarray(F, np.int64)
    Sv = S @ sphere_display_rotation(V, S).T
    _, front, back = _sphere_cameras(V, F, Sv)
    fig = _ratio_panels("sphere_area_ratio",
                        [(Sv, F, front, "unit sphere f(M), front\n(the surface camera's side)"),
                         (Sv, F, back, "unit sphere f(M), back")],
                        ratio_per_vertex, title or "Spherical image: local area ratio")
    return save_png(fig, path, DPI)


def plot_surface_and_sphere(V, F, S, ratio_per_vertex, path, title=None) -> Path:
    """The surface (left, the report camera of :func:`.figure.camera_for`) and its spherical
    image (right, turned by :func:`sphere_display_rotation` and seen from the same direction)
    coloured by the same local area ratio ``R(v)``, so corresponding regions match."""
    V, S = np.asarray(V, np.float64), np.asarray(S, np.float64)
    F = np.asarray(F, np.int64)
    Sv = S @ sphere_display_rotation(V, S).T
    cam, front, _ = _sphere_cameras(V, F, Sv)
    fig = _ratio_panels("surface_and_sphere",
                        [(V, F, cam, "surface M (orthographic view on its best-fit plane;\n"
                                     "shaded)"),
                         (Sv, F, front, "spherical image f(M), same view direction\n"
                                        "(sphere turned to match the surface)")],
                        ratio_per_vertex, title or "Surface and its spherical parameterization")
    return save_png(fig, path, DPI)


def _sphere_phase(entry: dict) -> str:
    """The kind of a spherical SEM history entry (keys of :data:`SPHERE_PHASE_STYLE`)."""
    phase = entry.get("phase")
    if phase is not None:
        return str(phase)
    return "start" if entry.get("iteration", 0) == 0 else "hemisphere"


def plot_sphere_convergence(history, path, title=None) -> Path:
    """Convergence of the spherical SEM: the excess energy ratio ``E_S·|M|/|f(M)|² − 1`` of the
    flat image triangles (the kernel's objective, eq. 15) of every recorded iterate against the
    elapsed seconds (log scale), markers by kind (:data:`SPHERE_PHASE_STYLE`; a gradient phase
    is one entry); folded faces in a second panel when there are any."""
    hist = list(history)
    t = np.array([h.get("seconds", np.nan) for h in hist], dtype=np.float64)
    excess = _positive(np.array([h.get("energy_ratio", np.nan) for h in hist], float) - 1.0)
    folds = np.array([h.get("folded_faces", 0) or 0 for h in hist], dtype=np.float64)
    kinds = np.array([_sphere_phase(h) for h in hist], dtype=object)
    any_folds = bool(np.any(folds > 0))
    fig = _new_figure("sphere_convergence")
    heights = [3, 1.2] if any_folds else [1]
    axes = np.atleast_1d(fig.subplots(len(heights), 1, sharex=True,
                                      gridspec_kw={"height_ratios": heights}))
    ax = axes[0]
    if len(hist):
        ax.plot(t, excess, color="0.5", lw=0.8, zorder=1)
        for kind in dict.fromkeys(kinds):
            sel = kinds == kind
            colour, marker, label = SPHERE_PHASE_STYLE.get(kind, ("tab:gray", "o", kind))
            ax.plot(t[sel], excess[sel], ls="none", marker=marker, ms=4, color=colour,
                    label=label, zorder=2)
        ax.set_yscale("log")
        ax.legend(fontsize=7, loc="upper right")
        ax.set_title(f"final: energy ratio − 1 = {excess[-1]:.3e}", fontsize=8, loc="left")
        if any_folds:
            axes[1].step(t, folds, where="post", color="tab:red")
            axes[1].set_ylabel("folded\nfaces", fontsize=8)
    else:
        ax.text(0.5, 0.5, "empty history", ha="center", va="center", transform=ax.transAxes)
    ax.set_ylabel("E_S / (|f(M)|²/|M|) − 1  (flat image triangles)")
    for a in axes:
        a.grid(alpha=0.3)
    axes[-1].set_xlabel("seconds")
    sub = f"{len(hist)} recorded iterates"
    if len(hist):
        sub += (f", {np.nanmax(t):.2f} s, folded faces at the end: {int(folds[-1])}"
                if np.isfinite(t).any() else "")
    fig.suptitle(f"{title or 'Spherical SEM convergence'}\n{sub}", fontsize=10)
    return save_png(fig, path, DPI)


def write_sphere_figures(folder: Path, V, F, S, history) -> list[Path]:
    """The figures of the spherical map ``S`` (n×3 unit vectors) of ``V`` (n×3), ``F`` (m×3)
    with its spherical SEM ``history`` into ``folder``."""
    folder = Path(folder)
    R = sphere_local_area_ratios(V, F, S)
    return [
        plot_sphere_area_ratio(V, F, S, R, folder / "sphere_area_ratio.png"),
        plot_area_ratio_histogram(R, folder / "area_ratio_histogram.png",
                                  title="Local area ratios on the sphere (geodesic areas)"),
        plot_sphere_convergence(history, folder / "convergence.png"),
        plot_surface_and_sphere(V, F, S, R, folder / "surface_and_sphere.png"),
    ]


CAPTIONS = {
    "disk_area_ratio.png": "The disk image coloured by the local area ratio R(v) of eq. (29) "
                           "(paper Fig. 3): 1 everywhere for an equiareal map.",
    "area_ratio_histogram.png": "Histogram of the local area ratios (paper Fig. 4).",
    "angle_histogram.png": "Angular distortion per corner (paper Fig. 5).",
    "convergence.png": "Convergence of SEM: energy ratio and area distortion per iterate "
                       "(paper Fig. 7).",
    "surface_and_disk.png": "The surface and its disk image, coloured by the same per-vertex "
                            "values.",
    "sphere_area_ratio.png": "The spherical image from two opposite sides, coloured by the "
                             "local area ratio R(v) of eq. (29) with geodesic triangle areas: "
                             "1 everywhere for an equiareal map.",
    "surface_and_sphere.png": "The surface and its spherical image seen from the same "
                              "direction, coloured by the same local area ratio.",
}
SPHERE_CAPTIONS = {
    "area_ratio_histogram.png": "Histogram of the local area ratios on the sphere (geodesic "
                                "triangle areas).",
    "convergence.png": "Convergence of the spherical SEM: excess energy ratio of every "
                       "recorded iterate against time.",
}


def write_report(folder: Path, metrics: dict, figure_names: list[str]) -> Path:
    """``report.html`` of the parameterize stage: the numbers of ``metrics`` (the stage's
    ``metrics.json``) and the figures ``figure_names`` (files in ``folder``)."""
    mesh = metrics.get("mesh", {})
    par = metrics.get("parameterization", {})
    dist = metrics.get("distortion", {})
    sphere = metrics.get("domain") == "sphere"
    rim = ("closed (no boundary)" if sphere
           else f"{mesh.get('boundary_vertices')} on the boundary")
    rows = [
        ("status", metrics.get("status")),
        ("domain", metrics.get("domain", "disk")),
        ("mesh", f"{mesh.get('vertices')} vertices, {mesh.get('faces')} faces, {rim}, "
                 f"{mesh.get('added_vertices')} added by the repair"),
        ("method", par.get("method")),
        ("mode", par.get("mode")),
        ("SEM status", par.get("status")),
        ("iterations", par.get("iterations")),
        ("linear solver", par.get("solver")),
    ]
    repairs = metrics.get("input", {}).get("repair_messages") or []
    rows += [("repairs by the intake", "; ".join(repairs))] if repairs else []
    rows += [(k.replace("_", " "), v) for k, v in dist.items()]
    if sphere:
        kernel = par.get("sphere_measures", {})
        rows += [("face area distortion, flat chord triangles (the kernel's objective)",
                  kernel.get("face_area_distortion")),
                 ("energy ratio, flat chord triangles", kernel.get("energy_ratio"))]
    captions = dict(CAPTIONS, **SPHERE_CAPTIONS) if sphere else CAPTIONS
    seconds = metrics.get("seconds", {})
    rows += [(f"time: {k} (s)", float(v)) for k, v in seconds.items()
             if isinstance(v, (int, float))]
    body = (h.kv_table(rows, ".6g")
            + ("<h2>Figures</h2>\n" + h.figures(figure_names, captions) if figure_names else "")
            + '\n<p class="foot">Written by sem-pipeline parameterize; numbers from '
              "metrics.json.</p>")
    title = "Spherical SEM parameterization" if sphere else "SEM disk parameterization"
    return h.write_page(Path(folder) / "report.html", title, body)
