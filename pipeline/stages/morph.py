"""Stage — morph a face into its registered image, and the files a person can open.

Input: the source vertices, the registered vertices (the source's vertices moved onto the
target surface by the registration) and the source faces (one connectivity). Output folder:

* ``frames/frame_000.obj`` … ``frame_{K−1}.obj`` —
  ``V(t_k) = (1 − t_k) V_source + t_k V_registered`` (:mod:`pipeline.geometry.morph`),
  ``t_0 = 0`` (the source) and ``t_{K−1} = 1`` (registered);
* ``morph.gif`` — the animation (shaded orthographic render, one camera, light and scale for all
  frames; loops forever);
* ``filmstrip.png`` — up to 6 frames side by side, first and last included;
* ``morph.json`` — frame count, easing, times, sizes;
* ``report.html`` — the animation, the filmstrip and those numbers.

The renders and the page are built by :mod:`pipeline.report.morph`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field

from ..errors import UserError
from ..geometry.morph import morph_frames
from ..io.artifacts import staged_output, write_json
from ..io.meshio import write_obj
from .stage import Context, Section, Stage


class MorphConfig(Section):
    """Morph from the source to its registered image: the stage's options.

    In a run it morphs the ``register`` stage's result; ``inputs`` (a registration folder or
    its ``registration.npz``, or a source and a registered mesh) morphs saved files instead.
    """

    inputs: Optional[list[str]] = Field(
        None, description="a 'register' output folder (or its registration.npz), or SOURCE and "
                          "REGISTERED meshes with the same connectivity")
    frames: int = Field(24, ge=2, le=2000, description="number of frames K")
    easing: Literal["linear", "ease-in-out", "cosine"] = "ease-in-out"
    frame_ms: int = Field(80, ge=10, le=10_000, description="GIF frame duration")
    size: int = Field(480, ge=64, le=2048, description="GIF frame size in pixels")
    filmstrip_frames: int = Field(6, ge=2, le=24, description="frames on filmstrip.png")


@dataclass
class Morph:
    """The ``morph`` artifact: the ``faces`` (m, 3) shared by every frame, the frame
    ``times`` (k,), the ``frames`` (k vertex arrays (n, 3)), the options and the metrics."""

    faces: np.ndarray
    times: np.ndarray
    frames: list
    options: MorphConfig
    metrics: dict = field(default_factory=dict)


def morph_stage(V_source, V_registered, F, options: MorphConfig | None = None) -> Morph:
    opt = options or MorphConfig()
    V0, V1 = np.asarray(V_source, np.float64), np.asarray(V_registered, np.float64)
    if V0.shape != V1.shape:
        raise UserError(f"source has {len(V0)} vertices but the registered mesh {len(V1)}; "
                        f"a morph needs the same connectivity (the registration's output)")
    times, frames = morph_frames(V0, V1, opt.frames, opt.easing)
    return Morph(np.asarray(F, np.int64), times, frames, opt,
                 {"frames": opt.frames, "easing": opt.easing, "times": times.tolist(),
                  "vertices": int(len(V0)), "faces": int(len(F))})


def write_morph(m: Morph, out_dir, progress=None) -> dict[str, Path]:
    """Write the frames, ``morph.gif``, ``filmstrip.png``, ``morph.json`` and ``report.html``
    all-or-nothing."""
    from ..report import morph as report

    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    written: dict[str, Path] = {}
    width = max(3, len(str(len(m.frames) - 1)))
    with staged_output(out_dir) as tmp:
        (tmp / "frames").mkdir()
        for k, (t, V) in enumerate(zip(m.times, m.frames)):
            write_obj(tmp / "frames" / f"frame_{k:0{width}d}.obj", V, m.faces,
                      header=f"sem-pipeline morph frame {k} of {len(m.frames)}, t = {t:.6f}")
        t1 = time.perf_counter()
        report.write_media(tmp, m.frames, m.faces, m.times, m.options.size, m.options.frame_ms,
                           m.options.filmstrip_frames, progress)
        t2 = time.perf_counter()
        m.metrics["seconds"] = {"frames_obj": t1 - t0, "render": t2 - t1}
        m.metrics["files"] = {"frames": f"frames/frame_{0:0{width}d}.obj … "
                                        f"frame_{len(m.frames) - 1:0{width}d}.obj",
                              "animation": "morph.gif", "filmstrip": "filmstrip.png"}
        write_json(tmp / "morph.json", m.metrics)
        report.write_report(tmp, m.metrics)
    written["frames"] = out_dir / "frames"
    written["gif"] = out_dir / "morph.gif"
    written["filmstrip"] = out_dir / "filmstrip.png"
    written["metrics"] = out_dir / "morph.json"
    written["report"] = out_dir / "report.html"
    return written


def check_morph_arrays(V0, V1, F, where: str):
    """``(V_source, V_registered, F)`` as float64, float64, int64 once they are a morph's
    inputs: n×3 finite positions twice, m ≥ 1 triangles indexing them; else a one-line
    :class:`UserError`."""
    V0, V1, F = np.asarray(V0), np.asarray(V1), np.asarray(F)
    n = len(V0)
    problem = None
    if V0.ndim != 2 or V0.shape[1:] != (3,) or n == 0 or V1.shape != V0.shape:
        problem = f"vertex arrays of shapes {V0.shape} and {V1.shape} (need two equal n×3)"
    elif not (np.issubdtype(V0.dtype, np.number) and np.issubdtype(V1.dtype, np.number)):
        problem = "non-numeric vertex arrays"
    elif not (np.isfinite(V0).all() and np.isfinite(V1).all()):
        problem = "NaN or infinite vertex positions"
    elif F.ndim != 2 or F.shape[1:] != (3,) or len(F) == 0 or \
            not np.issubdtype(F.dtype, np.integer):
        problem = f"faces of shape {F.shape} and type {F.dtype} (need m×3 integers)"
    elif F.min() < 0 or F.max() >= n:
        problem = f"face indices outside 0…{n - 1}"
    if problem:
        raise UserError(f"{where}: {problem}; re-run the registration that wrote it")
    return V0.astype(np.float64), V1.astype(np.float64), F.astype(np.int64)


def load_morph_inputs(paths: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(V_source, V_registered, F)`` from a registration folder / ``registration.npz``, or from
    two meshes with the same connectivity (source, registered)."""
    from ..io.meshio import read_mesh
    from ..geometry.repair import triangulate_polygons

    if len(paths) == 1:
        p = Path(paths[0])
        npz = p / "registration.npz" if p.is_dir() else p
        if not npz.is_file():
            raise UserError(f"'{p}' is not a registration folder (no registration.npz); pass "
                            f"the folder 'sem-pipeline register' wrote, or SOURCE and "
                            f"REGISTERED meshes")
        import zipfile

        try:
            with np.load(npz, allow_pickle=False) as z:
                arrays = z["source_vertices"], z["mapped_points"], z["source_faces"]
        except (KeyError, ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            reason = " ".join(str(exc).split())[:120] or type(exc).__name__
            raise UserError(f"{npz}: not a registration written by sem-pipeline register "
                            f"({reason}); re-run the registration") from None
        return check_morph_arrays(*arrays, where=str(npz))
    if len(paths) == 2:
        a, b = read_mesh(paths[0]), read_mesh(paths[1])
        Fa = triangulate_polygons(a.faces, len(a.V))[0]
        Fb = triangulate_polygons(b.faces, len(b.V))[0]
        if len(a.V) != len(b.V) or not np.array_equal(Fa, Fb):
            raise UserError(f"'{paths[0]}' and '{paths[1]}' do not share connectivity "
                            f"({len(a.V)} vs {len(b.V)} vertices); pass a source mesh and its "
                            f"registered.obj")
        return a.V, b.V, Fa
    raise UserError("morph takes a registration folder, or a source and a registered mesh")


def _run(ctx: Context) -> dict:
    mc = ctx.section("morph")
    if mc.inputs is not None:
        V0, V1, F = load_morph_inputs(mc.inputs)
    else:
        from ..geometry.repair import display_faces

        reg = ctx.artifacts["registration"]
        S = reg.pair.source.mesh
        V0, V1, F = S.V, reg.mapped, display_faces(S)
    return {"morph": morph_stage(V0, V1, F, mc)}


def _check(ctx: Context) -> None:
    """Refuse frames × size that do not fit in memory (every rendered frame is kept for the
    GIF and the filmstrip: ``size² × 4`` bytes each)."""
    from ..limits import check_memory

    mc = ctx.section("morph")
    check_memory(mc.frames * mc.size ** 2 * 4, f"morph: {mc.frames} frames of {mc.size}² "
                                                f"pixels", "ask for fewer frames or a smaller size")


def _write(ctx: Context, folder: Path) -> dict[str, Path]:
    return write_morph(ctx.artifacts["morph"], folder)


def _summary(ctx: Context, files: dict) -> str:
    m = ctx.artifacts["morph"]
    return (f"{m.options.frames} frames ({m.options.easing}) in frames/, animation morph.gif, "
            f"filmstrip filmstrip.png")


STAGE = Stage(name="morph", section=MorphConfig, run=_run, write=_write,
              needs=("registration",), needs_when=lambda mc: mc.inputs is None,
              makes=("morph",), positional=("inputs",), summary=_summary, check=_check,
              help="morph a face into its registered image (frames + GIF)")
