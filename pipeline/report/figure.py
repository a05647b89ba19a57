"""The figure toolkit every report uses: Agg figures, one camera, one shading, one PNG save.

* The matplotlib backend is set to ``Agg`` here, once, before anything else of matplotlib is
  imported by :mod:`pipeline.report`. Figures are :class:`matplotlib.figure.Figure` objects with
  an Agg canvas, never registered with pyplot, so nothing is left open and the functions are
  safe to call from threads.
* :func:`camera_for` — an orthographic view along the normal of a mesh's best-fit plane (PCA),
  from the side its face normals point to, with the mesh's ``+y`` up when the plane allows it
  (faces and most scans are stored y-up); the light is a fixed direction near the viewer,
  slightly above left. Fixed once and reused, so several meshes or frames are seen the same way.
* :func:`draw_surface` — faces painted back to front with Lambert shading (back faces dark)
  times their colour: ``"gouraud"`` interpolates area-weighted vertex normals' shades through
  Agg's ``draw_gouraud_triangles``; ``"flat"`` shades each face by its own normal and can draw
  the edges.
* :func:`save_png` — writes a figure through :func:`pipeline.io.artifacts.atomic_write`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
from matplotlib.artist import Artist, allow_rasterization  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ..io.artifacts import atomic_write  # noqa: E402

__all__ = ["BASE_COLOR", "Camera", "camera_for", "draw_surface", "new_figure", "render_rgb",
           "save_png", "unit_disk_axes"]

BASE_COLOR = (0.86, 0.78, 0.70)      # a neutral skin-like grey-beige


def new_figure(width_in: float, height_in: float, dpi: int = 100,
               layout: str | None = None) -> Figure:
    """A figure with an Agg canvas (not known to pyplot)."""
    fig = Figure(figsize=(width_in, height_in), dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Figure, path, dpi: int = 110) -> Path:
    """Save ``fig`` as a PNG at ``path`` atomically, release it and return the path."""
    try:
        return atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi))
    finally:
        fig.clear()


# ------------------------------------------------------------------------------------ camera


@dataclass(frozen=True)
class Camera:
    """An orthographic view: screen axes ``right``, ``up`` and ``toward`` (the viewer), all
    unit 3-vectors forming a right-handed frame around ``centre``; a unit ``light`` direction;
    the screen window ``xlim``, ``ylim`` in the mesh's units."""

    centre: np.ndarray
    right: np.ndarray
    up: np.ndarray
    toward: np.ndarray
    light: np.ndarray
    xlim: tuple[float, float]
    ylim: tuple[float, float]

    def project(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Screen positions (n×2) and depth towards the viewer (n) of the points ``V`` (n×3)."""
        X = np.asarray(V, dtype=np.float64) - self.centre
        return np.column_stack([X @ self.right, X @ self.up]), X @ self.toward

    def rotated(self, R: np.ndarray) -> Camera:
        """The same camera turned in the screen plane: new screen positions are the old ones
        times ``R`` (2×2, det +1). The light turns with the screen (it stays above left); the
        window is kept (see :meth:`fitted`)."""
        right = R[0, 0] * self.right + R[1, 0] * self.up
        up = R[0, 1] * self.right + R[1, 1] * self.up
        return replace(self, right=right, up=up, light=_head_light(right, up, self.toward))

    def fitted(self, pts: list[np.ndarray], margin: float) -> Camera:
        """The same view with a square window around every point of ``pts`` (arrays k×3)."""
        P = np.vstack([self.project(p)[0] for p in pts])
        lo, hi = P.min(axis=0), P.max(axis=0)
        half = 0.5 * float(np.max(hi - lo)) * (1.0 + 2.0 * margin)
        mid = 0.5 * (lo + hi)
        return replace(self, xlim=(mid[0] - half, mid[0] + half),
                       ylim=(mid[1] - half, mid[1] + half))


def _head_light(right: np.ndarray, up: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """The light: from near the viewer, slightly above left on the screen (unit 3-vector)."""
    light = toward + 0.5 * up - 0.4 * right
    return light / np.linalg.norm(light)


def camera_for(V: np.ndarray, F: np.ndarray, extra: list[np.ndarray] | None = None,
               margin: float = 0.04) -> Camera:
    """A camera looking at ``V`` (n×3, faces ``F`` m×3) along the normal of its best-fit plane;
    the square window covers ``V`` and every array in ``extra`` (e.g. all morph frames) with a
    ``margin`` (fraction of the extent on each side).

    The in-plane orientation keeps the mesh's own ``+y`` as up when the plane allows it (faces in
    ICT-FaceKit and the sample are ``+y`` up), else the second principal axis."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    c = V.mean(axis=0)
    _, _, W = np.linalg.svd(V - c, full_matrices=False)
    normal = W[2]
    n_sum = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0)
    if n_sum @ normal < 0:
        normal = -normal
    y = np.array([0.0, 1.0, 0.0])
    up = y - (y @ normal) * normal
    if np.linalg.norm(up) < 0.3:
        up = W[1] - (W[1] @ normal) * normal
    up /= np.linalg.norm(up)
    right = np.cross(up, normal)
    cam = Camera(c, right, up, normal, _head_light(right, up, normal), (0.0, 1.0), (0.0, 1.0))
    return cam.fitted([V] + [np.asarray(e, dtype=np.float64) for e in (extra or [])], margin)


# ----------------------------------------------------------------------------------- shading


def _lambert(N: np.ndarray, cam: Camera) -> np.ndarray:
    """Shade in [0, 1] of unit normals ``N`` (k×3): Lambert on front faces, dim on back faces."""
    lam = N @ cam.light
    front = N @ cam.toward >= 0
    return np.where(front, 0.22 + 0.78 * np.clip(lam, 0.0, 1.0), 0.15 + 0.15 * np.abs(lam))


def _unit(N: np.ndarray) -> np.ndarray:
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def vertex_shading(V: np.ndarray, F: np.ndarray, cam: Camera) -> np.ndarray:
    """Shade per vertex (n) from area-weighted vertex normals."""
    Nf = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N = np.column_stack([np.bincount(F.ravel(), weights=np.repeat(Nf[:, j], 3),
                                     minlength=len(V)) for j in range(3)])
    return _lambert(_unit(N), cam)


def face_shading(V: np.ndarray, F: np.ndarray, cam: Camera) -> np.ndarray:
    """Shade per face (m) from the face normals."""
    return _lambert(_unit(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])), cam)


class _Gouraud(Artist):
    """Triangles (m×3×2, data coordinates) with one RGBA per corner (m×3×4), interpolated
    (Agg ``draw_gouraud_triangles``) and drawn in the given order."""

    def __init__(self, tris, colors, **kwargs):
        super().__init__()
        self.set(**kwargs)
        self._tris = np.ascontiguousarray(tris, dtype=np.float64)
        self._colors = np.ascontiguousarray(colors, dtype=np.float64)

    @allow_rasterization
    def draw(self, renderer):
        if not self.get_visible() or len(self._tris) == 0:
            return
        gc = renderer.new_gc()
        self._set_gc_clip(gc)
        renderer.draw_gouraud_triangles(gc, self._tris, self._colors, self.get_transform())
        gc.restore()
        self.stale = False


def _crop(P: np.ndarray, F: np.ndarray, window) -> np.ndarray:
    """Faces (indices into ``F``) whose centroid is within ``window`` widened by 15 %."""
    (x0, x1), (y0, y1) = window
    C = P[F].mean(axis=1)
    pad = 0.15 * (x1 - x0)
    return np.flatnonzero((C[:, 0] > x0 - pad) & (C[:, 0] < x1 + pad)
                          & (C[:, 1] > y0 - pad) & (C[:, 1] < y1 + pad))


def draw_surface(ax, V: np.ndarray, F: np.ndarray, cam: Camera, *, shading: str = "gouraud",
                 color=BASE_COLOR, face_rgb=None, vertex_values=None, norm=None, cmap=None,
                 edges: bool = False, window=None):
    """Draw the shaded surface ``V`` (n×3), ``F`` (m×3) into ``ax`` as ``cam`` sees it.

    Colour: per-vertex ``vertex_values`` (n) through ``norm``/``cmap``, or ``face_rgb`` (m×3),
    or the single ``color``. ``shading`` is ``"gouraud"`` (smooth) or ``"flat"`` (per face;
    ``edges`` draws the edges). ``window`` ``((x0, x1), (y0, y1))`` draws only the faces there
    and zooms to it; else the camera's window is shown. Returns a colorbar mappable when values
    were given, else the artist."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    P, depth = cam.project(V)
    if window is not None:
        keep = _crop(P, F, window)
        F = F[keep]
        face_rgb = None if face_rgb is None else np.asarray(face_rgb)[keep]
    if vertex_values is not None:
        rgb = matplotlib.colormaps[cmap](norm(np.asarray(vertex_values, np.float64)))[:, :3]
        corner = rgb[F]
    elif face_rgb is not None:
        corner = np.repeat(np.asarray(face_rgb, np.float64)[:, None, :3], 3, axis=1)
    else:
        corner = np.broadcast_to(np.asarray(color, np.float64), (len(F), 3, 3))
    order = np.argsort(depth[F].mean(axis=1), kind="stable")          # back to front
    if shading == "gouraud":
        rgba = np.ones((len(F), 3, 4))
        rgba[:, :, :3] = np.clip(corner * vertex_shading(V, F, cam)[F][:, :, None], 0.0, 1.0)
        art = _Gouraud(P[F[order]], rgba[order], transform=ax.transData, rasterized=True)
        ax.add_artist(art)
    elif shading == "flat":
        rgb = np.clip(corner.mean(axis=1) * face_shading(V, F, cam)[:, None], 0.0, 1.0)
        art = PolyCollection(P[F[order]], facecolors=rgb[order],
                             edgecolors=(0.05, 0.05, 0.1, 0.9) if edges else "none",
                             linewidths=0.35 if edges else 0.0, antialiased=edges,
                             rasterized=True)
        ax.add_collection(art)
    else:
        raise ValueError(f"unknown shading '{shading}'")
    xlim, ylim = window if window is not None else (cam.xlim, cam.ylim)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for s in ax.spines.values():
        s.set_visible(False)
    if vertex_values is not None:
        from matplotlib.cm import ScalarMappable
        return ScalarMappable(norm=norm, cmap=cmap)
    return art


def render_rgb(V: np.ndarray, F: np.ndarray, cam: Camera, size: int = 480,
               label: str | None = None) -> np.ndarray:
    """One shaded view as an RGB uint8 array (size × size × 3), white background."""
    fig = new_figure(size / 100.0, size / 100.0, dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    draw_surface(ax, V, F, cam)
    if label:
        ax.text(0.03, 0.03, label, transform=ax.transAxes, fontsize=max(7, size // 48),
                color="0.25")
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
    fig.clear()
    return rgb


def unit_disk_axes(ax, lim: float = 1.05, circle_color="0.6", circle_lw: float = 0.6,
                   spines: bool = True) -> None:
    """The unit circle, equal aspect, ``[-lim, lim]²`` and no ticks: the frame of a disk map."""
    t = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(np.cos(t), np.sin(t), color=circle_color, lw=circle_lw)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for s in ax.spines.values():
        s.set_visible(spines)
