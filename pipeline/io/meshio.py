"""Reading and writing meshes.

:func:`read_mesh` returns the mesh *as given*: vertex order is kept exactly, polygons are not
triangulated (so the repair can count them), nothing is welded or cleaned — that is the job of
:mod:`pipeline.geometry.repair`. Supported formats:

* ``.obj`` — own parser: ``v x y z [w]`` or ``v x y z r g b [a]`` (per-vertex colours), ``f`` with
  ``v``, ``v/vt``, ``v/vt/vn`` or ``v//vn`` tokens, negative (relative) indices, polygons; every
  other statement (``vt``, ``vn``, ``g``, ``o``, ``usemtl``, comments …) is ignored; a UTF-8
  byte order mark at the start (as Windows editors save files) is skipped.
* ``.off`` — own parser for ASCII ``OFF``/``COFF``/``NOFF``/``CNOFF`` (colours from ``COFF``);
  the header's vertex and face counts must match the lines that follow, exactly.
* ``.ply``, ``.stl`` — via ``trimesh.load(path, process=False, force='mesh')`` (vertex order kept;
  an STL is a triangle soup whose duplicated corners the repair welds).
* ``.mat`` — MATLAB (v7 or older) via ``scipy.io.loadmat``: vertices ``V`` or ``v``, faces ``F`` or
  ``f`` (1-based), optional colours ``C`` or ``colors``.

Colours are float64 in [0, 1] (integer 0–255 data is divided by 255). Coordinates must be
finite and at most :data:`MAX_COORDINATE` in magnitude. Every failure is a
:class:`~pipeline.errors.UserError` with a one-line message.

:func:`write_obj` writes ``v``/``vt``/``f`` atomically (:func:`.artifacts.atomic_write`) using
one ``%``-format over all rows, which is fast for 10^6 faces and writes every float with its
shortest round-trip representation.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.errors import UserError, file_problem

from .artifacts import atomic_write

__all__ = ["RawMesh", "SUPPORTED_EXTENSIONS", "format_problem", "read_mesh", "write_obj"]

SUPPORTED_EXTENSIONS = (".obj", ".off", ".ply", ".stl", ".mat")
# Largest coordinate magnitude read: squared lengths and products of areas stay far from
# float64 overflow (≈ 1.8e308).
MAX_COORDINATE = 1e60
UTF8_BOM = b"\xef\xbb\xbf"


@dataclass
class RawMesh:
    """A mesh as read from disk.

    ``faces`` is an int64 m×3 array when every face is a triangle, else a list of int64 arrays
    (one polygon each, 0-based). ``colors`` is n×3 or n×4 float64 in [0, 1], or ``None``.
    """

    V: np.ndarray
    faces: np.ndarray | list
    colors: np.ndarray | None
    path: Path

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def all_triangles(self) -> bool:
        return isinstance(self.faces, np.ndarray)


# --------------------------------------------------------------------------------------------
# helpers


def _parse_numbers(text: str, dtype) -> np.ndarray:
    """Whitespace-separated numbers of ``dtype``; raises ValueError on anything unparsable
    (for integers also on tokens that are not integers)."""
    if dtype is np.int64 and re.search(r"[^\s0-9+\-]", text):
        raise ValueError("non-integer token")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return np.fromstring(text, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning) as exc:
            raise ValueError(str(exc)) from None


def _parse_floats(text: str) -> np.ndarray:
    return _parse_numbers(text, np.float64)


def _parse_ints(text: str) -> np.ndarray:
    return _parse_numbers(text, np.int64)


def _normalise_colors(C: np.ndarray | None, n: int, where: str) -> np.ndarray | None:
    """Colours to float64 n×3/n×4 in [0, 1]; 0–255 data (any value > 1) is divided by 255."""
    if C is None:
        return None
    C = np.asarray(C, dtype=np.float64)
    if C.ndim != 2 or C.shape[0] != n or C.shape[1] not in (3, 4):
        raise UserError(
            f"{where}: vertex colours have shape {C.shape}, expected {n}×3 or {n}×4; "
            f"fix or remove the colours"
        )
    if not np.all(np.isfinite(C)) or C.min(initial=0.0) < 0:
        raise UserError(f"{where}: vertex colours contain negative or non-finite values; fix them")
    if C.max(initial=0.0) > 1.0:
        C = C / 255.0
    return np.clip(C, 0.0, 1.0)


def _check_faces(faces, n: int, where: str):
    """Validate 0-based polygon indices against ``n`` vertices; return array or list."""
    if len(faces) == 0:
        raise UserError(f"{where}: no faces found; pass a surface mesh (not a point cloud)")
    if isinstance(faces, np.ndarray):
        lo, hi = int(faces.min()), int(faces.max())
    else:
        flat = np.concatenate(faces)
        lo, hi = int(flat.min()), int(flat.max())
    if lo < 0 or hi >= n:
        bad = lo if lo < 0 else hi
        raise UserError(
            f"{where}: face index {bad} (0-based) is out of range for {n} vertices; "
            f"fix the face list"
        )
    return faces


def _polygons(flat: np.ndarray, counts: np.ndarray):
    """Split ``flat`` by per-face ``counts``; m×3 array when all are triangles."""
    if np.all(counts == 3):
        return flat.reshape(-1, 3)
    return np.split(flat, np.cumsum(counts)[:-1])


# --------------------------------------------------------------------------------------------
# OBJ

_OBJ_V = re.compile(r"^[ \t]*v[ \t]+([^#\r\n]*)", re.M)
_OBJ_F = re.compile(r"^[ \t]*f[ \t]+([^#\r\n]*)", re.M)
_OBJ_VF = re.compile(r"^[ \t]*([vf])[ \t]+([^#\r\n]*)", re.M)
_SLASH = re.compile(r"/[^\s]*")


def _obj_vertex_numbers(vlines: list[str], where: str) -> tuple[np.ndarray, np.ndarray]:
    """The numbers of the ``v`` lines' texts ``vlines`` and the count on each line."""
    counts = np.fromiter((len(s.split()) for s in vlines), dtype=np.int64, count=len(vlines))
    try:
        flat = _parse_floats(" ".join(vlines))
    except ValueError:
        for i, s in enumerate(vlines):
            try:
                _parse_floats(s)
            except ValueError:
                raise UserError(
                    f"{where}: unparsable vertex line {i + 1} ('v {s.strip()[:40]}'); "
                    f"fix the file"
                ) from None
        raise UserError(f"{where}: unparsable vertex data; fix the file") from None
    return flat, counts


def _obj_vertices(flat: np.ndarray, counts: np.ndarray, where: str
                  ) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions and colours from the ``v`` lines' numbers ``flat`` and their per-line
    ``counts``."""
    if len(flat) != counts.sum() or counts.min() < 3:
        raise UserError(f"{where}: a vertex line has fewer than 3 coordinates; fix the file")
    if np.all(counts == counts[0]):
        rows = flat.reshape(-1, int(counts[0]))
        V = rows[:, :3].copy()
        k = int(counts[0])
    else:
        offsets = np.r_[0, np.cumsum(counts)[:-1]]
        k = int(counts.min())
        rows = flat[offsets[:, None] + np.arange(min(k, 7))]
        V = rows[:, :3].copy()
    C = None
    if k == 6:
        C = rows[:, 3:6]
    elif k >= 7:
        C = rows[:, 3:7]
    return V, _normalise_colors(C, len(V), where) if C is not None else None


def _obj_face_indices(flines: list[str], where: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw (1-based or negative) indices of all ``f`` lines, and per-line counts."""
    counts = np.fromiter((len(s.split()) for s in flines), dtype=np.int64, count=len(flines))
    text = " ".join(flines)
    if "/" in text:
        text = _SLASH.sub("", text)
    try:
        flat = _parse_ints(text)
    except ValueError:
        for i, s in enumerate(flines):
            try:
                _parse_ints(_SLASH.sub("", s))
            except ValueError:
                raise UserError(
                    f"{where}: unparsable face line {i + 1} ('f {s.strip()[:40]}'); fix the file"
                ) from None
        raise UserError(f"{where}: unparsable face data; fix the file") from None
    if len(flat) != counts.sum():
        raise UserError(f"{where}: unparsable face data; fix the file")
    return flat, counts


def _check_face_counts(counts: np.ndarray, where: str) -> None:
    if counts.min() < 3:
        i = int(np.argmax(counts < 3))
        raise UserError(
            f"{where}: face line {i + 1} has {int(counts[i])} vertices (need ≥ 3); fix the file"
        )


def _vertices_before(text: str) -> np.ndarray:
    """For each ``f`` line of the OBJ ``text``, the ``v`` lines before it."""
    kinds = [k for k, _ in _OBJ_VF.findall(text)]
    is_v = np.fromiter((k == "v" for k in kinds), dtype=bool, count=len(kinds))
    return np.cumsum(is_v)[~is_v]


def _line_of(raw: bytes, offset: int) -> int:
    """The 1-based line of byte ``offset`` of ``raw``, lines ending at ``\n``, ``\r\n`` or a
    lone ``\r`` (universal newlines)."""
    head = raw[:offset]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


def _check_no_nul(raw: bytes, where: str) -> None:
    """Refuse an OBJ file with a NUL byte (binary data, UTF-16 text or a file filled with
    zeros by a crash), naming the line of the first one."""
    nul = raw.find(b"\0")
    if nul >= 0:
        raise UserError(f"{where}: line {_line_of(raw, nul)}: NUL byte, not a text OBJ (binary "
                        f"or UTF-16 data); re-export the file as text")


def _read_obj(path: Path) -> RawMesh:
    """An OBJ file: its ``v`` and ``f`` numbers read in one compiled pass
    (:func:`._obj.obj_numbers`), or, for a file that pass leaves (anything but decimal
    numbers and integer face tokens in those statements), by the regular expressions and
    numpy's parsers here; both give the same numbers, and every error comes from the
    checks here in the same order. A file with a NUL byte (which the compiled pass leaves)
    is refused first (:func:`_check_no_nul`)."""
    from ._obj import obj_numbers

    where = str(path)
    try:
        raw = path.read_bytes().removeprefix(UTF8_BOM)
    except OSError as exc:
        raise UserError(f"cannot read '{path}': {exc.strerror}; check the path and permissions")
    numbers = obj_numbers(raw)
    if numbers is None:
        _check_no_nul(raw, where)
        # the text as read_text reads it: universal newlines
        text = raw.decode("utf-8", errors="replace").replace("\r\n", "\n").replace("\r", "\n")
        vlines, flines = _OBJ_V.findall(text), _OBJ_F.findall(text)
        n_v, n_f = len(vlines), len(flines)
    else:
        vflat, vcounts, flat, counts, v_before = numbers
        n_v, n_f = len(vcounts), len(counts)
    if not n_v:
        raise UserError(f"{where}: no vertices ('v' lines) found; pass a non-empty OBJ mesh")
    if not n_f:
        raise UserError(
            f"{where}: no faces ('f' lines) found; pass a surface mesh, not a point cloud"
        )
    if numbers is None:
        vflat, vcounts = _obj_vertex_numbers(vlines, where)
    V, C = _obj_vertices(vflat, vcounts, where)
    n = len(V)
    if numbers is None:
        flat, counts = _obj_face_indices(flines, where)
    _check_face_counts(counts, where)
    if np.any(flat == 0):
        raise UserError(
            f"{where}: face index 0 is invalid in OBJ (indices are 1-based); fix the file"
        )
    if np.any(flat < 0):
        # relative indices: -1 is the last vertex defined before this face line
        base = np.repeat(_vertices_before(text) if numbers is None else v_before, counts)
        idx = np.where(flat < 0, base + flat, flat - 1)
    else:
        idx = flat - 1
    faces = _check_faces(_polygons(idx, counts), n, where)
    return RawMesh(V=V, faces=faces, colors=C, path=path)


# --------------------------------------------------------------------------------------------
# OFF


def _read_off(path: Path) -> RawMesh:
    where = str(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise UserError(f"cannot read '{path}': {exc.strerror}; check the path and permissions")
    text = raw.decode("utf-8", errors="replace")
    lines = [s.split("#", 1)[0].strip() for s in text.splitlines()]
    lines = [s for s in lines if s]
    if not lines:
        raise UserError(f"{where}: file is empty; pass a non-empty OFF mesh")
    head = lines[0].split()
    word = head[0].upper()
    if not word.endswith("OFF") or "4" in word or "BINARY" in (t.upper() for t in head):
        raise UserError(
            f"{where}: unsupported OFF header '{lines[0][:30]}'; use an ASCII OFF/COFF/NOFF file"
        )
    prefix = word[:-3]
    has_normal = "N" in prefix
    has_color = "C" in prefix
    has_st = "ST" in prefix
    rest = head[1:]
    pos = 1
    if not rest:
        if len(lines) < 2:
            raise UserError(
                f"{where}: missing vertex/face counts after the OFF header; fix the file"
            )
        rest = lines[1].split()
        pos = 2
    try:
        nv, nf = int(rest[0]), int(rest[1])
    except (ValueError, IndexError):
        raise UserError(
            f"{where}: unparsable vertex/face counts '{' '.join(rest)}'; fix the file"
        ) from None
    if nv <= 0:
        raise UserError(f"{where}: no vertices; pass a non-empty mesh")
    if nf <= 0:
        raise UserError(f"{where}: no faces; pass a surface mesh, not a point cloud")
    vlines = lines[pos:pos + nv]
    flines = lines[pos + nv:pos + nv + nf]
    if len(vlines) < nv or len(flines) < nf:
        raise UserError(
            f"{where}: file ends early (header announces {nv} vertices and {nf} faces); "
            f"fix the file"
        )
    extra = len(lines) - (pos + nv + nf)
    if extra:
        raise UserError(
            f"{where}: header announces {nv} vertices and {nf} faces but {extra} more lines "
            f"follow them; fix the counts in the header"
        )
    counts = np.fromiter((len(s.split()) for s in vlines), dtype=np.int64, count=nv)
    try:
        flat = _parse_floats(" ".join(vlines))
    except ValueError:
        raise UserError(f"{where}: unparsable vertex data; fix the file") from None
    if len(flat) != counts.sum() or counts.min() < 3:
        raise UserError(f"{where}: a vertex line has fewer than 3 coordinates; fix the file")
    offsets = np.r_[0, np.cumsum(counts)[:-1]]
    V = flat[offsets[:, None] + np.arange(3)]
    C = None
    if has_color:
        start = 3 + (3 if has_normal else 0)
        extra = counts - start - (2 if has_st else 0)
        k = int(extra.min())
        if k >= 3:
            k = min(k, 4) if np.all(extra >= 4) else 3
            C = _normalise_colors(flat[offsets[:, None] + start + np.arange(k)], nv, where)
    fcounts = np.fromiter((len(s.split()) for s in flines), dtype=np.int64, count=nf)
    try:
        fflat = _parse_floats(" ".join(flines))
    except ValueError:
        raise UserError(f"{where}: unparsable face data; fix the file") from None
    if len(fflat) != fcounts.sum():
        raise UserError(f"{where}: unparsable face data; fix the file")
    foff = np.r_[0, np.cumsum(fcounts)[:-1]]
    k = fflat[foff]
    if np.any(k < 3) or np.any(k != np.round(k)) or np.any(k + 1 > fcounts):
        raise UserError(f"{where}: malformed face line (vertex count missing or < 3); fix the file")
    k = k.astype(np.int64)
    if np.all(k == 3):
        idx_f = fflat[foff[:, None] + 1 + np.arange(3)]
    else:
        sel = np.repeat(foff + 1, k) + (np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k))
        idx_f = fflat[sel]
    if np.any(idx_f != np.round(idx_f)):
        raise UserError(f"{where}: non-integer face index; fix the file")
    idx = idx_f.astype(np.int64)
    faces = _check_faces(idx if idx.ndim == 2 else _polygons(idx, k), nv, where)
    return RawMesh(V=V, faces=faces, colors=C, path=path)


# --------------------------------------------------------------------------------------------
# PLY / STL via trimesh


def _read_trimesh(path: Path) -> RawMesh:
    where = str(path)
    if path.stat().st_size == 0:
        raise UserError(f"{where}: file is empty; pass a non-empty mesh")
    try:
        import trimesh
    except ImportError:  # pragma: no cover - dependency
        raise UserError(
            "reading .ply/.stl needs the 'trimesh' package; pip install trimesh"
        ) from None
    try:
        mesh = trimesh.load(str(path), process=False, force="mesh")
    except Exception as exc:  # trimesh raises many types for corrupt files
        msg = " ".join(str(exc).split())[:120]
        raise UserError(
            f"{where}: cannot parse {path.suffix} file ({msg}); fix or re-export the file"
        ) from None
    V = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    Fa = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
    if len(V) == 0:
        raise UserError(f"{where}: no vertices found; pass a non-empty mesh")
    if len(Fa) == 0:
        raise UserError(f"{where}: no faces found; pass a surface mesh, not a point cloud")
    C = None
    visual = getattr(mesh, "visual", None)
    if visual is not None and getattr(visual, "kind", None) == "vertex":
        vc = np.asarray(visual.vertex_colors)
        if vc.shape[0] == len(V):
            vc = vc.astype(np.float64) / 255.0
            C = vc[:, :3] if np.all(vc[:, 3] == 1.0) else vc
    faces = _check_faces(Fa.reshape(-1, 3), len(V), where)
    return RawMesh(V=np.ascontiguousarray(V), faces=faces, colors=C, path=path)


# --------------------------------------------------------------------------------------------
# MATLAB


def _mat_array(d: dict, names: tuple[str, ...]):
    for k in names:
        if k in d:
            return k, np.asarray(d[k])
    return None, None


def _read_mat(path: Path) -> RawMesh:
    where = str(path)
    if path.stat().st_size == 0:
        raise UserError(f"{where}: file is empty; pass a non-empty .mat file")
    import scipy.io

    try:
        d = scipy.io.loadmat(str(path))
    except NotImplementedError:
        raise UserError(
            f"{where}: MATLAB v7.3 (HDF5) files are not supported; save with save(..., '-v7')"
        ) from None
    except Exception as exc:
        msg = " ".join(str(exc).split())[:120]
        raise UserError(
            f"{where}: cannot read .mat file ({msg}); re-save it with save(..., '-v7')"
        ) from None
    _, V = _mat_array(d, ("V", "v"))
    _, F = _mat_array(d, ("F", "f"))
    if V is None or F is None:
        keys = ", ".join(k for k in d if not k.startswith("__")) or "none"
        raise UserError(
            f"{where}: .mat file needs vertex array 'V' (or 'v') and face array 'F' (or 'f'); "
            f"found variables: {keys}"
        )
    if V.ndim == 2 and V.shape[1] != 3 and V.shape[0] == 3:
        V = V.T
    if F.ndim == 2 and F.shape[1] != 3 and F.shape[0] == 3:
        F = F.T
    if V.ndim != 2 or V.shape[1] != 3 or V.size == 0:
        raise UserError(f"{where}: 'V' has shape {V.shape}; expected n×3 vertex coordinates")
    if F.ndim != 2 or F.shape[1] < 3 or F.size == 0:
        raise UserError(
            f"{where}: 'F' has shape {F.shape}; expected m×3 (1-based) triangle indices"
        )
    try:
        V = V.astype(np.float64)
        Ff = F.astype(np.float64)
    except (TypeError, ValueError):
        raise UserError(f"{where}: 'V'/'F' are not numeric arrays; fix the .mat file") from None
    if np.any(Ff != np.round(Ff)):
        raise UserError(f"{where}: 'F' contains non-integer indices; fix the .mat file")
    Fi = Ff.astype(np.int64)
    if Fi.min() < 1:
        raise UserError(
            f"{where}: face index {int(Fi.min())} found but .mat faces must be 1-based (MATLAB); "
            f"add 1 to the face array"
        )
    Fi = Fi - 1
    if Fi.shape[1] == 3:
        faces = Fi
    else:
        faces = [row for row in Fi]
    faces = _check_faces(faces, len(V), where)
    _, C = _mat_array(d, ("C", "colors"))
    if C is not None and C.ndim == 2 and C.shape[0] in (3, 4) and C.shape[1] == len(V):
        C = C.T
    C = _normalise_colors(C, len(V), where) if C is not None else None
    return RawMesh(V=np.ascontiguousarray(V), faces=faces, colors=C, path=path)


# --------------------------------------------------------------------------------------------


def format_problem(path) -> str | None:
    """Why ``path`` is not a mesh file by its suffix (a one-line message naming the supported
    ones), or ``None`` when its suffix is one of :data:`SUPPORTED_EXTENSIONS`."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in SUPPORTED_EXTENSIONS:
        return None
    return (f"unsupported mesh format '{ext or path.name}' for '{path}'; "
            f"use one of {', '.join(SUPPORTED_EXTENSIONS)}")


def read_mesh(path) -> RawMesh:
    """Read ``.obj``, ``.off``, ``.ply``, ``.stl`` or ``.mat``; see the module docstring."""
    path = Path(path)
    ext = path.suffix.lower()
    problem = format_problem(path)
    if problem:
        raise UserError(problem)
    problem = file_problem(path)
    if problem:
        raise UserError(f"mesh file '{path}' {problem}; check the path")
    if path.stat().st_size == 0:
        raise UserError(f"mesh file '{path}' is empty; pass a non-empty mesh")
    reader = {".obj": _read_obj, ".off": _read_off, ".ply": _read_trimesh,
              ".stl": _read_trimesh, ".mat": _read_mat}[ext]
    mesh = reader(path)
    if not np.all(np.isfinite(mesh.V)):
        bad = int(np.count_nonzero(~np.isfinite(mesh.V).all(axis=1)))
        raise UserError(f"{path}: {bad} vertices have NaN/inf coordinates; fix the file")
    refuse_huge_coordinates(mesh.V, str(path))
    return mesh


def refuse_huge_coordinates(V: np.ndarray, subject: str) -> None:
    """Raise :class:`UserError` (naming ``subject``, a file or a mesh) where a coordinate of
    ``V`` (n×3) exceeds :data:`MAX_COORDINATE` in magnitude: squared lengths and areas would
    overflow."""
    big = float(np.abs(V).max(initial=0.0))
    if big > MAX_COORDINATE:
        raise UserError(f"{subject}: coordinates up to {big:.3g} overflow in squared lengths and "
                        f"areas (the limit is {MAX_COORDINATE:.0e} in magnitude); rescale the "
                        f"mesh")


def _format_rows(fmt: str, arr: np.ndarray) -> str:
    """``fmt`` repeated once per row of ``arr`` and filled as ``%`` fills it: ``fmt``'s
    fields are all ``%r`` (floats: their ``repr``) or all ``%d`` (integers), one per column,
    and the text between them is ASCII; compiled (:func:`..geometry._kernels.format_rows`)."""
    from ..geometry._kernels import format_rows

    if len(arr) == 0:
        return ""
    code = "%r" if "%r" in fmt else "%d"
    dtype = np.float64 if code == "%r" else np.int64
    return format_rows(fmt.split(code), np.ascontiguousarray(arr, dtype=dtype))


def write_obj(path, V, F, uv=None, colors=None, header=None) -> Path:
    """Write a triangle mesh as OBJ (1-based), atomically.

    ``v x y z`` (``v x y z r g b`` when ``colors`` is given; an alpha channel is dropped), one
    ``vt u v`` per vertex when ``uv`` (n×2) is given and then faces ``f i/i j/j k/k``, else
    ``f i j k``. ``header`` (str or list of str) is written as ``#`` comment lines. Floats are
    written with their shortest round-trip representation, so reading back gives identical
    arrays. Returns the path.
    """
    path = Path(path)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"V must be n×3, got {V.shape}")
    if F.size and (F.ndim != 2 or F.shape[1] != 3):
        raise ValueError(f"F must be m×3, got {F.shape}")
    parts = []
    if header:
        lines = [header] if isinstance(header, str) else list(header)
        for h in lines:
            for s in str(h).splitlines() or [""]:
                parts.append(f"# {s}\n")
    if colors is not None:
        C = np.asarray(colors, dtype=np.float64)
        if C.shape[0] != len(V) or C.ndim != 2 or C.shape[1] < 3:
            raise ValueError(f"colors must be n×3 or n×4, got {C.shape}")
        parts.append(_format_rows("v %r %r %r %r %r %r\n", np.hstack([V, C[:, :3]])))
    else:
        parts.append(_format_rows("v %r %r %r\n", V))
    F1 = F.reshape(-1, 3) + 1
    if uv is not None:
        U = np.asarray(uv, dtype=np.float64)
        if U.shape != (len(V), 2):
            raise ValueError(f"uv must be n×2 ({len(V)}×2), got {U.shape}")
        parts.append(_format_rows("vt %r %r\n", U))
        parts.append(_format_rows("f %d/%d %d/%d %d/%d\n", np.repeat(F1, 2, axis=1)))
    else:
        parts.append(_format_rows("f %d %d %d\n", F1))
    return atomic_write(path, "".join(parts))
