"""The morph stage's report: the animation, the filmstrip and a small ``report.html``.

* ``morph.gif`` — every frame rendered by one camera (fitted to all frames, so scale and light
  stay put), loops forever;
* ``filmstrip.png`` — up to ``filmstrip_frames`` frames side by side, first and last included;
* ``report.html`` — the animation, the filmstrip and the numbers of ``morph.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.artifacts import atomic_write
from . import html as h
from .figure import camera_for, new_figure, render_rgb, save_png

__all__ = ["render_frames", "write_gif", "write_filmstrip", "write_media", "write_report"]


def render_frames(frames: list[np.ndarray], faces: np.ndarray, times: np.ndarray, size: int,
                  progress=None) -> list[np.ndarray]:
    """Every frame (n×3 positions, one connectivity ``faces`` m×3) as an RGB image
    (size × size × 3, uint8) seen by one camera, labelled with its time ``t``."""
    cam = camera_for(frames[0], faces, extra=frames[1:])
    images = []
    for k, (t, V) in enumerate(zip(times, frames)):
        images.append(render_rgb(V, faces, cam, size, label=f"t = {t:.2f}"))
        if progress is not None:
            progress(k, len(frames))
    return images


def write_gif(path: Path, images: list[np.ndarray], frame_ms: int) -> Path:
    """The images as a looping GIF, ``frame_ms`` per frame, written atomically."""
    from PIL import Image

    gif = [Image.fromarray(im) for im in images]
    return atomic_write(path, lambda fh: gif[0].save(
        fh, format="GIF", save_all=True, append_images=gif[1:], duration=frame_ms, loop=0,
        optimize=False))


def write_filmstrip(path: Path, images: list[np.ndarray], times: np.ndarray, count: int
                    ) -> Path:
    """Up to ``count`` of the images, evenly spread (first and last included), side by side."""
    k = min(count, len(images))
    pick = np.unique(np.round(np.linspace(0, len(images) - 1, k)).astype(int))
    fig = new_figure(2.2 * len(pick), 2.5, dpi=110)
    for j, i in enumerate(pick):
        ax = fig.add_axes((j / len(pick), 0.0, 1.0 / len(pick), 0.88))
        ax.imshow(images[i])
        ax.set_axis_off()
        fig.text((j + 0.5) / len(pick), 0.93, f"frame {i}, t = {times[i]:.2f}", ha="center",
                 fontsize=8)
    return save_png(fig, path)


def write_media(folder: Path, frames: list[np.ndarray], faces: np.ndarray, times: np.ndarray,
                size: int, frame_ms: int, filmstrip_frames: int, progress=None) -> list[Path]:
    """``morph.gif`` and ``filmstrip.png`` of the frames into ``folder``."""
    folder = Path(folder)
    images = render_frames(frames, faces, times, size, progress)
    return [write_gif(folder / "morph.gif", images, frame_ms),
            write_filmstrip(folder / "filmstrip.png", images, times, filmstrip_frames)]


def write_report(folder: Path, metrics: dict) -> Path:
    """``report.html`` of the morph stage from ``metrics`` (the stage's ``morph.json``)."""
    files = metrics.get("files", {})
    rows = [("frames", metrics.get("frames")), ("easing", metrics.get("easing")),
            ("vertices", metrics.get("vertices")), ("faces", metrics.get("faces")),
            ("frame files", files.get("frames"))]
    rows += [(f"time: {k} (s)", float(v)) for k, v in metrics.get("seconds", {}).items()]
    body = [h.kv_table(rows, ".3g")]
    if files.get("animation"):
        body.append(h.figure(files["animation"], "The morph, source (t = 0) to registered "
                                                 "(t = 1), one camera for every frame."))
    if files.get("filmstrip"):
        body.append(h.figure(files["filmstrip"], "Evenly spaced frames."))
    body.append('<p class="foot">Written by sem-pipeline morph; numbers from morph.json.</p>')
    return h.write_page(Path(folder) / "report.html", "Morph", "\n".join(body))
