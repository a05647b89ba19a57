"""Offscreen shaded orthographic renders of a surface (matplotlib Agg, no display needed).

A :class:`Camera` is fixed once (from a reference mesh) and reused, so a sequence of frames
(the morph) is seen from the same viewpoint, at the same scale and under the same light. The
view is orthographic along the normal of the reference's best-fit plane (PCA), from the side the
faces' normals point to; the light is a fixed direction near the viewer (slightly above left).
Faces are painted back to front with Gouraud-interpolated Lambert shading (area-weighted vertex
normals) times their colour, through Agg's ``draw_gouraud_triangles``.
"""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
from matplotlib.artist import Artist  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

__all__ = ["Camera", "camera_for", "draw_surface", "render_rgb", "new_figure", "save_figure"]

BASE_COLOR = (0.86, 0.78, 0.70)      # a neutral skin-like grey-beige


@dataclass(frozen=True)
class Camera:
    centre: np.ndarray        # 3
    right: np.ndarray         # 3, screen x
    up: np.ndarray            # 3, screen y
    toward: np.ndarray        # 3, towards the viewer
    light: np.ndarray         # 3, unit
    xlim: tuple[float, float]
    ylim: tuple[float, float]

    def project(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        X = V - self.centre
        return np.column_stack([X @ self.right, X @ self.up]), X @ self.toward


def camera_for(V: np.ndarray, F: np.ndarray, extra: list[np.ndarray] | None = None,
               margin: float = 0.04) -> Camera:
    """A camera looking at ``V`` along the normal of its best-fit plane; the screen limits cover
    ``V`` and every array in ``extra`` (e.g. all morph frames) with a ``margin``.

    The in-plane orientation keeps the mesh's own ``+y`` as up when the plane allows it (faces in
    ICT-FaceKit and the sample are ``+y`` up), else the second principal axis."""
    V = np.asarray(V, dtype=np.float64)
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
    light = normal + 0.5 * up - 0.4 * right
    light /= np.linalg.norm(light)
    pts = [V] + [np.asarray(e, dtype=np.float64) for e in (extra or [])]
    P = np.vstack([np.column_stack([(p - c) @ right, (p - c) @ up]) for p in pts])
    lo, hi = P.min(axis=0), P.max(axis=0)
    half = 0.5 * float(np.max(hi - lo)) * (1.0 + 2.0 * margin)
    mid = 0.5 * (lo + hi)
    return Camera(c, right, up, normal, light, (mid[0] - half, mid[0] + half),
                  (mid[1] - half, mid[1] + half))


class _Gouraud(Artist):
    """Triangles (m×3×2, data coordinates) with one RGBA per corner (m×3×4), drawn in order."""

    def __init__(self, tris, colors):
        super().__init__()
        self._tris = np.ascontiguousarray(tris, dtype=np.float64)
        self._colors = np.ascontiguousarray(colors, dtype=np.float64)

    def draw(self, renderer):
        if not self.get_visible() or len(self._tris) == 0:
            return
        gc = renderer.new_gc()
        self._set_gc_clip(gc)
        renderer.draw_gouraud_triangles(gc, self._tris, self._colors, self.get_transform())
        gc.restore()
        self.stale = False


def vertex_shading(V: np.ndarray, F: np.ndarray, cam: Camera) -> np.ndarray:
    """Lambert shade in [0, 1] per vertex (area-weighted normals; back faces dark)."""
    Nf = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N = np.column_stack([np.bincount(F.ravel(), weights=np.repeat(Nf[:, j], 3),
                                     minlength=len(V)) for j in range(3)])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    lam = N @ cam.light
    front = N @ cam.toward >= 0
    return np.where(front, 0.22 + 0.78 * np.clip(lam, 0.0, 1.0), 0.15 + 0.15 * np.abs(lam))


def draw_surface(ax, V: np.ndarray, F: np.ndarray, cam: Camera, face_rgb=None,
                 vertex_values=None, norm=None, cmap=None):
    """Draw the shaded surface into ``ax``. Colour: per-vertex values through ``norm``/``cmap``,
    or ``face_rgb`` (m×3), or :data:`BASE_COLOR`. Returns a colorbar mappable when values were
    given, else the artist."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    P, depth = cam.project(V)
    shade = vertex_shading(V, F, cam)
    if vertex_values is not None:
        rgb = matplotlib.colormaps[cmap](norm(np.asarray(vertex_values, np.float64)))[:, :3]
        corner = rgb[F]
    elif face_rgb is not None:
        corner = np.repeat(np.asarray(face_rgb, np.float64)[:, None, :3], 3, axis=1)
    else:
        corner = np.broadcast_to(np.asarray(BASE_COLOR), (len(F), 3, 3))
    rgba = np.ones((len(F), 3, 4))
    rgba[:, :, :3] = np.clip(corner * shade[F][:, :, None], 0.0, 1.0)
    order = np.argsort(depth[F].mean(axis=1), kind="stable")          # back to front
    art = _Gouraud(P[F[order]], rgba[order])
    art.set_transform(ax.transData)
    ax.add_artist(art)
    ax.set_xlim(*cam.xlim)
    ax.set_ylim(*cam.ylim)
    ax.set_aspect("equal")
    ax.set_axis_off()
    if vertex_values is not None:
        from matplotlib.cm import ScalarMappable
        return ScalarMappable(norm=norm, cmap=cmap)
    return art


def new_figure(width_in: float, height_in: float, dpi: int = 100) -> Figure:
    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def render_rgb(V: np.ndarray, F: np.ndarray, cam: Camera, size: int = 480,
               label: str | None = None) -> np.ndarray:
    """One frame as an RGB uint8 array (size × size pixels), white background."""
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


def save_figure(fig: Figure, path, dpi: int = 110):
    """Save a figure as PNG and release it."""
    fig.savefig(path, format="png", dpi=dpi)
    fig.clear()
    return path
